"""hand_over (tasks/primitives/handover.py) and push (tasks/primitives/push.py): sentences to actions,
actions to specs, checked with numbers computed here (Pinocchio frame placements of the standing
talos, the scene's boxes, m g mu), and the refusals in task terms."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from language import parse
from robots import load_robot
from tasks.actions import Action
from tasks.compose import compile_actions
from tasks.exceptions import TaskDefinitionError
from tasks.scene import Scene, SceneObject
from tasks.serialize import spec_from_json, spec_to_json
from tasks.specs import Grasp, Push

CUP = SceneObject(name="cup", shape="cylinder", size=(0.04, 0.1), position=(0.52, 0.2, 0.77), aliases=("杯子",),
                  movable=True, mass=0.25)
TABLE = SceneObject(name="table", shape="box", size=(0.6, 1.0, 0.72), position=(0.75, 0.0, 0.36), aliases=("桌子",))
BOX = SceneObject(name="red box", shape="box", size=(0.15, 0.15, 0.15), position=(0.6, -0.2, 0.795), movable=True,
                  mass=0.5, friction=0.8, aliases=("红色盒子",))
SCENE = Scene(name="a cup and a box within reach", objects=(TABLE, CUP, BOX))


@pytest.fixture(scope="module")
def talos():
    return load_robot("talos")


@pytest.mark.parametrize(("text", "expected"), [
    ("push the box 20 cm", [("push", {"object": "the box", "distance": 0.2})]),
    ("push the red box forward 10 cm", [("push", {"object": "the red box", "distance": 0.1, "direction": "forward"})]),
    ("push the red box to the left 10 cm", [("push", {"object": "the red box", "distance": 0.1, "direction": "left"})]),
    ("把箱子往左推10厘米", [("push", {"object": "箱子", "distance": 0.1, "direction": "left"})]),
    ("把箱子推过去", [("push", {"object": "箱子"})]),
    ("把盒子往前推20厘米", [("push", {"object": "盒子", "distance": 0.2})]),
    ("push the red box with your left hand", [("push", {"object": "the red box", "arm": "left"})]),
    ("hand me the cup", [("hand_over", {"object": "the cup"})]),
    ("hand over the cup", [("hand_over", {"object": "the cup"})]),
    ("把杯子递给我", [("hand_over", {"object": "杯子"})]),
    ("pick up the cup and hand it to me", [("pick_up", {"object": "the cup"}), ("hand_over", {"object": "the cup"})]),
    ("pick up the cup, then hand it over", [("pick_up", {"object": "the cup"}), ("hand_over", {"object": "the cup"})]),
    ("拿起杯子然后递给我", [("pick_up", {"object": "杯子"}), ("hand_over", {"object": "杯子"})]),
])
def test_sentences(text, expected):
    """The words name the actions and their stated parameters (nothing else is stated)."""
    got = [(a["action"], a["params"]) for a in parse(text).to_dict()["actions"]]
    assert got == expected


def _shoulder(talos, side: str) -> np.ndarray:
    """The shoulder (the arm's second joint, where its first three axes meet) at the standing posture, world [m]
    (Pinocchio)."""
    model, data = talos.model, talos.data()
    pin.forwardKinematics(model, data, talos.q_standing)
    return data.oMi[model.getJointId(f"arm_{side}_2_joint")].translation.copy()


def test_hand_me_the_cup_picks_it_up_then_holds_it_out_in_front(talos):
    """"hand me the cup" = pick_up, then hand_over (the left hand: the cup is on the left); one Grasp
    with the hand-over point: 0.35-0.45 m ahead of the feet, straight ahead of the shoulder, below
    it and above the hip (lower chest height), within the arm's length of the Pinocchio shoulder;
    the hand-over target puts the grasp's offset (the cup's centre in the hand frame) at that point;
    the pick-up's hold target ends where the hand-over starts; the spec round-trips through JSON."""
    spec = compile_actions(list(parse("hand me the cup").actions), talos, scene=SCENE)
    assert spec.name == "pick_up, then hand_over"
    (g,) = spec.grasps
    assert g.frame == talos.frame("left_hand") and g.end is None
    p = np.asarray(g.offer)
    sh = _shoulder(talos, "left")
    model, data = talos.model, talos.data()
    pin.forwardKinematics(model, data, talos.q_standing)
    hip = data.oMi[model.getJointId("leg_left_1_joint")].translation
    assert 0.35 <= p[0] <= 0.45, p
    assert abs(p[1] - sh[1]) < 0.05, (p, sh)  # straight ahead of the shoulder
    assert hip[2] < p[2] < sh[2] - 0.1, p
    wrist = data.oMi[model.getJointId("arm_left_7_joint")].translation
    assert np.linalg.norm(p - sh) < np.linalg.norm(wrist - sh) + 0.2  # the forearm plus the hand's length
    (target,) = [t for t in spec.targets if t.name.endswith("holds the cup out")]
    M = pin.SE3(pin.rpy.rpyToMatrix(*target.rpy), np.asarray(target.position))
    assert np.linalg.norm(M.act(np.asarray(g.offset)) - p) < 1e-9
    window = g.offer_window
    assert target.window[0] == pytest.approx(window[0]) and window[1] - window[0] == pytest.approx(1.05, abs=0.08)
    lift = next(t for t in spec.targets if t.name.endswith("lifts the cup"))
    assert lift.window[1] == pytest.approx(window[0] - 1.5, abs=0.08)
    assert spec_from_json(spec_to_json(spec)) == spec


