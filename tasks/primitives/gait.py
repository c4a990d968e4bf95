"""Shared pieces of the leg motions (:mod:`.legs`, :mod:`.hop`): phase lists on the knot grid,
foot placements, the leg length, and arc footsteps.

A motion is written as a list of :class:`Segment`\\ s (a phase in seconds with its contacts).
:func:`segment_knots` turns each into whole knots (single support rounded to the nearest knot,
double support rounded down, flights rounded *up* so a flight is never shorter than asked),
:func:`sequence_duration` is the nominal duration the primitive reports (the knots at the
default grid), and :func:`write_segments` writes the phases through a
:class:`~tasks.primitives.base.FragmentBuilder` on exactly those knots and returns the knot
boundaries, so targets can be placed on a phase's start, middle or end.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import cast

import numpy as np
import pinocchio as pin

from robots import Robot
from tasks.exceptions import TaskDefinitionError
from tasks.footsteps import standing_feet
from tasks.primitives.base import DEFAULT_DT, FragmentBuilder
from tasks.primitives.geometry import Stance
from tasks.specs import Contact, Pose, Vec3

SIDES = ("left", "right")
OTHER = {"left": "right", "right": "left"}
SIDE_SIGN = {"left": 1.0, "right": -1.0}


@dataclass(frozen=True, slots=True, kw_only=True)
class Segment:
    """One phase of a leg motion, before it is put on the knot grid.

    Attributes:
        name: Phase name.
        duration: Nominal length [s].
        contacts: Soles in contact (empty: flight).
        swing_height: Clearance of a foot off the ground at the phase's middle [m].
        rounding: ``nearest``, ``floor`` (at least one knot) or ``ceil`` (flights).
    """

    name: str
    duration: float
    contacts: tuple[Contact, ...]
    swing_height: float = 0.05
    rounding: str = "nearest"


def segment_knots(seg: Segment, dt: float) -> int:
    """Whole knots of a segment on a grid of ``dt`` [s] (at least one)."""
    n = seg.duration / dt
    if seg.rounding == "ceil":
        k = math.ceil(n - 1e-9)
    elif seg.rounding == "floor":
        k = math.floor(n + 1e-9)
    else:
        k = round(n)
    return max(1, int(k))


def sequence_duration(segments: Sequence[Segment], dt: float = DEFAULT_DT) -> float:
    """Duration of the segments on a grid of ``dt`` [s]."""
    return sum(segment_knots(s, dt) for s in segments) * dt


def write_segments(b: FragmentBuilder, segments: Sequence[Segment]) -> list[int]:
    """Write the segments as phases on whole knots; the last one takes the rest of the fragment.

    Returns:
        Knot boundaries relative to the fragment start: ``[0, end of segment 1, ...]``.
    """
    bounds = [0]
    for seg in segments[:-1]:
        bounds.append(bounds[-1] + segment_knots(seg, b.dt))
    if bounds[-1] >= b.n_knots:
        raise TaskDefinitionError(
            f"{b.action.name}: its phases do not fit in {b.n_knots} knots of {b.dt:g} s; use the default grid"
        )
    bounds.append(b.n_knots)
    for seg, k in zip(segments, bounds[1:], strict=True):
        b.phase(seg.name, tau(b, k), seg.contacts, swing_height=seg.swing_height)
    return bounds


def tau(b: FragmentBuilder, k: int) -> float:
    """Nominal time of relative knot ``k`` (the builder maps it back onto exactly that knot)."""
    return float(k) * b.dt / b.scale


def contact(robot: Robot, side: str, placement: Pose) -> Contact:
    """A sole contact."""
    return Contact(frame=robot.frame(f"{side}_foot"), placement=placement)


def both(robot: Robot, where: dict[str, Pose]) -> tuple[Contact, ...]:
    """Both soles at their placements."""
    return tuple(contact(robot, s, where[s]) for s in SIDES)


def start_placements(robot: Robot, stance: Stance | None) -> dict[str, Pose]:
    """Sole placements of a stance (the standing feet by default)."""
    if stance is None:
        left, right = standing_feet(robot)
        return {"left": left, "right": right}
    return {"left": stance.left, "right": stance.right}


def heading_yaw(where: dict[str, Pose]) -> tuple[np.ndarray, float]:
    """Mid point (3,) and mean yaw [rad] of both soles."""
    yaws = [where[s].rpy[2] for s in SIDES]
    yaw = math.atan2(sum(math.sin(y) for y in yaws), sum(math.cos(y) for y in yaws))
    mid = 0.5 * (np.asarray(where["left"].position) + np.asarray(where["right"].position))
    return mid, yaw


def rz(yaw: float) -> np.ndarray:
    """Rotation about z (3, 3)."""
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def clean(v) -> Vec3:
    """A 3-tuple of floats with round-off below 1e-12 set to zero."""
    return cast(Vec3, tuple(0.0 if abs(float(x)) < 1e-12 else float(x) for x in v))


def wrap(angle: float) -> float:
    """Angle in (-pi, pi] [rad]."""
    return float(math.atan2(math.sin(angle), math.cos(angle)))


def shifted(pose: Pose, offset: np.ndarray) -> Pose:
    """A placement moved by a world offset (3,) [m]."""
    return Pose(position=clean(np.asarray(pose.position) + offset), rpy=pose.rpy)


@functools.cache
def leg_length(robot: Robot) -> float:
    """Height of the hip joints above the soles at the standing posture [m] (mean of both legs).

    The hip is the first joint of the chain from the base to the sole.
    """
    model, data = robot.model, robot.data()
    pin.framesForwardKinematics(model, data, robot.q_standing)
    out = []
    for side in SIDES:
        fid = robot.frame_id(f"{side}_foot")
        chain = [j for j in model.supports[model.frames[fid].parentJoint] if j > 1]
        if not chain:
            raise TaskDefinitionError(f"{robot.name}: no leg joints above the {side} sole")
        out.append(float(data.oMi[chain[0]].translation[2] - data.oMf[fid].translation[2]))
    return float(np.mean(out))


# ---------------------------------------------------------------------------------------------
# Arc footsteps
# ---------------------------------------------------------------------------------------------

ARC_STEP_FRACTION = 0.8  # outer-foot steps along an arc: at most this fraction of step_length_max
ARC_TURN_MAX = 0.35  # [rad] largest yaw between the feet on an arc


@dataclass(frozen=True, slots=True, kw_only=True)
class ArcSteps:
    """Footsteps along an arc.

    Attributes:
        swings: (side, landing placement) in order.
        left, right: Final placements.
        step_angle: Arc angle between the feet after each swing [rad].
    """

    swings: tuple[tuple[str, Pose], ...]
    left: Pose
    right: Pose
    step_angle: float


def arc_step_angle_max(robot: Robot, radius: float, width: float) -> float:
    """Largest arc angle between the feet [rad]: the outer foot's step within
    ``ARC_STEP_FRACTION * step_length_max`` and the yaw between the feet within ``ARC_TURN_MAX``."""
    outer = radius + 0.5 * width
    return min(ARC_STEP_FRACTION * robot.profile.step_length_max / outer, ARC_TURN_MAX)


def arc_steps(robot: Robot, where: dict[str, Pose], radius: float, side: str, angle: float) -> ArcSteps:
    """Alternating swings that carry both feet ``angle`` along a circle of ``radius`` [m].

    The centre of the circle is ``radius`` to the ``side`` of the point between the feet; each
    foot keeps its distance to the centre (inner foot ``radius - w/2``, outer ``radius + w/2``)
    and turns with the heading. The outer foot swings first, each swing lands the foot one
    step angle ahead of the other one, and a last swing brings the feet side by side.
    """
    mid, yaw = heading_yaw(where)
    sign = SIDE_SIGN[side]
    center = mid + rz(yaw) @ np.array([0.0, sign * radius, 0.0])
    width = float(np.linalg.norm(np.asarray(where["left"].position[:2]) - np.asarray(where["right"].position[:2])))
    n = max(1, math.ceil(angle / arc_step_angle_max(robot, radius, width) - 1e-9))
    step = angle / n
    start = dict(where)
    progress = {"left": 0.0, "right": 0.0}
    swings: list[tuple[str, Pose]] = []
    cur = dict(where)

    def place(s: str, phi: float) -> Pose:
        rot = rz(sign * phi)
        p = center + rot @ (np.asarray(start[s].position) - center)
        r0 = start[s].rpy
        return Pose(position=clean(p), rpy=clean((r0[0], r0[1], r0[2] + sign * phi)))  # continuous yaw: no jump at pi

    s = OTHER[side]  # the outer foot first
    for _ in range(n):
        progress[s] = progress[OTHER[s]] + step
        cur[s] = place(s, progress[s])
        swings.append((s, cur[s]))
        s = OTHER[s]
    progress[s] = progress[OTHER[s]]
    cur[s] = place(s, progress[s])
    swings.append((s, cur[s]))
    return ArcSteps(swings=tuple(swings), left=cur["left"], right=cur["right"], step_angle=step)


def stance_from(where: dict[str, Pose]) -> Stance:
    """A Stance from a side -> placement dict."""
    return Stance(left=where["left"], right=where["right"])


__all__ = [
    "ArcSteps",
    "Segment",
    "arc_step_angle_max",
    "arc_steps",
    "leg_length",
    "segment_knots",
    "sequence_duration",
    "write_segments",
]
