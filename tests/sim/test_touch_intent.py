"""The certificate's touch_object line (sim/intent.py ``object_touch_checks``): the touching hand's
collision meshes at the object it touches, the median over the held window, checked on recorded
configurations made here (no simulation: the arm posed at the touch target, or standing) against
coal distances computed independently with Pinocchio's geometry functions. The full Talos run
(planned, simulated, certified and the hand at the red box in MuJoCo) is
tests/sim/test_objects_sim.py::test_talos_touches_the_red_box_on_the_counter (long)."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import coal
import numpy as np
import pinocchio as pin
import pytest

from language import parse
from planner.results import CheckKind
from sim.intent import OBJECT_TOUCH_DISTANCE, object_touch_checks
from tasks.compose import compile_actions
from tasks.primitives.bodymap import arm_configuration, to_heading
from tasks.scene import load_scene

SCENE = Path(__file__).resolve().parents[2] / "examples" / "scenes" / "box_on_counter.json"


@pytest.fixture(scope="module")
def touch(talos):
    scene = load_scene(SCENE)
    spec = compile_actions(parse("touch the red box").actions, talos, scene=scene)
    (target,) = [t for t in spec.targets if t.touch is not None]
    side = "left" if target.frame == talos.frame("left_hand") else "right"
    posed = arm_configuration(talos, {side: to_heading(talos, np.asarray(target.position))}, natural=True)
    return spec, target, side, posed, scene.get("red box")


def _run(robot, spec, q):
    """A stand-in for a RunRecord: ``q`` held from 0 to the spec's end every 10 ms."""
    ts = np.arange(0.0, spec.horizon, 0.01)
    return SimpleNamespace(robot=robot, t=ts, q=np.tile(q, (len(ts), 1)),
                           ref=SimpleNamespace(plan=SimpleNamespace(spec=spec), duration=spec.horizon))


def _coal_gap(robot, side, q, position) -> float:
    """Independent: the box added to the collision model, every hand geometry paired with it."""
    model, gm = robot.model, robot.collision_model.copy()
    obj = load_scene(SCENE).get("red box")
    box = gm.addGeometryObject(pin.GeometryObject("red box", 0, 0, pin.SE3(np.eye(3), np.asarray(position, float)),
                                                  coal.Box(*obj.size)))
    sub = set(model.subtrees[model.frames[robot.frame_id(f"{side}_hand")].parentJoint])
    for i, o in enumerate(gm.geometryObjects):
        if o.parentJoint in sub:
            gm.addCollisionPair(pin.CollisionPair(i, box))
    gd = gm.createData()
    pin.computeDistances(model, model.createData(), gm, gd, q)
    return max(0.0, min(r.min_distance for r in gd.distanceResults))


def test_the_hand_at_the_box_passes_and_short_of_it_fails_in_the_actions_words(talos, touch):
    """Posed at the touch target, the hand's meshes are in the red box: the line passes at 0 m.
    Standing, the hand is far from it: the line fails, "touch object (action 1): the left hand
    stayed ... m from the red box", its value the coal distance. The box recorded 8 cm farther
    from the hand (where MuJoCo had it) is measured where it was: the hand is then short of it."""
    spec, target, side, posed, obj = touch
    (line,) = object_touch_checks(_run(talos, spec, posed), {})
    assert line.kind is CheckKind.INTENT_WORDS and line.ok and line.value == pytest.approx(
        _coal_gap(talos, side, posed, obj.position), abs=1e-4)
    assert line.value <= 0.001
    (far,) = object_touch_checks(_run(talos, spec, talos.q_standing), {})
    want = _coal_gap(talos, side, talos.q_standing, obj.position)
    assert not far.ok and far.value == pytest.approx(want, abs=1e-4) and want > 3 * OBJECT_TOUCH_DISTANCE
    assert far.message.startswith(f"touch object (action 1): the {side} hand stayed {want:.3f} m from the red box")
    run = _run(talos, spec, posed)
    away_from_hand = np.asarray(obj.position) - np.asarray(target.position)
    moved = np.asarray(obj.position) + 0.08 * away_from_hand / np.linalg.norm(away_from_hand)
    poses = {"red box": (np.tile(moved, (len(run.t), 1)), np.tile([0.0, 0.0, 0.0, 1.0], (len(run.t), 1)))}
    (away,) = object_touch_checks(run, poses)
    assert away.value == pytest.approx(_coal_gap(talos, side, posed, moved), abs=1e-4)
    assert away.value > 2 * OBJECT_TOUCH_DISTANCE and not away.ok
