"""Dynamic motions in MuJoCo: a planned 5 cm jump on Talos is certified, with a real flight.

Also the pieces that make it work, checked with numbers: the ballistic CoM reference of a
flight (planner.wbc.reference) and the torque bound of the jump primitive.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from planner import CacheSettings, PlannerSettings, plan
from planner.wbc.reference import PlanReference
from sim import simulate
from tasks.actions import Action
from tasks.compose import compile_actions
from tasks.exceptions import TaskDefinitionError
from tasks.primitives import jump

G = 9.81


@pytest.fixture(scope="module")
def jump_plan(talos):
    spec = compile_actions([Action(name="jump", params={"height": 0.05})], talos, dt=0.075)
    p = plan(spec, talos, settings=PlannerSettings(cache=CacheSettings(compile=False)))
    assert p.ok, p.summary()
    return p


def _flight(reference: PlanReference) -> np.ndarray:
    return np.nonzero(~reference.active.any(axis=1))[0]


def test_flight_reference_is_ballistic_and_reaches_take_off_speed(jump_plan, talos):
    """In flight the CoM reference falls at g; the take-off blend ends at the flight's speed."""
    ref = PlanReference(jump_plan, talos, dt=0.001)
    air = _flight(ref)
    assert len(air) > 150  # 0.225 s of flight
    np.testing.assert_allclose(ref.com_acceleration[air, 2], -G, atol=1e-9)
    i0 = air[0]  # the real take-off: half a knot interval after the last stance knot
    dt = float(jump_plan.t[1] - jump_plan.t[0])
    k_off = int(np.argmin(np.abs(jump_plan.t - (ref.times[i0] - dt / 2))))  # the last stance knot
    assert abs(jump_plan.t[k_off] + dt / 2 - ref.times[i0]) < 1e-3
    spec = jump_plan.spec
    assert not spec.phases[spec.phase_at(jump_plan.t[k_off] + 1e-6)].contacts  # the flight phase has begun
    # velocity continuous across take-off (1 ms samples)
    assert abs(ref.com_velocity[i0, 2] - ref.com_velocity[i0 - 1, 2]) < 0.05
    # the speed the plan's discrete flight has half a knot after its last stance knot
    v_half = (jump_plan.com[k_off + 1, 2] - jump_plan.com[k_off, 2]) / dt
    assert ref.com_velocity[i0, 2] == pytest.approx(v_half, abs=G * ref.dt)  # within a sample
    assert ref.com_velocity[i0, 2] > 0.8  # m/s
    # the flight is the parabola through the plan's own CoM at its flight and touch-down knots
    for t in (jump_plan.t[k_off + 1], ref.times[air[-1] + 1]):
        k = int(np.argmin(np.abs(jump_plan.t - t)))
        assert abs(jump_plan.t[k] - t) < 1e-6
        np.testing.assert_allclose(ref.plan_com[ref.index(t)], jump_plan.com[k], atol=1e-6)
    # no ZMP in flight (no vertical force): finite everywhere, the CoM itself there
    assert np.isfinite(ref.zmp).all()
    np.testing.assert_allclose(ref.zmp[air], ref.plan_com[air, :2])


def test_landing_blend_brakes_then_keeps_the_soles_loaded(jump_plan, talos):
    """After the touch-down the CoM reference first stops the fall at LANDING_BRAKE g, then rejoins
    the spline without asking the soles to pull: its vertical acceleration (second differences of
    the 1 ms positions, not the blend's own formula) never goes below -LANDING_UNLOAD g. Before,
    one 0.15 s Hermite asked for -1.3 g at its end (the soles unloaded to 4 % of the weight).
    Fast twin of tests/sim/test_faults.py's long pushed-jump test."""
    from planner.wbc.reference import FLIGHT_BLEND, LANDING_BLEND_MAX, LANDING_BRAKE, LANDING_UNLOAD

    ref = PlanReference(jump_plan, talos, dt=0.001)
    touch = int(_flight(ref)[-1]) + 1
    v_land = ref.com_velocity[touch - 1, 2]
    assert v_land < -0.5  # [m/s] a real fall to stop
    end = touch + int(round(LANDING_BLEND_MAX / ref.dt))
    z = ref.com[touch - 1 : end + 2, 2]
    acc = (z[2:] - 2 * z[1:-1] + z[:-2]) / ref.dt**2  # at samples touch .. end
    n_brake = int(-v_land / (LANDING_BRAKE * G) / ref.dt)
    assert n_brake > 40  # [ms] talos: 0.72 m/s at 1 g, 74 ms
    np.testing.assert_allclose(acc[1 : n_brake - 1], LANDING_BRAKE * G, atol=0.05)
    assert acc[1:].min() >= -LANDING_UNLOAD * G - 0.05
    np.testing.assert_allclose(ref.com_velocity[touch + n_brake + 1, 2], 0.0, atol=0.02)  # the fall stopped
    # the blend rejoins the spline within LANDING_BLEND_MAX, and no later than needed: it ends
    # after FLIGHT_BLEND and its last 10 ms step was the first that kept the soles loaded
    acc_all = np.diff(ref.com[:, 2], 2) / ref.dt**2
    assert np.abs(acc_all[end + 5 : end + 200]).max() < 3.0  # [m/s^2] back on the plan's gentle spline
    assert LANDING_BLEND_MAX > FLIGHT_BLEND


