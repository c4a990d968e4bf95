"""The torque margin rows (planner/trajopt/centroidal/torque.py): added only after a solve whose
joint torques (Pinocchio RNEA on the knots) exceed the margin, with the rest of RNEA beyond gravity
frozen per knot; their CasADi form against RNEA is in test_term_twins.py. The plan they make
(talos's march, certified) is the long test in tests/wbmp/test_retarget_certified.py; these are
its fast twins."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pinocchio as pin
import pytest

from planner import CentroidalSettings
from planner.trajopt.centroidal.torque import (
    TorqueMarginTerm,
    joint_ids,
    torque_margin_terms,
)
from planner.trajopt.symbolic import chart_to_configuration

JOINTS = ("arm_left_2_joint", "arm_right_2_joint")
N = 30
DT = 0.08


def _layout(robot, amplitude: float, period: float, joints=JOINTS) -> tuple[SimpleNamespace, np.ndarray]:
    """A stand-in for a dynamic layout (what the function reads) and a solution ``dq`` (N+1, nv)
    swinging the left shoulder roll out by ``amplitude`` [rad] with ``period`` [s]."""
    settings = CentroidalSettings(torque_joints=joints, torque_margin=0.85)
    lay = SimpleNamespace(centroidal_settings=settings, robot=robot, q_ref=np.array(robot.q_standing), dt=DT, N=N,
                          terms=("a kept term",), phase_name=lambda k: f"phase {k // 10}")
    t = DT * np.arange(N + 1)
    dq = np.zeros((N + 1, robot.nv))
    idx = robot.model.joints[robot.model.getJointId("arm_left_2_joint")].idx_v
    dq[:, idx] = amplitude * (1.0 - np.cos(2 * np.pi * t / period)) / 2
    return lay, dq


def _rnea(robot, q: np.ndarray, k: int, idx: list[int]) -> np.ndarray:
    """RNEA at knot k with its velocity and acceleration from the knots around it (Pinocchio)."""
    model = robot.model
    back = pin.difference(model, q[k - 1], q[k]) / DT
    ahead = pin.difference(model, q[k], q[k + 1]) / DT
    return pin.rnea(model, model.createData(), q[k], (back + ahead) / 2, (ahead - back) / DT)[idx]


def test_a_motion_within_the_margin_gets_no_rows(talos):
    lay, dq = _layout(talos, amplitude=0.3, period=2.0)  # the arm out 0.3 rad, slowly
    assert torque_margin_terms(lay, dq) is None


def test_a_motion_beyond_the_margin_gets_rows_with_the_rest_of_rnea_frozen(talos):
    model = talos.model
    lay, dq = _layout(talos, amplitude=1.4, period=0.8)  # out to 1.4 rad and back, quickly
    q = np.array([chart_to_configuration(model, lay.q_ref, d) for d in dq])
    idx = [model.joints[model.getJointId(n)].idx_v for n in JOINTS]
    limits = model.effortLimit[idx]
    worst = max(float(np.max(np.abs(_rnea(talos, q, k, idx)) / limits)) for k in range(2, N))
    assert worst > 1.05  # the swing asks more than the joint gives (the trigger, 1.0; not a knife edge)
    terms = torque_margin_terms(lay, dq)
    assert terms is not None and terms[0] == "a kept term"
    rows = [t for t in terms if isinstance(t, TorqueMarginTerm)]
    assert [t.knot for t in rows] == list(range(2, N))  # every variable knot
    for t in rows:
        k = t.knot
        assert t.structure == ("torque_margin", joint_ids(talos, JOINTS)) and t.phase == f"phase {k // 10}"
        n = len(JOINTS)  # upper rows (a load up to +margin), then lower rows (down to -margin)
        assert list(t.upper) == [0.85] * n + [np.inf] * n and list(t.lower) == [-np.inf] * n + [-0.85] * n
        # at the solution: gravity (exact) + the frozen rest is RNEA
        gravity = pin.computeGeneralizedGravity(model, model.createData(), q[k])[idx]
        rnea = _rnea(talos, q, k, idx)
        np.testing.assert_allclose(gravity + t.params, rnea, atol=1e-6)
        rows = t.residual(SimpleNamespace(model=model, data=model.createData(), q=q[k]))
        # each row is RNEA or gravity alone, whichever is further out on its side
        np.testing.assert_allclose(rows[:n], np.maximum(rnea, gravity) / limits, atol=1e-8)
        np.testing.assert_allclose(rows[n:], np.minimum(rnea, gravity) / limits, atol=1e-8)
    # re-linearized: the rows replaced, not added twice
    again = torque_margin_terms(SimpleNamespace(**{**vars(lay), "terms": terms}), dq)
    assert again is not None and len(again) == len(terms)


def test_no_joints_named_no_rows_and_an_unknown_joint_is_named(talos):
    lay, dq = _layout(talos, amplitude=1.4, period=0.8, joints=())
    assert torque_margin_terms(lay, dq) is None
    with pytest.raises(ValueError, match="no joint 'arm_left_9_joint'"):
        joint_ids(talos, ("arm_left_9_joint",))


def test_retargets_bound_talos_strained_arm_joints_and_leave_g1_s_settings_alone(talos, g1):
    from wbmp.retarget import ARM_TORQUE_MARGIN, MAX_ITERATIONS, TRACKING_GUESS, retarget_settings

    s = retarget_settings(talos)
    assert s.centroidal.torque_joints == tuple(f"arm_{side}_{i}_joint" for side in ("left", "right")
                                               for i in range(1, 6))
    assert s.centroidal.torque_margin == ARM_TORQUE_MARGIN and s.solver.max_iterations == MAX_ITERATIONS
    # G1's shoulders hold their arms: its settings are those without a robot
    assert retarget_settings(g1).centroidal == retarget_settings().centroidal == CentroidalSettings(
        tracking_guess=TRACKING_GUESS)


def test_a_plan_between_the_margin_and_the_trigger_gets_no_rows_but_keeps_rows_it_has(talos):
    """Rows come only when a plan asks more than the joint gives (``torque_trigger`` 1.0); a layout
    that has them re-linearizes them while the plan asks more than the margin (0.85 + 0.02)."""
    model = talos.model
    idx = [model.joints[model.getJointId(n)].idx_v for n in JOINTS]
    for amplitude in (0.9, 1.0, 1.1, 1.2, 1.3):  # the first swing asking between 0.9 and 0.98 of a limit
        lay, dq = _layout(talos, amplitude=amplitude, period=1.2)
        q = np.array([chart_to_configuration(model, lay.q_ref, d) for d in dq])
        worst = max(float(np.max(np.abs(_rnea(talos, q, k, idx)) / model.effortLimit[idx])) for k in range(2, N))
        if 0.9 < worst < 0.98:
            break
    else:
        pytest.fail("no swing between 0.9 and 0.98 of the limit")
    assert torque_margin_terms(lay, dq) is None
    with_rows = SimpleNamespace(**{**vars(lay), "terms": ("a kept term", TorqueMarginTerm.at(
        5, talos, joint_ids(talos, JOINTS), 0.85, np.zeros(len(JOINTS)), "p"))})
    again = torque_margin_terms(with_rows, dq)
    assert again is not None and len([t for t in again if isinstance(t, TorqueMarginTerm)]) == N - 2
