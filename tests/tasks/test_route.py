"""walk_to around objects (tasks/primitives/route.py through tasks/primitives/objects.py): the
footprint distance against tasks.scene.signed_distance, the route's body clearance against coal
distances between the robot's collision meshes (placed with Pinocchio along the route) and the
object shapes, the enclosed target refused naming what encloses it."""

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
from tasks.exceptions import SceneConflict
from tasks.grounding import Grounded
from tasks.primitives.geometry import Stance
from tasks.primitives.objects import WALK_MARGIN, walk_plan
from tasks.primitives.route import ROUTE_MARGIN, clearance_radius, footprint_distance
from tasks.scene import SceneObject, load_scene, signed_distance

SCENES = Path(__file__).resolve().parents[2] / "examples" / "scenes"


@pytest.fixture(scope="module")
def warehouse():
    return load_scene(SCENES / "warehouse.json")


def test_footprint_distance_is_the_signed_distance_at_the_objects_height():
    """Upright boxes (yawed), cylinders and spheres: the horizontal distance to the outline equals
    tasks.scene.signed_distance at the object's centre height, inside and out."""
    rng = np.random.default_rng(7)
    objects = [
        SceneObject(name="b", shape="box", size=(0.6, 0.3, 0.5), position=(1.0, -0.5, 0.25), rpy=(0.0, 0.0, 0.7)),
        SceneObject(name="c", shape="cylinder", size=(0.2, 0.8), position=(-0.4, 0.3, 0.4)),
        SceneObject(name="s", shape="sphere", size=(0.25,), position=(0.2, 0.9, 0.25)),
    ]
    for obj in objects:
        xy = np.asarray(obj.position[:2]) + rng.uniform(-0.8, 0.8, size=(200, 2))
        ours = footprint_distance(obj, xy)
        ref = [signed_distance(obj, (x, y, obj.position[2])) for x, y in xy]
        np.testing.assert_allclose(ours, ref, atol=1e-12, err_msg=obj.name)
        assert (ours < 0).any() and (ours > 0).any(), obj.name


def _grounded(scene, name, robot) -> Grounded:
    return Grounded(reference=f"the {name}", obj=scene.get(name), scene=scene, start=Stance.standing(robot))


def _poses(plan) -> list[tuple[float, float, float, int]]:
    """(x, y, yaw, leg) every 5 cm along each leg and every 0.2 rad through each turn in place."""
    out = []
    p = np.asarray(plan.waypoints[0])
    yaw = 0.0
    for k, leg in enumerate(plan.legs):
        for a in np.linspace(yaw, yaw + leg.angle, max(2, math.ceil(abs(leg.angle) / 0.2) + 1)):
            out.append((p[0], p[1], float(a), k))
        yaw += leg.angle
        u = np.array([math.cos(yaw), math.sin(yaw)])
        for s in np.linspace(0.0, leg.distance, max(2, math.ceil(leg.distance / 0.05) + 1)):
            out.append((*(p + s * u), yaw, k))
        p = p + leg.distance * u
    return out


def _mesh_clearance(robot, x, y, yaw, obj, cache) -> float:
    """coal distance between the robot's collision meshes (standing posture carried to x, y, yaw with
    Pinocchio) and the object's box."""
    H0 = Stance.standing(robot).heading()
    T = pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, yaw), np.array([x, y, 0.0])) * H0.inverse()
    q = robot.q_standing.copy()
    q[:7] = pin.SE3ToXYZQUAT(T * pin.XYZQUATToSE3(q[:7]))
    cm = robot.collision_model
    if "gdata" not in cache:
        cache["gdata"], cache["data"] = pin.GeometryData(cm), robot.data()
    pin.updateGeometryPlacements(robot.model, cache["data"], cm, cache["gdata"], q)
    shape = coal.Box(*obj.size)
    M = coal.Transform3s(pin.SE3(pin.rpy.rpyToMatrix(*obj.rpy), np.array(obj.position)))
    best = math.inf
    for i, go in enumerate(cm.geometryObjects):
        res = coal.DistanceResult()
        coal.distance(go.geometry, coal.Transform3s(cache["gdata"].oMg[i]), shape, M, coal.DistanceRequest(), res)
        best = min(best, res.min_distance)
    return best


