"""The controller's compiled fast path: the equality-only solve is the QP's optimum, or it is not used."""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin
import pytest
from scipy.optimize import lsq_linear

from planner.wbc import WbcSettings, WholeBodyController
from planner.wbc.kernel import _log3_quat
from sim import build_model
from sim.handmade import arm_plan

KKT_ATOL = 1e-7  # equality rows and stationarity of an exact (direct) solve, scaled units
INEQ_ATOL = 1e-6  # the inequality check's tolerance (WbcSettings.eps_abs)
ACTIVE_ATOL = 1e-7  # a row this close to its bound counts as active in the KKT check


@pytest.fixture(scope="module")
def arm(talos):
    return arm_plan(talos, duration=1.0, dt=0.05)


def _states(robot, rng, n):
    for _ in range(n):
        dq = np.concatenate([np.zeros(6), 0.02 * rng.standard_normal(robot.nv - 6)])
        yield pin.integrate(robot.model, robot.q_standing, dq), 0.05 * rng.standard_normal(robot.nv)


def _assert_kkt(full: WholeBodyController, x: np.ndarray) -> None:
    """x solves the full QP (H, g, A, b, C, l, u) of ``full``'s last tick: KKT conditions.

    Equality rows hold, every inequality row holds, and H x + g = -(A^T y + C_act^T z) for some
    y and some z >= 0 on the active rows (a bounded least-squares fit, so redundant active rows,
    like the four pyramid rows of a lifted-off corner, are judged fairly).
    """
    assert np.abs(full.A @ x - full.b).max() < KKT_ATOL
    cx = full.C @ x
    assert np.all(cx <= full.u + INEQ_ATOL) and np.all(cx >= full.l - INEQ_ATOL)
    upper = cx >= full.u - ACTIVE_ATOL
    lower = (cx <= full.l + ACTIVE_ATOL) & (full.l > -1e19)
    G = np.hstack([full.A.T, full.C[upper].T, -full.C[lower].T])
    n_eq = full.A.shape[0]
    lo = np.concatenate([np.full(n_eq, -np.inf), np.zeros(G.shape[1] - n_eq)])
    grad = full.H @ x + full.g
    fit = lsq_linear(G, -grad, bounds=(lo, np.full(G.shape[1], np.inf)), tol=1e-12)
    # rounding in H x + g is relative to its terms (the angular-momentum rows weigh 100)
    scale = max(1.0, np.abs(full.H @ x).max(), np.abs(full.g).max())
    assert np.abs(grad + G @ fit.x).max() < KKT_ATOL * scale


def test_fast_solution_meets_the_kkt_conditions_of_the_full_qp(talos, arm):
    """Where the compiled path answers, its (a, f) satisfies the full QP's KKT conditions.

    Two controllers see the same closed-loop states (Talos raising its hand quickly in MuJoCo):
    one with the fast path (equality-only solve, then active-set iterations), one without
    (proxsuite on every tick). Every 10th tick the compiled answer is checked against the full
    QP's KKT conditions; on every tick its torques match proxsuite's to its tolerance.
    """
    sm = build_model(talos, timestep=0.001)
    d = sm.data()
    fast = WholeBodyController(talos)
    # The reference solves to 1e-7 so that the comparison measures the fast path, not
    # proxsuite's own stopping error (0.038 N m at 1e-6 with the inscribed friction pyramid).
    full = WholeBodyController(talos, WbcSettings(fast_path=False, eps_abs=1e-7))
    q, v = np.array(arm.q[0]), np.zeros(talos.nv)
    sm.set_state(d, q, v)
    for ctrl in (fast, full):
        ctrl.reset(q, v)
    n_ticks, worst_tau, checked = 400, 0.0, {"fast": 0, "active set": 0}
    for i in range(n_ticks):
        sm.state(d, q, v)
        tau = fast.compute(0.001 * i, q, v, arm)
        tau_full = full.compute(0.001 * i, q, v, arm)
        assert full.last.ok
        compiled = str(fast.last.status).startswith("solved")  # else proxsuite answered both
        if compiled:
            worst_tau = max(worst_tau, float(np.abs(tau - tau_full).max()))
        kind = "fast" if fast.last.iterations == 0 else "active set"
        if compiled and i % 10 == 0:
            _assert_kkt(full, fast._x)
            checked[kind] += 1
        d.ctrl[sm.actuator_select] = tau
        mujoco.mj_step(sm.model, d)
    # [N m] proxsuite stops at eps_abs = 1e-6 on scaled forces (one unit is m g / 8 = 111 N)
    assert worst_tau < 3e-2
    # this quick (1 s) raise unloads sole corners at times, so both compiled paths were checked
    assert checked["fast"] > 0 and checked["active set"] > 0, checked
    # proxsuite is the exception: at most a few ticks where the active set does not settle
    # (400 of 400 on an AMD EPYC with com_weight 10; on the shared Intel Xeon build box 383 with 10 and
    # 374 with the default 50: a CoM weight above the soles' moves more corner forces to their bounds)
    assert fast.fast_ticks + fast.active_set_ticks >= 0.9 * n_ticks


