"""Leg motions without a flight: ``kick``, ``march``, ``stomp``, ``lunge``, ``walk_arc``.

- ``kick(leg, direction, height [m], duration [s])``: shift the weight onto the other foot
  (``SHIFT_TIME``, both feet down), stand on it with the CoM held over the stance sole's centre (HARD)
  for ``duration`` while the kicking sole reaches ``height`` above the ground and
  ``KICK_REACH_FRACTION`` (forward) or ``KICK_SIDE_FRACTION`` (side, outwards) of the leg length
  away from its standing place at the middle of that phase (HARD, ``KICK_TOLERANCE``), then put it
  down and shift back. Dynamic like ``balance``: planned kinematically, the weight shift ended
  with the CoM still moving and G1's plan put its ZMP 0.13 m outside the stance sole, so the
  simulated CoM stopped 4.9 cm short of it. Refused above ``KICK_HEIGHT_FRACTION`` of the leg length.
- ``march(count, height [m])``: ``count`` alternating foot lifts in place, the right foot first,
  with the robot's step timing; each lifted sole clears ``height`` at mid-swing (HARD) and lands
  where it was. Dynamic (contact forces), like ``step``.
- ``stomp(leg, count, height [m])``: the same foot lifted ``count`` times and put down on its own
  placement. The impact itself is not modelled: the planner lands the foot at rest.
- ``lunge(leg, direction, length [m], depth [m], duration [s])``: one foot steps ``length``
  forward (or outwards), the CoM goes down ``depth`` over the spread feet (HARD at the middle of
  ``duration``), up again, and the foot steps back. Dynamic.
- ``walk_arc(radius [m], side, angle [rad])``: footsteps along a circle of ``radius`` whose centre
  is on the ``side`` of the robot, for ``angle`` (default a full circle; see
  :func:`tasks.primitives.gait.arc_steps`). Dynamic; the robot ends turned by ``angle``.

Every dynamic one asks for the CoM to end over the final feet (HARD, ``END_TOLERANCE``).
"""

from __future__ import annotations

import math

import numpy as np

from robots import Robot
from tasks.exceptions import TaskDefinitionError
from tasks.footsteps import lateral_step_max, step_width
from tasks.primitives.arms import UPPER_ARM_OUT, hold_upper_arms
from tasks.primitives.base import Fragment, FragmentBuilder, Primitive
from tasks.primitives.gait import (
    OTHER,
    SIDE_SIGN,
    Segment,
    arc_step_angle_max,
    arc_steps,
    both,
    contact,
    heading_yaw,
    leg_length,
    rz,
    sequence_duration,
    shifted,
    stance_from,
    start_placements,
    tau,
    write_segments,
)
from tasks.primitives.geometry import Stance, standing_geometry
from tasks.specs import Pose

PARTS = frozenset({"legs", "com"})
SHIFT_TIME = 1.0  # [s] kick: weight shift before and after the one-foot phase
KICK_HEIGHT_FRACTION = 0.3  # highest kick: this fraction of the leg length (hip above the sole)
KICK_REACH_FRACTION = 0.25  # forward kick: the sole this fraction of the leg length ahead
KICK_SIDE_FRACTION = 0.15  # side kick: the sole this fraction of the leg length outwards
KICK_TOLERANCE = 0.02  # [m]
LIFT_FRACTION = 0.3  # march/stomp: highest sole lift, this fraction of the leg length
COM_TOLERANCE = 0.01  # [m] CoM over the stance sole before a kick
END_TOLERANCE = 0.02  # [m] CoM ground projection at the end vs the point between the feet
LUNGE_TOLERANCE = 0.02  # [m] CoM height at the bottom of a lunge
SHIFT_FRACTION = 0.5  # opening shift and closing settle: this fraction of step_duration


# ---------------------------------------------------------------------------------------------
# kick
# ---------------------------------------------------------------------------------------------


def kick_height_max(robot: Robot) -> float:
    """Highest kick [m]: ``KICK_HEIGHT_FRACTION`` of the leg length."""
    return KICK_HEIGHT_FRACTION * leg_length(robot)