@pytest.mark.parametrize("robot_name", ["talos", "g1"])
def test_route_to_the_blue_box_keeps_every_object_the_margin_away(warehouse, robot_name):
    """The crate stack is in the straight line to the blue box: the walk goes around it. At every
    5 cm and through every turn, the point between the feet keeps each object's clearance radius
    (tasks.scene.signed_distance), and the robot's collision meshes (coal) stay ROUTE_MARGIN from
    every object (WALK_MARGIN on the final approach) where the route comes nearest to it;
    the end faces the blue box."""
    robot = load_robot(robot_name)
    plan = walk_plan(robot, _grounded(warehouse, "blue box", robot))
    assert len(plan.legs) >= 3 and plan.reach_gap <= 0.0
    poses = _poses(plan)
    last = len(plan.legs) - 1
    # the route leaves the straight line: its widest point is beyond the stack's side
    stack = warehouse.get("crate stack")
    assert max(abs(y) for _, y, _, _ in poses) > stack.size[1] / 2
    nearest: dict[str, tuple[float, int]] = {}
    for n, (x, y, _, leg) in enumerate(poses):
        for obj in warehouse.objects:
            d = signed_distance(obj, (x, y, obj.position[2]))
            if leg < last:
                assert d >= clearance_radius(robot, obj) - 1e-9, (obj.name, x, y)
            nearest[obj.name] = min(nearest.get(obj.name, (math.inf, 0)), (d, n))
    box = warehouse.get("blue box")
    x, y, yaw, _ = poses[-1]
    to_box = math.atan2(box.position[1] - y, box.position[0] - x)
    assert abs(math.remainder(yaw - to_box, 2 * math.pi)) < 1e-6
    # the meshes where the route comes nearest to each object (g1's meshes are loaded once per
    # session, test_objects.py loads them too)
    cache: dict = {}
    worst = math.inf
    for name, (d, n) in nearest.items():
        obj = warehouse.get(name)
        if d > clearance_radius(robot, obj) + 0.2:
            continue
        for x, y, yaw, leg in poses[n:n + 1]:
            c = _mesh_clearance(robot, x, y, yaw, obj, cache)
            worst = min(worst, c)
            assert c >= (ROUTE_MARGIN if leg < last else WALK_MARGIN) - 1e-6, (name, x, y, yaw, c)
    assert worst < 0.2, worst  # it does pass close to something (the target at the end)


def test_walk_to_the_door_goes_around_the_kitchen_table():
    """The table is in the straight line to the door: the compiled walk has several turns and its
    footsteps (every sole placement of the spec) stay clear of the table."""
    kitchen = load_scene(SCENES / "kitchen.json")
    robot = load_robot("talos")
    spec = compile_actions([Action(name="walk_to", params={"object": "the door"})], robot, scene=kitchen)
    turns = {p.name.split(": ")[1] for p in spec.phases if ": leg " in p.name}
    assert len(turns) >= 3, turns
    table = kitchen.get("table")
    for phase in spec.phases:
        for c in phase.contacts:
            assert footprint_distance(table, np.array(c.placement.position[:2]))[0] > 0.2, phase.name


def test_an_enclosed_box_is_refused_naming_what_encloses_it(warehouse):
    robot = load_robot("g1")
    with pytest.raises(SceneConflict, match="walk_to: the green box is enclosed by the tall crate, the wide crate, "
                                            "the back wall and the side wall") as e:
        compile_actions([Action(name="walk_to", params={"object": "绿色箱子"})], robot, scene=warehouse)
    assert e.value.object_name == "green box"
