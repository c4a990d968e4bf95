"""pick_up (tasks/primitives/grasp.py) compiled in a scene where the cup is within reach, checked with
Pinocchio numbers computed here: the hand targets put the object's grasp point between the talos
fingertips, the grasp and its hold window are in the spec (and round-trip), and the language says
"pick up the cup", 拿起那个杯子, "walk to the cup and pick it up" and 走过去拿起那个杯子."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from language import parse
from robots import load_robot
from tasks.actions import Action
from tasks.compose import compile_actions
from tasks.exceptions import TaskDefinitionError
from tasks.primitives.grasp import GRASP_CLEARANCE, grasp_point
from tasks.scene import Scene, SceneObject
from tasks.serialize import spec_from_json, spec_to_json
from tasks.specs import Grasp

CUP = SceneObject(name="cup", shape="cylinder", size=(0.04, 0.1), position=(0.52, -0.2, 0.77), aliases=("杯子",),
                  movable=True, mass=0.25, colour=(0.85, 0.1, 0.1, 1.0))
TABLE = SceneObject(name="table", shape="box", size=(0.6, 1.0, 0.72), position=(0.75, 0.0, 0.36), aliases=("桌子",))
NEAR = Scene(name="a cup within reach", objects=(TABLE, CUP))


def _standing_geometry(robot):
    """(model, data, collision model, its data) with frames and collision placements at the standing posture."""
    model, data = robot.model, robot.data()
    cm = robot.collision_model
    gd = pin.GeometryData(cm)
    pin.framesForwardKinematics(model, data, robot.q_standing)
    pin.updateGeometryPlacements(model, data, cm, gd, robot.q_standing)
    return model, data, cm, gd


def distance(geometry, M: pin.SE3, obj: SceneObject) -> float:
    """coal's distance from a collision geometry placed at ``M`` to a box scene object (negative: into it)."""
    import coal

    return coal.distance(geometry, coal.Transform3s(M.rotation, M.translation), coal.Box(*obj.size),
                         coal.Transform3s(np.eye(3), np.asarray(obj.position)), coal.DistanceRequest(),
                         coal.DistanceResult())


@pytest.fixture(scope="module")
def talos():
    return load_robot("talos")


@pytest.fixture(scope="module")
def spec(talos):
    return compile_actions([Action(name="pick_up", params={"object": "the cup", "height": 0.12})], talos, scene=NEAR)


def test_pick_up_writes_approach_grasp_lift_hold_and_the_grasp(spec, talos):
    """Four phases named after the cup, one Grasp of the right hand (the cup is on the right) from the
    grasp phase on, lifting 0.12 m, held to the end of the motion; the spec round-trips through JSON."""
    names = [p.name.split(": ")[-1] for p in spec.phases]
    assert names[1:5] == ["approach the cup", "grasp the cup", "lift the cup", "hold the cup"]
    (g,) = spec.grasps
    assert (g.object, g.frame, g.lift, g.end) == ("cup", talos.frame("right_hand"), 0.12, None)
    starts = dict(zip(names, spec.phase_start_times(), strict=False))
    assert g.start == pytest.approx(starts["grasp the cup"], abs=0.2)
    assert spec_from_json(spec_to_json(spec)) == spec


def test_the_held_cup_sits_between_the_fingertips(spec, talos):
    """At the grasp target, with the hand in its target orientation, the cup's grasp point is midway
    between talos's two-fingertip side and its one-fingertip side (Pinocchio, standing posture:
    where the closing fingers meet, sim/grasp.py), and the grasp's offset carries the cup's centre
    there; the lift target is the grasp target raised by the height."""
    model, data = talos.model, talos.data()
    pin.framesForwardKinematics(model, data, talos.q_standing)
    hand = data.oMf[talos.frame_id("right_hand")]
    local = {fr.name.split("_")[3]: hand.actInv(data.oMf[f].translation) for f, fr in enumerate(model.frames)
             if fr.name.startswith("gripper_right_fingertip")}
    tips_in_hand = 0.5 * (0.5 * (local["1"] + local["2"]) + local["3"])  # the pair's middle and the single tip
    at = next(t for t in spec.targets if t.name.endswith("right hand at the cup"))
    lift = next(t for t in spec.targets if t.name.endswith("right hand lifts the cup"))
    R = pin.rpy.rpyToMatrix(*at.rpy)
    point = np.asarray(at.position) + R @ tips_in_hand
    np.testing.assert_allclose(point, grasp_point(talos, "right", CUP), atol=1e-9)
    (g,) = spec.grasps
    np.testing.assert_allclose(np.asarray(at.position) + R @ np.asarray(g.offset), CUP.position, atol=1e-9)
    np.testing.assert_allclose(np.asarray(lift.position) - np.asarray(at.position), [0, 0, 0.12], atol=1e-9)
    # the fingers stay above the table: the grasp point is raised from the cup's centre
    assert point[2] > CUP.position[2] and point[2] <= CUP.position[2] + 0.05 + 1e-9
    assert GRASP_CLEARANCE > 0