def test_pick_up_and_hand_it_to_me_is_the_same_motion(talos):
    """Said with the pick-up, in English or Chinese, the spec is the same as "hand me the cup"."""
    a = compile_actions(list(parse("hand me the cup").actions), talos, scene=SCENE)
    b = compile_actions(list(parse("pick up the cup and hand it to me").actions), talos, scene=SCENE)
    c = compile_actions(list(parse("拿起杯子然后递给我").actions), talos, scene=SCENE)
    assert a.grasps == b.grasps == c.grasps and a.targets == b.targets == c.targets


def test_hand_over_refusals(talos):
    """A fixed object, an object held in the other hand, and an object that would come near another
    one at the hand-over point are refused in task terms."""
    with pytest.raises(TaskDefinitionError, match="table is fixed"):
        compile_actions([Action(name="hand_over", params={"object": "the table"})], talos, scene=SCENE)
    with pytest.raises(TaskDefinitionError, match="other hand"):
        compile_actions([Action(name="pick_up", params={"object": "the cup", "arm": "left"}),
                         Action(name="hand_over", params={"object": "it", "arm": "right"})], talos, scene=SCENE)
    offer = compile_actions(list(parse("hand me the cup").actions), talos, scene=SCENE).grasps[0].offer
    above = offer[2] + CUP.size[1] / 2 + 0.01 + 0.025  # a 5 cm board 1 cm over the held cup's top
    shelf = SceneObject(name="shelf", shape="box", size=(0.3, 1.0, 0.05), position=(offer[0], 0.0, above))
    with pytest.raises(TaskDefinitionError, match=r"from the shelf .*step back"):
        compile_actions(list(parse("hand me the cup").actions), talos,
                        scene=Scene(name="low shelf", objects=(*SCENE.objects, shelf)))


def test_push_writes_a_moving_contact_and_the_push_record(talos):
    """"push the red box 10 cm": the right hand (the box is on the right); hand targets on the box's near
    face that name the box, evenly spaced along the heading (+x) by 10 cm in all, at one height where
    the hand's lowest collision point (Pinocchio geometry placements at the standing posture) is 3 cm
    above the box's bottom; a Push record of 0.1 m along +x over the push; the spec round-trips."""
    spec = compile_actions(list(parse("push the red box 10 cm").actions), talos, scene=SCENE)
    (p,) = spec.pushes
    assert (p.object, p.frame, p.direction, p.distance) == ("red box", talos.frame("right_hand"), (1.0, 0.0, 0.0), 0.1)
    on = [t for t in spec.targets if t.touch == "red box" and ("on the" in t.name or "pushes" in t.name)]
    xs = np.array([t.position[0] for t in on])
    assert xs[-1] - xs[0] == pytest.approx(0.1, abs=1e-9)
    assert np.allclose(np.diff(xs), 0.1 / (len(xs) - 1))
    assert len({round(t.position[2], 9) for t in on}) == 1 and len({round(t.position[1], 9) for t in on}) == 1
    assert on[0].time == pytest.approx(p.start) and on[-1].time == pytest.approx(p.end)
    model, data = talos.model, talos.data()
    gm = talos.collision_model
    gd = pin.GeometryData(gm)
    pin.framesForwardKinematics(model, data, talos.q_standing)
    pin.updateGeometryPlacements(model, data, gm, gd, talos.q_standing)
    fid = talos.frame_id("right_hand")
    below = set(model.subtrees[model.frames[fid].parentJoint])
    lowest = min(float((np.asarray(go.geometry.vertices()) @ gd.oMg[i].rotation.T + gd.oMg[i].translation)[:, 2].min())
                 for i, go in enumerate(gm.geometryObjects)
                 if go.parentJoint in below and int(getattr(go.geometry, "num_vertices", 0)))
    drop = data.oMf[fid].translation[2] - lowest  # the hand frame above its lowest point
    bottom = BOX.position[2] - BOX.size[2] / 2
    assert on[0].position[2] - drop - bottom == pytest.approx(0.03, abs=1e-6)
    assert spec_from_json(spec_to_json(spec)) == spec


