"""Leaning on a table with both hands (issue 33): the leaning posture, the hands' contacts with
their support regions on the table top, the compiled spec, the refusals and the words.

The references are independent of :mod:`tasks.primitives.lean`: Pinocchio forward kinematics of the
leaning configuration, every collision mesh carried to the world by Pinocchio's geometry
placements, the table's top face and near edge from its box by hand (``examples/scenes/table.json``:
a 0.6 x 1.2 m top at 0.62 m, its near edge 0.35 m ahead). The plan and its MuJoCo certificate are
the long test ``tests/sim/test_lean.py`` (this file is its fast twin).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from tasks.actions import Action
from tasks.compose import compile_actions
from tasks.exceptions import BeyondCapability
from tasks.primitives.geometry import Stance
from tasks.primitives.lean import leaning
from tasks.scene import load_scene
from tests.meshes import collision_meshes

TABLE = Path(__file__).resolve().parents[2] / "examples" / "scenes" / "table.json"
TOP, NEAR, FAR, HALF_WIDTH = 0.62, 0.35, 0.95, 0.6  # the table by hand [m]


@pytest.fixture(scope="module")
def table():
    return load_scene(TABLE)


@pytest.fixture(scope="module")
def leant(talos, table):
    return leaning(talos, Stance.standing(talos), table.objects[0])


def test_the_leaning_hands_rest_on_the_table_top_by_forward_kinematics(talos, table, leant):
    """Each hand's lowest mesh vertex (the hand link and below) on the top (2 mm), at least 9 cm
    inside the near edge; the region corners (FK of the contact frame) on the top inside its edges;
    no other mesh below the top over the table; the soles where they stand (1 mm); the CoM over them."""
    model, data = talos.model, talos.model.createData()
    pin.framesForwardKinematics(model, data, leant.q)
    assert len(leant.contacts) == 2
    hands = set()
    for side, c in zip(("left", "right"), leant.contacts, strict=True):  # on a link of the hand (talos: a fingertip)
        joint = model.frames[talos.frame_id(f"{side}_hand")].parentJoint
        assert model.frames[talos.frame_id(c.frame)].parentJoint in model.subtrees[joint]
        hands |= set(model.subtrees[joint])
        M = data.oMf[talos.frame_id(c.frame)]
        assert np.allclose(M.translation, c.placement.position, atol=1e-9)
        corners = np.asarray(c.region) @ M.rotation.T + M.translation
        assert np.allclose(corners[:, 2], TOP, atol=2e-3)
        assert np.all(corners[:, 0] > NEAR) and np.all(corners[:, 0] < FAR) and np.all(np.abs(corners[:, 1]) < HALF_WIDTH)
        assert np.ptp(corners[:, 0]) >= 0.01 - 1e-9 and np.ptp(corners[:, 1]) >= 0.01 - 1e-9  # a pad, not a point
        assert np.linalg.norm(corners.mean(axis=0) - M.translation) < 0.05  # the link's origin near its contact
        assert c.normal == (0.0, 0.0, 1.0) and c.friction_coefficient == pytest.approx(0.6)  # the table's
    meshes = collision_meshes(talos, leant.q)
    for side, sign in (("left", 1.0), ("right", -1.0)):
        joint = model.frames[talos.frame_id(f"{side}_hand")].parentJoint
        v = np.vstack([w for j, w in meshes if j in model.subtrees[joint]])
        low = v[np.argmin(v[:, 2])]
        assert low[2] == pytest.approx(TOP, abs=2e-3)
        assert low[0] > NEAR + 0.09 and sign * low[1] > 0.1
    over = [w[(w[:, 0] > NEAR) & (np.abs(w[:, 1]) < HALF_WIDTH)] for j, w in meshes if j not in hands]
    assert min(float(w[:, 2].min()) for w in over if len(w)) > TOP + 0.01  # nothing else reaches the top
    stance = Stance.standing(talos)
    for side in ("left", "right"):
        assert np.allclose(data.oMf[talos.frame_id(f"{side}_foot")].translation, stance.sole(side).position, atol=1e-3)
    com = pin.centerOfMass(model, data, leant.q)
    assert abs(com[0]) < 0.03 and abs(com[1]) < 0.01  # over the soles (the standing CoM's place)


def test_lean_on_the_table_compiles_to_hand_contacts_and_touches(talos, table, leant):
    spec = compile_actions([Action(name="lean_on", params={})], talos, scene=table)
    assert spec.dynamic
    held = [p for p in spec.phases if any(c.region for c in p.contacts)]
    assert [p.name for p in held] == ["1 lean_on: leaning"]
    assert [c for c in held[0].contacts if c.region] == list(leant.contacts)
    assert {t.touch for t in spec.targets if t.touch} == {"table"}
    start = sum(p.duration for p in spec.phases[:spec.phases.index(held[0])])
    end = start + held[0].duration
    for t in (t for t in spec.targets if t.touch):  # the hands may touch from before the touch-down to after the lift-off
        assert t.window[0] < start and t.window[1] > end
    com = [c for c in spec.com_targets if "CoM over" in c.name]
    assert len(com) == 1 and com[0].window[0] < start and com[0].window[1] > end  # in place before and after


def test_leaning_is_refused_in_task_terms(talos, table):
    with pytest.raises(BeyondCapability, match="there is no table in the scene"):
        compile_actions([Action(name="lean_on", params={})], talos, scene=None)
    obj = table.objects[0]
    stance = Stance.standing(talos)
    with pytest.raises(BeyondCapability, match=r"the table's top at 0.90 m is above talos's hands hanging \(0.6"):
        leaning(talos, stance, dataclasses.replace(obj, size=(0.6, 1.2, 0.9), position=(0.65, 0.0, 0.45)))
    with pytest.raises(BeyondCapability, match="the table's top at 0.20 m is too low for talos to lean on: its base would drop 0.[2-9]"):
        leaning(talos, stance, dataclasses.replace(obj, size=(0.6, 1.2, 0.2), position=(0.65, 0.0, 0.1)))
    with pytest.raises(BeyondCapability, match="the table's top is not within talos's reach ahead"):
        leaning(talos, stance, dataclasses.replace(obj, position=(1.6, 0.0, 0.31)))


@pytest.mark.parametrize("text", ["lean on the table with both hands", "lean on the table", "双手撑在桌子上",
                                  "brace yourself on the desk"])
def test_the_words_for_leaning_on_a_table(text):
    from language import parse

    assert [a.name for a in parse(text).actions] == ["lean_on"]