def test_held_target_lasts_to_the_end_of_the_motion(spec):
    """The lift target is held until the end of the motion (nothing moves the arm after it)."""
    lift = next(t for t in spec.targets if t.name.endswith("right hand lifts the cup"))
    assert lift.window is not None and lift.window[1] == pytest.approx(spec.horizon)


def test_pick_up_refusals(talos):
    """A fixed object and one out of reach are refused in task terms."""
    with pytest.raises(TaskDefinitionError, match="fixed in the scene"):
        compile_actions([Action(name="pick_up", params={"object": "the table"})], talos, scene=NEAR)
    far = Scene(objects=(TABLE, SceneObject(name="cup", shape="cylinder", size=(0.04, 0.1), position=(1.0, 0.0, 0.77),
                                            movable=True, mass=0.25)))
    with pytest.raises(TaskDefinitionError, match=r"beyond the right hand's reach.*walk to it first"):
        compile_actions([Action(name="pick_up", params={"object": "the cup", "arm": "right"})], talos, scene=far)


def test_grasp_spec_validation():
    """A grasp names a movable object of the scene and does not overlap another on the same hand."""
    from tasks.specs import Phase, TaskSpec

    g = Grasp(name="g", object="cup", frame="gripper_right_base_link", offset=(0.0, 0.0, -0.1), start=0.5)
    TaskSpec(phases=(Phase(name="p", duration=2.0),), scene=NEAR, grasps=(g,))
    with pytest.raises(TaskDefinitionError, match="no object 'mug'"):
        TaskSpec(phases=(Phase(name="p", duration=2.0),), scene=NEAR,
                 grasps=(Grasp(name="g", object="mug", frame="f", offset=(0.0, 0.0, 0.0), start=0.5),))
    with pytest.raises(TaskDefinitionError, match="fixed to the world"):
        TaskSpec(phases=(Phase(name="p", duration=2.0),), scene=NEAR,
                 grasps=(Grasp(name="g", object="table", frame="f", offset=(0.0, 0.0, 0.0), start=0.5),))
    with pytest.raises(TaskDefinitionError, match="overlap"):
        TaskSpec(phases=(Phase(name="p", duration=2.0),), scene=NEAR,
                 grasps=(g, Grasp(name="h", object="cup", frame="f", offset=(0.0, 0.0, 0.0), start=1.0)))


@pytest.mark.parametrize(("text", "expected"), [
    ("pick up the cup", [("pick_up", "the cup")]),
    ("拿起那个杯子", [("pick_up", "那个杯子")]),
    ("捡起杯子", [("pick_up", "杯子")]),
    ("walk to the cup and pick it up", [("walk_to", "the cup"), ("pick_up", "the cup")]),
    ("walk over and pick up the cup", [("walk_to", "the cup"), ("pick_up", "the cup")]),
    ("走过去拿起那个杯子", [("walk_to", "那个杯子"), ("pick_up", "那个杯子")]),
])
def test_pick_up_sentences(text, expected):
    """The seed sentence and its twins parse to walk_to + pick_up with the same reference."""
    plan = parse(text)
    assert [(a.name, a.params["object"]) for a in plan.actions] == expected


