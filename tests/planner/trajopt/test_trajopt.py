"""Plans checked against their constraints with Pinocchio numerics; failures explained in task terms."""

from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest

from planner import CacheSettings, PlannerSettings, SolverSettings, plan
from planner.exceptions import PlanningFailed
from robots import FrameNotFound
from tasks.specs import CoMBounds, Phase, Priority
from tests.planner.planning_cases import assert_plan_meets_spec, reach_spec, squat_spec

# Built in memory only: the disk cache has its own tests (test_cache.py).
SETTINGS = PlannerSettings(cache=CacheSettings(compile=False))


@pytest.fixture(scope="module")
def talos_squat(talos):
    spec = squat_spec(talos, 0.15)
    return spec, plan(spec, talos, settings=SETTINGS)


def test_talos_squat_meets_its_constraints(talos, talos_squat):
    """A 3 s, 15 cm squat on Talos: soles held to 1 mm / 1 mrad, CoM inside the shrunk polygon,
    limits held, CoM at the target depth at mid-motion, in at most 20 iterations."""
    spec, result = talos_squat
    assert result.ok, result.summary()
    worst = assert_plan_meets_spec(result, talos, spec)
    assert worst["contact_pos"] < 1e-6 and worst["contact_rot"] < 1e-6
    assert result.stats.iterations <= 20
    k = int(round(1.5 / result.dt))
    assert result.com[0, 2] - result.com[k, 2] == pytest.approx(0.15, abs=0.0101)


def test_talos_reach_meets_its_constraints(talos):
    """The right hand reaches a point 15 cm forward, 20 cm up, within its 1 cm tolerance at t = 1.5 s."""
    spec = reach_spec(talos, (0.15, -0.05, 0.2))
    result = plan(spec, talos, settings=SETTINGS)
    assert result.ok, result.summary()
    assert_plan_meets_spec(result, talos, spec)
    assert result.stats.iterations <= 20


def test_g1_squat_and_reach_meet_their_constraints(g1):
    """The same two tasks on the Unitree G1 (smaller soles, different kinematics)."""
    for spec in (squat_spec(g1, 0.08), reach_spec(g1, (0.1, -0.05, 0.1))):
        result = plan(spec, g1, settings=SETTINGS)
        assert result.ok, result.summary()
        assert_plan_meets_spec(result, g1, spec)


def test_constraint_report_lists_every_group(talos_squat):
    """The report has a row per stance sole (position [m] and orientation [rad]), the CoM polygon,
    the CoM target and joint position/velocity limits, each with unit and time."""
    _, result = talos_squat
    names = {c.name: c for c in result.checks}
    for expected, unit in [("left_foot contact position", "m"), ("left_foot contact orientation", "rad"),
                           ("right_foot contact position", "m"), ("CoM bound 'balance' support polygon", "m"),
                           ("CoM target 'bottom'", "m"), ("joint position limits", "rad"),
                           ("joint velocity limits", "rad/s")]:
        assert names[expected].unit == unit
        assert 0.0 <= names[expected].time <= 3.0
    assert "solved" in result.summary() and "build" in result.summary()


def test_soft_target_becomes_a_cost(talos):
    """A SOFT hand target is approached (not reached exactly) and does not fail the plan."""
    spec = reach_spec(talos, (0.1, 0.0, 0.1))
    soft = dataclasses.replace(spec.targets[0], priority=Priority.SOFT, weight=50.0)
    spec = dataclasses.replace(spec, targets=(soft,))
    result = plan(spec, talos, settings=SETTINGS)
    assert result.ok
    err = next(c for c in result.checks if "reach" in c.name).violation
    assert 0.0 < err < 0.14  # closer than the start (0.141 m away), not necessarily within 1 cm


