"""The certificate's touch_object line (sim/intent.py ``object_touch_checks``): the touching hand's
collision meshes at the object it touches, the median over the held window, checked on recorded
configurations made here (no simulation: standing, a box placed at or away from the hand) against
coal distances computed independently with Pinocchio's geometry functions. The full Talos run
(planned, simulated, certified and the hand at the red box in MuJoCo) is
tests/sim/test_objects_sim.py::test_talos_touches_the_red_box_on_the_counter (long)."""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import coal
import numpy as np
import pinocchio as pin
import pytest

from planner.results import CheckKind
from sim.intent import OBJECT_TOUCH_DISTANCE, object_touch_checks
from tasks.scene import Scene, SceneObject
from tasks.specs import FrameTarget, Phase, TaskSpec


@pytest.fixture(scope="module")
def touch(talos):
    """A red box (0.2 x 0.2 x 0.15 m, as in examples/scenes/box_on_counter.json) centred on the
    standing left hand frame, and a touch_object target there over 1-2 s of a 3 s spec: the hand's
    meshes are in the box."""
    data = talos.model.createData()
    pin.framesForwardKinematics(talos.model, data, talos.q_standing)
    hand = data.oMf[talos.frame_id("left_hand")].translation.copy()
    box = SceneObject(name="red box", shape="box", size=(0.2, 0.2, 0.15), position=tuple(float(x) for x in hand),
                      movable=True, mass=0.5)
    target = FrameTarget(name="1 touch_object: left hand touching the red box", frame=talos.frame("left_hand"),
                         position=tuple(float(x) for x in hand), window=(1.0, 2.0), touch="red box")
    spec = TaskSpec(phases=(Phase(name="1 touch_object: touch the red box", duration=3.0),), targets=(target,),
                    scene=Scene(name="a box at the hand", objects=(box,)))
    return spec, target, "left", talos.q_standing, box


def _run(robot, spec, q):
    """A stand-in for a RunRecord: ``q`` held from 0 to the spec's end every 10 ms."""
    ts = np.arange(0.0, spec.horizon, 0.01)
    return SimpleNamespace(robot=robot, t=ts, q=np.tile(q, (len(ts), 1)),
                           ref=SimpleNamespace(plan=SimpleNamespace(spec=spec), duration=spec.horizon))


def _coal_gap(robot, side, q, position) -> float:
    """Independent: the box added to the collision model, every hand geometry paired with it."""
    model, gm = robot.model, robot.collision_model.copy()
    box = gm.addGeometryObject(pin.GeometryObject("red box", 0, 0, pin.SE3(np.eye(3), np.asarray(position, float)),
                                                  coal.Box(0.2, 0.2, 0.15)))
    sub = set(model.subtrees[model.frames[robot.frame_id(f"{side}_hand")].parentJoint])
    for i, o in enumerate(gm.geometryObjects):
        if o.parentJoint in sub:
            gm.addCollisionPair(pin.CollisionPair(i, box))
    gd = gm.createData()
    pin.computeDistances(model, model.createData(), gm, gd, q)
    return max(0.0, min(r.min_distance for r in gd.distanceResults))


def test_the_hand_at_the_box_passes_and_short_of_it_fails_in_the_actions_words(talos, touch):
    """The hand's meshes in the red box: the line passes at 0 m. The box 0.3 m ahead of the hand:
    the line fails, "touch object (action 1): the left hand stayed ... m from the red box", its
    value the coal distance. The box recorded 0.3 m to the left (where MuJoCo had it: knocked aside) is
    measured where it was: the hand is then short of it."""
    spec, target, side, posed, obj = touch
    (line,) = object_touch_checks(_run(talos, spec, posed), {})
    assert line.name == "intent: touch object (action 1): the left hand at the red box"
    assert line.kind is CheckKind.INTENT_WORDS and line.ok and line.value == pytest.approx(
        _coal_gap(talos, side, posed, obj.position), abs=1e-4)
    assert line.value <= 0.001
    away = np.asarray(obj.position) + np.array([0.3, 0.0, 0.0])
    far_box = dataclasses.replace(obj, position=tuple(float(x) for x in away))
    far_spec = dataclasses.replace(spec, scene=Scene(name="a box ahead", objects=(far_box,)))
    (far,) = object_touch_checks(_run(talos, far_spec, posed), {})
    want = _coal_gap(talos, side, posed, away)
    assert not far.ok and far.value == pytest.approx(want, abs=1e-4) and want > 3 * OBJECT_TOUCH_DISTANCE
    assert far.message.startswith(f"touch object (action 1): the {side} hand stayed {want:.3f} m from the red box")
    run = _run(talos, spec, posed)
    moved = np.asarray(obj.position) + np.array([0.0, 0.3, 0.0])
    poses = {"red box": (np.tile(moved, (len(run.t), 1)), np.tile([0.0, 0.0, 0.0, 1.0], (len(run.t), 1)))}
    (fallen,) = object_touch_checks(run, poses)
    assert fallen.value == pytest.approx(_coal_gap(talos, side, posed, moved), abs=1e-4)
    assert fallen.value > 2 * OBJECT_TOUCH_DISTANCE and not fallen.ok