def test_pick_up_height_and_hand_from_the_sentence():
    """A height and a hand are slots of pick_up; "it" with no object before it is refused."""
    (a,) = parse("pick up the cup 20 cm with your left hand").actions
    assert (a.params["height"], a.params["arm"]) == (pytest.approx(0.2), "left")
    from language.exceptions import InvalidParameter

    with pytest.raises(InvalidParameter, match='"it": no object was named before it'):
        parse("pick it up")


BOOK = SceneObject(name="book", shape="box", size=(0.2, 0.2, 0.04), position=(0.58, -0.4, 0.74),
                   colour=(0.1, 0.6, 0.2, 1.0))
SHELF = SceneObject(name="shelf", shape="box", size=(0.4, 1.0, 1.0), position=(0.3, 1.6, 0.5), aliases=("架子",))


def test_put_the_cup_on_another_object(talos):
    """"pick up the cup, then put it on the book": the release's place is on the book's top face (the
    cup's bottom on it, its footprint inside the face), the put-down target carries the cup's centre
    (the grasp's offset in the hand frame) there and comes from 8 cm above; "put the cup on the shelf"
    out of reach is refused in task terms; 把杯子放到架子上 names the same action."""
    scene = Scene(name="cup and book", objects=(TABLE, CUP, BOOK))
    spec = compile_actions(list(parse("pick up the cup, then put it on the book").actions), talos, scene=scene)
    (g,) = spec.grasps
    place = np.asarray(g.place)
    assert place[2] == pytest.approx(BOOK.position[2] + 0.02 + 0.05)  # book top + half the cup
    for i in (0, 1):
        assert abs(place[i] - BOOK.position[i]) <= BOOK.size[i] / 2 - CUP.size[0] + 1e-9
    down = next(t for t in spec.targets if t.name.endswith("puts the cup down on the book"))
    above = next(t for t in spec.targets if t.name.endswith("above the book"))
    R = pin.rpy.rpyToMatrix(*down.rpy)
    np.testing.assert_allclose(np.asarray(down.position) + R @ np.asarray(g.offset), place, atol=1e-9)
    np.testing.assert_allclose(np.asarray(above.position) - np.asarray(down.position), [0, 0, 0.08], atol=1e-9)
    assert above.time < down.window[0] <= g.end == down.window[1]
    far = Scene(name="cup and shelf", objects=(TABLE, CUP, SHELF))
    with pytest.raises(TaskDefinitionError, match=r"beyond the right hand's reach .* walk to the shelf first"):
        compile_actions(list(parse("pick up the cup, then put it on the shelf").actions), talos, scene=far)
    (a,) = parse("把杯子放到架子上").actions
    assert (a.name, a.params["object"], a.params["on"]) == ("put_down", "杯子", "架子")


def test_a_held_cup_is_carried_while_the_feet_move(talos):
    """"pick up the cup, then walk backward two steps": the lift target holds until the steps start;
    from then to the end the torso and right-arm joints keep angles (costs) that, on the standing
    posture (Pinocchio), put the hand where it lifted the cup relative to the feet, within 2 mm and
    0.01 rad; carrying an object no hand holds is refused; the kitchen's "walk to the cup, pick it
    up, walk to the shelf and put it on it" compiles, the cup placed on the shelf's top."""
    spec = compile_actions(list(parse("pick up the cup, then walk backward two steps").actions), talos, scene=NEAR)
    step = next(p for p in spec.phases if p.name.startswith("2 step"))
    t_step = spec.phase_start_times()[spec.phases.index(step)]
    lift = next(t for t in spec.targets if t.name.endswith("right hand lifts the cup"))
    assert lift.window[1] == pytest.approx(t_step)
    carry = [t for t in spec.joint_targets if "carry the cup" in t.name]
    assert len(carry) == 9 and all(t.window == pytest.approx((t_step, spec.horizon)) for t in carry)
    model, data = talos.model, talos.data()
    q = talos.q_standing.copy()
    for t in carry:
        q[model.joints[model.getJointId(t.joint)].idx_q] = t.value
    assert {model.names[model.getJointId(t.joint)][:5] for t in carry} == {"torso", "arm_r"}
    pin.framesForwardKinematics(model, data, q)
    err = pin.log6(data.oMf[talos.frame_id("right_hand")].actInv(
        pin.SE3(pin.rpy.rpyToMatrix(*lift.rpy), np.asarray(lift.position)))).vector  # pick-up stance = standing
    assert np.linalg.norm(err[:3]) < 2e-3 and np.linalg.norm(err[3:]) < 0.01
    with pytest.raises(TaskDefinitionError, match="no hand holds the cup to carry; pick it up first"):
        compile_actions(list(parse("walk to the table with the cup").actions), talos, scene=NEAR)
    from tasks.scene import load_scene

    kitchen = load_scene(Path(__file__).resolve().parents[2] / "examples" / "scenes" / "kitchen.json")
    spec = compile_actions(list(parse("walk to the cup, pick it up, walk to the shelf and put it on it").actions), talos,
                           scene=kitchen)
    (g,) = spec.grasps
    shelf = kitchen.get("shelf")
    assert g.place[2] == pytest.approx(shelf.position[2] + shelf.size[2] / 2 + 0.05)
    assert any("3 walk_to: carry the cup" in t.name for t in spec.joint_targets)