def _check_kick(params: dict, robot: Robot) -> None:
    h, top = params["height"], kick_height_max(robot)
    if h > top + 1e-12:
        raise TaskDefinitionError(
            f"kick height {h:g} m is beyond {robot.name}'s {top:.2f} m (its hips are {leg_length(robot):.2f} m above "
            f"the soles; a kick lifts the sole at most {KICK_HEIGHT_FRACTION:g} of that while standing on the other "
            f"foot); ask for at most {top:.2f} m"
        )


def _kick_offset(robot: Robot, leg: str, direction: str, height: float) -> np.ndarray:
    """Kicking sole at the top of the kick, relative to its standing place, heading frame (3,)."""
    L = leg_length(robot)
    if direction == "forward":
        return np.array([KICK_REACH_FRACTION * L, 0.0, height])
    return np.array([0.0, SIDE_SIGN[leg] * KICK_SIDE_FRACTION * L, height])


def _kick_duration(params: dict, robot: Robot) -> float:
    return SHIFT_TIME + params["duration"] + SHIFT_TIME


def _build_kick(b: FragmentBuilder) -> Fragment:
    leg = b.params["leg"]
    stance = OTHER[leg]
    D = b.params["duration"]
    g = b.geometry
    sole = b.world(g.sole_centers[stance])
    b.com_target(f"CoM over the {stance} sole", (sole[0], sole[1], None), window=(SHIFT_TIME, SHIFT_TIME + D),
                 tolerance=COM_TOLERANCE)
    top = g.position(f"{leg}_foot") + _kick_offset(b.robot, leg, b.params["direction"], b.params["height"])
    b.frame_target(f"{leg} foot kicks {b.params['direction']}", f"{leg}_foot", position=b.world(top),
                   time=SHIFT_TIME + 0.5 * D, tolerance=KICK_TOLERANCE)
    home = b.world(g.com)
    end = _kick_duration(b.params, b.robot)
    b.com_target("CoM back between the feet", (home[0], home[1], None), time=end, tolerance=COM_TOLERANCE)
    b.phase(f"shift onto the {stance} foot", SHIFT_TIME)
    b.phase(f"kick with the {leg} foot", SHIFT_TIME + D, b.contacts((stance,)), swing_height=0.02)
    b.phase("both feet down", end)
    hold_upper_arms(b, b.nominal, ("left", "right"))  # G1's right upper arm went into the torso's meshes
    return b.finish(PARTS, dynamic=True)


def _kick_limits(robot: Robot) -> dict[str, str]:
    return {"height": f"at most {kick_height_max(robot):.2f} m on {robot.name} ({KICK_HEIGHT_FRACTION:g} of its "
                      f"{leg_length(robot):.2f} m leg)"}


KICK = Primitive(name="kick", nominal_duration=_kick_duration, build=_build_kick, parts=lambda p: PARTS,
                 check=_check_kick, limits=_kick_limits, dynamic=True)


# ---------------------------------------------------------------------------------------------
# march, stomp
# ---------------------------------------------------------------------------------------------


def lift_height_max(robot: Robot) -> float:
    """Highest sole lift of a march or stomp [m]: ``LIFT_FRACTION`` of the leg length."""
    return LIFT_FRACTION * leg_length(robot)


def _check_lift(name: str):
    def check(params: dict, robot: Robot) -> None:
        h, top = params["height"], lift_height_max(robot)
        if h > top + 1e-12:
            raise TaskDefinitionError(
                f"{name} height {h:g} m is beyond {robot.name}'s {top:.2f} m ({LIFT_FRACTION:g} of its "
                f"{leg_length(robot):.2f} m leg); ask for at most {top:.2f} m"
            )
    return check


def _lift_segments(robot: Robot, where: dict[str, Pose], sides: list[str], height: float,
                   double_scale: float = 1.0) -> list[Segment]:
    """Weight shift, then per side a single support (that foot lifted) and a double support."""
    prof = robot.profile
    settle = SHIFT_FRACTION * prof.step_duration
    segs = [Segment(name="shift weight", duration=settle, contacts=both(robot, where))]
    for i, side in enumerate(sides):
        segs.append(Segment(name=f"lift {i + 1}: {side} foot up", duration=prof.step_duration,
                            contacts=(contact(robot, OTHER[side], where[OTHER[side]]),), swing_height=height))
        last = i == len(sides) - 1
        segs.append(Segment(name="settle" if last else f"lift {i + 1}: both feet down",
                            duration=settle if last else double_scale * prof.double_support_duration,
                            contacts=both(robot, where), rounding="nearest" if last else "floor"))
    return segs


