"""A motion resampled at a uniform rate for motion trackers (RL tracking policies, retargeting
tools): one ``.npz`` whose keys say their own order and units.

Keys (``docs/export.md`` is the reference): ``fps``, ``t`` (N,) [s], ``root_pos`` (N, 3) [m],
``root_rot`` (N, 4) in the order of ``root_rot_order`` (``"xyzw"``), ``root_lin_vel`` and
``root_ang_vel`` (N, 3) in the world frame, ``joint_pos``/``joint_vel`` (N, n) with
``joint_names`` (n,) in the same order, and the provenance (``robot``, ``source``, ``knot_t``...).
When the source has movable scene objects' poses: ``object_names`` (k,), ``object_pos`` (N, k, 3)
[m] and ``object_rot`` (N, k, 4) (order ``root_rot_order``), in the world frame.

Interpolation between two knots of the motion file at fraction ``u``: positions, joint angles
and velocities linearly, the root quaternion by slerp along the shorter arc. Samples are at
``t0 + j / fps`` up to the last knot; one that falls on a knot holds that knot's values.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from wbmp.export.columns import MotionColumns, execution_columns, joint_names, plan_columns, refused

TRACKER_FORMAT = "wbmp-tracker"
TRACKER_VERSION = 1
DEFAULT_FPS = 50.0  # [Hz] a humanoid tracking policy's usual control rate
MAX_FPS = 1000.0  # [Hz]
MAX_SAMPLES = 500_000  # samples of one tracker file (about 150 MB for a 30-joint robot)
ROOT_ROT_ORDER = "xyzw"
SOURCES = ("plan", "execution")
INTERPOLATION = "linear: root_pos, joint_pos, velocities; slerp (shorter arc): root_rot"
OBJECTS_INTERPOLATION = "linear: root_pos, joint_pos, velocities, object_pos; slerp (shorter arc): root_rot, object_rot"
_SLACK = 1e-9  # [-] of a sample period: a sample this close past the last knot still counts


def sample_times(t: np.ndarray, fps: float) -> np.ndarray:
    """Uniform sample times [s] ``t[0] + j / fps``, ``j = 0, 1, ...``, up to ``t[-1]``."""
    count = int(np.floor((float(t[-1]) - float(t[0])) * fps + _SLACK)) + 1
    return float(t[0]) + np.arange(count) / fps


def _segments(t: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Knot index k (t[k] <= s <= t[k+1]) and fraction u in [0, 1] of each sample time."""
    k = np.clip(np.searchsorted(t, s, side="right") - 1, 0, len(t) - 2)
    u = np.clip((s - t[k]) / (t[k + 1] - t[k]), 0.0, 1.0)
    return k, u


def _lerp(x: np.ndarray, k: np.ndarray, u: np.ndarray) -> np.ndarray:
    return (1.0 - u)[:, None] * x[k] + u[:, None] * x[k + 1]


