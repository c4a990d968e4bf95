"""Self-collision and scene objects in the simulation, and the certificate's collision lines.

References: the robot's collision model (robots.collision) for which pairs MuJoCo collides;
coal distances on the URDF meshes (Pinocchio geometry) for what the certificate measures;
textbook inertia formulas for the movable objects.
"""

from __future__ import annotations

import dataclasses
import itertools

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from planner.results import CheckKind
from robots.collision import body_part, collision_model
from sim import SimSettings, build_model, simulate
from sim.collisions import MeshDistance
from sim.handmade import arm_plan, joint_plan, squat_plan, standing_plan
from sim.model import OBJECT_PREFIX, ROBOT_ROLE
from tasks.scene import Scene, SceneObject

#: Talos's left arm swung inward through its left hip link (standing posture elsewhere): on the way
#: only left-gripper links touch ``leg_left_3_link`` in MuJoCo (searched on a grid), and at the
#: bump's top the gripper's URDF mesh is inside the hip's (coal).
HAND_INTO_HIP = {"arm_left_1_joint": -0.75, "arm_left_2_joint": 0.1, "arm_left_3_joint": -1.2,
                 "arm_left_4_joint": -0.33}


def _mujoco_link_pairs(sm) -> set[tuple[str, str]]:
    m = sm.model
    return {tuple(sorted((sm.geom_body_names[m.pair_geom1[p]], sm.geom_body_names[m.pair_geom2[p]])))
            for p in range(m.npair)}


@pytest.mark.parametrize("name", ["talos", "g1"])
def test_mujoco_collides_exactly_the_collision_model_pairs(name, request):
    """Every MuJoCo pair joins two links of a model pair, every model pair has its geoms' pairs,
    and no other robot geoms can collide (contype/conaffinity keep robot-robot contacts off)."""
    robot = request.getfixturevalue(name)
    sm = build_model(robot)
    model_pairs = set(collision_model(robot).pairs)
    assert sm.rest_overlap == {}  # no hull of a model pair overlaps at rest on these robots
    assert _mujoco_link_pairs(sm) == model_pairs
    assert len(set(sm.pair_index.tolist())) == len(model_pairs) == len(sm.collision_pairs)
    m = sm.model
    robot_geoms = np.nonzero(sm.geom_role == ROBOT_ROLE)[0]
    # one MuJoCo pair per two collision geoms (the sole boxes, floor stand-ins, excluded)
    soles = set(sm.sole_geoms.values())
    per_link: dict[str, int] = {}
    for g in robot_geoms.tolist():
        if g not in soles:
            per_link[sm.geom_body_names[g]] = per_link.get(sm.geom_body_names[g], 0) + 1
    assert m.npair == sum(per_link[a] * per_link[b] for a, b in model_pairs) == len(sm.pair_index)
    for g1, g2 in itertools.combinations(robot_geoms.tolist(), 2):
        assert not (m.geom_contype[g1] & m.geom_conaffinity[g2] or m.geom_contype[g2] & m.geom_conaffinity[g1])


@pytest.mark.parametrize("name", ["talos", "g1"])
def test_no_self_contact_standing(name, request):
    """In the standing posture no pair of the collision model touches in MuJoCo (and coal agrees
    that their meshes are apart)."""
    robot = request.getfixturevalue(name)
    sm = build_model(robot)
    d = sm.data()
    sm.set_state(d, robot.q_standing)
    pair_geoms = set(zip(sm.model.pair_geom1.tolist(), sm.model.pair_geom2.tolist(), strict=True))
    touching = [c for c in range(d.ncon) if tuple(d.contact.geom[c].tolist()) in pair_geoms
                or tuple(d.contact.geom[c][::-1].tolist()) in pair_geoms]
    assert touching == []


def _scene() -> Scene:
    return Scene(name="test", objects=(
        SceneObject(name="block", shape="box", size=(0.3, 0.2, 0.4), position=(0.8, 0.0, 0.2),
                    rpy=(0.0, 0.0, 0.3), colour=(0.8, 0.2, 0.2, 1.0)),
        SceneObject(name="can", shape="cylinder", size=(0.05, 0.2), position=(0.0, 0.9, 0.1), movable=True,
                    mass=2.0, friction=0.5, colour=(0.1, 0.3, 0.9, 1.0)),
        SceneObject(name="ball", shape="sphere", size=(0.1,), position=(-0.9, 0.0, 0.1), movable=True, mass=0.5),
    ))