def test_out_of_range_reach_names_hand_time_and_distance(talos):
    """A point 1.4 m ahead is out of reach: PlanningFailed names the hand, the time and the gap."""
    spec = reach_spec(talos, None, absolute=(1.4, -0.3, 1.0))
    with pytest.raises(PlanningFailed) as err:
        plan(spec, talos, settings=SETTINGS)
    message = err.value.diagnosis
    assert "right_hand target 'reach'" in message and "t = 1.50 s" in message
    gap = float(re.search(r"is ([0-9.]+) m beyond reach", message).group(1))
    assert 0.1 < gap < 0.6
    assert err.value.plan is not None and not err.value.plan.ok


def test_too_large_margin_names_the_bound_and_phase(g1):
    """A 0.3 m margin leaves no room in the G1's double-support polygon: the bound and phase are named."""
    spec = squat_spec(g1, 0.05, margin=0.3)
    result = plan(spec, g1, settings=SETTINGS, throw=False)
    assert not result.ok
    assert result.diagnosis.startswith("CoM bound 'balance' cannot hold in phase 'squat'")


def test_first_phase_must_match_standing(talos):
    """Contacts of the first phase away from the standing soles are refused with the distance."""
    spec = squat_spec(talos, 0.1)
    c0 = spec.phases[0].contacts[0]
    moved = dataclasses.replace(c0, placement=dataclasses.replace(c0.placement, position=(0.3, 0.085, 0.0)))
    spec = dataclasses.replace(spec, phases=(dataclasses.replace(spec.phases[0],
                                                                 contacts=(moved, spec.phases[0].contacts[1])),))
    with pytest.raises(PlanningFailed, match="contact left_foot in the first phase 'squat' is 0.300 m"):
        plan(spec, talos, settings=SETTINGS)


def test_unknown_frame_raises_frame_not_found(talos):
    """A target on a frame the robot lacks raises robots.FrameNotFound with a suggestion."""
    spec = reach_spec(talos, (0.1, 0.0, 0.0))
    spec = dataclasses.replace(spec, targets=(dataclasses.replace(spec.targets[0], frame="right_hnad"),))
    with pytest.raises(FrameNotFound, match="right_hnad"):
        plan(spec, talos, settings=SETTINGS)


def test_dynamic_squat_has_contact_forces(talos):
    """spec.dynamic=True adds contact forces (planner/centroidal.py): they carry the weight at rest."""
    spec = dataclasses.replace(squat_spec(talos, 0.1), dynamic=True)
    p = plan(spec, talos, settings=SETTINGS)
    assert p.ok, p.summary()
    total = sum(p.forces.values())  # starts and ends at rest: the mean force is the weight
    np.testing.assert_allclose(total[1:-1].mean(axis=0), [0.0, 0.0, talos.mass * 9.81], atol=1.0)
    assert any(c.name.endswith("friction cone") for c in p.checks)


def test_swing_foot_clears_the_ground(talos):
    """Standing on the left foot for a phase, the right sole rises to its swing height at mid-phase."""
    base = squat_spec(talos, 0.0)
    left, right = base.phases[0].contacts
    ds = Phase(name="shift", duration=1.0, contacts=(left, right))
    ss = Phase(name="stand on left", duration=1.2, contacts=(left,), swing_height=0.05)
    back = Phase(name="back", duration=1.2, contacts=(left, right))
    spec = dataclasses.replace(base, phases=(ds, ss, back), com_targets=(),
                               com_bounds=(CoMBounds(name="balance", margin=0.01),))
    result = plan(spec, talos, settings=SETTINGS)
    assert result.ok, result.summary()
    assert_plan_meets_spec(result, talos, spec)
    import pinocchio as pin

    data = talos.data()
    k = int(round(1.6 / result.dt))
    pin.framesForwardKinematics(talos.model, data, result.q[k])
    assert data.oMf[talos.frame_id("right_foot")].translation[2] >= 0.05 - 1e-6