COUNTER = SceneObject(name="counter", shape="box", size=(0.6, 1.0, 0.85), position=(0.72, 0.0, 0.425))  # the box 5 cm over its edge
BIG_BOX = SceneObject(name="red box", shape="box", size=(0.2, 0.2, 0.15), position=(0.47, 0.0, 0.925), movable=True,
                      mass=0.5, aliases=("红色盒子",), colour=(0.8, 0.12, 0.1, 1.0))


def test_both_hands_press_the_box_sides(talos):
    """用双手拿起红色盒子 / "pick up the red box with both hands": two grasps of the box over the same
    window, one per hand; at each press target the hand's collision meshes (coal, placed where the
    target puts the hand frame) go 0.5-1.5 cm into the box (the planned squeeze) and stay clear of
    the counter under it, and its fingertip frames point forward; a cup cannot be held that way."""
    for text in ("用双手拿起红色盒子", "pick up the red box with both hands"):
        (a,) = parse(text).actions
        assert (a.name, a.params["arm"]) == ("pick_up", "both")
    scene = Scene(name="a box on a counter", objects=(COUNTER, BIG_BOX))
    spec = compile_actions(list(parse("pick up the red box with both hands").actions), talos, scene=scene)
    left, right = spec.grasps
    assert {left.frame, right.frame} == {talos.frame("left_hand"), talos.frame("right_hand")}
    assert (left.start, left.end, left.hold) == (right.start, right.end, right.hold)
    model, data, cm, gd = _standing_geometry(talos)

    for side in ("left", "right"):
        t = next(t for t in spec.targets if t.name.endswith(f"{side} hand presses the red box"))
        fid = talos.frame_id(f"{side}_hand")
        below = set(model.subtrees[model.frames[fid].parentJoint])
        target = pin.SE3(pin.rpy.rpyToMatrix(*t.rpy), np.asarray(t.position))
        placed = [(go.geometry, target * data.oMf[fid].actInv(gd.oMg[i]))
                  for i, go in enumerate(cm.geometryObjects) if go.parentJoint in below]
        into_box = min(distance(g, M, BIG_BOX) for g, M in placed)
        assert -0.015 <= into_box <= -0.005, (side, into_box)
        tips = [target * data.oMf[fid].actInv(data.oMf[f]).translation
                for f, fr in enumerate(model.frames) if fr.name.startswith(f"gripper_{side}_fingertip")]
        fingers = np.mean(tips, axis=0) - target.translation  # fingers forward: the arms reach out under the box
        assert fingers[0] > 0.8 * np.linalg.norm(fingers), (side, fingers)
        assert min(distance(g, M, COUNTER) for g, M in placed) > 0.02
    with pytest.raises(TaskDefinitionError, match="both hands pick up a box"):
        compile_actions([Action(name="pick_up", params={"object": "the cup", "arm": "both"})], talos, scene=NEAR)


