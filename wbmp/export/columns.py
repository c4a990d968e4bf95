"""The columns of a motion file that other tools read: base pose, joint positions and velocities,
and the movable scene objects' poses."""

from __future__ import annotations

import unicodedata
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from wbmp.errors import CliError, ExitCode

BASE_NQ = 7  # free flyer: x, y, z [m], qx, qy, qz, qw (Pinocchio order)
BASE_NV = 6  # free flyer: linear [m/s] and angular [rad/s] velocity in the base frame
OBJECT_FRAME_PREFIX = "object_"  # keeps an object's frame apart from the robot's URDF links


@dataclass(frozen=True, eq=False)
class MotionColumns:
    """One trajectory (the plan or the execution) split into the parts other tools name.

    Attributes:
        t: Times [s], (T,).
        position_base_in_world: Base position [m], (T, 3).
        quaternion_base_in_world: Base orientation, (T, 4), order x, y, z, w (Pinocchio's and ROS's).
        joint_positions: (T, n) [rad] (or [m] for a prismatic joint), joints in ``joint_names`` order.
        joint_velocities: (T, n) [rad/s].
        base_velocity_in_base: (T, 6): linear [m/s] then angular [rad/s], in the base frame.
        joint_accelerations: (T, n) [rad/s^2] or None (the execution has none).
        joint_torques: (T, n) [N m] or None (the plan has none).
        object_names: The movable scene objects this trajectory has poses of (the file's
            ``object_names`` order), or () when it has none.
        object_pose: (T, k, 7) their poses in the world: centre x, y, z [m], quaternion x, y, z, w;
            None when ``object_names`` is empty.
    """

    t: np.ndarray
    position_base_in_world: np.ndarray
    quaternion_base_in_world: np.ndarray
    joint_positions: np.ndarray
    joint_velocities: np.ndarray
    base_velocity_in_base: np.ndarray
    joint_accelerations: np.ndarray | None = None
    joint_torques: np.ndarray | None = None
    object_names: tuple[str, ...] = ()
    object_pose: np.ndarray | None = None


def plan_columns(motion) -> MotionColumns:
    """The plan of a motion file (joint torques None).

    Raises:
        CliError (exit 2): the joints cannot be named one column each (see :func:`joint_names`).
    """
    joint_names(motion)
    plan = motion.plan
    names = tuple(motion.objects)
    pose = np.stack([motion.objects[n] for n in names], axis=1) if names else None
    return _columns(plan.t, plan.q, plan.v, plan.a, None, names, pose)


def execution_columns(motion) -> MotionColumns | None:
    """The simulated execution of a motion file (joint accelerations None), or None if it has none.

    Raises:
        CliError (exit 2): the joints cannot be named one column each (see :func:`joint_names`).
    """
    joint_names(motion)
    ex = motion.execution
    if ex is None:
        return None
    poses = ex.object_poses()
    names = tuple(poses)
    return _columns(ex.t, ex.q, ex.v, None, ex.tau, names,
                    np.stack(list(poses.values()), axis=1) if names else None)


def _columns(t, q, v, a, tau, object_names=(), object_pose=None) -> MotionColumns:
    return MotionColumns(
        t=np.asarray(t, dtype=float),
        position_base_in_world=np.asarray(q[:, :3], dtype=float),
        quaternion_base_in_world=np.asarray(q[:, 3:BASE_NQ], dtype=float),
        joint_positions=np.asarray(q[:, BASE_NQ:], dtype=float),
        joint_velocities=np.asarray(v[:, BASE_NV:], dtype=float),
        base_velocity_in_base=np.asarray(v[:, :BASE_NV], dtype=float),
        joint_accelerations=None if a is None else np.asarray(a[:, BASE_NV:], dtype=float),
        joint_torques=None if tau is None else np.asarray(tau, dtype=float),
        object_names=tuple(object_names),
        object_pose=None if object_pose is None else np.asarray(object_pose, dtype=float),
    )


