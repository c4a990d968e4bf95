"""touch_object (tasks/primitives/objects.py): the hand target on the line from the shoulder
(Pinocchio) to the object's nearest surface point (tasks.scene.signed_distance), a planned
contact (FrameTarget.touch) that the planner's scene rows leave out only there, the sentence forms
and the refusals."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from language import parse
from robots import load_robot
from tasks.compose import compile_actions
from tasks.exceptions import TaskDefinitionError
from tasks.primitives.bodymap import arm_configuration, to_heading
from tasks.primitives.objects import TOUCH_DEPTH
from tasks.scene import Scene, SceneObject, load_scene, signed_distance
from tasks.serialize import spec_from_json, spec_to_json
from tasks.specs import FrameTarget, Phase, TaskSpec

WAREHOUSE = Path(__file__).resolve().parents[2] / "examples" / "scenes" / "warehouse.json"
BOX = SceneObject(name="box", shape="box", size=(0.4, 0.4, 0.75), position=(0.75, 0.0, 0.375),
                  aliases=("盒子", "carton"))
ONE_BOX = Scene(name="one box", objects=(BOX,))


@pytest.fixture(scope="module")
def talos():
    return load_robot("talos")


def _touch(spec) -> FrameTarget:
    (target,) = [t for t in spec.targets if t.touch is not None]
    return target


@pytest.mark.parametrize("sentence", ["摸一下那个盒子", "touch the box with your right hand"])
def test_the_hand_goes_to_the_boxs_surface_point_nearest_to_the_shoulder(talos, sentence):
    """The touched point is the box's point nearest to the shoulder (a grid search of the box's
    surface); the hand frame target is on the shoulder-to-point line, short of the point by the
    hand's extent in front of its frame less TOUCH_DEPTH, so inside the signed distance band."""
    spec = compile_actions(parse(sentence).actions, talos, scene=ONE_BOX)
    target = _touch(spec)
    assert target.touch == "box" and target.window is not None
    assert spec_from_json(spec_to_json(spec)) == spec
    side = "right" if "right" in target.frame else "left"
    data = talos.data()
    pin.framesForwardKinematics(talos.model, data, talos.q_standing)
    sh = data.oMf[talos.frame_id(f"{side}_shoulder")].translation
    # the nearest surface point by brute force over the box's faces
    g = np.linspace(-0.5, 0.5, 101)
    faces = []
    for axis in range(3):
        for sign in (-0.5, 0.5):
            a, b = np.meshgrid(g, g, indexing="ij")
            pts = np.zeros((a.size, 3))
            others = [i for i in range(3) if i != axis]
            pts[:, axis] = sign
            pts[:, others[0]], pts[:, others[1]] = a.ravel(), b.ravel()
            faces.append(np.asarray(BOX.position) + pts * np.asarray(BOX.size))
    surface = np.concatenate(faces)
    near = surface[np.argmin(np.linalg.norm(surface - sh, axis=1))]
    hand = np.asarray(target.position)
    to_near, to_hand = near - sh, hand - sh
    cos = float(to_near @ to_hand) / (np.linalg.norm(to_near) * np.linalg.norm(to_hand))
    assert math.acos(min(1.0, cos)) < 0.02
    assert np.linalg.norm(hand - near) < np.linalg.norm(sh - near)
    u = to_near / np.linalg.norm(to_near)
    assert _posed_gap(talos, side, hand) <= 0.001
    assert _posed_gap(talos, side, hand - (TOUCH_DEPTH + 0.01) * u) > 0.002


def _posed_gap(robot, side, point, obj=BOX) -> float:
    """Coal distance between the box ``obj`` and the hand's meshes (every link below the hand
    frame's joint) with the arm posed at world ``point`` (the robot stands at the origin)."""
    import coal

    model, gm = robot.model, robot.collision_model.copy()
    box = gm.addGeometryObject(pin.GeometryObject("box", 0, 0, pin.SE3(np.eye(3), np.asarray(obj.position)),
                                                  coal.Box(*obj.size)))
    sub = set(model.subtrees[model.frames[robot.frame_id(f"{side}_hand")].parentJoint])
    for i, o in enumerate(gm.geometryObjects):
        if o.parentJoint in sub:
            gm.addCollisionPair(pin.CollisionPair(i, box))
    q = arm_configuration(robot, {side: to_heading(robot, point)}, natural=True)
    gd = gm.createData()
    pin.computeDistances(model, model.createData(), gm, gd, q)
    return min(r.min_distance for r in gd.distanceResults)


def test_walk_to_the_red_box_and_touch_it(talos):
    """"it" is the red box; the touch starts where the walk ends (the target is near the red box,
    1.6 m from where the robot starts)."""
    warehouse = load_scene(WAREHOUSE)
    spec = compile_actions(parse("walk to the red box and touch it").actions, talos, scene=warehouse)
    target = _touch(spec)
    red = warehouse.get("red box")
    assert target.touch == "red box"
    assert 0.0 < signed_distance(red, target.position) < 0.2
    assert target.window[0] > 5.0  # after the walk


