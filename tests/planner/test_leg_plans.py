"""Leg motions planned on Talos (and G1's hop): the plans pass their own checks and, recomputed
with Pinocchio from ``plan.q``, do what the primitives promise (kick height and reach, lifts in
place, lunge depth, a ballistic one-foot flight). The quarter circle is planned and certified in
``tests/sim/test_leg_sims.py``."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from tasks.actions import Action
from tasks.compose import compile_actions
from tasks.primitives import standing_geometry

planner = pytest.importorskip("planner")

HARD_SLACK = 1e-4  # [m] solver tolerance on top of a HARD target's own tolerance


def _plan(robot, actions):
    from planner import CacheSettings, PlannerSettings

    spec = compile_actions(actions, robot)
    result = planner.plan(spec, robot, settings=PlannerSettings(cache=CacheSettings(compile=False)),
                          throw=False)
    assert result.ok, f"{spec.name}: {result.diagnosis}\n{result.summary()}"
    assert all(c.ok for c in result.checks), result.summary()
    return spec, result


def _frame(robot, q, role):
    data = robot.data()
    pin.framesForwardKinematics(robot.model, data, q)
    return data.oMf[robot.frame_id(role)]


def _knot(plan, t):
    return int(round(t / plan.dt))


def _phase_middles(spec, n_contacts):
    t, out = 0.0, []
    for p in spec.phases:
        if len(p.contacts) == n_contacts:
            out.append((p, t + 0.5 * p.duration))
        t += p.duration
    return out


@pytest.mark.long  # in make test-long: the 2-core suite stays under 10 minutes (~15 s); twin:
# tests/sim/test_leg_sims.py::test_kick_passes (the kick planned, then certified in MuJoCo)
def test_kick_plan(talos):
    """kick(right, forward, 0.15 m): at the target time the right sole is 0.15 m up and ahead
    (within the 2 cm tolerance), while the left sole stays where it stands."""
    spec, plan = _plan(talos, [Action(name="kick", params={"leg": "right", "height": 0.15})])
    (target,) = spec.targets
    q = plan.q[_knot(plan, target.time)]
    sole = _frame(talos, q, "right_foot").translation
    assert np.linalg.norm(sole - np.array(target.position)) <= target.tolerance + HARD_SLACK
    assert sole[2] >= 0.15 - target.tolerance - HARD_SLACK
    left0 = _frame(talos, talos.q_standing, "left_foot").translation
    for q in plan.q:
        assert np.linalg.norm(_frame(talos, q, "left_foot").translation - left0) <= 1e-4


@pytest.mark.slow
def test_march_plan(talos):
    """march(2, 0.1 m): at the middle of each single support the lifted sole (Pinocchio on plan.q)
    is at least 0.1 m up, alternating right, left (longer marches alternate on: tests/tasks/test_legs.py)."""
    spec, plan = _plan(talos, [Action(name="march", params={"count": 2, "height": 0.1})])
    lifted = []
    for phase, t in _phase_middles(spec, 1):
        up = "left_foot" if phase.contacts[0].frame == talos.frame("right_foot") else "right_foot"
        z = _frame(talos, plan.q[_knot(plan, t)], up).translation[2]
        assert z >= 0.1 - HARD_SLACK, phase.name
        lifted.append(up)
    assert lifted == ["right_foot", "left_foot"]


@pytest.mark.slow
def test_lunge_plan(talos):
    """lunge(left, forward, depth 0.1 m): the CoM (Pinocchio on plan.q) is 0.1 m below standing
    at the bottom, within its 2 cm tolerance, with the left sole 0.3 m ahead."""
    spec, plan = _plan(talos, [Action(name="lunge", params={"leg": "left", "depth": 0.1})])
    (bottom,) = [c for c in spec.com_targets if "lunge bottom" in c.name]
    q = plan.q[_knot(plan, bottom.time)]
    z = pin.centerOfMass(talos.model, talos.data(), q)[2]
    assert z == pytest.approx(standing_geometry(talos).com[2] - 0.1, abs=bottom.tolerance + HARD_SLACK)
    ahead = _frame(talos, q, "left_foot").translation - _frame(talos, talos.q_standing, "left_foot").translation
    assert ahead == pytest.approx([0.3, 0.0, 0.0], abs=1e-3)


def test_controller_reference_unwraps_past_a_half_turn():
    """Walking a circle turns the base past pi from its start: the controller's chart picks the
    rotation vector of the same rotation closest to the previous knot instead of jumping from
    +pi to -pi (and leaves vectors within a half turn untouched)."""
    from planner.wbc.reference import _unwrap

    prev = np.array([0.0, 0.01, 3.10])
    w = pin.log3(pin.exp3(np.array([0.0, 0.01, 3.25])))  # principal log: about -3.03 about z
    assert w[2] < 0
    u = _unwrap(w, prev)
    assert np.allclose(pin.exp3(u), pin.exp3(w), atol=1e-12)
    assert u[2] == pytest.approx(3.25, abs=1e-6) and np.linalg.norm(u - prev) < 0.2
    small = np.array([0.0, 0.0, 1.0])
    assert _unwrap(small, np.array([0.0, 0.0, 0.9])) is small


@pytest.mark.long  # in make test-long: the 2-core suite stays under 10 minutes (~19 s)
@pytest.mark.slow
def test_hop_plan_on_g1(g1):
    """hop(right, 1) on G1 (certified in MuJoCo, tests/sim/test_leg_sims.py): the plan passes its
    checks; during the flight no contact force acts,
    both soles (Pinocchio on plan.q) are off the ground and the CoM follows a ballistic arc
    (vertical acceleration -g within the finite-difference error); only the right sole pushes."""
    spec, plan = _plan(g1, [Action(name="hop", params={"foot": "right", "count": 1})])
    t, flight = 0.0, None
    for p in spec.phases:
        if not p.contacts:
            flight = (t, t + p.duration)
        t += p.duration
    assert flight is not None
    inside = [k for k, tk in enumerate(plan.t) if flight[0] + 1e-9 < tk < flight[1] - 1e-9]
    assert inside
    assert set(plan.forces) == {g1.frame("left_foot"), g1.frame("right_foot")}
    for frame, f in plan.forces.items():
        assert np.abs(f[inside]).max() <= 1e-6, frame
        if frame == g1.frame("left_foot"):
            pushing = [k for k, tk in enumerate(plan.t) if tk < flight[0] and np.linalg.norm(f[k]) > 1.0]
            assert pushing and max(pushing) < flight[0] / plan.dt - 10  # the left foot is off well before take-off
    for k in inside:
        for side in ("left_foot", "right_foot"):
            assert _frame(g1, plan.q[k], side).translation[2] > 0.0
    com_z = np.array([pin.centerOfMass(g1.model, g1.data(), plan.q[k])[2] for k in range(len(plan.t))])
    k0, k1 = int(round(flight[0] / plan.dt)), int(round(flight[1] / plan.dt))
    acc = np.diff(com_z[k0:k1 + 1], 2) / plan.dt**2
    assert acc == pytest.approx(-9.81, abs=0.5)