def test_push_refusals_name_the_numbers(talos):
    """A box too heavy to slide is refused with its friction force mu m g (computed here) against what
    the arm can push; a fixed object, a sphere, a push over the table's edge, something in the way."""
    heavy = SceneObject(name="red box", shape="box", size=(0.15, 0.15, 0.15), position=(0.6, -0.2, 0.795),
                        movable=True, mass=20.0, friction=0.8)
    force = 0.8 * 20.0 * 9.81
    with pytest.raises(TaskDefinitionError, match=rf"needs {force:.0f} N to slide; the right arm can push \d+ N"):
        compile_actions(list(parse("push the red box 10 cm").actions), talos,
                        scene=Scene(name="heavy", objects=(TABLE, heavy)))
    with pytest.raises(TaskDefinitionError, match="fixed"):
        compile_actions([Action(name="push", params={"object": "the table"})], talos, scene=SCENE)
    ball = SceneObject(name="ball", shape="sphere", size=(0.05,), position=(0.55, -0.2, 0.77), movable=True, mass=0.1)
    with pytest.raises(TaskDefinitionError, match="sphere"):
        compile_actions([Action(name="push", params={"object": "the ball"})], talos,
                        scene=Scene(name="ball", objects=(TABLE, ball)))
    narrow = SceneObject(name="table", shape="box", size=(0.25, 1.0, 0.72), position=(0.575, 0.0, 0.36))
    with pytest.raises(TaskDefinitionError, match="edge of the table"):  # the centre would leave x <= 0.7
        compile_actions([Action(name="push", params={"object": "the red box", "distance": 0.15})], talos,
                        scene=Scene(name="edge", objects=(narrow, BOX)))
    wall = SceneObject(name="book", shape="box", size=(0.05, 0.3, 0.2), position=(0.75, -0.2, 0.82), movable=True, mass=0.3)
    with pytest.raises(TaskDefinitionError, match="book is in the way"):
        compile_actions([Action(name="push", params={"object": "the red box", "distance": 0.1})], talos,
                        scene=Scene(name="blocked", objects=(TABLE, BOX, wall)))


def test_spec_records_validate():
    """A Push's direction must be a horizontal unit vector; a Grasp's offer needs its window."""
    with pytest.raises(TaskDefinitionError, match="horizontal unit vector"):
        Push(name="p", object="box", frame="hand", direction=(1.0, 1.0, 0.0), distance=0.1, start=0.0, end=1.0)
    with pytest.raises(TaskDefinitionError, match="end .* must be after start"):
        Push(name="p", object="box", frame="hand", direction=(1.0, 0.0, 0.0), distance=0.1, start=1.0, end=1.0)
    with pytest.raises(TaskDefinitionError, match="offer and offer_window go together"):
        Grasp(name="g", object="cup", frame="hand", offset=(0.0, 0.0, 0.0), start=0.0, offer=(0.4, 0.0, 1.1))


def test_pushing_sideways_is_refused_with_the_pick_up_that_does_it(talos, tmp_path, capsys):
    """"push the red box to the left 10 cm" (and 往右推, backward) is refused before planning, in task terms
    (wbmp solve: exit 3, one line); the sentence the message offers compiles: a grasp that places the
    box 10 cm to the left (+y, the robot's left) of where it stood."""
    import json
    import re

    from tasks.scene import scene_to_dict
    from wbmp.cli import main

    offered = {}
    for text, said in (("push the red box to the left 10 cm", "10 cm to the left"), ("把红色盒子往右推5厘米", "5 cm to the right"),
                       ("push the red box backward", "10 cm back")):
        with pytest.raises(TaskDefinitionError, match="pushes objects forward only") as e:
            compile_actions(list(parse(text).actions), talos, scene=SCENE)
        offered[said] = re.search(r'\("([^"]+)"\)', str(e.value)).group(1)
        assert offered[said].endswith(f"then put it down {said}"), str(e.value)
    spec = compile_actions(list(parse(offered["10 cm to the left"]).actions), talos, scene=SCENE)
    (placed,) = [g for g in spec.grasps if g.place is not None]
    assert np.allclose(placed.place, np.asarray(BOX.position) + [0.0, 0.1, 0.0], atol=1e-9), placed.place
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(scene_to_dict(SCENE)))
    assert main(["solve", "push the red box to the left 10 cm", "--scene", str(path), "--no-sim", "--quiet"]) == 3
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("wbmp solve: error: ") and "forward only" in err[0], err
