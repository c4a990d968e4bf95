"""Talos sits down on the chair of ``examples/scenes/chair.json`` (and stands up again): the plan's
seat contacts recomputed independently of the planner and of :mod:`tasks.primitives.seat`, and the
motion certified in MuJoCo (the seat lines of :mod:`sim.seat` among the certificate's).

References: Pinocchio forward kinematics of the planned configurations at every knot the plan holds
the thighs on the seat, the thighs' collision-mesh vertices carried to the world by Pinocchio's
geometry placements, the seat's top face by hand from its box (0.31 m, x -0.55..-0.10 m). The fast
twin: ``tests/tasks/test_seat.py`` (the sitting configuration, the compiled contacts, the refusals).
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

CHAIR = Path(__file__).resolve().parents[2] / "examples" / "scenes" / "chair.json"
TOP, X_RANGE, Y_HALF = 0.31, (-0.55, -0.10), 0.25  # the seat's top face, by hand from chair.json
CHAIR_BOXES = (((-0.55, -0.25, 0.27), (-0.10, 0.25, 0.31)),  # the seat board, then the pedestal under its rear
               ((-0.55, -0.25, 0.0), (-0.30, 0.25, 0.27)))


def _vertices(robot, data, cdata, q, links) -> np.ndarray:
    pin.updateGeometryPlacements(robot.model, data, robot.collision_model, cdata, q)
    out = [np.asarray(g.geometry.vertices(), dtype=float).reshape(-1, 3) @ cdata.oMg[i].rotation.T + cdata.oMg[i].translation
           for i, g in enumerate(robot.collision_model.geometryObjects)
           if robot.model.frames[g.parentFrame].name in links and hasattr(g.geometry, "num_vertices")]
    return np.vstack(out)


@pytest.mark.long  # a kinematic plan with scene rows (5 s with a built solver, about a minute cold), then
#   6 to 10 s of MuJoCo and the certificate (about a minute)
@pytest.mark.parametrize("stand_up", [False, True], ids=["sit down", "sit down then stand up"])
def test_sitting_on_the_chair_planned_and_certified_with_the_thighs_on_the_seat(talos, stand_up):
    scene = load_scene(CHAIR)
    actions = [Action(name="sit_down", params={})] + ([Action(name="stand_up", params={})] if stand_up else [])
    spec = compile_actions(actions, talos, scene=scene)
    p = plan(spec, talos, settings=PlannerSettings())
    assert p.ok
    _planned_on_the_seat(talos, spec, p, stand_up)
    execution = simulate(p, talos)
    assert execution.certificate.ok, execution.certificate.reason
    seat = [c for c in execution.certificate.checks
            if c.kind in (CheckKind.SEAT_PLACEMENT, CheckKind.SEAT_SLIP, CheckKind.SEAT_CONTACT)]
    assert len(seat) == 7 and all(c.ok for c in seat)  # per thigh: where, slip, how long; nothing else on it
    model, data = talos.model, talos.model.createData()
    t = np.asarray(execution.t)
    sitting = (t > 3.9) & (t < 4.6)  # seated in both motions (sat on from 3.6 s, rising from 6.0 s)
    for q in np.asarray(execution.q)[sitting][::50]:  # the executed region corners on the seat's top (5 mm)
        pin.framesForwardKinematics(model, data, q)
        for c in (c for c in spec.phases[2].contacts if c.region):
            M = data.oMf[talos.frame_id(c.frame)]
            assert np.allclose((np.asarray(c.region) @ M.rotation.T + M.translation)[:, 2], TOP, atol=5e-3)


def _planned_on_the_seat(talos, spec, p, stand_up: bool) -> None:
    model, data = talos.model, talos.model.createData()
    cdata = talos.collision_model.createData()
    seat_phases = [(sum(ph.duration for ph in spec.phases[:i]), ph) for i, ph in enumerate(spec.phases)
                   if any(c.region for c in ph.contacts)]
    assert seat_phases
    thighs = {c.frame for _, ph in seat_phases for c in ph.contacts if c.region}
    others = {f.name for f in model.frames if f.type == pin.FrameType.BODY} - thighs
    held = 0
    for k, tk in enumerate(p.t):
        on = [ph for t0, ph in seat_phases if t0 - 1e-9 <= tk <= t0 + ph.duration + 1e-9]
        if not on:
            continue
        held += 1
        pin.framesForwardKinematics(model, data, p.q[k])
        for c in (c for c in on[0].contacts if c.region):
            M = data.oMf[talos.frame_id(c.frame)]
            corners = np.asarray(c.region) @ M.rotation.T + M.translation
            assert np.allclose(corners[:, 2], TOP, atol=1e-3)  # every region corner on the seat's top
            assert np.all((corners[:, 0] >= X_RANGE[0]) & (corners[:, 0] <= X_RANGE[1]))
            assert np.all(np.abs(corners[:, 1]) <= Y_HALF)
        low = _vertices(talos, data, cdata, p.q[k], thighs)
        assert low[:, 2].min() == pytest.approx(TOP, abs=2e-3)  # the thighs rest on it, not in it
        rest = _vertices(talos, data, cdata, p.q[k], others)
        for lo, hi in CHAIR_BOXES:  # no other link within 2 mm of the board or the pedestal (hips: 5.7 mm above)
            inside = np.all((rest >= np.asarray(lo) - 0.002) & (rest <= np.asarray(hi) + 0.002), axis=1)
            assert not inside.any(), rest[inside][:3]
    assert held * spec.dt >= 1.0
    if stand_up:  # back up: the base at its standing place (2 cm), the feet never moved
        pin.framesForwardKinematics(model, data, p.q[-1])
        ref = talos.model.createData()
        pin.framesForwardKinematics(model, ref, talos.q_standing)
        base = talos.frame_id("base")
        assert np.linalg.norm(data.oMf[base].translation - ref.oMf[base].translation) < 0.02
