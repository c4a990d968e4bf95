"""Talos leans on the table of ``examples/scenes/table.json`` with both hands: the plan's hand
contacts recomputed independently of the planner and of :mod:`tasks.primitives.lean`, and the
motion certified in MuJoCo (the region-contact lines of :mod:`sim.seat` among the certificate's).

References: Pinocchio forward kinematics of the planned configurations at every knot the plan holds
the hands on the table, every collision mesh carried to the world by Pinocchio's geometry
placements, the table's top face by hand from its box (0.62 m, x 0.35..0.95 m, y -0.6..0.6 m); the
executed configurations of MuJoCo for the hands on the top. The fast twin: ``tests/tasks/test_lean.py``
(the leaning configuration, the compiled contacts, the refusals, the words).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from planner import CheckKind, PlannerSettings, plan
from sim import simulate
from tasks.actions import Action
from tasks.compose import compile_actions
from tasks.scene import load_scene
from tests.meshes import collision_meshes, region_phase

TABLE = Path(__file__).resolve().parents[2] / "examples" / "scenes" / "table.json"
TOP, X_RANGE, Y_HALF = 0.62, (0.35, 0.95), 0.6  # the table's top face, by hand from table.json


@pytest.mark.long  # a dynamic plan with scene rows (20 to 50 s with a built solver, a minute or two cold),
#   then 7.7 s of MuJoCo and the certificate (one to two minutes), per robot
@pytest.mark.parametrize("name", ["talos", "g1"])
def test_leaning_on_the_table_planned_and_certified_with_both_hands_on_the_top(name, request):
    talos = request.getfixturevalue(name)  # the robot (talos's gripper or g1's rubber hand on the top)
    spec = compile_actions([Action(name="lean_on", params={})], talos, scene=load_scene(TABLE))
    p = plan(spec, talos, settings=PlannerSettings())
    assert p.ok
    window = _planned_on_the_top(talos, spec, p)
    execution = simulate(p, talos)
    assert execution.certificate.ok, execution.certificate.reason
    lines = [c for c in execution.certificate.checks
             if c.kind in (CheckKind.SEAT_PLACEMENT, CheckKind.SEAT_SLIP, CheckKind.SEAT_CONTACT)]
    assert len(lines) == 7 and all(c.ok for c in lines)  # per hand: where, slip, how long; nothing else on it
    model, data = talos.model, talos.model.createData()
    t = np.asarray(execution.t)
    held = (t > window[0] + 0.3) & (t < window[1] - 0.3)
    hands = [c for c in spec.phases[next(i for i, ph in enumerate(spec.phases) if any(c.region for c in ph.contacts))].contacts
             if c.region]
    for q in np.asarray(execution.q)[held][::50]:  # the executed region corners on the top (5 mm)
        pin.framesForwardKinematics(model, data, q)
        for c in hands:
            M = data.oMf[talos.frame_id(c.frame)]
            assert np.allclose((np.asarray(c.region) @ M.rotation.T + M.translation)[:, 2], TOP, atol=5e-3)


def _planned_on_the_top(talos, spec, p) -> tuple[float, float]:
    """Every knot the plan holds the hands: the region corners on the top (1 mm), inside its edges,
    the hands' lowest mesh vertices on it (2 mm), no other mesh but the wrist's (g1's hangs 3 mm above
    it) reaching down to 1 cm above it over the table."""
    model, data = talos.model, talos.model.createData()
    t0, phase = region_phase(spec)
    hands = [c for c in phase.contacts if c.region]
    assert len(hands) == 2
    mine = {int(j) for side in ("left", "right") for j in model.subtrees[model.frames[talos.frame_id(f"{side}_hand")].parentJoint]}
    assert all(model.frames[talos.frame_id(c.frame)].parentJoint in mine for c in hands)
    wrists = {int(model.parents[model.frames[talos.frame_id(c.frame)].parentJoint]) for c in hands}
    held = 0
    for k, tk in enumerate(p.t):
        if not t0 - 1e-9 <= tk <= t0 + phase.duration + 1e-9:
            continue
        held += 1
        pin.framesForwardKinematics(model, data, p.q[k])
        for c in hands:
            M = data.oMf[talos.frame_id(c.frame)]
            corners = np.asarray(c.region) @ M.rotation.T + M.translation
            assert np.allclose(corners[:, 2], TOP, atol=1e-3)
            assert np.all((corners[:, 0] > X_RANGE[0]) & (corners[:, 0] < X_RANGE[1]) & (np.abs(corners[:, 1]) < Y_HALF))
        low, rest = [], []
        for joint, v in collision_meshes(talos, p.q[k]):
            if joint in mine:
                low.append(v)
            elif joint not in wrists:
                rest.append(v)
        assert np.vstack(low)[:, 2].min() == pytest.approx(TOP, abs=2e-3)
        rest_v = np.vstack(rest)
        over = (rest_v[:, 0] > X_RANGE[0]) & (np.abs(rest_v[:, 1]) < Y_HALF)
        assert not over.any() or rest_v[over, 2].min() > TOP + 0.01
    assert held * spec.dt >= 1.5
    return t0, t0 + phase.duration