@pytest.mark.parametrize(("text", "direction", "distance"), [
    ("pick up the cup, then put it down 20 cm to the left", "left", 0.2),
    ("pick up the cup, then put it 10 cm forward", "forward", 0.1),
    ("pick up the cup, then put it down to the right", "right", None),
    ("拿起杯子，然后把它放到左边20厘米", "left", 0.2),
])
def test_put_down_on_a_spot_parses(text, direction, distance):
    """A direction (seen from the robot) and a distance are put_down's slots."""
    a = parse(text).actions[-1]
    assert (a.name, a.params.get("direction"), a.params.get("distance")) == ("put_down", direction,
                                                                             pytest.approx(distance) if distance else None)


def test_put_down_on_a_spot(talos):
    """"put it down 20 cm to the left": the place is where the cup stood moved 0.2 m along the robot's
    left (heading frame; world +y here), on the table; the put-down target carries the cup's centre (the
    grasp offset in the hand frame) there. "put it back" and "put it on the table" (the surface it
    stood on) put it where it stood. A spot off the table is refused with the room there is that way
    (the table's edge: 0.5 m from the table's centre line, less the cup's radius), one beyond reach
    with the distance."""
    scene = Scene(name="cup and table", objects=(TABLE, CUP))

    def compiled(text):
        return compile_actions(list(parse(text).actions), talos, scene=scene)

    spec = compiled("pick up the cup, then put it down 20 cm to the left")
    (g,) = spec.grasps
    np.testing.assert_allclose(g.place, np.asarray(CUP.position) + [0.0, 0.2, 0.0], atol=1e-12)
    down = next(t for t in spec.targets if "puts the cup down" in t.name)
    R = pin.rpy.rpyToMatrix(*down.rpy)
    np.testing.assert_allclose(np.asarray(down.position) + R @ np.asarray(g.offset), g.place, atol=1e-9)
    for text in ("pick up the cup, then put it back", "pick up the cup, then put the cup back on the table",
                 "pick up the cup, then put it on the table"):
        (g,) = compiled(text).grasps
        np.testing.assert_allclose(g.place, CUP.position, atol=1e-12, err_msg=text)
    room = (TABLE.position[1] - TABLE.size[1] / 2) - (CUP.position[1] - CUP.size[0])  # to the right edge: negative
    with pytest.raises(TaskDefinitionError, match=rf"0.40 m to the right of where the cup stood, the cup would be off "
                                                  rf"the top of the table: it can move at most {-room:.2f} m that way"):
        compiled("pick up the cup, then put it down 40 cm to the right")
    with pytest.raises(TaskDefinitionError, match=r"0.60 m to the left of where the cup stood is 0.\d\d m beyond the "
                                                  r"right hand's reach from where the robot stands"):
        compiled("pick up the cup, then put it down 60 cm to the left")
    with pytest.raises(TaskDefinitionError, match="the book stands 0.20 m further from the robot than where the cup stood"):
        book = dataclasses.replace(BOOK, position=(0.72, -0.2, 0.74))
        compile_actions(list(parse("pick up the cup, then put it 20 cm forward").actions), talos,
                        scene=Scene(name="cup and book", objects=(TABLE, CUP, book)))


def test_both_hands_put_the_box_back_down(talos):
    """"pick up the red box with both hands, then put it down" / 用双手拿起红色盒子然后放下: both grasps
    end together at the put-down's release with the place where the box stood; each hand is lowered
    onto its press pose of the pick-up (the box back on the counter), stays there one knot past the
    release (the planned hands still as the simulation's welds let go), then out beside the box, back
    in front of the body and to rest; putting it on another object with both hands is refused."""
    scene = Scene(name="a box on a counter", objects=(COUNTER, BIG_BOX))
    for text in ("pick up the red box with both hands, then put it down", "用双手拿起红色盒子然后放下"):
        spec = compile_actions(list(parse(text).actions), talos, scene=scene)
        left, right = spec.grasps
        assert left.end is not None and (left.start, left.end, left.place) == (right.start, right.end, right.place)
        assert left.place == pytest.approx(BIG_BOX.position)
        for side in ("left", "right"):
            press = next(t for t in spec.targets if t.name.endswith(f"{side} hand presses the red box"))
            down = next(t for t in spec.targets if t.name.endswith(f"{side} hand puts the red box down"))
            assert down.position == pytest.approx(press.position) and down.rpy == pytest.approx(press.rpy)
            assert down.window[1] == pytest.approx(left.end + spec.dt)  # still one knot after the welds let go
            lift = next(t for t in spec.targets if t.name.endswith(f"{side} hand lifts the red box"))
            assert lift.window[1] <= down.window[0]  # the hold ends where the put-down starts
            rest = next(t for t in spec.targets if t.name.endswith(f"{side} hand back at rest"))
            assert rest.time > down.window[1]
    with pytest.raises(TaskDefinitionError, match="held with both hands: it is put back where it was"):
        compile_actions(list(parse("pick up the red box with both hands, then put it on the counter").actions), talos,
                        scene=scene)


