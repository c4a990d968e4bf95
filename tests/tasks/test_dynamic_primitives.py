"""step / walk / turn / jump primitives: the specs they compile to, and refusals in task terms."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

from tasks.actions import Action
from tasks.compose import compile_actions
from tasks.exceptions import TaskDefinitionError
from tasks.footsteps import standing_feet
from tasks.primitives import robot_limits
from tasks.primitives.geometry import standing_geometry
from tasks.primitives.jump import (
    TAKEOFF_MARGIN,
    G,
    _straight_up_speed,
    flight_time,
    max_jump_height,
    takeoff_speeds,
)


def _spec(robot, *actions, dt=0.075):
    return compile_actions([Action(name=n, params=p, overlay=o) for n, p, o in actions], robot, dt=dt)


def _on_grid(spec):
    t = 0.0
    for p in spec.phases:
        t += p.duration
        assert abs(t / spec.dt - round(t / spec.dt)) < 1e-6, f"phase {p.name!r} does not end on a knot"


@pytest.mark.parametrize("name", ["talos", "g1"])
def test_four_steps_forward_spec(name, request):
    """Dynamic spec, one sole down in 5 swing phases of equal whole-knot length, CoM ends between the moved feet."""
    robot = request.getfixturevalue(name)
    spec = _spec(robot, ("step", {"direction": "forward", "length": 0.15, "count": 4}, False))
    assert spec.dynamic
    _on_grid(spec)
    single = [p for p in spec.phases if len(p.contacts) == 1]
    assert len(single) == 5
    assert len({round(p.duration, 9) for p in single}) == 1
    assert single[0].duration == pytest.approx(round(robot.profile.step_duration / spec.dt) * spec.dt)
    end = spec.phases[-1].contacts
    x0 = standing_feet(robot)[0].position[0]
    assert [c.placement.position[0] - x0 for c in end] == pytest.approx([0.6, 0.6])
    (target,) = [t for t in spec.com_targets if "back over the feet" in t.name]
    com0 = standing_geometry(robot).com
    assert target.position[:2] == pytest.approx((com0[0] + 0.6, com0[1]))  # the standing CoM, carried 0.6 m


def test_turn_then_step_follows_the_new_heading(talos):
    """After turn(pi/2), 'forward' steps move along world +y."""
    spec = _spec(talos, ("turn", {"angle": math.pi / 2}, False), ("step", {"direction": "forward", "length": 0.1, "count": 2}, False))
    _on_grid(spec)
    end = {c.frame: c.placement for c in spec.phases[-1].contacts}
    start = standing_feet(talos)
    for side, p0 in zip(("left", "right"), start, strict=True):
        p = end[talos.frame(f"{side}_foot")]
        assert p.rpy[2] == pytest.approx(math.pi / 2)
        # the foot turned about the mid point, then moved 0.2 m along +y
        rotated = np.array([-p0.position[1], p0.position[0]])
        np.testing.assert_allclose(np.array(p.position[:2]) - rotated, [0.0, 0.2], atol=1e-9)


def test_sideways_and_walk_compile(g1):
    """Two side steps left: four single-support phases, left foot first; walk covers the distance."""
    spec = _spec(g1, ("step", {"direction": "left", "length": 0.08, "count": 2}, False))
    swings = [p.name for p in spec.phases if len(p.contacts) == 1]
    assert len(swings) == 4 and "left foot swings" in swings[0] and "right foot swings" in swings[1]
    walk = _spec(g1, ("walk", {"distance": 0.5, "direction": "backward"}, False))
    x0 = standing_feet(g1)[0].position[0]
    assert walk.phases[-1].contacts[0].placement.position[0] - x0 == pytest.approx(-0.5)


@pytest.mark.parametrize("name", ["talos", "g1"])
@pytest.mark.parametrize("dt", [0.05, 0.075])
def test_jump_spec(name, dt, request):
    """Crouch below standing, a whole-knot flight >= 2 sqrt(2h/g) without contacts, landing, CoM back up."""
    robot = request.getfixturevalue(name)
    h = 0.05
    spec = _spec(robot, ("jump", {"height": h}, False), dt=dt)
    assert spec.dynamic
    _on_grid(spec)
    names = [p.name.split(": ")[-1] for p in spec.phases]
    assert names == ["stand", "crouch", "push off", "flight", "landing", "recover", "stand"]
    flight = spec.phases[3]
    assert flight.contacts == ()
    assert flight.duration >= flight_time(h) - 1e-9 and flight.duration < flight_time(h) + dt
    assert G * flight.duration**2 / 8 >= h  # the ballistic rise is at least what was asked
    z0 = standing_geometry(robot).com[2]
    targets = {t.name.split(": ")[-1]: t for t in spec.com_targets}
    assert targets["crouch"].position[2] < z0 - 0.04
    assert targets["crouch"].position[2] >= z0 - robot.profile.squat_depth_max - 1e-9
    assert targets["landed and standing"].position[2] == pytest.approx(z0)
    t_flight0 = sum(p.duration for p in spec.phases[:3])
    assert t_flight0 < targets["flight apex"].time < t_flight0 + flight.duration


def test_forward_jump_moves_the_landing(talos):
    """jump(forward=0.1): landing and the last stand use soles 0.1 m ahead."""
    spec = _spec(talos, ("jump", {"height": 0.05, "forward": 0.1}, False))
    x0 = standing_feet(talos)[0].position[0]
    for p in spec.phases[4:]:
        assert [c.placement.position[0] - x0 for c in p.contacts] == pytest.approx([0.1, 0.1])
    for p in spec.phases[:3]:
        assert [c.placement.position[0] - x0 for c in p.contacts] == pytest.approx([0.0, 0.0])


def test_overlay_does_not_stretch_the_flight(talos):
    """Waving while jumping stretches the jump to the wave's length, never the flight."""
    alone = _spec(talos, ("jump", {"height": 0.06}, False))
    both = _spec(talos, ("jump", {"height": 0.06}, False), ("wave", {"repeat": 4, "duration": 1.0}, True))
    assert both.horizon > alone.horizon
    fl = [p.duration for p in both.phases if p.contacts == ()]
    assert fl == [p.duration for p in alone.phases if p.contacts == ()]