def object_names(motion) -> list[str]:
    """The movable objects a motion file has poses of, in its ``object_names`` order (planned or
    simulated poses; [] for a file without objects)."""
    names = list(motion.objects)
    if not names and motion.execution is not None:
        names = list(motion.execution.objects)
    return names


def object_frame_ids(names: Iterable[str], taken: Iterable[str] = ()) -> dict[str, str]:
    """Object name -> its frame id: ``object_`` + the name made a ROS name, unique.

    The name is NFKD-normalized with its combining marks dropped (``Café`` -> ``Cafe``) and lower
    cased; each character outside ``a-z``, ``0-9`` that is still non-ASCII becomes ``u`` and its code
    point in 4+ lower-case hex digits between underscores (``杯`` -> ``_u676f_``); every other run of
    characters outside ``a-z0-9`` (spaces, ``-``, ``.``...) becomes one ``_``; leading and trailing
    ``_`` are dropped. So ``Red cup`` -> ``object_red_cup``, ``杯子`` -> ``object_u676f_u5b50``.
    Names that give the same id (``Cup``, ``cup``), or an id in ``taken`` (the world and base
    frames), get ``_2``, ``_3``... in ``names`` order (the first keeps the plain id).
    """
    used = set(taken)
    out: dict[str, str] = {}
    for name in names:
        lowered = unicodedata.normalize("NFKD", unicodedata.normalize("NFKD", name).lower())
        chars = []
        for ch in lowered:  # one code point each
            if unicodedata.combining(ch):
                continue
            if ("a" <= ch <= "z") or ("0" <= ch <= "9"):
                chars.append(ch)
            elif ord(ch) < 128:
                chars.append("_")
            else:
                chars.append(f"_u{ord(ch):04x}_")
        slug = "_".join(part for part in "".join(chars).split("_") if part)
        base = OBJECT_FRAME_PREFIX + slug if slug else OBJECT_FRAME_PREFIX.rstrip("_")
        frame, n = base, 1
        while frame in used:
            n += 1
            frame = f"{base}_{n}"
        used.add(frame)
        out[name] = frame
    return out


def refused(message: str) -> CliError:
    """A motion file this export cannot convert (exit 2, like a damaged motion file)."""
    return CliError(message, ExitCode.USAGE)


def joint_names(motion) -> list[str]:
    """The actuated joints' names (URDF names, Pinocchio order), one per q and v column.

    Raises:
        CliError (exit 2): the file names no joints or not one per column (a file written without
            a robot), or a joint has more position than velocity coordinates (a continuous or
            spherical joint, which these formats do not describe as one number).
    """
    nq, nv = motion.plan.q.shape[1], motion.plan.v.shape[1]
    names = list(motion.joint_names)
    if nq - BASE_NQ != nv - BASE_NV:
        raise refused(f"motion file of {motion.robot_name!r}: nq - 7 = {nq - BASE_NQ} position but "
                              f"nv - 6 = {nv - BASE_NV} velocity columns (a continuous or spherical joint); "
                              "this export needs one position per joint: use --format json or csv")
    if len(names) != nv - BASE_NV:
        raise refused(f"motion file of {motion.robot_name!r}: key 'joint_names' has {len(names)} names "
                              f"for {nv - BASE_NV} joints; this export names every joint (write the file with "
                              "`wbmp solve --out`, which stores them), or use --format json or csv")
    for i, name in enumerate(names):  # a bag's JointState and a tracker's columns are found by name
        if not name.strip() or any(ord(c) < 32 or ord(c) == 127 for c in name) or len(name) > 256:
            raise refused(f"motion file of {motion.robot_name!r}: key 'joint_names' has an unusable name "
                          f"{name[:40]!r} at index {i} (empty, blank or with control characters); this "
                          "export names every joint: use --format json or csv")
    seen: dict[str, int] = {}
    for i, name in enumerate(names):
        if name in seen:
            raise refused(f"motion file of {motion.robot_name!r}: key 'joint_names' names {name[:40]!r} twice "
                          f"(index {seen[name]} and {i}); this export names every joint once: use --format json or csv")
        seen[name] = i
    return names
