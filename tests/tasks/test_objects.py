"""Actions on scene objects without a grasp (tasks/primitives/objects.py), compiled in
examples/scenes/kitchen.json and checked with Pinocchio (and coal) numbers computed here: the
walk_to stance faces the object, its body stays the margin away from what it stops at, and the
object is within reach; the head and the arm point at the object."""

from __future__ import annotations

import math
from pathlib import Path

import coal  # type: ignore[import-untyped]
import numpy as np
import pinocchio as pin
import pytest

from robots import load_robot
from tasks.actions import Action
from tasks.compose import compile_actions
from tasks.exceptions import GroundingError, TaskDefinitionError
from tasks.primitives.arms import BEND_MAX, REACH_FRACTION
from tasks.primitives.geometry import Stance
from tasks.primitives.objects import LOOK_TOLERANCE, POINT_CLEARANCE, WALK_MARGIN
from tasks.scene import extent, load_scene, signed_distance
from tasks.serialize import spec_from_json, spec_to_json

KITCHEN = Path(__file__).resolve().parents[2] / "examples" / "scenes" / "kitchen.json"


@pytest.fixture(scope="module")
def kitchen():
    return load_scene(KITCHEN)


@pytest.fixture(scope="module")
def talos():
    return load_robot("talos")


@pytest.fixture(scope="module")
def g1():
    return load_robot("g1")


def _q_at(robot, stance: Stance) -> np.ndarray:
    """The standing configuration carried to ``stance`` (base moved and yawed like the feet)."""
    T = stance.transform_from_standing(robot)
    q = robot.q_standing.copy()
    base = pin.XYZQUATToSE3(q[:7])
    q[:7] = pin.SE3ToXYZQUAT(T * base)
    return q


def _end_stance(spec) -> Stance:
    contacts = {c.frame: c.placement for c in spec.phases[-1].contacts}
    left = next(v for k, v in contacts.items() if "left" in k or k.startswith("l"))
    right = next(v for k, v in contacts.items() if v is not left)
    return Stance(left=left, right=right)


def _clearance(robot, q, obj) -> float:
    """Smallest coal distance between the robot's collision meshes at ``q`` and a box object [m]."""
    data, cm = robot.data(), robot.collision_model
    gdata = pin.GeometryData(cm)
    pin.updateGeometryPlacements(robot.model, data, cm, gdata, q)
    box = coal.Box(*obj.size)
    M = pin.SE3(pin.rpy.rpyToMatrix(*obj.rpy), np.array(obj.position))
    best = math.inf
    for i, go in enumerate(cm.geometryObjects):
        req, res = coal.DistanceRequest(), coal.DistanceResult()
        coal.distance(go.geometry, coal.Transform3s(gdata.oMg[i]), box, coal.Transform3s(M), req, res)
        best = min(best, res.min_distance)
    return best


def _frames(robot, q, *roles):
    data = robot.data()
    pin.framesForwardKinematics(robot.model, data, q)
    return [data.oMf[robot.frame_id(r)].copy() for r in roles]


@pytest.mark.parametrize("robot_name", ["talos", "g1"])
def test_walk_to_the_table_stops_the_margin_away_facing_it_within_reach(request, kitchen, robot_name):
    robot = request.getfixturevalue(robot_name)
    spec = compile_actions([Action(name="walk_to", params={"object": "the table"})], robot, scene=kitchen)
    assert spec.dynamic and spec.scene == kitchen
    assert spec_from_json(spec_to_json(spec)) == spec
    table = kitchen.get("table")
    stance = _end_stance(spec)
    # facing +x (the table's centre is straight ahead)
    assert stance.left.rpy[2] == pytest.approx(0.0, abs=1e-9) and stance.right.rpy[2] == pytest.approx(0.0, abs=1e-9)
    q = _q_at(robot, stance)
    # the body's meshes (coal) are at least the margin from the table, and not much more (the
    # stop is computed from the boxes of the meshes: at most a few cm more than the margin)
    d = _clearance(robot, q, table)
    assert WALK_MARGIN - 1e-6 <= d <= WALK_MARGIN + 0.15, d
    # within reach: the table's point nearest to a shoulder is within the arm's reach of it once
    # the shoulder bends at most BEND_MAX about the hips (the shoulder moves at most that chord)
    lo, hi = extent(table)
    gaps = []
    for side in ("left", "right"):
        sh, hip = _frames(robot, q, f"{side}_shoulder", "base")
        near = np.clip(sh.translation, lo, hi)
        L = _arm_chain_length(robot, side)
        chord = 2 * math.sin(BEND_MAX / 2) * np.linalg.norm(sh.translation - hip.translation)
        gaps.append(np.linalg.norm(near - sh.translation) - REACH_FRACTION * L - chord)
    assert min(gaps) <= 0.0, gaps