def test_scene_objects_become_mujoco_geoms(talos):
    """Static objects are world geoms, movable ones free bodies whose mass and inertia are the
    shape's; sizes, poses, colours and friction as the scene says; a resting movable object stays put."""
    scene = _scene()
    sm = build_model(talos, scene=scene)
    m = sm.model
    assert sm.object_names == ("block", "can", "ball")
    geom = {o.name: mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, OBJECT_PREFIX + o.name) for o in scene.objects}
    block, can, ball = (geom[n] for n in ("block", "can", "ball"))
    assert m.geom_bodyid[block] == 0  # fixed to the world
    np.testing.assert_allclose(m.geom_size[block], [0.15, 0.1, 0.2])
    np.testing.assert_allclose(m.geom_pos[block], [0.8, 0.0, 0.2])
    quat = pin.Quaternion(pin.rpy.rpyToMatrix(0.0, 0.0, 0.3))
    np.testing.assert_allclose(np.abs(m.geom_quat[block]), np.abs([quat.w, quat.x, quat.y, quat.z]), atol=1e-12)
    np.testing.assert_allclose(m.geom_rgba[block], [0.8, 0.2, 0.2, 1.0], atol=1e-6)
    body = m.geom_bodyid[can]
    assert m.body_jntnum[body] == 1 and m.jnt_type[m.body_jntadr[body]] == mujoco.mjtJoint.mjJNT_FREE
    assert m.body_mass[body] == pytest.approx(2.0)
    r, h = 0.05, 0.2
    np.testing.assert_allclose(sorted(m.body_inertia[body]),
                               sorted([2.0 * (3 * r**2 + h**2) / 12] * 2 + [2.0 * r**2 / 2]), rtol=1e-6)
    assert m.geom_friction[can, 0] == pytest.approx(0.5)
    assert m.body_mass[m.geom_bodyid[ball]] == pytest.approx(0.5)
    np.testing.assert_allclose(m.body_inertia[m.geom_bodyid[ball]], [2 / 5 * 0.5 * 0.1**2] * 3, rtol=1e-6)
    # the robot keeps its joint order and state maps; the movable objects rest on the floor
    d = sm.data()
    sm.set_state(d, talos.q_standing)
    start = d.xpos[m.geom_bodyid[can]].copy()
    for _ in range(300):
        mujoco.mj_step(m, d)
    np.testing.assert_allclose(d.xpos[m.geom_bodyid[can]], start, atol=2e-3)
    assert d.xpos[m.geom_bodyid[ball]][2] == pytest.approx(0.1, abs=2e-3)


def _check(execution, kind):
    [check] = [c for c in execution.certificate.checks if c.kind == kind]
    return check


@pytest.fixture(scope="module")
def hand_run(talos):
    plan = joint_plan(talos, HAND_INTO_HIP, duration=3.0, name="hand into hip")
    return plan, simulate(plan, talos, settings=SimSettings(settle_time=0.2))


def test_hand_through_hip_fails_on_self_collision(talos, hand_run):
    """A plan that drives the left hand through the left hip (coal: their URDF meshes intersect at
    the top of the motion) fails the certificate on the self-collision line, which names the pair:
    MuJoCo stops the hand on the hip (a few mm deep), pressing with more than the 10 N limit."""
    plan, ex = hand_run
    mid = len(plan.t) // 2
    assert MeshDistance(talos).between(plan.q[mid], "gripper_left_base_link", "leg_left_3_link") == 0.0
    check = _check(ex, CheckKind.SELF_COLLISION)
    assert not check.ok and not ex.certificate.ok
    hand, hip = body_part(talos, "gripper_left_base_link"), body_part(talos, "leg_left_3_link")
    assert check.subject == f"{hand} / {hip}" == "left hand / left thigh"
    assert "/ leg_left_3_link" in check.message and "gripper_left_" in check.message
    assert ex.certificate.reason.startswith(f"{hand} hit the {hip} at t = ")
    assert 0.5 < check.time < 1.5  # on the way in (the top is at 1.5 s)
    assert "self-collision: left hand / left thigh" in ex.summary()


@pytest.fixture(scope="module")
def squat_run(talos):
    return simulate(squat_plan(talos, depth=0.15, duration=2.5), talos, settings=SimSettings(settle_time=0.2))


