"""Posture primitives: ``stand``, ``raise_arms``, ``bow``, ``turn_head``, ``lean``.

Each goes from the standing posture to a held pose and back, with the feet where they are:
the pose is reached at ``OUT_FRACTION`` of the duration, held (HARD targets) until
``HOLD_END_FRACTION`` and left again towards the standing posture.

- ``raise_arms(arm)``: hands ``RAISE_HEIGHT * L`` above their shoulder (``L`` the arm's length),
  which is above the head on every built-in robot.
- ``bow(angle)``: the torso frame pitched forward by ``angle`` about the heading frame's y axis
  (orientation target on the torso frame, robot-agnostic: any joint may contribute).
- ``turn_head(direction, angle)``: the head frame rotated by ``angle`` (yaw for left/right,
  pitch for up/down). Refused for robots without neck joints and beyond the neck's range.
- ``lean(direction, amount)``: the CoM ground projection shifted by ``amount`` in the heading
  frame, within the support polygon shrunk by the spec's margin.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from robots import Robot
from tasks.exceptions import TaskDefinitionError
from tasks.primitives.arms import fold_waypoints
from tasks.primitives.base import Fragment, FragmentBuilder, Primitive, arms_of, rest_targets
from tasks.primitives.geometry import (
    SIDE_SIGN,
    neck_range,
    require_role,
    standing_geometry,
)
from tasks.specs import Priority

OUT_FRACTION = 0.4
HOLD_END_FRACTION = 0.6
RAISE_HEIGHT = 0.75  # [L] hand above the shoulder frame for raise_arms
RAISE_OUT = 0.0  # [L] hand outside the shoulder frame
RAISE_FORWARD = 0.25  # [L] hand ahead of the shoulder frame: the arms go up through the front, on the stronger shoulder pitch joints
RAISE_TOLERANCE = 0.02  # [m]
FOLD_MIN_TIME = 3.0  # [s] raises at least this long pass through the folded-elbow waypoints
ORIENTATION_TOLERANCE = 0.05  # [rad] bow and turn_head
LEAN_TOLERANCE = 0.01  # [m]
LEAN_RAMP = (0.25, 0.5, 0.75)  # [-] fractions of the way out (and back) given a soft CoM waypoint ...
LEAN_RAMP_WEIGHT = 100.0  # ... of this weight, on a cosine profile


def _duration(params: dict, robot: Robot) -> float:
    return params["duration"]


# --- stand ------------------------------------------------------------------------------
def build_stand(b: FragmentBuilder) -> Fragment:
    """One double-support phase; the posture cost keeps the robot at its standing posture."""
    b.phase("stand", b.params["duration"])
    return b.finish(frozenset())


STAND = Primitive(name="stand", nominal_duration=_duration, build=build_stand, parts=lambda p: frozenset())


# --- raise_arms -------------------------------------------------------------------------
def raised_hand_position(robot: Robot, side: str) -> np.ndarray:
    """Standing-frame point (3,) a raised ``side`` hand goes to [m]."""
    g = standing_geometry(robot)
    L = g.arm_length[side]
    shoulder = g.position(f"{side}_shoulder") if f"{side}_shoulder" in g.placements else g.position(f"{side}_hand")
    return (shoulder + RAISE_HEIGHT * L * g.heading_axis("up") + RAISE_FORWARD * L * g.heading_axis("forward")
            + RAISE_OUT * L * SIDE_SIGN[side] * g.heading_axis("left"))


def build_raise_arms(b: FragmentBuilder) -> Fragment:
    """Hands up, held, back to rest; a raise that lasts at least ``FOLD_MIN_TIME`` goes up and down
    through the folded-elbow waypoints (:func:`tasks.primitives.arms.fold_waypoints`, as pointing up
    and stretching do). Why: raised over 4 s while balancing on one foot, Talos's arms swung up
    through the side with a straight elbow, past 101 % of the shoulder roll joint's torque limit
    against gravity, and the right hand fell 8.8 cm behind its plan in MuJoCo (2.7 mm with the
    waypoints). A 2 s raise goes straight up through the front and passes; through the waypoints
    it whipped the arms (hand 14 cm off its plan)."""
    T = b.params["duration"]
    sides = arms_of(b.params["arm"])
    if T * b.scale >= FOLD_MIN_TIME - 1e-9:
        fold_waypoints(b, sides)
    for side in sides:
        b.frame_target(f"{side} hand raised", f"{side}_hand", position=b.world(raised_hand_position(b.robot, side)),
                       window=(OUT_FRACTION * T, HOLD_END_FRACTION * T), tolerance=RAISE_TOLERANCE)
    rest_targets(b, [f"{s}_hand" for s in sides], tau=T)
    b.phase("raise arms", T)
    return b.finish(frozenset(f"{s}_arm" for s in sides))


RAISE_ARMS = Primitive(name="raise_arms", nominal_duration=_duration, build=build_raise_arms,
                       parts=lambda p: frozenset(f"{s}_arm" for s in arms_of(p["arm"])))


# --- bow --------------------------------------------------------------------------------
def _rotated(robot: Robot, role: str, axis_word: str, angle: float) -> np.ndarray:
    """Standing orientation of ``role`` turned by ``angle`` about a heading-frame axis."""
    g = standing_geometry(robot)
    return pin.exp3(angle * g.heading_axis(axis_word)) @ g.rotation(role)


def bowed_torso_rotation(robot: Robot, angle: float) -> np.ndarray:
    """Standing-frame orientation (3, 3) of the torso frame bowed by ``angle`` [rad]."""
    return _rotated(robot, "torso", "left", angle)  # +angle about +y tilts the torso forward


def check_bow(params: dict, robot: Robot) -> None:
    """The robot needs a torso frame."""
    require_role(robot, "torso", "bow")


def build_bow(b: FragmentBuilder) -> Fragment:
    """Torso orientation target held at the bottom of the bow."""
    check_bow(b.params, b.robot)
    T = b.params["duration"]
    b.frame_target("torso bowed", "torso", rpy=b.world_rotation(bowed_torso_rotation(b.robot, b.params["angle"])),
                   window=(OUT_FRACTION * T, HOLD_END_FRACTION * T), orientation_tolerance=ORIENTATION_TOLERANCE)
    b.frame_target("torso upright again", "torso", rpy=b.world_rotation(b.geometry.rotation("torso")), time=T,
                   orientation_tolerance=ORIENTATION_TOLERANCE)
    b.phase("bow", T)
    return b.finish(frozenset({"torso", "legs", "com"}))


BOW = Primitive(name="bow", nominal_duration=_duration, build=build_bow,
                parts=lambda p: frozenset({"torso", "legs", "com"}), check=check_bow)


# --- turn_head --------------------------------------------------------------------------
HEAD_AXES = {"left": ("up", 1.0), "right": ("up", -1.0), "down": ("left", 1.0), "up": ("left", -1.0)}


def head_turn_axis(robot: Robot, direction: str) -> np.ndarray:
    """World axis (3,) about which the head turns (positive sense) for ``direction``."""
    word, sign = HEAD_AXES[direction]
    return sign * standing_geometry(robot).heading_axis(word)


def turned_head_rotation(robot: Robot, direction: str, angle: float) -> np.ndarray:
    """Standing-frame orientation (3, 3) of the head frame turned towards ``direction``."""
    return pin.exp3(angle * head_turn_axis(robot, direction)) @ standing_geometry(robot).rotation("head")


def check_turn_head(params: dict, robot: Robot) -> None:
    """A neck is needed, and the angle must be within its range."""
    require_role(robot, "head", "turn_head")
    if not standing_geometry(robot).neck_joints:
        raise TaskDefinitionError(f"{robot.name} has no neck joint to turn its head")
    reach = neck_range(robot, head_turn_axis(robot, params["direction"]))
    if params["angle"] > reach + 1e-9:
        raise TaskDefinitionError(
            f"turn_head angle {params['angle']:g} rad {params['direction']} is beyond {robot.name}'s "
            f"neck range of {reach:.2f} rad in that direction"
        )


def limits_turn_head(robot: Robot) -> dict[str, str]:
    """Neck range per direction, or the absence of a neck."""
    if not robot.has_role("head") or not standing_geometry(robot).neck_joints:
        return {"direction": f"not available: {robot.name} has no neck joint"}
    ranges = ", ".join(f"{d} {neck_range(robot, head_turn_axis(robot, d)):.2f}" for d in HEAD_AXES)
    return {"angle": f"at most [rad]: {ranges} on {robot.name}"}


def build_turn_head(b: FragmentBuilder) -> Fragment:
    """Head orientation target held, then back."""
    check_turn_head(b.params, b.robot)
    T = b.params["duration"]
    rot = turned_head_rotation(b.robot, b.params["direction"], b.params["angle"])
    b.frame_target(f"head turned {b.params['direction']}", "head", rpy=b.world_rotation(rot),
                   window=(OUT_FRACTION * T, HOLD_END_FRACTION * T), orientation_tolerance=ORIENTATION_TOLERANCE)
    b.frame_target("head forward again", "head", rpy=b.world_rotation(b.geometry.rotation("head")), time=T,
                   orientation_tolerance=ORIENTATION_TOLERANCE)
    b.phase(f"look {b.params['direction']}", T)
    return b.finish(frozenset({"head"}))


def size_limits_turn_head(params: dict, robot: Robot) -> dict[str, float]:
    """The neck's range towards ``direction`` (none without a neck: the check says so)."""
    if not robot.has_role("head") or not standing_geometry(robot).neck_joints:
        return {}
    return {"angle": neck_range(robot, head_turn_axis(robot, params["direction"]))}


