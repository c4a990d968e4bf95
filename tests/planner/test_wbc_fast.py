"""The controller's compiled fast path: the equality-only solve is the QP's optimum, or it is not used."""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from planner.wbc import WbcSettings, WholeBodyController
from planner.wbc_kernel import _log3_quat
from sim import build_model
from sim.handmade import arm_plan

KKT_ATOL = 1e-7  # equality rows and stationarity of an exact (direct) solve, scaled units
INEQ_ATOL = 1e-6  # the inequality check's tolerance (WbcSettings.eps_abs)


@pytest.fixture(scope="module")
def arm(talos):
    return arm_plan(talos, duration=1.0, dt=0.05)


def _states(robot, rng, n):
    for _ in range(n):
        dq = np.concatenate([np.zeros(6), 0.02 * rng.standard_normal(robot.nv - 6)])
        yield pin.integrate(robot.model, robot.q_standing, dq), 0.05 * rng.standard_normal(robot.nv)


def test_fast_solution_meets_the_kkt_conditions_of_the_full_qp(talos, arm):
    """Where the fast path answers, its (a, f) satisfies the full QP's KKT conditions.

    Two controllers see the same closed-loop states (Talos raising its hand in MuJoCo): one with
    the fast path, one without (proxsuite on every tick). The fast solution must satisfy the full
    QP's A x = b, every inequality, and H x + g in the range of A^T (no inequality multiplier
    needed); on every tick, whichever path answered, the torques match proxsuite's.
    """
    sm = build_model(talos, timestep=0.001)
    d = sm.data()
    fast = WholeBodyController(talos)
    full = WholeBodyController(talos, WbcSettings(fast_path=False))
    q, v = np.array(arm.q[0]), np.zeros(talos.nv)
    sm.set_state(d, q, v)
    for ctrl in (fast, full):
        ctrl.reset(q, v)
    n_ticks, worst_tau = 400, 0.0
    for i in range(n_ticks):
        sm.state(d, q, v)
        tau = fast.compute(0.001 * i, q, v, arm)
        tau_full = full.compute(0.001 * i, q, v, arm)
        assert full.last.ok
        worst_tau = max(worst_tau, float(np.abs(tau - tau_full).max()))
        if fast.last.iterations == 0 and i % 40 == 0:
            x = fast._x
            assert np.abs(full.A @ x - full.b).max() < KKT_ATOL
            cx = full.C @ x
            assert np.all(cx <= full.u + INEQ_ATOL) and np.all(cx >= full.l - INEQ_ATOL)
            grad = full.H @ x + full.g
            y, *_ = np.linalg.lstsq(full.A.T, -grad, rcond=None)
            assert np.abs(grad + full.A.T @ y).max() < KKT_ATOL * max(1.0, np.abs(grad).max())
        d.ctrl[sm.actuator_select] = tau
        mujoco.mj_step(sm.model, d)
    assert worst_tau < 1e-2  # [N m] proxsuite stops at eps_abs = 1e-6 on scaled variables
    # this quick (1 s) raise unloads sole corners at times, so both paths were compared
    assert 0.5 * n_ticks <= fast.fast_ticks < n_ticks, f"fast path on {fast.fast_ticks} of {n_ticks}"


def test_active_torque_limit_falls_back_to_the_full_qp(talos, arm):
    """Torque limits below the unconstrained optimum's torques: proxsuite answers, within the limits."""
    q, v = np.array(arm.q[0]), np.zeros(talos.nv)
    probe = WholeBodyController(talos, WbcSettings(torque_scale=1.0))
    probe.reset(q, v)
    tau0 = probe.compute(0.0, q, v, arm)
    scale = 0.8 * float(np.max(np.abs(tau0) / talos.torque_limits))
    fast = WholeBodyController(talos, WbcSettings(torque_scale=scale))
    full = WholeBodyController(talos, WbcSettings(torque_scale=scale, fast_path=False))
    for ctrl in (fast, full):
        ctrl.reset(q, v)
    tau = fast.compute(0.0, q, v, arm)
    tau_full = full.compute(0.0, q, v, arm)
    assert fast.last.ok and fast.last.iterations > 0  # proxsuite iterated
    assert fast.fast_ticks == 0
    assert np.all(np.abs(tau) <= scale * talos.torque_limits + 1e-9)
    np.testing.assert_allclose(tau, tau_full, atol=1e-6)


def test_posture_error_on_the_manifold_matches_pin_difference(talos, rng):
    """The kernel's base-rotation error equals pin.difference's angular part, up to half-turns."""
    model = talos.model
    out = np.empty(3)
    for angle in (1e-9, 0.3, 2.0, np.pi - 1e-6):
        for _ in range(5):
            axis = rng.standard_normal(3)
            axis /= np.linalg.norm(axis)
            q0 = pin.randomConfiguration(model, -np.ones(model.nq), np.ones(model.nq))
            q0[:3] = 0.0
            r0 = pin.Quaternion(rng.standard_normal(4)).normalized().toRotationMatrix()
            r1 = r0 @ pin.exp3(angle * axis)
            q0[3:7] = pin.Quaternion(r0).coeffs()
            q1 = q0.copy()
            q1[3:7] = -pin.Quaternion(r1).coeffs()  # the other sign of the same rotation
            _log3_quat(q0, q1, out)
            np.testing.assert_allclose(out, pin.difference(model, q0, q1)[3:6], atol=1e-8)
            np.testing.assert_allclose(out, angle * axis, atol=1e-6)