def slerp(q0: np.ndarray, q1: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Spherical interpolation of unit quaternions (rows, any component order) along the shorter
    arc; exact at ``u = 0`` and ``u = 1`` (up to the sign of ``q1``)."""
    q0 = q0 / np.linalg.norm(q0, axis=1, keepdims=True)
    q1 = q1 / np.linalg.norm(q1, axis=1, keepdims=True)
    dot = np.sum(q0 * q1, axis=1)
    q1 = np.where((dot < 0.0)[:, None], -q1, q1)
    dot = np.abs(dot)
    theta = np.arccos(np.clip(dot, -1.0, 1.0))
    sin = np.sin(theta)
    near = sin < 1e-9  # (almost) the same rotation: linear, then normalized
    safe = np.where(near, 1.0, sin)
    w0 = np.where(near, 1.0 - u, np.sin((1.0 - u) * theta) / safe)
    w1 = np.where(near, u, np.sin(u * theta) / safe)
    out = w0[:, None] * q0 + w1[:, None] * q1
    return out / np.linalg.norm(out, axis=1, keepdims=True)


def quaternion_to_matrix(quat_xyzw: np.ndarray) -> np.ndarray:
    """Rotation matrices (N, 3, 3) of unit quaternions (N, 4) in x, y, z, w order."""
    x, y, z, w = (quat_xyzw / np.linalg.norm(quat_xyzw, axis=1, keepdims=True)).T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], axis=-1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], axis=-1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], axis=-1),
    ], axis=-2)


def resample(cols: MotionColumns, fps: float) -> dict[str, np.ndarray]:
    """The columns at ``fps`` [Hz]: ``t``, ``root_pos``, ``root_rot`` (xyzw, consecutive samples on
    one hemisphere), ``root_lin_vel``, ``root_ang_vel`` (world frame), ``joint_pos``, ``joint_vel``,
    and when ``cols`` has objects ``object_pos`` (N, k, 3) and ``object_rot`` (N, k, 4) (xyzw, each
    object's samples on one hemisphere), interpolated as the root is."""
    t = cols.t
    s = sample_times(t, fps)
    k, u = _segments(t, s)
    rot = _slerp_track(cols.quaternion_base_in_world, k, u)
    rotation_base_to_world = quaternion_to_matrix(cols.quaternion_base_in_world)
    v = cols.base_velocity_in_base
    lin_world = np.einsum("nij,nj->ni", rotation_base_to_world, v[:, :3])
    ang_world = np.einsum("nij,nj->ni", rotation_base_to_world, v[:, 3:])
    out = {
        "t": s,
        "root_pos": _lerp(cols.position_base_in_world, k, u),
        "root_rot": rot,
        "root_lin_vel": _lerp(lin_world, k, u),
        "root_ang_vel": _lerp(ang_world, k, u),
        "joint_pos": _lerp(cols.joint_positions, k, u),
        "joint_vel": _lerp(cols.joint_velocities, k, u),
    }
    if cols.object_pose is not None:
        pose = cols.object_pose
        out["object_pos"] = np.stack([_lerp(pose[:, i, :3], k, u) for i in range(pose.shape[1])], axis=1)
        out["object_rot"] = np.stack([_slerp_track(pose[:, i, 3:], k, u) for i in range(pose.shape[1])], axis=1)
    return out


def _slerp_track(quat: np.ndarray, k: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Quaternions (T, 4) slerped at segments ``k``, fractions ``u``; consecutive samples kept on
    one hemisphere (no sign jump between samples)."""
    rot = slerp(quat[k], quat[k + 1], u)
    flips = np.concatenate([[False], np.sum(rot[1:] * rot[:-1], axis=1) < 0.0])
    return np.where((np.cumsum(flips) % 2 == 1)[:, None], -rot, rot)


def check_fps(fps: float, duration: float | None = None) -> None:
    """Refuse a rate that is not a number in (0, MAX_FPS] Hz, or that gives fewer than 2 samples.

    Raises:
        ValueError: one line naming the value and the range.
    """
    if not (isinstance(fps, (int, float)) and np.isfinite(fps) and 0.0 < fps <= MAX_FPS):
        raise ValueError(f"fps must be a rate in (0, {MAX_FPS:g}] Hz, got {fps!r}")
    if duration is not None and duration * fps + _SLACK < 1.0:
        raise ValueError(f"fps {fps:g} Hz gives one sample for a {duration:g} s motion; raise it to at least "
                         f"{1.0 / duration:g} Hz")
    if duration is not None and duration * fps + 1.0 > MAX_SAMPLES:
        raise ValueError(f"fps {fps:g} Hz gives {duration * fps + 1.0:.0f} samples for a {duration:g} s motion, "
                         f"more than the {MAX_SAMPLES} a tracker file holds; lower it to at most "
                         f"{(MAX_SAMPLES - 1) / duration:g} Hz")


def source_columns(motion, fps: float, source: str) -> tuple[list[str], MotionColumns]:
    """The joint names and the columns of ``motion``'s plan or execution, checked for a sampling
    at ``fps`` (the tracker and LAFAN1 exports' common start).

    Raises:
        CliError (exit 2): the joints cannot be named, or ``source="execution"`` and the file
            holds no simulated execution.
        ValueError: a bad ``fps`` or ``source``.
    """
    if source not in SOURCES:
        raise ValueError(f"source must be one of {', '.join(SOURCES)}, got {source!r}")
    names = joint_names(motion)
    cols = plan_columns(motion) if source == "plan" else execution_columns(motion)
    if cols is None:
        raise refused(f"motion file of {motion.robot_name!r} holds no simulated execution (it was solved "
                      "with --no-sim); export the plan (--source plan) or solve again with the simulation")
    check_fps(fps, float(cols.t[-1] - cols.t[0]))
    return names, cols


def tracker_arrays(motion, fps: float = DEFAULT_FPS, source: str = "plan",
                   base_frame: str | None = None) -> dict[str, Any]:
    """Every key of the tracker file of ``motion``'s plan or execution, resampled at ``fps``.

    Raises:
        CliError (exit 2): the joints cannot be named, or ``source="execution"`` and the file
            holds no simulated execution.
        ValueError: a bad ``fps`` or ``source``.
    """
    from wbmp.export.rosbag import WORLD_FRAME, base_frame_of
    names, cols = source_columns(motion, fps, source)
    out: dict[str, Any] = {
        "format": np.array(TRACKER_FORMAT), "version": np.array(TRACKER_VERSION),
        "fps": np.array(float(fps)), "robot": np.array(motion.robot_name), "source": np.array(source),
        "joint_names": np.array(names, dtype=str), "root_rot_order": np.array(ROOT_ROT_ORDER),
        "world_frame": np.array(WORLD_FRAME), "up_axis": np.array("z"),
        "root_frame": np.array(base_frame or base_frame_of(motion.robot_name)),
        "interpolation": np.array(INTERPOLATION if cols.object_pose is None else OBJECTS_INTERPOLATION),
        "knot_t": cols.t,
    }
    out.update(resample(cols, fps))
    if cols.object_pose is not None:
        out["object_names"] = np.array(cols.object_names, dtype=str)
    return out