def _march_sides(params: dict) -> list[str]:
    return [("right", "left")[i % 2] for i in range(params["count"])]


def _stomp_sides(params: dict) -> list[str]:
    return [params["leg"]] * params["count"]


def _lifts(name: str, sides_of, double_scale: float) -> Primitive:
    def nominal_duration(params: dict, robot: Robot) -> float:
        where = start_placements(robot, None)
        return sequence_duration(_lift_segments(robot, where, sides_of(params), params["height"], double_scale))

    def build(b: FragmentBuilder) -> Fragment:
        where = start_placements(b.robot, b.stance)
        write_segments(b, _lift_segments(b.robot, where, sides_of(b.params), b.params["height"], double_scale))
        _com_home(b, b.stance, nominal_duration(b.params, b.robot))
        hold_upper_arms(b, b.nominal, ("left", "right"))  # G1's upper arms went into the torso's meshes
        return b.finish(PARTS, dynamic=True)

    def limits(robot: Robot) -> dict[str, str]:
        return {"height": f"at most {lift_height_max(robot):.2f} m on {robot.name} ({LIFT_FRACTION:g} of its "
                          f"{leg_length(robot):.2f} m leg)"}

    return Primitive(name=name, nominal_duration=nominal_duration, build=build, parts=lambda p: PARTS,
                     check=_check_lift(name), limits=limits, dynamic=True)


def _com_home(b: FragmentBuilder, end: Stance, t_end: float) -> None:
    home = end.transform_from_standing(b.robot).act(standing_geometry(b.robot).com)
    b.com_target("CoM back over the feet", (float(home[0]), float(home[1]), None), time=t_end,
                 tolerance=END_TOLERANCE)


MARCH = _lifts("march", _march_sides, 1.0)
STOMP = _lifts("stomp", _stomp_sides, 2.0)


# ---------------------------------------------------------------------------------------------
# lunge
# ---------------------------------------------------------------------------------------------


def lunge_length_max(robot: Robot, direction: str) -> float:
    """Longest lunge [m]: the robot's longest step forward, its longest side step sideways."""
    return robot.profile.step_length_max if direction == "forward" else lateral_step_max(robot)


def _lunge_length(params: dict, robot: Robot) -> float:
    length = params["length"]
    return lunge_length_max(robot, params["direction"]) if length is None else float(length)


def _check_lunge(params: dict, robot: Robot) -> None:
    length, top = _lunge_length(params, robot), lunge_length_max(robot, params["direction"])
    if length > top + 1e-12:
        kind = "step" if params["direction"] == "forward" else "side step"
        raise TaskDefinitionError(
            f"lunge length {length:g} m is beyond {robot.name}'s longest {kind} of {top:.2f} m; ask for at most {top:.2f} m"
        )
    depth, deepest = params["depth"], robot.profile.squat_depth_max
    if depth > deepest + 1e-12:
        raise TaskDefinitionError(
            f"lunge depth {depth:g} m is beyond {robot.name}'s reachable {deepest:.2f} m; ask for a depth of at most "
            f"{deepest:.2f} m"
        )


def _lunge_segments(params: dict, robot: Robot, where: dict[str, Pose]) -> tuple[list[Segment], dict[str, Pose]]:
    prof = robot.profile
    leg, stance = params["leg"], OTHER[params["leg"]]
    _, yaw = heading_yaw(where)
    local = np.array([1.0, 0.0, 0.0]) if params["direction"] == "forward" else np.array([0.0, SIDE_SIGN[leg], 0.0])
    out = dict(where)
    out[leg] = shifted(where[leg], rz(yaw) @ local * _lunge_length(params, robot))
    settle = SHIFT_FRACTION * prof.step_duration
    segs = [
        Segment(name="shift weight", duration=settle, contacts=both(robot, where)),
        Segment(name=f"{leg} foot steps out", duration=prof.step_duration,
                contacts=(contact(robot, stance, where[stance]),)),
        Segment(name="lunge down and up", duration=params["duration"], contacts=both(robot, out)),
        Segment(name=f"{leg} foot steps back", duration=prof.step_duration,
                contacts=(contact(robot, stance, where[stance]),)),
        Segment(name="settle", duration=settle, contacts=both(robot, where)),
    ]
    return segs, out