def test_g1s_wider_wrist_stays_off_the_box(g1):
    """g1 (examples/scenes/box_on_low_table.json): at each press target (coal, the meshes placed where
    the target puts the hand frame, standing relative placements) the wrist and forearm meshes above
    the hand stay at least 1 cm off the box, the hand's own meshes off it too (the welds hold the
    box), and both clear the table; the hand frame is level with the box's side, not turned."""
    from tasks.scene import load_scene

    scene = load_scene(Path(__file__).resolve().parents[2] / "examples" / "scenes" / "box_on_low_table.json")
    box, table = scene.get("red box"), scene.get("table")
    spec = compile_actions(list(parse("用双手拿起红色盒子").actions), g1, scene=scene)
    model, data, cm, gd = _standing_geometry(g1)

    for side in ("left", "right"):
        t = next(t for t in spec.targets if t.name.endswith(f"{side} hand presses the red box"))
        fid = g1.frame_id(f"{side}_hand")
        joint = model.frames[fid].parentJoint
        target = pin.SE3(pin.rpy.rpyToMatrix(*t.rpy), np.asarray(t.position))
        np.testing.assert_allclose(target.rotation, data.oMf[fid].rotation, atol=1e-9)  # g1's standing hand
        placed = {i: target * data.oMf[fid].actInv(gd.oMg[i]) for i in range(len(cm.geometryObjects))}
        hand = [i for i, go in enumerate(cm.geometryObjects) if go.parentJoint in model.subtrees[joint]]
        wrist = [i for i, go in enumerate(cm.geometryObjects) if "wrist" in go.name and i not in hand and side in go.name]
        assert wrist
        assert min(distance(cm.geometryObjects[i].geometry, placed[i], box) for i in wrist) >= 0.0095
        assert 0.0 < min(distance(cm.geometryObjects[i].geometry, placed[i], box) for i in hand) < 0.03
        assert min(distance(cm.geometryObjects[i].geometry, placed[i], table) for i in hand + wrist) > 0.02


def test_the_arms_may_stay_at_the_box_a_few_knots_after_the_release(talos):
    """planner contact_exclusions for "pick up the red box with both hands, then put it down": every
    sphere may touch the box from the grasp to CONTACT_PADDING knots after the release (the hands are
    still at it as the welds let go), none but the hands' own after that."""
    from planner.trajopt.collision import sphere_sets
    from planner.trajopt.layout import make_layout
    from planner.trajopt.scene_collision import CONTACT_PADDING, contact_exclusions, obstacles

    scene = Scene(name="a box on a counter", objects=(COUNTER, BIG_BOX))
    spec = compile_actions(list(parse("pick up the red box with both hands, then put it down").actions), talos,
                           scene=scene)
    lay = make_layout(spec, talos)
    sets = sphere_sets(talos)
    obs = obstacles(spec.scene)
    box = next(i for i, o in enumerate(obs) if o.name == BIG_BOX.name)
    every = contact_exclusions(lay, sets, obs)[:, :, box].all(axis=1)  # (N+1,) all spheres exempt at that knot
    g = spec.grasps[0]
    t = np.asarray(lay.t)
    first, last = int(np.argmax(t >= g.start - 1e-9)), int(np.flatnonzero(t <= g.end + 1e-9)[-1])
    assert every[first:last + CONTACT_PADDING + 1].all()
    assert not every[:first].any() and not every[last + CONTACT_PADDING + 1:].any()