@pytest.mark.parametrize("name, best", [("talos", 1.92), ("g1", 3.69)])
def test_one_metre_jump_is_explained(name, best, request):
    """1 m needs 4.43 m/s at take-off; the message gives what the legs can do and what to ask for."""
    robot = request.getfixturevalue(name)
    with pytest.raises(TaskDefinitionError) as info:
        _spec(robot, ("jump", {"height": 1.0}, False))
    msg = str(info.value)
    assert "jump height 1 m needs a take-off speed of 4.43 m/s" in msg
    assert f"rise at about {best:.2f} m/s" in msg
    assert f"ask for at most {max_jump_height(robot):.2f} m" in msg
    # joint speeds bound it from above; the leg torques (push-off acceleration) may bound it lower
    assert max_jump_height(robot) <= (TAKEOFF_MARGIN * best) ** 2 / (2 * G) + 1e-9
    _spec(robot, ("jump", {"height": round(max_jump_height(robot) - 0.01, 2)}, False))  # just below is fine


def test_two_metre_step_and_far_forward_jump_are_refused(talos):
    """Step limits come from the profile, forward jumps' from the flight."""
    with pytest.raises(TaskDefinitionError, match="step length 2 m is beyond talos's 0.30 m"):
        _spec(talos, ("step", {"length": 2.0}, False))
    with pytest.raises(TaskDefinitionError, match="jump forward 1 m with a 0.05 m rise"):
        _spec(talos, ("jump", {"height": 0.05, "forward": 1.0}, False))  # talos's flights bound it below the step