def test_window_target_holds_on_every_knot(talos):
    """A hand target over a window is met at every knot of the window."""
    spec = reach_spec(talos, (0.1, 0.0, 0.1))
    target = dataclasses.replace(spec.targets[0], time=None, window=(1.2, 1.8), tolerance=0.02)
    spec = dataclasses.replace(spec, targets=(target,))
    result = plan(spec, talos, settings=SETTINGS)
    import pinocchio as pin

    data = talos.data()
    goal = np.array(target.position)
    for k in np.flatnonzero((result.t >= 1.2 - 1e-9) & (result.t <= 1.8 + 1e-9)):
        pin.framesForwardKinematics(talos.model, data, result.q[k])
        assert np.linalg.norm(data.oMf[talos.frame_id("right_hand")].translation - goal) <= 0.02


def test_frame_target_accepts_pinocchio_frame_names(talos):
    """A Pinocchio frame name works where a role name does."""
    spec = reach_spec(talos, (0.1, 0.0, 0.1))
    spec = dataclasses.replace(spec, targets=(dataclasses.replace(spec.targets[0], frame=talos.frame("right_hand")),))
    assert plan(spec, talos, settings=SETTINGS).ok


def test_unreachable_com_bound_names_the_bound_and_phase(talos):
    """A CoM box that needs the CoM 0.3 m above the ground mid-motion is infeasible: the diagnosis
    names the bound, the phase and how far the CoM stays outside."""
    spec = dataclasses.replace(squat_spec(talos, 0.0), com_targets=(), com_bounds=(
        CoMBounds(name="balance"),
        CoMBounds(name="low", upper=(None, None, 0.3), support_polygon=False, window=(1.4, 1.6))))
    result = plan(spec, talos, settings=SETTINGS, throw=False)
    assert not result.ok
    m = re.match(r"CoM bound 'low' cannot hold in phase 'squat': the CoM ends ([0-9.]+) m outside", result.diagnosis)
    assert m and float(m.group(1)) > 0.05, result.diagnosis


def test_nominal_warm_start_saves_iterations_and_keeps_the_optimum(talos, talos_squat):
    """Starting from the blended inverse-kinematics motion takes fewer iterations than starting
    from the standing posture, and lands on the same optimum."""
    spec, _ = talos_squat
    # without self-collision rows: the collision rounds add a solve each
    base = dataclasses.replace(SETTINGS, collision=dataclasses.replace(SETTINGS.collision, self_collision=False))
    nominal = plan(spec, talos, settings=base)
    standing = plan(spec, talos, settings=dataclasses.replace(base, solver=SolverSettings(warm_start="standing")))
    assert nominal.stats.iterations < standing.stats.iterations
    assert nominal.stats.objective == pytest.approx(standing.stats.objective, rel=1e-5)
    assert np.abs(nominal.q - standing.q).max() < 1e-3


def test_nominal_keyframe_meets_contacts_and_target(talos):
    """The inverse kinematics keyframe holds both soles (1 mm) and puts the CoM at the squat depth."""
    import pinocchio as pin

    from planner.trajopt.layout import make_layout
    from planner.trajopt.nominal import nominal_motion
    from planner.trajopt.symbolic import chart_to_configuration

    spec = squat_spec(talos, 0.15)
    lay = make_layout(spec, talos)
    dq = nominal_motion(lay)
    k = int(round(1.5 / lay.dt))
    q = chart_to_configuration(talos.model, lay.q_ref, dq[k])
    data = talos.data()
    pin.framesForwardKinematics(talos.model, data, q)
    for c in spec.phases[0].contacts:
        assert np.linalg.norm(data.oMf[talos.frame_id(c.frame)].translation - np.array(c.placement.position)) < 1e-3
    assert pin.centerOfMass(talos.model, data, q)[2] == pytest.approx(spec.com_targets[0].position[2], abs=1e-3)
    assert np.abs(dq[:2]).max() == 0.0 and np.array_equal(dq[-1], dq[-2])
