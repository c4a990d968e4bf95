"""Handing a held object over: ``hand_over(object, arm)`` (docs/objects.md).

The hand that holds the object (after a ``pick_up``; :func:`tasks.compose.compile_actions` puts a
pick-up before a hand-over of an object no hand holds yet) brings it to the *hand-over point*, in
front of the robot at chest height, and holds it still there for a person standing in front to
take it. Two phases, both feet down:

1. *bring*: :data:`BRING_TIME`, the hand from where it holds the object to the hand-over pose;
2. *hold out*: :data:`OFFER_TIME`, the hand held there (:data:`OFFER_TARGET_TOLERANCE`), and on
   until the next action that moves this arm or the feet (like the pick-up's hold).

The hand-over point comes from the arm (heading frame where the robot stands, ``r`` the hand's
reach from the shoulder, :func:`tasks.primitives.arms.reach`): the object's centre
:data:`OFFER_AHEAD` ``r`` ahead of the shoulder, :data:`OFFER_DOWN` ``r`` below it (lower chest
height), straight ahead of the shoulder (:data:`OFFER_INWARD`). talos: 0.38 m ahead of the feet,
1.05 m high, 0.29 m to the side. The hand keeps its standing orientation (the object upright), the
object's centre at its held place (the pick-up's grasp offset). Higher, or nearer the midline, the
talos wrist (fingers down) does not get there: "0.35 r below, half the shoulder's offset" (1.17 m,
0.15 m to the side) was refused by the planner, the hand 0.20 m short of its target.

Refused before planning, in task terms: the held object would come within
:data:`OFFER_CLEARANCE` of another object there (a table or shelf in front: step back first), the
arm cannot hold the hand there with the legs standing (:func:`tasks.primitives.grasp.carry_posture`),
a box held with both hands.

The spec's :class:`~tasks.specs.Grasp` of the object gets ``offer`` (the point) and
``offer_window`` (the hold-out phase); the simulation's certificate checks the object's centre
there (``sim/grasp.py``).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin

from robots import Robot
from tasks.exceptions import TaskDefinitionError
from tasks.primitives.arms import reach, shoulder
from tasks.primitives.base import Fragment, FragmentBuilder, Primitive
from tasks.primitives.bodymap import to_standing
from tasks.primitives.geometry import Stance, standing_geometry
from tasks.primitives.grasp import (
    GRASP_TARGET_TOLERANCE,
    carry_posture,
    grasp_offset,
    grasp_point,
    holding_arm,
    object_arm_parts,
)
from tasks.primitives.objects import grounded
from tasks.scene import SceneObject, extent
from tasks.specs import Grasp

OFFER_AHEAD = 0.7  # [reach] the object's centre this far ahead of the shoulder (heading frame)
OFFER_DOWN = 0.55  # [reach] and this far below it: lower chest height (talos: the fingers-down wrist limits it)
OFFER_INWARD = 1.0  # laterally this fraction of the shoulder's offset from the midline (straight ahead of it)
OFFER_CLEARANCE = 0.02  # [m] the held object's box from every other object's box at the hand-over point
OFFER_TARGET_TOLERANCE = GRASP_TARGET_TOLERANCE  # [m] planned hand position while held out
BRING_TIME = 1.5  # [s] nominal: held pose -> hand-over pose
OFFER_TIME = 1.0  # [s] held out, still
DURATION = BRING_TIME + OFFER_TIME


def offer_point(robot: Robot, stance: Stance, side: str) -> np.ndarray:
    """The hand-over point (world) [m]: where the held object's centre goes (module docstring)."""
    sh = shoulder(robot, side)
    r = reach(robot, side)
    local = np.array([sh[0] + OFFER_AHEAD * r, OFFER_INWARD * sh[1], sh[2] - OFFER_DOWN * r])
    return np.asarray(stance.transform_from_standing(robot).act(to_standing(robot, local)), dtype=float)


def held_offset(robot: Robot, side: str, obj: SceneObject) -> np.ndarray:
    """The object's centre in the ``side`` hand frame while a one-handed pick-up holds it (3,) [m]
    (the same as :func:`tasks.primitives.grasp.build_pick_up` writes into its Grasp)."""
    R = standing_geometry(robot).rotation(f"{side}_hand")
    centre = np.asarray(obj.position, dtype=float) - grasp_point(robot, side, obj)  # vertical, any stance
    return grasp_offset(robot, side) + R.T @ centre


def hand_pose(robot: Robot, stance: Stance, side: str, obj: SceneObject) -> pin.SE3:
    """The ``side`` hand frame's world pose holding ``obj``'s centre at the hand-over point, in its
    standing orientation."""
    T = stance.transform_from_standing(robot)
    R = T.rotation @ standing_geometry(robot).rotation(f"{side}_hand")
    return pin.SE3(R, offer_point(robot, stance, side) - R @ held_offset(robot, side, obj))


