"""Whole-body QP controller: the solution obeys the physics it was given, and tracks references."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from planner.wbc import ControllerError, WbcSettings, WholeBodyController
from planner.wbc.reference import PlanReference
from sim.handmade import arm_plan, standing_plan

DYNAMICS_ATOL = 1e-4  # [N, N m] QP tolerance 1e-6 on scaled variables, times ~100 N per unit
FRICTION_ATOL = 1e-3  # [N] same tolerance on the pyramid rows, in newtons


@pytest.fixture(scope="module")
def stand(talos):
    return standing_plan(talos, duration=1.0, dt=0.05)


@pytest.fixture(scope="module")
def arm(talos):
    return arm_plan(talos, duration=2.0, dt=0.05)


def _perturbed_state(robot, rng):
    q = pin.integrate(
        robot.model,
        robot.q_standing,
        np.concatenate([np.zeros(6), 0.02 * rng.standard_normal(robot.nv - 6)]),
    )
    v = 0.05 * rng.standard_normal(robot.nv)
    return q, v


def test_standing_forces_carry_the_weight(talos, stand):
    """At rest in the standing posture the contact forces sum to m g and the accelerations are ~0."""
    ctrl = WholeBodyController(talos)
    q, v = talos.q_standing.copy(), np.zeros(talos.nv)
    ctrl.reset(q, v)
    for k in range(5):
        ctrl.compute(0.001 * k, q, v, stand)
    assert ctrl.last.ok
    total = sum(ctrl.contact_forces().values())
    np.testing.assert_allclose(total, [0.0, 0.0, talos.mass * 9.81], atol=0.5)
    assert np.abs(ctrl.acceleration()).max() < 1e-2


def test_solution_satisfies_dynamics_friction_and_torques(talos, stand, rng):
    """M a + h = S tau + Jc^T f holds row by row; corner forces lie in their friction pyramids."""
    ctrl = WholeBodyController(talos)
    q, v = _perturbed_state(talos, rng)
    ctrl.reset(q, v)
    tau = ctrl.compute(0.0, q, v, stand)
    assert ctrl.last.ok
    data = talos.data()
    a = ctrl.acceleration()
    lhs = pin.rnea(talos.model, data, q, v, a)  # M a + h
    f = np.concatenate([c.reshape(-1) for c in ctrl.corner_forces().values()])
    rhs = ctrl.contact_jacobian_transpose() @ f
    rhs[6:] += tau
    np.testing.assert_allclose(lhs, rhs, atol=DYNAMICS_ATOL)
    mu = talos.profile.friction_coefficient * ctrl.settings.friction_scale
    for corners in ctrl.corner_forces().values():
        assert np.all(corners[:, 2] >= -FRICTION_ATOL)
        assert np.all(np.abs(corners[:, :2]) <= mu * corners[:, 2:3] + FRICTION_ATOL)
    assert np.all(np.abs(tau) <= talos.torque_limits + 1e-9)


def test_stance_feet_do_not_accelerate(talos, stand, rng):
    """The stance soles' classical accelerations follow the (small) Baumgarte feedback only."""
    ctrl = WholeBodyController(talos)
    q, v = talos.q_standing.copy(), np.zeros(talos.nv)
    ctrl.reset(q, v)
    ctrl.compute(0.0, q, v, stand)
    data = talos.data()
    pin.forwardKinematics(talos.model, data, q, v, ctrl.acceleration())
    for role in ("left_foot", "right_foot"):
        acc = pin.getFrameClassicalAcceleration(talos.model, data, talos.frame_id(role), pin.LOCAL)
        assert np.linalg.norm(acc.vector) < 1e-5


def test_torque_limits_are_enforced(talos, stand, rng):
    """With limits scaled to 30 %, no output torque exceeds the scaled limit."""
    ctrl = WholeBodyController(talos, WbcSettings(torque_scale=0.3))
    q, v = _perturbed_state(talos, rng)
    ctrl.reset(q, v)
    tau = ctrl.compute(0.0, q, v, stand)
    assert np.all(np.abs(tau) <= 0.3 * talos.torque_limits + 1e-9)


def test_qpsolvers_backend_matches_proxsuite(talos, arm, rng):
    """The same tick through qpsolvers' proxqp gives the same torques as the persistent solver."""
    q, v = _perturbed_state(talos, rng)
    taus = {}
    for backend in ("proxsuite", "proxqp"):
        ctrl = WholeBodyController(talos, WbcSettings(backend=backend))
        ctrl.reset(q, v)
        taus[backend] = ctrl.compute(0.5, q, v, arm)
    np.testing.assert_allclose(
        taus["proxqp"], taus["proxsuite"], atol=1e-2, err_msg="backend=proxqp"
    )


def test_unknown_backend_is_refused(talos):
    """A backend that is not installed raises ControllerError naming the available ones."""
    with pytest.raises(ControllerError, match="available: proxsuite"):
        WholeBodyController(talos, WbcSettings(backend="no-such-solver"))


def test_bad_settings_are_refused():
    """Negative weights are refused at construction."""
    with pytest.raises(ControllerError, match="com_weight"):
        WbcSettings(com_weight=-1.0)


