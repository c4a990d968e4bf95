"""The physical figures of a retargeted motion, from its configurations (Pinocchio forward kinematics).

Definitions (docs/retarget.md), over the clip's span (the lead-in and lead-out excluded):

* **tracking error** [m]: distance between each tracked robot frame (base, torso, head, hands,
  feet) and its scaled source keypoint, at every sample; mean and max, and the worst one named
  (keypoint and time).
* **foot skate** [mm]: while a foot's labelled contact holds (the spec's phases), the largest
  horizontal travel of its sole frame from where the contact began (the UHC-style skate, as
  displacement rather than speed).
* **penetration** [mm]: the deepest any sole corner goes below the floor (z < 0), at any time.
* **float** [mm]: while a foot's labelled contact holds, the largest height of its lowest sole
  corner above the floor.
* **joint jerk** [rad/s^3]: mean over samples and joints of |d^3 q / dt^3| (finite differences).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from robots import Robot, sole_corners_in_world
from tasks.mocap.retarget import TRACKED, Reference
from tasks.mocap.source import SIDES
from tasks.specs import TaskSpec


@dataclass(frozen=True)
class Figures:
    """The figures of one motion (see the module for the definitions)."""

    tracking_mean: float  # [m]
    tracking_max: float  # [m]
    worst: str  # "left_hand 0.31 m from the source at 2.40 s"
    skate: float  # [mm]
    penetration: float  # [mm]
    float_: float  # [mm]
    jerk: float  # [rad/s^3]
    per_keypoint: dict[str, float | None]  # mean tracking error per keypoint [m] (None: never tracked)
    worst_role: str = ""  # the keypoint of the largest error
    worst_time: float = 0.0  # [s] when it happened

    def to_dict(self) -> dict[str, object]:
        """The figures as JSON-ready numbers."""
        return {"tracking_mean_m": self.tracking_mean, "tracking_max_m": self.tracking_max, "worst": self.worst,
                "foot_skate_mm": self.skate, "penetration_mm": self.penetration, "float_mm": self.float_,
                "joint_jerk_rad_s3": self.jerk, "tracking_mean_per_keypoint_m": dict(self.per_keypoint)}

    def summary(self) -> str:
        """Two lines for the terminal."""
        return (f"tracking error: mean {self.tracking_mean:.3f} m, max {self.tracking_max:.3f} m ({self.worst})\n"
                f"foot skate {self.skate:.1f} mm, penetration {self.penetration:.1f} mm, float {self.float_:.1f} mm, "
                f"joint jerk {self.jerk:.0f} rad/s^3")


def contact_windows(spec: TaskSpec, frame: str) -> list[tuple[float, float]]:
    """Time spans [s] over which ``frame`` is in one continuous contact at one placement."""
    spans: list[list] = []  # [start, end, placement]
    for start, phase in zip(spec.phase_start_times(), spec.phases, strict=True):
        c = next((c for c in phase.contacts if c.frame == frame), None)
        if c is None:
            continue
        if spans and abs(spans[-1][1] - start) < 1e-9 and spans[-1][2] == c.placement:
            spans[-1][1] = start + phase.duration
        else:
            spans.append([start, start + phase.duration, c.placement])
    return [(float(a), float(b)) for a, b, _ in spans]


@dataclass(frozen=True, eq=False)
class Tracks:
    """The tracked keypoints of a motion beside their scaled source, sample by sample.

    Attributes:
        t: Sample times (T,) [s].
        robot: Role -> the robot frame's position (T, 3) [m] (Pinocchio forward kinematics).
        source: Role -> the scaled source keypoint at the same time (T, 3) [m].
        error: Role -> their distance (T,) [m]; NaN outside the clip, and for a foot while its
            labelled contact holds (it tracks its fixed placement then, not the rolling source foot).
        soles: Foot side -> the sole frame's position (T, 3) [m].
        corners: Foot side -> the sole's four corners (T, 4, 3) [m].
        inside: The samples within the clip's span (T,).
    """

    t: np.ndarray
    robot: dict[str, np.ndarray]
    source: dict[str, np.ndarray]
    error: dict[str, np.ndarray]
    soles: dict[str, np.ndarray]
    corners: dict[str, np.ndarray]
    inside: np.ndarray

    def worst(self) -> tuple[str, int, float]:
        """(role, sample index, error [m]) of the largest tracking error; ("", 0, -1.0) when no
        sample has one."""
        stack = np.array([self.error[r] for r in TRACKED])
        if not np.isfinite(stack).any():
            return "", 0, -1.0
        i_role, i_t = np.unravel_index(np.nanargmax(stack), stack.shape)
        return TRACKED[int(i_role)], int(i_t), float(stack[i_role, i_t])

    def select(self, keep: np.ndarray) -> Tracks:
        """These tracks at the samples ``keep`` (a boolean mask or indices) only."""
        def cut(d: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
            return {k: v[keep] for k, v in d.items()}

        return Tracks(t=self.t[keep], robot=cut(self.robot), source=cut(self.source), error=cut(self.error),
                      soles=cut(self.soles), corners=cut(self.corners), inside=self.inside[keep])

    def foot_heights(self) -> dict[str, np.ndarray]:
        """Foot side -> the height of its sole's lowest corner (T,) [m]."""
        return {s: c[:, :, 2].min(axis=1) for s, c in self.corners.items()}


