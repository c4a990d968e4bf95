"""The controller's centroidal angular-momentum task, against Pinocchio and finite differences."""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin
import pytest

from planner.wbc import ControllerError, WbcSettings, WholeBodyController
from sim.handmade import arm_plan


@pytest.fixture(scope="module")
def arm(g1):
    return arm_plan(g1, duration=2.0, dt=0.05)


def _states(robot, rng, n):
    """Random states near standing: joints and base rotated, arbitrary velocities."""
    for _ in range(n):
        dq = np.concatenate([np.zeros(3), 0.05 * rng.standard_normal(3), 0.2 * rng.standard_normal(robot.nv - 6)])
        yield pin.integrate(robot.model, robot.q_standing, dq), 0.5 * rng.standard_normal(robot.nv)


def test_momentum_rows_are_pinocchio_centroidal_map_and_its_drift(g1, arm, rng):
    """Rows = angular rows of A_g(q) (fresh Pinocchio data); drift = d/dt (A_g(q(t)) v) at fixed v
    by central differences; several ticks on one controller (no state accumulates over calls)."""
    model = g1.model
    ctrl = WholeBodyController(g1)
    for i, (q, v) in enumerate(_states(g1, rng, 3)):
        if i == 0:
            ctrl.reset(q, v)
        ctrl.compute(0.3 + 0.001 * i, q, v, arm)
        A, drift, _ = ctrl.angular_momentum_task()
        ag = pin.computeCentroidalMap(model, model.createData(), q)
        np.testing.assert_allclose(A, ag[3:], atol=1e-10)

        def h(s, q=q, v=v):
            return pin.computeCentroidalMap(model, model.createData(), pin.integrate(model, q, s * v))[3:] @ v

        eps = 1e-6
        fd = (h(eps) - h(-eps)) / (2 * eps)
        assert np.abs(drift).max() > 0.1  # [N m] not a vanishing term at these speeds
        np.testing.assert_allclose(drift, fd, atol=1e-6 * max(1.0, np.abs(fd).max()))


def test_momentum_task_brings_the_rate_of_angular_momentum_to_its_desired_value(g1, arm):
    """The QP's own solution (a, f): Pinocchio's rate of centroidal angular momentum for (q, v, a)
    is much closer to the task's desired rate with the task than without it."""
    model = g1.model
    q = g1.q_standing.copy()
    v = np.zeros(g1.nv)
    v[3:6] = [0.1, 0.3, 0.05]  # [rad/s] the whole body turning: a momentum error to correct
    gaps = {}
    for weight in (0.0, 100.0):
        ctrl = WholeBodyController(g1, dataclasses.replace(WbcSettings(), momentum_weight=weight))
        ctrl.reset(q, v)
        ctrl.compute(0.3, q, v, arm)
        assert ctrl.last.ok
        a = ctrl.acceleration()
        rate = pin.computeCentroidalMomentumTimeVariation(model, model.createData(), q, v, a).angular
        probe = WholeBodyController(g1, dataclasses.replace(WbcSettings(), momentum_weight=100.0))
        probe.reset(q, v)
        probe.compute(0.3, q, v, arm)
        desired = probe.angular_momentum_task()[2]
        gaps[weight] = float(np.linalg.norm(rate - desired))
    assert gaps[100.0] < 0.25 * gaps[0.0], gaps


def test_momentum_task_off_has_no_rows(g1, arm):
    ctrl = WholeBodyController(g1, dataclasses.replace(WbcSettings(), momentum_weight=0.0))
    ctrl.reset(g1.q_standing, np.zeros(g1.nv))
    ctrl.compute(0.0, g1.q_standing, np.zeros(g1.nv), arm)
    with pytest.raises(ControllerError, match="momentum task is off"):
        ctrl.angular_momentum_task()