def _lunge_duration(params: dict, robot: Robot) -> float:
    return sequence_duration(_lunge_segments(params, robot, start_placements(robot, None))[0])


def _build_lunge(b: FragmentBuilder) -> Fragment:
    where = start_placements(b.robot, b.stance)
    segs, _ = _lunge_segments(b.params, b.robot, where)
    bounds = write_segments(b, segs)
    z0 = b.world_z(float(b.geometry.com[2]))
    mid = (bounds[2] + bounds[3]) // 2
    b.com_target("lunge bottom", (None, None, z0 - b.params["depth"]), time=tau(b, mid), tolerance=LUNGE_TOLERANCE)
    _com_home(b, b.stance, tau(b, bounds[-1]))
    return b.finish(PARTS, dynamic=True)


def _lunge_limits(robot: Robot) -> dict[str, str]:
    return {
        "length": f"at most {lunge_length_max(robot, 'forward'):.2f} m forward, {lunge_length_max(robot, 'side'):.2f} m "
                  f"sideways on {robot.name} (default: these)",
        "depth": f"at most {robot.profile.squat_depth_max:.2f} m on {robot.name}",
    }


LUNGE = Primitive(name="lunge", nominal_duration=_lunge_duration, build=_build_lunge, parts=lambda p: PARTS,
                  check=_check_lunge, limits=_lunge_limits, dynamic=True)


# ---------------------------------------------------------------------------------------------
# walk_arc
# ---------------------------------------------------------------------------------------------


def arc_radius_min(robot: Robot) -> float:
    """Smallest arc radius [m]: the distance between the feet (the inner foot then walks a
    circle of half that)."""
    return step_width(robot)


def _check_arc(params: dict, robot: Robot) -> None:
    r, top = params["radius"], arc_radius_min(robot)
    if r < top - 1e-12:
        raise TaskDefinitionError(
            f"walk_arc radius {r:g} m is below {robot.name}'s {top:.2f} m (the distance between its feet; on a "
            f"tighter circle the inner foot would step around a point); ask for at least {top:.2f} m, or turn in place"
        )


def _arc_segments(params: dict, robot: Robot, where: dict[str, Pose]) -> tuple[list[Segment], dict[str, Pose]]:
    prof = robot.profile
    steps = arc_steps(robot, where, params["radius"], params["side"], params["angle"])
    settle = SHIFT_FRACTION * prof.step_duration
    segs = [Segment(name="shift weight", duration=settle, contacts=both(robot, where))]
    cur = dict(where)
    for i, (side, target) in enumerate(steps.swings):
        segs.append(Segment(name=f"step {i + 1}: {side} foot swings", duration=prof.step_duration,
                            contacts=(contact(robot, OTHER[side], cur[OTHER[side]]),)))
        cur[side] = target
        last = i == len(steps.swings) - 1
        segs.append(Segment(name="settle" if last else f"step {i + 1}: double support",
                            duration=settle if last else prof.double_support_duration,
                            contacts=both(robot, cur), rounding="nearest" if last else "floor"))
    return segs, cur


def _arc_duration(params: dict, robot: Robot) -> float:
    return sequence_duration(_arc_segments(params, robot, start_placements(robot, None))[0])


def _build_arc(b: FragmentBuilder) -> Fragment:
    where = start_placements(b.robot, b.stance)
    segs, end = _arc_segments(b.params, b.robot, where)
    bounds = write_segments(b, segs)
    b.end_stance = stance_from(end)
    _com_home(b, b.end_stance, tau(b, bounds[-1]))
    hold_upper_arms(b, b.nominal, ("left", "right"), out=UPPER_ARM_OUT)  # G1's left upper arm grazed the torso
    return b.finish(PARTS, dynamic=True)


def _arc_limits(robot: Robot) -> dict[str, str]:
    r = 1.0
    step = arc_step_angle_max(robot, r, step_width(robot))
    return {"radius": f"at least {arc_radius_min(robot):.2f} m on {robot.name}; steps of at most "
                      f"{math.degrees(step):.0f} deg of arc on a 1 m circle"}


WALK_ARC = Primitive(name="walk_arc", nominal_duration=_arc_duration, build=_build_arc, parts=lambda p: PARTS,
                     check=_check_arc, limits=_arc_limits, dynamic=True)