@pytest.mark.parametrize("active_set_iterations", [8, 0])
def test_active_torque_limits_solved_exactly(talos, arm, active_set_iterations):
    """Torque limits below the unconstrained optimum's torques.

    With active-set iterations the saturated joints are held at their limits and the answer
    meets the full QP's KKT conditions; without them proxsuite answers. Either way the torques
    are within the limits and match a controller that always uses proxsuite.
    """
    q, v = np.array(arm.q[0]), np.zeros(talos.nv)
    probe = WholeBodyController(talos, WbcSettings(torque_scale=1.0))
    probe.reset(q, v)
    tau0 = probe.compute(0.0, q, v, arm)
    scale = 0.8 * float(np.max(np.abs(tau0) / talos.torque_limits))
    ctrl = WholeBodyController(
        talos, WbcSettings(torque_scale=scale, active_set_iterations=active_set_iterations)
    )
    full = WholeBodyController(talos, WbcSettings(torque_scale=scale, fast_path=False))
    for c in (ctrl, full):
        c.reset(q, v)
    tau = ctrl.compute(0.0, q, v, arm)
    tau_full = full.compute(0.0, q, v, arm)
    assert ctrl.last.ok and ctrl.last.iterations > 0 and ctrl.fast_ticks == 0
    assert ctrl.active_set_ticks == (1 if active_set_iterations else 0)
    if active_set_iterations:
        _assert_kkt(full, ctrl._x)
        assert np.isclose(np.max(np.abs(tau) / (scale * talos.torque_limits)), 1.0)  # held at the limit
    assert np.all(np.abs(tau) <= scale * talos.torque_limits + 1e-9)
    np.testing.assert_allclose(tau, tau_full, atol=1e-3)


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


def test_clamped_cubic_spline_and_tridiagonal_solve_match_scipy():
    """The controller's own spline and tridiagonal solver (no scipy.interpolate/linalg import on
    the solve path) give scipy's clamped CubicSpline and solve_banded to round-off."""
    from scipy.interpolate import CubicSpline
    from scipy.linalg import solve_banded

    from planner.wbc.reference import clamped_cubic_spline, solve_tridiagonal

    rng = np.random.default_rng(3)
    for n in (2, 3, 9, 41):
        t = np.cumsum(rng.uniform(0.02, 0.2, n))
        y, d0, d1 = rng.normal(size=(n, 4)), rng.normal(size=4), rng.normal(size=4)
        times = np.concatenate([np.linspace(t[0], t[-1], 301), t])
        ours = clamped_cubic_spline(t, y, d0, d1, times)
        spline = CubicSpline(t, y, bc_type=((1, d0), (1, d1)), axis=0)
        for order in range(3):
            scale = max(1.0, float(np.abs(spline(times, order)).max()))
            assert np.abs(ours[order] - spline(times, order)).max() < 1e-9 * scale, (n, order)
    for n in (1, 2, 7, 500):
        ab = rng.uniform(-1.0, 1.0, (3, n))
        ab[1] = 2.5 + rng.uniform(0.0, 1.0, n)  # strictly diagonally dominant
        rhs = rng.normal(size=(n, 2))
        assert np.abs(solve_tridiagonal(ab, rhs) - solve_banded((1, 1), ab, rhs)).max() < 1e-12
