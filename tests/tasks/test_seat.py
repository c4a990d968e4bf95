"""Seats and sitting (issue 33): ``examples/scenes/chair.json``, contacts with a support region on
the thighs, ``sit_down``/``stand_up`` and their refusals.

The references are independent of :mod:`tasks.primitives.seat`: Pinocchio forward kinematics of the
planned sitting configuration, the thighs' collision-mesh vertices carried to the world by
Pinocchio's geometry placements, the seat's top face from its box by hand. The plan and MuJoCo
certificate of "sit down" are not in the suite yet (docs/scenes.md, "Seats").
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from tasks.actions import Action
from tasks.compose import compile_actions
from tasks.exceptions import BeyondCapability, TaskDefinitionError
from tasks.primitives.geometry import Stance
from tasks.primitives.seat import sitting
from tasks.scene import SceneObject, load_scene, scene_from_dict, scene_to_dict
from tasks.specs import Contact, Pose

CHAIR = Path(__file__).resolve().parents[2] / "examples" / "scenes" / "chair.json"


@pytest.fixture(scope="module")
def chair():
    return load_scene(CHAIR)


@pytest.fixture(scope="module")
def sat(talos, chair):
    return sitting(talos, Stance.standing(talos), chair.objects[0])


def test_the_chair_file_round_trips_and_only_a_static_upright_box_is_a_seat(chair):
    seat = chair.objects[0]
    assert seat.seat is True and chair.objects[1].seat is None and chair.objects[2].seat is None
    data = scene_to_dict(chair)
    assert data["objects"][0]["seat"] is True and "seat" not in data["objects"][1]  # absent: older JSON unchanged
    assert scene_from_dict(data) == chair
    for bad in ({"shape": "sphere", "size": (0.2,)}, {"movable": True, "mass": 2.0}, {"rpy": (0.2, 0.0, 0.0)}):
        with pytest.raises(TaskDefinitionError, match="seat"):
            dataclasses.replace(seat, **bad)


def test_the_sitting_thighs_rest_on_the_seat_by_forward_kinematics(talos, chair, sat):
    """Every region corner (Pinocchio FK of the sitting q) on the seat's top face, the thighs' lowest
    mesh vertices at the top (by hand: 0.31 m), the soles where the robot stands (1 mm)."""
    seat = chair.objects[0]
    top = seat.position[2] + seat.size[2] / 2
    lo = np.array(seat.position[:2]) - np.array(seat.size[:2]) / 2
    hi = np.array(seat.position[:2]) + np.array(seat.size[:2]) / 2
    model, data = talos.model, talos.model.createData()
    pin.framesForwardKinematics(model, data, sat.q)
    assert len(sat.contacts) == 2
    for c in sat.contacts:
        M = data.oMf[talos.frame_id(c.frame)]
        assert np.allclose(M.translation, c.placement.position, atol=1e-9)
        corners = np.asarray(c.region) @ M.rotation.T + M.translation
        assert np.allclose(corners[:, 2], top, atol=2e-3)
        assert np.all(corners[:, :2] >= lo) and np.all(corners[:, :2] <= hi)
        assert c.normal == (0.0, 0.0, 1.0) and c.friction_coefficient == seat.friction
        assert np.ptp(corners[:, 0]) > 0.02 and np.ptp(corners[:, 1]) > 0.05  # a region, not a point
    cdata = talos.collision_model.createData()
    pin.updateGeometryPlacements(model, data, talos.collision_model, cdata, sat.q)
    thighs = {c.frame for c in sat.contacts}
    lowest = min(
        float((np.asarray(g.geometry.vertices(), dtype=float).reshape(-1, 3) @ cdata.oMg[i].rotation.T
               + cdata.oMg[i].translation)[:, 2].min())
        for i, g in enumerate(talos.collision_model.geometryObjects)
        if model.frames[g.parentFrame].name in thighs and hasattr(g.geometry, "num_vertices"))
    assert lowest == pytest.approx(top, abs=2e-3)
    stance = Stance.standing(talos)
    for side in ("left", "right"):
        assert np.allclose(data.oMf[talos.frame_id(f"{side}_foot")].translation, stance.sole(side).position, atol=1e-3)
    com = pin.centerOfMass(model, data, sat.q)
    assert lo[0] < com[0] < 0.0  # sitting: the CoM over the seat, behind the heels


def test_a_region_contact_gives_its_corners_and_the_surface_normal_to_the_planner(talos, sat):
    from planner.trajopt.centroidal import contact_geometry

    c = sat.contacts[0]
    g = contact_geometry(c, talos)
    R = pin.rpy.rpyToMatrix(*c.placement.rpy)
    assert np.allclose(g.points_in_world, np.asarray(c.region) @ R.T + np.asarray(c.placement.position), atol=1e-12)
    assert np.allclose(g.normal, (0, 0, 1)) and np.allclose(g.rotation.T @ g.rotation, np.eye(3), atol=1e-12)
    assert g.friction_coefficient == pytest.approx(0.8)
    with pytest.raises(TaskDefinitionError, match="region must be 3 to 16 points"):
        Contact(frame="x", placement=Pose(position=(0, 0, 0), rpy=(0, 0, 0)), region=((0.0, 0.0, 0.0),))
    with pytest.raises(TaskDefinitionError, match="normal must be a unit vector"):
        Contact(frame="x", placement=Pose(position=(0, 0, 0), rpy=(0, 0, 0)), normal=(0.0, 0.0, 0.5))


def test_sit_down_then_stand_up_compiles_to_thigh_contacts_on_the_seat(talos, chair, sat):
    spec = compile_actions([Action(name="sit_down", params={}), Action(name="stand_up", params={})], talos,
                           scene=chair)
    sitting_phases = [p for p in spec.phases if any(c.region for c in p.contacts)]
    assert [p.name for p in sitting_phases] == ["1 sit_down: sitting", "transition", "2 stand_up: sitting"]
    for p in sitting_phases:
        assert {c.frame for c in p.contacts if c.region} == {c.frame for c in sat.contacts}
        assert [c for c in p.contacts if c.region] == list(sat.contacts)
    assert not any(c.region for c in spec.phases[0].contacts) and not any(c.region for c in spec.phases[-1].contacts)
    touches = {t.touch for t in spec.targets if t.touch}
    assert touches == {"chair"}
    # seated from the sit to the rise: the legs may touch the seat over it (held across the transition)
    start = sum(p.duration for p in spec.phases[:2])
    rise = sum(p.duration for p in spec.phases[:5])
    windows = sorted(t.window for t in spec.targets if t.touch)
    assert windows[0][0] < start and windows[-1][1] > rise and windows[0][1] == pytest.approx(windows[-1][0])
    assert not any(j.time is not None and start < j.time < rise for j in spec.joint_targets)  # no standing waypoints


def test_sitting_is_refused_in_task_terms(talos, chair):
    with pytest.raises(BeyondCapability, match="there is no seat in the scene"):
        compile_actions([Action(name="sit_down", params={})], talos, scene=None)
    with pytest.raises(BeyondCapability, match="the backrest is not a seat"):
        compile_actions([Action(name="sit_down", params={"object": "the backrest"})], talos, scene=chair)
    with pytest.raises(BeyondCapability, match="the robot is not sitting"):
        compile_actions([Action(name="stand_up", params={})], talos, scene=chair)
    seat = chair.objects[0]
    high = dataclasses.replace(seat, position=(-0.325, 0.0, 0.45))
    with pytest.raises(BeyondCapability, match="above talos's thighs sitting with level thighs .0.33 m"):
        sitting(talos, Stance.standing(talos), high)
    ahead = dataclasses.replace(seat, position=(0.6, 0.0, 0.29))
    with pytest.raises(BeyondCapability, match="the chair is not under talos's left thigh"):
        sitting(talos, Stance.standing(talos), ahead)


@pytest.mark.parametrize("text,action", [
    ("sit down", "sit_down"), ("sit on the chair", "sit_down"), ("坐下", "sit_down"), ("坐在椅子上", "sit_down"),
    ("get up from the chair", "stand_up"), ("起身", "stand_up")])
def test_the_words_for_sitting(text, action):
    from language import parse

    assert [a.name for a in parse(text).actions] == [action]


@pytest.mark.parametrize("text", ["sit down, then stand up", "坐下，然后站起来", "sit on the chair and then get up"])
def test_standing_up_after_sitting_down_is_stand_up(talos, chair, text):
    """"stand up" alone is ``stand`` (as before); after ``sit_down`` it rises from the seat."""
    from language import parse
    from tasks.compose import ground_actions

    actions = ground_actions(parse(text).actions, chair)
    assert [a.name for a in actions] == ["sit_down", "stand_up"]
    assert actions[1].params["object"].obj.name == "chair"


def test_a_seat_object_keeps_older_scene_json(chair):
    plain = SceneObject(name="box", shape="box", size=(0.1, 0.1, 0.1), position=(1.0, 0.0, 0.05))
    assert "seat" not in scene_to_dict(dataclasses.replace(chair, objects=(plain,)))["objects"][0]


def test_the_planner_holds_the_thighs_in_position_and_counts_their_regions_in_the_support_polygon(talos, chair, sat):
    """While seated the support polygon is the hull of the sole rectangles and the thighs' regions
    (by hand: scipy's hull of those corners); the thighs get 3 position rows, the soles their 6."""
    from scipy.spatial import ConvexHull

    from planner.trajopt.layout import make_layout, support_polygon
    from robots import sole_corners_in_world

    spec = compile_actions([Action(name="sit_down", params={})], talos, scene=chair)
    lay = make_layout(spec, talos)
    seated = next(k for k in lay.variable_knots if len(lay.contacts_at[k]) == 4 and k > 0
                  and len(lay.contacts_at[k - 1]) == 4)
    pts = [sole_corners_in_world(talos.profile.sole, side, pin.SE3(pin.rpy.rpyToMatrix(*spec.phases[0].contacts[i].placement.rpy),
                                                                  np.asarray(spec.phases[0].contacts[i].placement.position)))
           for i, side in enumerate(("left", "right"))]
    for c in sat.contacts:
        R = pin.rpy.rpyToMatrix(*c.placement.rpy)
        pts.append(np.asarray(c.region) @ R.T + np.asarray(c.placement.position))
    xy = np.vstack(pts)[:, :2]
    want = xy[ConvexHull(xy).vertices]
    got = support_polygon(lay, seated)
    assert len(got) == len(want) and all(np.min(np.linalg.norm(want - g, axis=1)) < 1e-9 for g in got)
    assert got[:, 0].min() < -0.20  # the polygon reaches back under the thighs (the soles end at -0.10)
    kinds = {(t.kind, t.structure[1]) for t in lay.terms if t.knot == seated and t.kind.startswith("contact")}
    thighs = {talos.frame_id(c.frame) for c in sat.contacts}
    assert {f for k, f in kinds if k == "contact_position"} == thighs
    assert {f for k, f in kinds if k == "contact"} == {talos.frame_id(f"{s}_foot") for s in ("left", "right")}
