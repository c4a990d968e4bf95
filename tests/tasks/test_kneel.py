"""Kneeling on one knee on the floor (issue 33): the kneeling posture, the knee's contact with its
support region on the floor, the compiled spec, the refusals and the words.

The references are independent of :mod:`tasks.primitives.kneel`: Pinocchio forward kinematics of the
kneeling configuration, every collision mesh carried to the world by Pinocchio's geometry
placements, the floor at z = 0, the standing sole from ``robot.q_standing``, the support polygon as
the convex hull (by hand, a cross-product test) of the standing sole's and the knee region's corners.
The plan and its MuJoCo certificate are the long test ``tests/sim/test_kneel.py`` (this file is its
fast twin).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from language import parse
from tasks.actions import Action
from tasks.compose import compile_actions
from tasks.exceptions import BeyondCapability
from tasks.primitives import kneel as kneel_module
from tasks.primitives.geometry import Stance
from tasks.primitives.kneel import kneeling
from tests.meshes import collision_meshes


@pytest.fixture(scope="module")
def knelt(talos):
    return kneeling(talos, Stance.standing(talos), "right")


def _cross(a, b) -> float:
    return float(a[0] * b[1] - a[1] * b[0])


def _inside(p, pts) -> bool:
    """p (2,) inside the convex hull of pts (n, 2): monotone chain, then every edge's cross product."""
    pts = sorted(map(tuple, pts))
    def half(seq):
        h: list = []
        for q in seq:
            while len(h) >= 2 and _cross(np.subtract(h[-1], h[-2]), np.subtract(q, h[-2])) <= 0:
                h.pop()
            h.append(q)
        return h
    hull = half(pts)[:-1] + half(pts[::-1])[:-1]
    return all(_cross(np.subtract(b, a), np.subtract(p, a)) > 0 for a, b in zip(hull, hull[1:] + hull[:1], strict=True))


@pytest.mark.parametrize("side", ["right", "left"])
def test_the_knee_rests_on_the_floor_and_nothing_else_but_the_standing_foot_by_forward_kinematics(talos, knelt, side):
    other = "left" if side == "right" else "right"
    knelt = knelt if side == "right" else kneeling(talos, Stance.standing(talos), "left")
    model, data = talos.model, talos.model.createData()
    pin.framesForwardKinematics(model, data, knelt.q)
    c = knelt.contact
    assert c.frame == f"leg_{side}_4_link" and c.normal == (0.0, 0.0, 1.0)
    M = data.oMf[talos.frame_id(c.frame)]
    corners = np.asarray(c.region) @ M.rotation.T + M.translation
    assert np.allclose(corners[:, 2], 0.0, atol=1e-3)  # the region on the floor
    assert np.allclose(M.translation, c.placement.position, atol=1e-9)
    size = np.ptp(corners[:, :2], axis=0)
    assert size.min() >= 0.02 - 1e-9 and size.max() < 0.10  # a knee's pad, not a shin
    shin = model.frames[talos.frame_id(c.frame)].parentJoint
    low = min(v[:, 2].min() for j, v in collision_meshes(talos, knelt.q) if j == shin)
    assert abs(low) < 2e-3  # the shin's lowest vertex on the floor
    standing = talos.data()
    pin.framesForwardKinematics(model, standing, np.asarray(talos.q_standing))
    sole = talos.frame_id(f"{other}_foot")
    assert np.allclose(data.oMf[sole].translation, standing.oMf[sole].translation, atol=2e-3)  # the standing foot stays
    assert np.linalg.norm(pin.log3(data.oMf[sole].rotation.T @ standing.oMf[sole].rotation)) < 5e-3
    # the knee behind the feet, on the kneeling foot's line
    assert corners[:, 0].mean() == pytest.approx(-kneel_module.KNEE_BACK, abs=0.02)
    assert corners[:, 1].mean() == pytest.approx(standing.oMf[talos.frame_id(f"{side}_foot")].translation[1], abs=0.02)
    stands = set(model.subtrees[model.frames[sole].parentJoint]) | {model.frames[sole].parentJoint}
    thigh = model.parents[shin]
    for j, v in collision_meshes(talos, knelt.q):
        if j in stands or j == shin:
            continue
        assert v[:, 2].min() > (0.004 if j == thigh else 0.02), model.names[j]  # nothing else on the floor
    sole_corners = talos.sole_corners_in_world(knelt.q, other)
    com = pin.centerOfMass(model, data, knelt.q)
    assert _inside(com[:2], np.vstack([sole_corners[:, :2], corners[:, :2]]))  # statically balanced on foot and knee
    assert knelt.q[model.joints[shin].idx_q] == pytest.approx(kneel_module.KNEE_BEND, abs=0.05)