def tracks(robot: Robot, t: np.ndarray, q: np.ndarray, ref: Reference) -> Tracks:
    """The tracked keypoints of configurations ``q`` (T, nq) at times ``t`` (T,) [s] and their source."""
    model, data = robot.model, robot.data()
    clip0, clip1 = float(ref.t[0]), float(ref.t[-1])
    fids = {role: robot.frame_id(role) for role in TRACKED}
    feet = {side: robot.frame_id(f"{side}_foot") for side in SIDES}
    pos = {role: np.empty((len(t), 3)) for role in TRACKED}
    soles = {side: np.empty((len(t), 3)) for side in SIDES}
    corners = {side: np.empty((len(t), 4, 3)) for side in SIDES}
    sole = robot.profile.sole
    for i, qi in enumerate(q):
        pin.framesForwardKinematics(model, data, qi)
        for role, fid in fids.items():
            pos[role][i] = data.oMf[fid].translation
        for side in SIDES:
            soles[side][i] = data.oMf[feet[side]].translation
            corners[side][i] = sole_corners_in_world(sole, side, data.oMf[feet[side]])  # this FK's (no new Data)
    inside = (t >= clip0 - 1e-9) & (t <= clip1 + 1e-9)
    frame_of = np.clip(np.round((t - clip0) / (ref.t[1] - ref.t[0])).astype(int), 0, len(ref.t) - 1)
    source = {role: ref.points[role][frame_of] for role in TRACKED}
    errors: dict[str, np.ndarray] = {}
    for role in TRACKED:
        err = np.linalg.norm(pos[role] - source[role], axis=1)
        if role.endswith("_foot"):  # a stance foot tracks its fixed placement, not the rolling source foot
            side = role.split("_")[0]
            err = np.where(ref.contact[side][frame_of], np.nan, err)
        errors[role] = np.where(inside, err, np.nan)
    return Tracks(t=np.asarray(t, dtype=float), robot=pos, source=source, error=errors, soles=soles,
                  corners=corners, inside=inside)


def motion_figures(robot: Robot, t: np.ndarray, q: np.ndarray, spec: TaskSpec, ref: Reference) -> Figures:
    """The figures of configurations ``q`` (T, nq) at times ``t`` (T,) [s] retargeting ``ref``."""
    tr = tracks(robot, t, q, ref)
    clip0, clip1 = float(ref.t[0]), float(ref.t[-1])
    soles, corners, inside = tr.soles, tr.corners, tr.inside
    stack = np.array([tr.error[r] for r in TRACKED])
    worst_role, i_t, worst_err = tr.worst()
    d = tr.robot[worst_role][i_t] - tr.source[worst_role][i_t]
    axis = int(np.argmax(np.abs(d)))
    words = [("behind", "ahead of"), ("right of", "left of"), ("below", "above")][axis]
    worst = (f"{worst_role.replace('_', ' ')} {worst_err:.2f} m from the source at {t[i_t]:.2f} s, "
             f"mostly {abs(d[axis]):.2f} m {words[int(d[axis] > 0)]} it")
    skate = 0.0
    float_ = 0.0
    for side in SIDES:
        frame = robot.frame(f"{side}_foot")
        for a, b in contact_windows(spec, frame):
            a, b = max(a, clip0), min(b, clip1)
            sel = (t >= a - 1e-9) & (t <= b + 1e-9)
            if sel.sum() < 2:
                continue
            xy = soles[side][sel, :2]
            skate = max(skate, float(np.linalg.norm(xy - xy[0], axis=1).max()))
            float_ = max(float_, float(corners[side][sel, :, 2].min(axis=1).max()))
    low = min(float(corners[s][:, :, 2].min()) for s in SIDES)
    joints = q[:, 7:]
    dt = float(np.median(np.diff(t)))
    jerk = float(np.abs(np.diff(joints[inside], n=3, axis=0)).mean() / dt**3) if inside.sum() > 3 else 0.0
    return Figures(tracking_mean=float(np.nanmean(stack)), tracking_max=float(np.nanmax(stack)), worst=worst,
                   skate=1000.0 * skate, penetration=1000.0 * max(0.0, -low), float_=1000.0 * max(0.0, float_),
                   jerk=jerk, per_keypoint={r: _mean(tr.error[r]) for r in TRACKED}, worst_role=worst_role,
                   worst_time=float(t[i_t]))


def torque_cause(robot: Robot, role: str, time: float, t: np.ndarray, tau: np.ndarray,
                 window: float = 0.3, share: float = 0.95) -> str:
    """Why a keypoint missed its source, when a joint that carries it was at its torque limit:
    ``"arm_right_2_joint at its torque limit (21.7 of 22.3 N m)"`` (the joint of the frame's chain
    with the highest peak |tau| / limit within ``window`` [s] of ``time``, if at least ``share``);
    empty otherwise. ``tau`` (T, nv - 6) [N m] at times ``t`` (T,)."""
    model = robot.model
    joint = model.frames[robot.frame_id(role)].parentJoint
    chain = []
    while joint > 1:  # the actuated joints up to the free flyer
        chain.append(joint)
        joint = model.parents[joint]
    near = np.abs(t - time) <= window
    limits = robot.torque_limits
    if not near.any() or not chain or tau.shape[1] != len(limits):
        return ""
    best, name, peak, limit = 0.0, "", 0.0, 0.0
    for j in chain:
        col = model.joints[j].idx_v - 6
        if not 0 <= col < len(limits) or limits[col] <= 0:
            continue
        p = float(np.abs(tau[near, col]).max())
        if p / limits[col] > best:
            best, name, peak, limit = p / limits[col], model.names[j], p, float(limits[col])
    return f"{name} at its torque limit ({peak:.1f} of {limit:.1f} N m)" if best >= share else ""


def _mean(values: np.ndarray) -> float | None:
    """Mean of the finite values (None when there are none: a foot in contact throughout)."""
    finite = values[np.isfinite(values)]
    return float(finite.mean()) if len(finite) else None