def _arm_chain_length(robot, side: str) -> float:
    """Sum of the joint-to-joint distances from the shoulder frame to the hand frame (Pinocchio)."""
    model, data = robot.model, robot.data()
    pin.framesForwardKinematics(model, data, robot.q_standing)
    hand = model.frames[robot.frame_id(f"{side}_hand")]
    shoulder = model.frames[robot.frame_id(f"{side}_shoulder")]
    chain, j = [], hand.parentJoint
    while j > shoulder.parentJoint:
        chain.append(data.oMi[j].translation)
        j = model.parents[j]
    points = [data.oMf[robot.frame_id(f"{side}_hand")].translation, *chain, data.oMi[shoulder.parentJoint].translation]
    return float(sum(np.linalg.norm(a - b) for a, b in zip(points, points[1:], strict=False)))


def test_walk_to_the_cup_stops_at_the_table_edge(kitchen, talos):
    """The cup is on the table: the walk stops the margin before the table, the cup within reach."""
    spec = compile_actions([Action(name="walk_to", params={"object": "the cup"})], talos, scene=kitchen)
    stance = _end_stance(spec)
    cup = kitchen.get("cup")
    yaw = math.atan2(cup.position[1], cup.position[0])  # turned towards the cup's centre first
    assert stance.left.rpy[2] == pytest.approx(yaw, abs=1e-6)
    d = _clearance(talos, _q_at(talos, stance), kitchen.get("table"))
    assert WALK_MARGIN - 1e-6 <= d <= WALK_MARGIN + 0.15, d


def test_look_at_points_the_head_at_the_object(kitchen, talos):
    """The head target's forward axis (the standing head's axis along the heading, Pinocchio) points
    from the head (Pinocchio) at the cup's centre."""
    spec = compile_actions([Action(name="look_at", params={"object": "杯子"})], talos, scene=kitchen)
    target = next(t for t in spec.targets if "looking at the cup" in t.name)
    (head,) = _frames(talos, talos.q_standing, "head")
    forward_in_head = head.rotation.T @ np.array([1.0, 0.0, 0.0])
    axis = pin.rpy.rpyToMatrix(*target.rpy) @ forward_in_head
    to_cup = np.asarray(kitchen.get("cup").position) - head.translation
    angle = math.acos(min(1.0, float(axis @ to_cup) / np.linalg.norm(to_cup)))
    assert angle < LOOK_TOLERANCE / 10, angle
    assert target.orientation_tolerance == LOOK_TOLERANCE


def test_look_at_is_refused_without_a_neck_and_beyond_its_range(kitchen, talos, g1):
    with pytest.raises(TaskDefinitionError, match="g1 has no neck joint to look at the cup"):
        compile_actions([Action(name="look_at", params={"object": "the cup"})], g1, scene=kitchen)
    with pytest.raises(TaskDefinitionError, match=r"action 2 \(look_at\): look_at: the cup is .* rad down .* "
                                                  r"beyond talos's neck range"):
        compile_actions([Action(name="walk_to", params={"object": "the table"}),
                         Action(name="look_at", params={"object": "the cup"})], talos, scene=kitchen)


@pytest.mark.parametrize("robot_name", ["talos", "g1"])
def test_point_at_the_cup_after_walking_to_the_table(request, kitchen, robot_name):
    """The hand target is on the line from the shoulder (Pinocchio, at the stance the walk ends in)
    to the cup's centre, clear of every object; the left arm, the cup being on the left."""
    robot = request.getfixturevalue(robot_name)
    spec = compile_actions([Action(name="walk_to", params={"object": "the table"}),
                            Action(name="point_at", params={"object": "the cup"})], robot, scene=kitchen)
    target = next(t for t in spec.targets if "pointing at the cup" in t.name)
    assert target.frame == robot.frame("left_hand")
    (sh,) = _frames(robot, _q_at(robot, _end_stance(spec)), "left_shoulder")
    to_hand = np.asarray(target.position) - sh.translation
    to_cup = np.asarray(kitchen.get("cup").position) - sh.translation
    angle = math.acos(min(1.0, float(to_hand @ to_cup) / (np.linalg.norm(to_hand) * np.linalg.norm(to_cup))))
    assert angle < 1e-6, angle
    assert np.linalg.norm(to_hand) <= _arm_chain_length(robot, "left")
    for obj in kitchen.objects:
        assert signed_distance(obj, target.position) >= POINT_CLEARANCE - 1e-9, obj.name


def test_object_actions_need_a_scene_and_a_unique_object(kitchen, talos):
    with pytest.raises(GroundingError, match='point_at "the cup" refers to an object, but there is no scene'):
        compile_actions([Action(name="point_at", params={"object": "the cup"})], talos)
    with pytest.raises(GroundingError, match=r'action 2 \(point_at\): "the box" could be red box .* or blue box'):
        compile_actions([Action(name="wave"), Action(name="point_at", params={"object": "the box"})], talos,
                        scene=kitchen)
    with pytest.raises(TaskDefinitionError, match='walk_to needs an object: say which, e.g. "walk to the table"'):
        compile_actions([Action(name="walk_to")], talos, scene=kitchen)