def test_reference_interpolates_the_knots(talos, arm):
    """The dense reference passes through every knot and its velocity is the derivative of q."""
    ref = PlanReference(arm, talos, dt=0.001, zmp_margin=None)  # no balance filter
    for k in range(0, len(arm.t), 7):
        i = ref.index(float(arm.t[k]))
        np.testing.assert_allclose(ref.q[i], arm.q[k], atol=1e-9)
        np.testing.assert_allclose(ref.com[i], arm.com[k], atol=1e-9)
    i = ref.n // 3
    fd = pin.difference(talos.model, ref.q[i - 1], ref.q[i + 1]) / (2 * ref.dt)
    np.testing.assert_allclose(fd, ref.v[i], atol=1e-4)
    fd_a = (ref.v[i + 1] - ref.v[i - 1]) / (2 * ref.dt)
    np.testing.assert_allclose(fd_a[6:], ref.a[i, 6:], atol=1e-3)


def test_hand_task_pulls_the_hand_towards_its_reference(talos, arm):
    """With the hand 5 cm below its reference, the QP accelerates it upwards."""
    ctrl = WholeBodyController(talos)
    ref = ctrl.reference_for(arm)
    k = ref.n // 2
    q, v = ref.q[k].copy(), np.zeros(talos.nv)
    ctrl.reset(q, v)
    hand = talos.frame("right_hand")
    data = talos.data()
    pin.framesForwardKinematics(talos.model, data, q)
    ref.frames[hand].position[k] = data.oMf[talos.frame_id(hand)].translation + np.array(
        [0.0, 0.0, 0.05]
    )
    ctrl.compute(float(ref.times[k]), q, v, ref)
    pin.forwardKinematics(talos.model, data, q, v, ctrl.acceleration())
    acc = pin.getFrameClassicalAcceleration(
        talos.model, data, talos.frame_id(hand), pin.LOCAL_WORLD_ALIGNED
    ).linear
    assert acc[2] > 1.0  # kp 100 * 0.05 m = 5 m/s^2 asked, shared with the other tasks


def test_balance_filter_keeps_a_feasible_com_and_moves_an_infeasible_one(talos, arm):
    """A zero ZMP shift returns the plan's CoM exactly; a shifted ZMP is realized by the new CoM."""
    from planner.wbc.reference import balance_com, project_into_polygon

    ref = PlanReference(arm, talos, zmp_margin=None)
    same = balance_com(ref.plan_com, np.zeros((ref.n, 2)), ref.dt)
    np.testing.assert_allclose(same, ref.plan_com[:, :2], atol=1e-12)
    shift = np.zeros((ref.n, 2))
    shift[ref.n // 3 : 2 * ref.n // 3, 1] = 0.05  # move the ZMP 5 cm left for a third of the motion
    new = balance_com(ref.plan_com, shift, ref.dt)
    dt, c, z = ref.dt, ref.plan_com, ref.plan_com[:, 2]
    zmp = lambda xy: xy[1:-1] - (z[1:-1] / 9.81)[:, None] * (xy[2:] - 2 * xy[1:-1] + xy[:-2]) / dt**2  # noqa: E731
    moved = zmp(new) - zmp(c[:, :2])
    assert np.abs(moved - shift[1:-1]).max() < 1e-3  # [m], vertical CoM acceleration neglected here
    assert np.allclose(new[[0, -1]], c[[0, -1], :2])
    square = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])
    pts = np.array([[0.5, 0.2], [2.0, 0.0], [3.0, 3.0]])
    assert np.allclose(project_into_polygon(pts, square), [[0.5, 0.2], [1.0, 0.0], [1.0, 1.0]])


def test_balance_filter_moves_the_com_only_where_the_zmp_moved(talos, arm):
    """Filtered CoM: unchanged where no ZMP shift was needed around it, and within 3 cm of the plan."""
    ref = PlanReference(arm, talos)
    assert np.abs(ref.com - ref.plan_com).max() < 0.03  # [m]
    assert np.array_equal(ref.com[:, 2], ref.plan_com[:, 2])
    moved = np.abs(ref.zmp_shift).max(axis=1) > 0
    assert moved.any() and not moved.all()


def test_flight_landings_map_each_flight_sample_to_its_touchdown():
    """Samples of a flight (no active contact between two stances) know the flight's first sample
    and its touch-down sample; stances and a flight that never lands are not flights to land."""
    from planner.wbc.controller import _flight_landings

    active = np.array([[1, 1], [0, 1], [0, 0], [0, 0], [0, 1], [1, 1], [0, 0], [0, 0]], dtype=bool)
    assert _flight_landings(active) == {2: (2, 4), 3: (2, 4)}
    assert _flight_landings(np.zeros((3, 0), dtype=bool)) == {}


def test_flight_window_weighs_the_com_as_flight_com_weight_around_each_flight(g1):
    """The window of flight_com_weight: from `span` samples before a flight to `span` after its
    touch-down (none without a flight); away from flights a tick weighs the CoM rows com_weight."""
    from planner.wbc.controller import _flight_window

    active = np.array([[1, 1]] * 5 + [[0, 0]] * 3 + [[1, 1]] * 6 + [[0, 1]] * 2, dtype=bool)
    window = _flight_window(active, 2)
    np.testing.assert_array_equal(np.flatnonzero(window), np.arange(3, 11))  # 5-2 .. touch-down 8 + 2
    assert not _flight_window(active[:, :0], 2).any() and not _flight_window(active[:5], 2).any()
    plan = standing_plan(g1, duration=0.2)
    for w in (50.0, 7.0):
        ctrl = WholeBodyController(g1, WbcSettings(com_weight=w, flight_com_weight=3.0))
        ctrl.compute(0.0, plan.q[0], np.zeros(g1.nv), plan)
        np.testing.assert_allclose(ctrl._w_rows[:3], np.sqrt(w))