def test_forward_jump_beyond_what_the_landing_absorbs_is_refused(talos):
    """'jump forward 30 cm' (a 5 cm rise: 0.20 s of flight, sqrt(8 h / g)) needs 1.49 m/s of forward
    take-off speed; beyond 0.5 m/s (0.10 m) it is refused with the numbers (it planned and failed
    the landing's dynamics check, exit 4); 0.10 m compiles."""
    T = 2.0 * np.sqrt(2.0 * 0.05 / 9.81)
    with pytest.raises(TaskDefinitionError) as info:
        _spec(talos, ("jump", {"height": 0.05, "forward": 0.3}, False))
    msg = str(info.value)
    assert f"needs a forward take-off speed of {0.3 / T:.2f} m/s" in msg
    assert "at most 0.10 m forward with that rise" in msg
    _spec(talos, ("jump", {"height": 0.05, "forward": 0.1}, False))
    limits = robot_limits(talos)
    assert "0.30 m forward" in limits["step"]["length"] and "0.15 m sideways" in limits["step"]["length"]
    assert limits["jump"]["height"].startswith(f"at most {max_jump_height(talos):.2f} m")


def test_a_robot_whose_forward_jumps_fell_refuses_them_and_jumps_in_place(g1, talos):
    """g1's profile says 0 m/s of forward take-off (every forward jump fell in MuJoCo, even 5 cm):
    "jump forward" (and 5 cm) is refused as beyond its capability (exit 4), a jump in place compiles;
    "jump forward" means 0.10 m, what talos's landing absorbs with a 5 cm rise, and compiles there."""
    from language import parse
    from tasks.exceptions import BeyondCapability

    assert g1.profile.jump_forward_speed_max == 0.0 and talos.profile.jump_forward_speed_max == 0.5
    for fwd in (0.05, 0.1):
        with pytest.raises(BeyondCapability, match="g1 cannot jump forward"):
            _spec(g1, ("jump", {"height": 0.05, "forward": fwd}, False))
    _spec(g1, ("jump", {"height": 0.05, "forward": 0.0}, False))
    (action,) = parse("jump forward").actions
    assert action.params["forward"] == pytest.approx(0.1)
    compile_actions([action], talos)


def test_takeoff_speed_estimate_is_a_real_motion(talos):
    """The estimate's joint velocities keep both soles still, hit one velocity limit, and deeper crouches are faster."""
    speeds = takeoff_speeds(talos)
    assert len(speeds) == int(talos.profile.squat_depth_max / 0.025 + 1e-9) + 1
    assert all(b.speed > a.speed for a, b in zip(speeds, speeds[1:]))
    assert all(b.com_drop > a.com_drop for a, b in zip(speeds, speeds[1:]))
    q = talos.q_standing
    model, data = talos.model, talos.data()
    pin.computeJointJacobians(model, data, q)
    pin.framesForwardKinematics(model, data, q)
    speed, joint = _straight_up_speed(talos, q)
    assert speed == pytest.approx(speeds[0].speed) and joint == speeds[0].limiting_joint
    # rebuild the motion: base straight up, legs compensating
    J = np.vstack([pin.getFrameJacobian(model, data, talos.frame_id(f"{s}_foot"), pin.ReferenceFrame.LOCAL_WORLD_ALIGNED) for s in ("left", "right")])
    base = np.zeros(6)
    base[:3] = pin.Quaternion(q[3:7]).matrix().T @ [0.0, 0.0, 1.0]  # world up, in the base frame
    legs = np.linalg.lstsq(J[:, 6:], -J[:, :6] @ base, rcond=None)[0]
    v = np.concatenate([base, legs])
    v *= 1.0 / np.max(np.abs(legs) / talos.velocity_limits[6:])
    np.testing.assert_allclose(J @ v, 0.0, atol=1e-9)
    assert np.max(np.abs(v[6:]) / talos.velocity_limits[6:]) == pytest.approx(1.0)
    assert (pin.jacobianCenterOfMass(model, data, q) @ v)[2] == pytest.approx(speed)