def test_the_compiled_kneel_holds_the_standing_sole_then_adds_the_knee_region(talos, knelt):
    spec = compile_actions([Action(name="kneel", params={})], talos)
    names = [[c.frame for c in p.contacts] for p in spec.phases]
    assert ["left_sole_link", "leg_right_4_link"] in names
    i = names.index(["left_sole_link", "leg_right_4_link"])
    assert names[i - 1] == names[i + 1] == ["left_sole_link"]  # on one foot down and up
    assert names[0] == names[-1] == ["left_sole_link", "right_sole_link"]
    knee = spec.phases[i].contacts[1]
    assert knee.region == knelt.contact.region and knee.normal == (0.0, 0.0, 1.0)
    assert knee.friction_coefficient == talos.profile.friction_coefficient
    assert spec.phases[i].duration >= 1.5
    assert any("CoM back between the feet" in t.name for t in spec.com_targets)


def test_refused_when_the_knee_cannot_bend_enough(talos, monkeypatch):
    kneel_module._posture.cache_clear()
    monkeypatch.setattr(kneel_module, "KNEE_BEND", 3.0)  # beyond talos's 2.618 rad knee
    with pytest.raises(BeyondCapability, match=r"knees bend at most 2\.62 rad .*needs 3\.00 rad"):
        kneeling(talos, Stance.standing(talos), "right")
    kneel_module._posture.cache_clear()


def test_refused_when_an_object_stands_where_the_knee_goes(talos):
    from tasks.scene import SceneObject

    box = SceneObject(name="crate", shape="box", size=(0.2, 0.2, 0.2), position=(-0.25, -0.1, 0.1))
    with pytest.raises(BeyondCapability, match="the crate is where talos's right knee would go down"):
        kneeling(talos, Stance.standing(talos), "right", (box,))
    far = SceneObject(name="crate", shape="box", size=(0.2, 0.2, 0.2), position=(1.5, 0.0, 0.1))
    assert kneeling(talos, Stance.standing(talos), "right", (far,)).side == "right"


def test_a_sentence_kneeling_onto_a_crate_is_refused_before_planning_naming_the_leg_and_the_crate(talos):
    """What ``wbmp solve "跪下" --scene crate.json`` prints (exit 4, one line): the spec's binding
    refuses the knee's contact inside the crate (``tasks.robot_check``), no solver built; the CLI maps
    a SceneConflict to exit 4 (``wbmp.errors``)."""
    from tasks import bind
    from tasks.exceptions import SceneConflict
    from tasks.scene import Scene, SceneObject

    crate = Scene(objects=(SceneObject(name="crate", shape="box", size=(0.3, 0.3, 0.2), position=(-0.3, -0.09, 0.1)),))
    spec = compile_actions(parse("跪下").actions, talos, scene=crate)
    with pytest.raises(SceneConflict, match=r"the right leg's leg_right_4_link placement .* in phase '1 kneel: kneel on the right knee' "
                                            r"puts it inside the crate") as e:
        bind(spec, talos)
    assert e.value.object_name == "crate"


@pytest.mark.parametrize(("sentence", "knee"), [("kneel down", "right"), ("kneel on your left knee", "left"),
                                                ("go down on one knee", "right"), ("跪下", "right"), ("单膝跪下", "right"),
                                                # the motion starts standing: getting up from a kneel is the kneel's own rise
                                                ("get up from kneeling", "right"), ("stand up from kneeling on your left knee", "left"),
                                                ("从跪姿站起来", "right")])
def test_the_words(sentence, knee):
    actions = parse(sentence).actions
    assert [a.name for a in actions] == ["kneel"] and actions[0].params["knee"] == knee


def test_get_up_after_a_kneel_is_its_own_rise_and_stand_up_after_a_sit_is_unchanged(talos):
    for sentence in ("kneel down then get up", "跪下然后站起来"):
        actions = parse(sentence).actions
        assert [a.name for a in actions] == ["kneel", "stand"]
        spec = compile_actions(actions, talos)
        alone = compile_actions([Action(name="kneel", params={})], talos)
        assert sum(p.duration for p in spec.phases) == pytest.approx(sum(p.duration for p in alone.phases))  # no second stand
    assert [a.name for a in parse("sit down then stand up").actions] == ["sit_down", "stand"]


@pytest.mark.parametrize("sentence", ["kneel on both knees", "双膝跪下"])
def test_both_knees_are_refused_in_task_terms(talos, sentence):
    actions = parse(sentence).actions
    assert actions[0].params["knee"] == "both"
    with pytest.raises(BeyondCapability, match=r"kneel: talos kneels on one knee only .*: say \"kneel on one knee\""):
        compile_actions(actions, talos)


def test_g1_is_refused_its_thigh_would_pass_into_its_torso(g1):
    """g1's kneeling posture exists (the knee 0.23 m behind its feet) but its standing thigh meets its
    torso in the planner's collision model: refused in task terms (its plan failed on that pair)."""
    kneel_module._posture.cache_clear()
    with pytest.raises(BeyondCapability, match=r"kneel: kneeling on its right knee, g1's left hip would pass 0\.0\d\d m "
                                               r"into its torso"):
        kneeling(g1, Stance.standing(g1), "right")