TURN_HEAD = Primitive(name="turn_head", nominal_duration=_duration, build=build_turn_head,
                      parts=lambda p: frozenset({"head"}), check=check_turn_head, limits=limits_turn_head,
                      size_limits=size_limits_turn_head)


# --- lean -------------------------------------------------------------------------------
def lean_limit(robot: Robot, direction: str) -> float:
    """Largest CoM shift in ``direction`` that stays in the shrunk support polygon [m]."""
    g = standing_geometry(robot)
    return g.max_com_shift(g.heading_axis(direction))


def check_lean(params: dict, robot: Robot) -> None:
    """The shifted CoM must stay over the support polygon."""
    limit = lean_limit(robot, params["direction"])
    if params["amount"] > limit + 1e-9:
        raise TaskDefinitionError(
            f"lean amount {params['amount']:g} m {params['direction']} is beyond {robot.name}'s support "
            f"polygon: at most {max(limit, 0.0):.3f} m with both feet down"
        )


def limits_lean(robot: Robot) -> dict[str, str]:
    """Largest amount per direction."""
    ranges = ", ".join(f"{d} {lean_limit(robot, d):.3f}" for d in ("forward", "backward", "left", "right"))
    return {"amount": f"at most [m]: {ranges} on {robot.name}"}


def build_lean(b: FragmentBuilder) -> Fragment:
    """CoM shift held, then back over the standing point, planned with the centroidal dynamics
    (contact forces, the centre of pressure inside the soles; ``dynamic=True``), whatever its size.

    Why every lean: the controller keeps a kinematic plan's ZMP inside the support polygon scaled by
    0.35 about its centre (``PlanReference(zmp_scale=0.35)``) wherever the plan's CoM is inside it,
    and re-solves the CoM path from that. A kinematic lean's ZMP swings far beyond its CoM between
    knots (Talos "lean to your right": up to 15 cm, with the ramp waypoints), so the CoM reference
    the robot follows fell short of the plan's: 79 % of the planned shift at the hold's peak,
    "lean forward" 82 %, "raise your hands while leaning forward" 63 %. A dynamic plan's ZMP is
    inside the soles by construction and the controller takes its CoM as it is: 100 %, 96 % and
    85 % (PlanReference, Talos; G1's lean 92 % -> 100 %). Planning takes 2-7 s instead of 1-5 s.
    The earlier rule (dynamic only when a smooth shift's ZMP came within 2 cm of the soles' edge)
    left every default lean kinematic."""
    check_lean(b.params, b.robot)
    T = b.params["duration"]
    g = b.geometry
    shifted = g.com + b.params["amount"] * g.heading_axis(b.params["direction"])
    p = b.world(shifted)
    b.com_target(f"lean {b.params['direction']}", (p[0], p[1], None),
                 window=(OUT_FRACTION * T, HOLD_END_FRACTION * T), tolerance=LEAN_TOLERANCE)
    home = b.world(g.com)
    for k, f in enumerate(LEAN_RAMP):  # a smooth way out and back (soft): no ZMP spike at the hold's ends
        s_ = 0.5 * (1.0 - np.cos(np.pi * f))
        w = b.world(g.com + s_ * b.params["amount"] * g.heading_axis(b.params["direction"]))
        b.com_target(f"CoM on the way out #{k + 1}", (w[0], w[1], None), time=f * OUT_FRACTION * T,
                     priority=Priority.SOFT, weight=LEAN_RAMP_WEIGHT)
        b.com_target(f"CoM on the way back #{k + 1}", (w[0], w[1], None),
                     time=T - f * (1.0 - HOLD_END_FRACTION) * T, priority=Priority.SOFT, weight=LEAN_RAMP_WEIGHT)
    b.com_target("CoM back over the feet", (home[0], home[1], None), time=T, tolerance=LEAN_TOLERANCE)
    b.phase(f"lean {b.params['direction']}", T)
    return b.finish(frozenset({"com", "legs"}), dynamic=True)


LEAN = Primitive(name="lean", nominal_duration=_duration, build=build_lean,
                 parts=lambda p: frozenset({"com", "legs"}), check=check_lean, limits=limits_lean,
                 size_limits=lambda p, robot: {"amount": lean_limit(robot, p["direction"])})