def test_jump_5cm_is_certified_with_a_real_flight(jump_plan, talos):
    """Tracked in MuJoCo: passes every check, both soles leave the floor, apex within 5 cm."""
    ex = simulate(jump_plan, talos)
    cert = ex.certificate
    assert cert.ok, cert.summary()
    assert cert.check("peak torque").value <= 98.0
    assert cert.check("CoM tracking error").value < 0.05
    airborne = np.all([np.abs(f[:, 2]) < 1e-6 for f in ex.contact_forces.values()], axis=0)
    assert airborne.sum() * ex.timestep > 0.1  # [s] of real flight
    rise = ex.com[:, 2].max() - ex.com[np.nonzero(airborne)[0][0], 2]
    assert rise > 0.03  # [m] CoM rise from the moment both soles left the floor


def test_jump_height_bounded_by_leg_torques(talos):
    """Talos: 15 cm passes the joint-speed check but its knees cannot push hard enough."""
    assert 0.05 <= jump.max_jump_height(talos) < 0.15
    with pytest.raises(TaskDefinitionError, match=r"jump height 0.15 m .* leg torques give at most") as info:
        jump.check({"height": 0.15, "forward": 0.0}, talos)
    assert f"ask for at most {jump.max_jump_height(talos):.2f} m" in str(info.value)
    jump.check({"height": jump.max_jump_height(talos), "forward": 0.0}, talos)  # accepted


@pytest.mark.slow
def test_talos_four_steps_forward_is_certified(talos):
    """4 steps of 0.15 m in MuJoCo: every check passes, the soles touch down when planned.

    Before the swing-clearance floor (planner.trajopt.centroidal.SWING_CLEARANCE) the plan put the
    swinging toe on the ground 0.15 s before its touch-down and the simulation reported an
    unplanned contact.
    """
    spec = compile_actions(
        [Action(name="step", params={"direction": "forward", "length": 0.15, "count": 4})], talos, dt=0.075
    )
    p = plan(spec, talos, settings=PlannerSettings(cache=CacheSettings(compile=False)))
    assert p.ok, p.summary()
    ex = simulate(p, talos)
    assert ex.certificate.ok, ex.certificate.summary()
    base_advance = ex.q[-1, 0] - ex.q[0, 0]
    assert base_advance == pytest.approx(0.6, abs=0.05)  # [m] the robot really walked


@pytest.mark.slow
@pytest.mark.parametrize(("action", "advance"), [
    (Action(name="step", params={"direction": "forward", "length": 0.15, "count": 4}), (0.6, 0.0)),
    (Action(name="turn", params={"angle": np.pi / 2}), (0.0, 0.0)),
    # make test-long (~6 s of CPU each, the 2-core suite's budget); twins: four steps forward and
    # the turn above, the same walking controller and certificate
    pytest.param(Action(name="walk", params={"direction": "backward", "distance": 0.4}), (-0.4, 0.0),
                 marks=pytest.mark.long),
    pytest.param(Action(name="walk", params={"direction": "left", "distance": 0.2}), (0.0, 0.2),
                 marks=pytest.mark.long),
], ids=["four_steps_forward", "turn_90_deg", "walk_backward", "walk_left"])
def test_g1_walk_and_turn_are_certified(g1, action, advance):
    """G1 with whole-body angular momentum in the plan: certified in MuJoCo, and the simulated
    base ends where the steps take it (``advance``, x forward and y left [m]).

    With the centroidal-only model the plan's full-dynamics ZMP left the soles by 15-17 cm and the
    CoM left its plan by 6.6-6.9 cm (limit 5 cm); now the plan's own ZMP stays in its support
    polygon and the simulation follows it. With that model `walk backward` fell at 3.6 s and `walk
    to the left` left the CoM 7.6 cm from its plan (docs/primitives.md); the planner now refuses
    those plans itself (two 0.20 m steps backward, G1's longest, and two 0.10 m side steps: contact
    moment 0.18-0.19 m from the full dynamics'). Both track within 1 cm now.
    """
    spec = compile_actions([action], g1, dt=0.075)
    p = plan(spec, g1, settings=PlannerSettings(cache=CacheSettings(compile=False)))
    assert p.ok, p.summary()
    ex = simulate(p, g1)
    assert ex.certificate.ok, ex.certificate.summary()
    assert ex.certificate.check("CoM tracking error").value < 0.04  # [m] it was 0.068 m
    assert not any(e.kind == "plan_zmp" for e in ex.events)
    moved = ex.q[-1, :2] - ex.q[0, :2]
    np.testing.assert_allclose(moved, advance, atol=0.05)  # [m] the robot really walked