def test_squat_passes_with_both_collision_lines(talos, squat_run):
    """A squat passes; the self-collision line gives its closest pair at a distance no larger than
    coal's on the URDF meshes (MuJoCo measures the convex hulls, which contain the meshes)."""
    ex = squat_run
    assert ex.certificate.ok, ex.certificate.summary()
    check = _check(ex, CheckKind.SELF_COLLISION)
    scene = _check(ex, CheckKind.SCENE_COLLISION)
    assert check.ok and scene.ok and scene.name == "scene collision: no objects"
    assert check.value > 0 and check.unit == "mm"
    n = int(np.argmin(np.abs(ex.t - check.time)))
    links = {body_part(talos, a): a for pair in collision_model(talos).pairs for a in pair}
    a, b = check.subject.split(" / ")
    # the feet are left out of the comparison: MuJoCo's foot pair is the ankle meshes (the sole
    # boxes are never paired), coal's the whole foot (a known gap, docs/simulation-collisions.md)
    feet = {"left foot", "right foot"}
    if a in links and b in links and links[a] != links[b] and {a, b} != feet:
        mesh = MeshDistance(talos).between(ex.q[n], links[a], links[b])
        assert check.value / 1000 <= mesh + 1e-3
    summary = ex.summary()
    assert "self-collision: " in summary and "scene collision" in summary


def _box_distance(robot, q, box: SceneObject) -> float:
    """Coal distance between a box and the robot's URDF collision meshes at ``q`` [m]."""
    import coal  # type: ignore[import-untyped]

    gmodel = robot.collision_model.copy()
    placement = pin.SE3(pin.rpy.rpyToMatrix(*box.rpy), np.array(box.position))
    shape = coal.Box(*box.size)
    obj = pin.GeometryObject("box", 0, 0, placement, shape)
    k = gmodel.addGeometryObject(obj)
    for i in range(k):
        gmodel.addCollisionPair(pin.CollisionPair(i, k))
    gdata = gmodel.createData()
    data = robot.model.createData()
    pin.computeDistances(robot.model, data, gmodel, gdata, q)
    return min(r.min_distance for r in gdata.distanceResults)


def test_static_box_away_from_the_robot_is_untouched(talos):
    """A static box 30 cm in front of the standing robot: no contact, and the scene line reports
    the closest distance, within 2 cm below coal's on the URDF meshes (hulls contain meshes)."""
    box = SceneObject(name="crate", shape="box", size=(0.2, 0.4, 0.3), position=(0.45, 0.0, 0.15))
    plan = standing_plan(talos, duration=1.0)
    plan = dataclasses.replace(plan, spec=dataclasses.replace(plan.spec, scene=Scene(objects=(box,))))
    ex = simulate(plan, talos, settings=SimSettings(settle_time=0.2))
    assert ex.certificate.ok, ex.certificate.summary()
    check = _check(ex, CheckKind.SCENE_COLLISION)
    assert check.ok and check.subject.endswith("/ 'crate'")
    n = int(np.argmin(np.abs(ex.t - check.time)))
    reference = _box_distance(talos, ex.q[n], box)
    assert 0.05 < reference < 0.5
    assert reference - 0.02 <= check.value / 1000 <= reference + 1e-3


def test_hand_into_a_box_fails_on_scene_collision(talos):
    """The right hand's path goes through a static box: the scene line fails, naming the hand and
    the box."""
    plan = arm_plan(talos, side="right", offset=(0.25, 0.0, 0.15), duration=2.0)
    data = talos.data()
    mid = len(plan.t) // 2
    pin.framesForwardKinematics(talos.model, data, plan.q[mid])
    hand = data.oMf[talos.frame_id("right_hand")].translation
    box = SceneObject(name="box", shape="box", size=(0.1, 0.1, 0.1), position=tuple(float(x) for x in hand))
    assert _box_distance(talos, plan.q[mid], box) <= 0.0  # the plan itself goes through the box
    plan = dataclasses.replace(plan, spec=dataclasses.replace(plan.spec, scene=Scene(objects=(box,))))
    ex = simulate(plan, talos, settings=SimSettings(settle_time=0.2))
    check = _check(ex, CheckKind.SCENE_COLLISION)
    assert not check.ok and not ex.certificate.ok
    assert check.subject.startswith("right ") and check.subject.endswith("/ 'box'")
    assert "touched 'box'" in check.message
    assert any(e.kind == "unplanned_contact" and "'box'" in e.message for e in ex.events)