def test_a_box_out_of_reach_is_refused_with_walk_to_it_first(talos):
    warehouse = load_scene(WAREHOUSE)
    with pytest.raises(TaskDefinitionError, match=r"touch_object: the blue box is .* beyond the \w+ hand's reach "
                                                  r"from where the robot stands: walk to it first"):
        compile_actions(parse("touch the blue box").actions, talos, scene=warehouse)


def test_a_touch_names_an_object_of_the_spec_scene():
    target = FrameTarget(name="t", frame="right_hand", position=(0.5, 0.0, 0.8), touch="crate")
    with pytest.raises(TaskDefinitionError, match="touch names 'crate', which is no object of the spec's scene"):
        TaskSpec(phases=(Phase(name="p", duration=1.0),), targets=(target,), scene=ONE_BOX)


def test_the_planner_leaves_out_only_the_touching_hand_and_box_in_the_window(talos):
    """contact_exclusions: the spheres of the right hand's joint and the joints below it (Pinocchio
    subtree), with the box, on the target's knots (and the padding); nothing else but the standing
    feet (their placements were checked against the scene before planning: no rows while they stand)."""
    from planner.trajopt.collision import sphere_sets
    from planner.trajopt.layout import knots_of, make_layout
    from planner.trajopt.scene_collision import CONTACT_PADDING, contact_exclusions, obstacles

    spec = compile_actions(parse("touch the box with your right hand").actions, talos, scene=ONE_BOX)
    lay = make_layout(spec, talos)
    sets = sphere_sets(talos)
    obs = obstacles(spec.scene)
    out = contact_exclusions(lay, sets, obs)
    target = _touch(spec)
    model = talos.model
    hand_joint = model.frames[talos.frame_id(target.frame)].parentJoint
    below = set(model.subtrees[hand_joint])
    ks = knots_of(lay.t, target.time, target.window, lay.N)
    spheres = {s for s in range(len(sets.sphere_radius)) if int(sets.joints[sets.sphere_owner[s]]) in below}
    assert spheres
    feet = {int(model.frames[talos.frame_id(f"{side}_foot")].parentJoint) for side in ("left", "right")}
    standing = np.array([int(sets.joints[o]) in feet for o in sets.sphere_owner])
    assert out[:, standing].all()  # both feet stand through the whole touch
    out = out & ~standing[None, :, None]
    knots, sph, _ = np.nonzero(out)
    assert set(sph.tolist()) == spheres
    assert min(knots) == max(0, min(ks) - CONTACT_PADDING) and max(knots) == min(lay.N, max(ks) + CONTACT_PADDING)


def test_a_box_against_the_chest_is_touched_farther_out_or_refused(g1):
    """G1 and the low table's box (examples/scenes/box_on_low_table.json, its near edge 0.16 m
    ahead): posed at the box's point nearest to the shoulder, the wrist's spheres are 3 cm into
    the torso's, which the planner cannot plan (MAX_ITERATIONS). The touched point moves ahead on
    the box's top until the posed arm clears the body by bodymap.CLEARANCE in the planner's sphere
    model; the posed hand's meshes still reach the box (coal). A box whose every point is that close
    (against the chest) is refused, naming the object and "step back first"."""
    from tasks.primitives.bodymap import CLEARANCE, sphere_clearance

    scene = load_scene(Path(__file__).resolve().parents[2] / "examples" / "scenes" / "box_on_low_table.json")
    box = scene.get("red box")
    spec = compile_actions(parse("touch the red box").actions, g1, scene=scene)
    target = _touch(spec)
    side = "right" if target.frame == g1.frame("right_hand") else "left"
    q = arm_configuration(g1, {side: to_heading(g1, np.asarray(target.position))}, natural=True)
    assert sphere_clearance(g1, q, side, other_arm=False)[0] >= CLEARANCE - 1e-6
    assert target.position[0] > box.position[0] - 0.5 * box.size[0] + 0.05  # not at the near edge
    assert _posed_gap(g1, side, np.asarray(target.position), box) <= 0.001
    close = SceneObject(name="red box", shape="box", size=(0.16, 0.16, 0.12), position=(0.16, 0.0, 0.76), movable=True,
                         mass=0.4)
    table = scene.get("table")
    near = dataclasses.replace(table, position=(0.33, 0.0, 0.35))
    with pytest.raises(TaskDefinitionError, match=r"touch_object: the red box is too close to the body for the \w+ "
                                                  r"hand to touch it: .* step back first"):
        compile_actions(parse("touch the red box").actions, g1, scene=Scene(name="close", objects=(near, close)))
