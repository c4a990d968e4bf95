"""Talos kneels on its right knee on the floor and gets up ("kneel down then get up"), and on its left
knee ("kneel on your left knee"): the plan's
knee contact recomputed independently of the planner and of :mod:`tasks.primitives.kneel`, and the
motion certified in MuJoCo (the region-contact lines of :mod:`sim.seat` for the floor among the
certificate's, and the unplanned-contact line: no other body part on the floor).

References: Pinocchio forward kinematics of the planned configurations at every knot the plan holds
the knee, every collision mesh carried to the world by Pinocchio's geometry placements, the floor at
z = 0; the executed configurations of MuJoCo for the knee region on the floor. The fast twins:
``tests/tasks/test_kneel.py`` (the kneeling configuration, the compiled contacts, the refusals, the
words) and ``tests/sim/test_kneel_lines.py`` (the floor lines on synthetic runs).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from language import parse
from planner import CheckKind, PlannerSettings, plan
from sim import simulate
from tasks.compose import compile_actions
from tests.meshes import collision_meshes, region_phase


@pytest.mark.long  # a dynamic plan (30 to 80 s), then 9.6 s of MuJoCo and the certificate (40 to 100 s), per knee
@pytest.mark.parametrize(("sentence", "side"), [("kneel down then get up", "right"), ("kneel on your left knee", "left")])
def test_kneeling_on_one_knee_and_getting_up_planned_and_certified(talos, sentence, side):
    spec = compile_actions(parse(sentence).actions, talos)
    p = plan(spec, talos, settings=PlannerSettings())
    assert p.ok
    t0, phase = region_phase(spec)
    knee = next(c for c in phase.contacts if c.region)
    assert knee.frame == f"leg_{side}_4_link"
    model, data = talos.model, talos.model.createData()
    shin = model.frames[talos.frame_id(knee.frame)].parentJoint
    sole = talos.frame_id(f"{'left' if side == 'right' else 'right'}_foot")
    foot = {int(j) for j in model.subtrees[model.frames[sole].parentJoint]}
    held = 0
    for k, tk in enumerate(p.t):
        if not t0 - 1e-9 <= tk <= t0 + phase.duration + 1e-9:
            continue
        held += 1
        pin.framesForwardKinematics(model, data, p.q[k])
        M = data.oMf[talos.frame_id(knee.frame)]
        corners = np.asarray(knee.region) @ M.rotation.T + M.translation
        assert np.allclose(corners[:, 2], 0.0, atol=1e-3)  # the region on the floor
        assert np.allclose(M.translation, knee.placement.position, atol=2e-3)  # held where planned
        for joint, vertices in collision_meshes(talos, p.q[k]):
            low = float(vertices[:, 2].min())
            if joint == shin:
                assert abs(low) < 3e-3  # the shin's lowest vertex on the floor
            elif joint not in foot and joint != model.parents[shin]:
                assert low > 0.02, model.names[joint]  # nothing else near the floor
    assert held >= 15
    execution = simulate(p, talos)
    assert execution.certificate.ok, execution.certificate.reason
    lines = {c.kind: c for c in execution.certificate.checks
             if c.kind in (CheckKind.SEAT_PLACEMENT, CheckKind.SEAT_SLIP, CheckKind.SEAT_CONTACT)}
    assert set(lines) == {CheckKind.SEAT_PLACEMENT, CheckKind.SEAT_SLIP, CheckKind.SEAT_CONTACT}
    assert all(c.ok and c.subject == knee.frame and "on the floor" in c.name for c in lines.values())
    unplanned = next(c for c in execution.certificate.checks if c.kind == CheckKind.UNPLANNED_CONTACTS)
    assert unplanned.ok and unplanned.value == 0.0
    t = np.asarray(execution.t)
    on = (t > t0 + 0.3) & (t < t0 + phase.duration - 0.3)
    for q in np.asarray(execution.q)[on][::50]:  # the executed region corners on the floor (5 mm)
        pin.framesForwardKinematics(model, data, q)
        M = data.oMf[talos.frame_id(knee.frame)]
        assert np.allclose((np.asarray(knee.region) @ M.rotation.T + M.translation)[:, 2], 0.0, atol=5e-3)