@pytest.mark.slow
def test_g1_jump_5cm_is_certified_with_the_planned_take_off_momentum(g1):
    """G1 jumps 5 cm in MuJoCo: certified, and the body leaves the floor with about the plan's
    angular momentum (Pinocchio's A_g v on the simulated state against the reference's).

    Before: the plan folded the waist (93 % of its torque), the take-off reference first slowed
    the CoM and then asked for 2.5 g, and the controller had no momentum task; the body took off
    with 4.3-4.9 N m s of pitch momentum against the planned 1.4-1.9 and fell on landing.
    """
    spec = compile_actions([Action(name="jump", params={"height": 0.05})], g1, dt=0.075)
    p = plan(spec, g1, settings=PlannerSettings(cache=CacheSettings(compile=False)))
    assert p.ok, p.summary()
    waist = [g1.joint_names.index(n) for n in jump.torso_joints(g1)]
    assert np.abs(p.q[:, 7:][:, waist]).max() < 0.1  # [rad] the torso is held (it folded to 0.95)
    ex = simulate(p, g1)
    assert ex.certificate.ok, ex.certificate.summary()
    ref = PlanReference(p, g1, dt=ex.timestep)
    i0 = _flight(ref)[0]
    k = int(np.argmin(np.abs(ex.t - ref.times[i0])))
    h = pin.computeCentroidalMomentum(g1.model, g1.model.createData(), ex.q[k], ex.v[k]).angular
    assert np.abs(h - ref.angular_momentum[i0]).max() < 1.2  # [N m s] it was 3.1 (pitch)
    airborne = np.all([np.abs(f[:, 2]) < 1e-6 for f in ex.contact_forces.values()], axis=0)
    assert airborne.sum() * ex.timestep > 0.1  # [s] of real flight


@pytest.mark.parametrize("early", [True, False])
def test_flight_sole_reference_starts_when_the_controller_flight_does(jump_plan, talos, early):
    """The controller's flight starts half a knot after the plan's lift-off knot (the stance is
    held until the reference's take-off). With ``early_touchdown`` the soles' references replay
    the plan's path from the lift-off knot over that shorter flight: at the controller's first
    flight sample each sole reference is the plan's sole at the lift-off knot (forward kinematics
    of the plan's configuration, on the floor), not the spline's point half a knot later (already
    off the floor), and the touch-down pose is unchanged. Without it the spline is kept."""
    from planner.wbc import WbcSettings
    from planner.wbc.controller import WholeBodyController

    ctrl = WholeBodyController(talos, WbcSettings(early_touchdown=early))
    ref = ctrl.reference_for(jump_plan)
    ctrl.reset(jump_plan.q[0], np.zeros(talos.model.nv))
    ctrl.compute(0.0, jump_plan.q[0], np.zeros(talos.model.nv), ref)  # builds the stacked references
    air = _flight(ref)
    a, touch = int(air[0]), int(air[-1]) + 1
    dt = float(jump_plan.t[1] - jump_plan.t[0])
    k_off = int(np.argmin(np.abs(jump_plan.t - (ref.times[a] - dt / 2))))
    data = talos.model.createData()
    pin.framesForwardKinematics(talos.model, data, jump_plan.q[k_off])
    for i, name in enumerate(ref.contact_frames):
        lift = data.oMf[talos.model.getFrameId(name)].translation
        spline = ref.frames[name].position[a]
        assert spline[2] - lift[2] > 0.002  # the spline is already 2 mm+ up at the controller's flight start
        got = ctrl._ref_pos[a, 1 + i]
        if early:
            np.testing.assert_allclose(got, lift, atol=5e-4)
        else:
            np.testing.assert_allclose(got, spline, atol=1e-12)
        np.testing.assert_allclose(ctrl._ref_pos[touch, 1 + i], ref.frames[name].position[touch], atol=1e-12)
