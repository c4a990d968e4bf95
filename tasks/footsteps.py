"""Footstep generator: steps, walks and turns in place as contact sequences.

A :class:`ContactSequence` is the lower-body part of a dynamic TaskSpec: alternating double
support (both soles down) and single support (one sole down, the other swinging to its next
placement) phases, plus the list of :class:`Footstep`\\ s and where the feet end.

Timing and sizes come from the robot profile: a single-support phase lasts
``profile.step_duration``, the double support between two steps
``profile.double_support_duration``; the sequence opens with a weight shift and closes with a
settling phase of ``SHIFT_FRACTION * step_duration`` each. The lateral distance between the feet
is the one of the start stance (the standing feet by default).

Gaits (directions are taken in the heading frame of the start stance: x forward, y left):

- ``forward``/``backward``: ``count`` steps, the right foot first; each swing foot lands
  ``length`` ahead of the stance foot, then a closing step brings the trailing foot alongside.
  The body advances ``count * length``; ``length`` is the distance between the feet along the
  walking direction (the usual *step length*), at most ``profile.step_length_max``.
- ``left``/``right``: ``count`` side steps; each is the leading foot (the one on the side of
  motion) moving out by ``length``, then the other foot following by ``length``, so the feet
  alternate and the body advances ``count * length``; at most ``lateral_step_max(robot)``.
- ``turn(angle)``: the feet rotate about the point between them, alternately; each swing turns
  the foot at most ``TURN_STEP_MAX`` beyond the other one, and the last swing, always the foot on
  the far side of the turn, brings the feet parallel again. A swing that lands the foot turned
  toward the other one (toe-in: the far-side foot overtaking) lands it ``sole.x_max * sin(toe-in)``
  farther out along its own lateral axis, so the toes stay as far apart as the standing feet's
  (talos's shins intersected in the toe-in double supports of a 90 degree turn otherwise).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from robots import Robot
from tasks.exceptions import TaskDefinitionError
from tasks.specs import Contact, Phase, Pose

DIRECTIONS = ("forward", "backward", "left", "right")
TURN_STEP_MAX = 0.4  # [rad] largest yaw between the two feet while turning
LATERAL_FRACTION = 0.5  # side steps: at most this fraction of profile.step_length_max
SHIFT_FRACTION = 0.5  # opening shift and closing settle: this fraction of step_duration
SWING_HEIGHT = 0.05  # [m] default sole clearance at mid-swing
SIDES = ("left", "right")
OTHER = {"left": "right", "right": "left"}
_AXIS = {"forward": (1.0, 0.0), "backward": (-1.0, 0.0), "left": (0.0, 1.0), "right": (0.0, -1.0)}


@dataclass(frozen=True, slots=True, kw_only=True)
class Footstep:
    """One swing of one foot.

    Attributes:
        side: ``left`` or ``right``.
        frame: The foot's contact frame name.
        start: Placement before the swing.
        target: Landing placement.
    """

    side: str
    frame: str
    start: Pose
    target: Pose

    @property
    def displacement(self) -> float:
        """Horizontal distance the foot travels [m]."""
        return float(math.dist(self.start.position[:2], self.target.position[:2]))

    @property
    def rotation(self) -> float:
        """Yaw change of the foot [rad], in (-pi, pi]."""
        return _wrap(self.target.rpy[2] - self.start.rpy[2])


@dataclass(frozen=True, slots=True, kw_only=True)
class ContactSequence:
    """Phases of a footstep plan and where the feet go.

    Attributes:
        phases: Weight shift, then single support / double support per step, then settling.
        steps: The swings in order.
        left, right: Final placements of the soles.
    """

    phases: tuple[Phase, ...]
    steps: tuple[Footstep, ...]
    left: Pose
    right: Pose

    @property
    def duration(self) -> float:
        """Total duration [s]."""
        return float(sum(p.duration for p in self.phases))

    def final(self, side: str) -> Pose:
        """Final placement of the ``side`` sole."""
        return self.left if side == "left" else self.right


# ---------------------------------------------------------------------------------------------
# Geometry helpers
# ---------------------------------------------------------------------------------------------


def _wrap(angle: float) -> float:
    return float(math.atan2(math.sin(angle), math.cos(angle)))


def _clean(v) -> tuple[float, float, float]:
    return tuple(0.0 if abs(float(x)) < 1e-12 else float(x) for x in v)  # type: ignore[return-value]


def standing_feet(robot: Robot) -> tuple[Pose, Pose]:
    """Placements of the left and right sole frames at ``robot.q_standing``."""
    data = robot.data()
    pin.framesForwardKinematics(robot.model, data, robot.q_standing)
    out = []
    for side in SIDES:
        m = data.oMf[robot.frame_id(f"{side}_foot")]
        out.append(Pose(position=_clean(m.translation), rpy=_clean(pin.rpy.matrixToRpy(m.rotation))))
    return out[0], out[1]


def _heading(left: Pose, right: Pose) -> tuple[np.ndarray, float]:
    """Mid point (3,) and mean yaw of two sole placements."""
    yaws = (left.rpy[2], right.rpy[2])
    yaw = math.atan2(sum(math.sin(y) for y in yaws), sum(math.cos(y) for y in yaws))
    mid = 0.5 * (np.asarray(left.position) + np.asarray(right.position))
    return mid, yaw


def _rz(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _moved(pose: Pose, offset_in_world: np.ndarray, yaw: float | None = None) -> Pose:
    rpy = pose.rpy if yaw is None else (pose.rpy[0], pose.rpy[1], _wrap(yaw))
    return Pose(position=_clean(np.asarray(pose.position) + offset_in_world), rpy=_clean(rpy))


def lateral_step_max(robot: Robot) -> float:
    """Longest side step the generator plans [m]: ``LATERAL_FRACTION * step_length_max``."""
    return LATERAL_FRACTION * robot.profile.step_length_max


def step_width(robot: Robot, left: Pose | None = None, right: Pose | None = None) -> float:
    """Lateral distance between the sole frames [m]: the profile's ``step_width`` when set, else
    the one of the given (default: standing) feet."""
    if robot.profile.step_width > 0.0:
        return robot.profile.step_width
    if left is None or right is None:
        left, right = standing_feet(robot)
    _, yaw = _heading(left, right)
    rel = _rz(yaw).T @ (np.asarray(left.position) - np.asarray(right.position))
    return float(abs(rel[1]))


# ---------------------------------------------------------------------------------------------
# Sequences
# ---------------------------------------------------------------------------------------------


def _phases(robot: Robot, steps: list[Footstep], left: Pose, right: Pose, swing_height: float,
            label: str) -> tuple[Phase, ...]:
    prof = robot.profile
    frames = {s: robot.frame(f"{s}_foot") for s in SIDES}
    where = {"left": left, "right": right}

    def both() -> tuple[Contact, ...]:
        return tuple(Contact(frame=frames[s], placement=where[s]) for s in SIDES)

    shift = SHIFT_FRACTION * prof.step_duration
    phases = [Phase(name=f"{label}shift weight", duration=shift, contacts=both())]
    for i, st in enumerate(steps):
        stance = OTHER[st.side]
        phases.append(Phase(
            name=f"{label}step {i + 1}: {st.side} foot swings", duration=prof.step_duration,
            contacts=(Contact(frame=frames[stance], placement=where[stance]),), swing_height=swing_height,
        ))
        where[st.side] = st.target
        last = i == len(steps) - 1
        phases.append(Phase(
            name=f"{label}settle" if last else f"{label}step {i + 1}: double support",
            duration=shift if last else prof.double_support_duration, contacts=both(),
        ))
    return tuple(phases)


def _start(robot: Robot, left: Pose | None, right: Pose | None) -> tuple[Pose, Pose]:
    if (left is None) != (right is None):
        raise TaskDefinitionError("footsteps: give both start placements (left and right) or neither")
    if left is None or right is None:
        return standing_feet(robot)
    return left, right


def _check_direction(direction: str) -> None:
    if direction not in DIRECTIONS:
        raise TaskDefinitionError(f"step direction must be one of {', '.join(DIRECTIONS)}, got {direction!r}")


def _check_positive(what: str, value: float, unit: str) -> None:
    if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0.0):
        raise TaskDefinitionError(f"{what} must be a positive number [{unit}], got {value!r}")


def step_length_limit(robot: Robot, direction: str) -> float:
    """Longest step in ``direction`` the generator plans for ``robot`` [m]."""
    _check_direction(direction)
    if direction in ("forward", "backward"):
        return robot.profile.step_length_max
    return lateral_step_max(robot)


def footsteps(robot: Robot, direction: str, length: float, count: int, *, left: Pose | None = None,
              right: Pose | None = None, swing_height: float = SWING_HEIGHT, label: str = "") -> ContactSequence:
    """``count`` steps of ``length`` in ``direction`` (see the module docstring for the gaits).

    Args:
        robot: The robot (timing, step limits, foot frames).
        direction: ``forward``, ``backward``, ``left`` or ``right`` in the start heading frame.
        length: Step length [m]: distance between the feet along the direction after each step.
        count: Number of steps (>= 1).
        left, right: Start placements of the soles (default: standing).
        swing_height: Sole clearance at mid-swing [m].
        label: Prefix of the phase names.

    Returns:
        The contact sequence; the body ends ``count * length`` away along ``direction``.

    Raises:
        TaskDefinitionError: unknown direction, non-positive length or count, or a step longer
            than the robot's limit (the message names the limit).
    """
    _check_direction(direction)
    _check_positive("step length", length, "m")
    if isinstance(count, bool) or not isinstance(count, int) or count < 1:
        raise TaskDefinitionError(f"step count must be a whole number >= 1, got {count!r}")
    limit = step_length_limit(robot, direction)
    if length > limit + 1e-12:
        kind = "step length" if direction in ("forward", "backward") else "side step"
        raise TaskDefinitionError(
            f"{kind} {length:g} m is beyond {robot.name}'s {limit:.2f} m; take more, shorter steps "
            f"(e.g. {math.ceil(length / limit)} steps of at most {limit:.2f} m)"
        )
    left, right = _start(robot, left, right)
    _, yaw = _heading(left, right)
    axis = _rz(yaw) @ np.array([*_AXIS[direction], 0.0])
    where = {"left": left, "right": right}
    frames = {s: robot.frame(f"{s}_foot") for s in SIDES}
    steps: list[Footstep] = []

    def swing(side: str, offset: np.ndarray) -> None:
        target = _moved(where[side], offset)
        steps.append(Footstep(side=side, frame=frames[side], start=where[side], target=target))
        where[side] = target

    if direction in ("forward", "backward"):
        # progress of each foot along the axis, relative to the start
        progress = {"left": 0.0, "right": 0.0}
        side = "right"
        for _ in range(count):
            new = progress[OTHER[side]] + length
            swing(side, axis * (new - progress[side]))
            progress[side] = new
            side = OTHER[side]
        swing(side, axis * (progress[OTHER[side]] - progress[side]))  # closing step
    else:
        lead = direction
        for _ in range(count):
            swing(lead, axis * length)
            swing(OTHER[lead], axis * length)
    phases = _phases(robot, steps, left, right, swing_height, label)
    return ContactSequence(phases=phases, steps=tuple(steps), left=where["left"], right=where["right"])


def walk(robot: Robot, distance: float, direction: str = "forward", *, left: Pose | None = None,
         right: Pose | None = None, swing_height: float = SWING_HEIGHT, label: str = "") -> ContactSequence:
    """Cover ``distance`` in ``direction`` with the fewest equal steps within the robot's limit.

    Args:
        robot: The robot.
        distance: How far the body moves [m].
        direction: ``forward``, ``backward``, ``left`` or ``right``.
        left, right: Start placements (default: standing).
        swing_height: Sole clearance at mid-swing [m].
        label: Prefix of the phase names.

    Returns:
        The contact sequence of ``ceil(distance / limit)`` steps of ``distance / count``.

    Raises:
        TaskDefinitionError: unknown direction or non-positive distance.
    """
    _check_direction(direction)
    _check_positive("walking distance", distance, "m")
    limit = step_length_limit(robot, direction)
    count = max(1, math.ceil(distance / limit - 1e-9))
    return footsteps(robot, direction, distance / count, count, left=left, right=right,
                     swing_height=swing_height, label=label)


def turn(robot: Robot, angle: float, *, left: Pose | None = None, right: Pose | None = None,
         swing_height: float = SWING_HEIGHT, label: str = "", step_max: float = TURN_STEP_MAX) -> ContactSequence:
    """Turn in place by ``angle`` (left, counter-clockwise, positive) in alternating swings.

    The feet rotate about the point between them. With ``n = ceil(|angle| / step_max)``, the feet
    swing to ``angle / n``, ``2 angle / n`` and so on, alternately, and a last swing brings the
    feet parallel: ``n + 1`` swings, the feet never more than ``step_max`` apart in yaw. That last
    swing is the far-side foot's (the right foot in a left turn), so the near-side foot swings
    first when ``n`` is odd, the far-side foot when it is even. The far-side foot's other swings
    turn it toward the near-side foot (toe-in); each lands :func:`toe_in_widening` farther out
    along the foot's lateral axis, so the toes (and the shins above them) stay as far apart as
    the standing feet's. The end stance is the start stance turned by ``angle`` about its mid
    point.

    Args:
        robot: The robot.
        angle: Yaw change [rad], in [-pi, pi], nonzero.
        left, right: Start placements (default: standing).
        swing_height: Sole clearance at mid-swing [m].
        label: Prefix of the phase names.
        step_max: Largest yaw between the feet [rad].

    Returns:
        The contact sequence.

    Raises:
        TaskDefinitionError: ``angle`` is zero, not finite or beyond a half turn.
    """
    if not (isinstance(angle, (int, float)) and math.isfinite(angle) and 1e-6 < abs(angle) <= math.pi + 1e-12):
        raise TaskDefinitionError(f"turn angle must be nonzero and within [-pi, pi] rad, got {angle!r}")
    _check_positive("turn step", step_max, "rad")
    left, right = _start(robot, left, right)
    mid, yaw0 = _heading(left, right)
    n = math.ceil(abs(angle) / step_max - 1e-9)
    inc = angle / n
    offsets = {s: np.asarray(p.position) - mid for s, p in (("left", left), ("right", right))}
    rel_yaw = {s: _wrap(p.rpy[2] - yaw0) for s, p in (("left", left), ("right", right))}
    where = {"left": left, "right": right}
    frames = {s: robot.frame(f"{s}_foot") for s in SIDES}
    steps: list[Footstep] = []
    near = "left" if angle > 0 else "right"
    side = near if n % 2 == 1 else OTHER[near]
    for k in range(1, n + 2):
        theta = min(k, n) * inc
        yaw = _wrap(yaw0 + theta + rel_yaw[side])
        position = mid + _rz(theta) @ offsets[side]
        if side != near and k <= n:  # toe-in: the far-side foot overtakes the near-side one
            outward = 1.0 if side == "left" else -1.0
            position = position + _rz(yaw) @ np.array([0.0, outward * toe_in_widening(robot, abs(inc)), 0.0])
        target = Pose(position=_clean(position), rpy=_clean((where[side].rpy[0], where[side].rpy[1], yaw)))
        steps.append(Footstep(side=side, frame=frames[side], start=where[side], target=target))
        where[side] = target
        side = OTHER[side]
    phases = _phases(robot, steps, left, right, swing_height, label)
    return ContactSequence(phases=phases, steps=tuple(steps), left=where["left"], right=where["right"])


def toe_in_widening(robot: Robot, toe_in: float) -> float:
    """How much farther out a turning foot lands when it is turned ``toe_in`` [rad] toward the
    other foot [m]: ``sole.x_max * sin(toe_in)``, the distance its toe (the sole's front edge) comes
    inward by turning, so the toes stay as far apart as parallel feet's."""
    return float(robot.profile.sole.x_max * math.sin(abs(toe_in)))


__all__ = [
    "DIRECTIONS",
    "TURN_STEP_MAX",
    "ContactSequence",
    "Footstep",
    "footsteps",
    "lateral_step_max",
    "standing_feet",
    "step_length_limit",
    "step_width",
    "toe_in_widening",
    "turn",
    "walk",
]