def _box_gap(lo0: np.ndarray, hi0: np.ndarray, lo1: np.ndarray, hi1: np.ndarray) -> float:
    """Distance between two axis-aligned boxes [m] (0 when they overlap)."""
    d = np.maximum(0.0, np.maximum(lo0 - hi1, lo1 - hi0))
    return float(np.linalg.norm(d))


def _side(params: dict, robot: Robot) -> str:
    """The holding hand: the stated one (composition fills in the one that picked it up), else the
    one on the object's side."""
    return str(params["arm"]) if params.get("arm") else holding_arm({"object": params["object"]}, robot)


def _check(params: dict, robot: Robot) -> None:
    g = grounded(params, "hand_over")
    if not g.obj.movable:
        raise TaskDefinitionError(f"hand_over: the {g.obj.name} is fixed in the scene (movable: false); it cannot be "
                                  "handed over")
    if not robot.has_role("left_hand") or not robot.has_role("right_hand"):
        raise TaskDefinitionError(f"hand_over: {robot.name} has no hand frames")
    if not isinstance(g.start, Stance):
        return  # where the robot will stand is not known yet
    side = _side(params, robot)
    point = offer_point(robot, g.start, side)
    lo, hi = (np.asarray(v, dtype=float) for v in extent(g.obj))
    lo, hi = lo - np.asarray(g.obj.position) + point, hi - np.asarray(g.obj.position) + point
    for other in g.scene.objects:
        if other.name == g.obj.name:
            continue
        olo, ohi = (np.asarray(v, dtype=float) for v in extent(other))
        gap = _box_gap(lo, hi, olo, ohi)
        if gap < OFFER_CLEARANCE:
            raise TaskDefinitionError(
                f"hand_over: held out in front of the robot at chest height, the {g.obj.name} would be "
                f"{gap * 100:.1f} cm from the {other.name} (at least "
                f"{OFFER_CLEARANCE * 100:g} cm): step back from the {other.name} first")
    hand = g.start.transform_from_standing(robot).inverse() * hand_pose(robot, g.start, side, g.obj)
    try:
        carry_posture(robot, side, hand)
    except TaskDefinitionError:
        raise TaskDefinitionError(
            f"hand_over: the {side} arm cannot hold the {g.obj.name} out in front of {robot.name} at chest height with "
            "the legs standing") from None


def build_hand_over(b: FragmentBuilder) -> Fragment:
    """Bring the held object to the hand-over point and hold it there (module docstring)."""
    g = grounded(b.params, "hand_over")
    if not isinstance(g.start, Stance):
        g = dataclasses.replace(g, start=b.stance)
        b.params["object"] = g
    side = _side(b.params, b.robot)
    b.params["arm"] = side
    _check(b.params, b.robot)
    pose = hand_pose(b.robot, b.stance, side, g.obj)
    point = offer_point(b.robot, b.stance, side)
    rpy = b.world_rotation(b.geometry.rotation(f"{side}_hand"))
    name, role = g.obj.name, f"{side}_hand"
    what = f"{side} hand holds the {name} out"
    b.frame_target(what, role, position=tuple(float(x) for x in pose.translation), rpy=rpy,
                   window=(BRING_TIME, DURATION), tolerance=OFFER_TARGET_TOLERANCE)
    b.holds.append(b.name(what))
    b.phase(f"bring the {name}", BRING_TIME)
    b.phase(f"hold out the {name}", DURATION)
    offset = held_offset(b.robot, side, g.obj)
    b.grasps.append(Grasp(
        name=b.name(f"{side} hand hands over the {name}"), object=name, frame=b.robot.frame(role),
        offset=(float(offset[0]), float(offset[1]), float(offset[2])), start=b.t0,
        offer=(float(point[0]), float(point[1]), float(point[2])), offer_window=b.window(BRING_TIME, DURATION)))
    return b.finish(frozenset({f"{side}_arm", "torso"}))


HAND_OVER = Primitive(name="hand_over", nominal_duration=lambda params, robot: DURATION, build=build_hand_over,
                      parts=object_arm_parts, check=_check)

PRIMITIVES = (HAND_OVER,)

__all__ = ["BRING_TIME", "HAND_OVER", "OFFER_AHEAD", "OFFER_CLEARANCE", "OFFER_DOWN", "OFFER_INWARD", "OFFER_TIME",
           "PRIMITIVES", "build_hand_over", "hand_pose", "held_offset", "offer_point"]
