"""Leg motions (kick, march, walk_arc, hop, lunge, stomp, jog): the specs they compile to on each
robot, their parameters and ranges, and their refusals in task terms."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

from tasks.actions import REGISTRY, Action
from tasks.compose import compile_actions
from tasks.exceptions import BeyondCapability, TaskDefinitionError
from tasks.footsteps import standing_feet
from tasks.primitives import PRIMITIVES, robot_limits, standing_geometry, to_knot
from tasks.primitives.gait import ARC_STEP_FRACTION, ARC_TURN_MAX, leg_length
from tasks.primitives.hop import JOG_MARGIN, ONE_LEG_MARGIN, one_leg_push
from tasks.primitives.jump import TORQUE_MARGIN, G, takeoff_speeds
from tasks.primitives.legs import KICK_HEIGHT_FRACTION, KICK_REACH_FRACTION
from tasks.serialize import spec_from_json, spec_to_json
from wbmp.errors import ExitCode, classify

LEGS = ("kick", "march", "walk_arc", "hop", "lunge", "stomp", "jog")
ONE_LEG_PUSH = ("hop", "jog")  # refused on robots whose single leg cannot push off


def _spec(robot, name, **params):
    return compile_actions([Action(name=name, params=params)], robot)


def _on_grid(spec):
    t = 0.0
    for p in spec.phases:
        to_knot(p.duration, spec.dt)
        t += p.duration
        to_knot(round(t, 9), spec.dt)
    for item in (*spec.targets, *spec.com_targets):
        for t in (item.time,) if item.time is not None else item.window:  # a target holds at a time or over a window
            to_knot(t, spec.dt)


def _sole(robot, spec, phase, side):
    (c,) = [c for c in phase.contacts if c.frame == robot.frame(f"{side}_foot")]
    return np.array(c.placement.position), c.placement.rpy[2]


def test_registry_order_and_parameters():
    """The leg motions follow jump in the registry, every float has a unit and a range, and
    their defaults lie in those ranges."""
    names = list(REGISTRY)
    i = names.index("jump")
    assert names[i + 1:i + 1 + len(LEGS)] == list(LEGS)
    for name in LEGS:
        assert name in PRIMITIVES
        for p in REGISTRY[name].params:
            if p.kind == "float":
                assert p.unit in ("m", "s", "rad") and p.minimum is not None and p.maximum is not None
                assert p.default is None or p.minimum <= p.default <= p.maximum
    with pytest.raises(TaskDefinitionError, match="kick height 2 m is above the maximum 1 m"):
        Action(name="kick", params={"height": 2.0})
    with pytest.raises(TaskDefinitionError, match="kick direction must be one of forward, side"):
        Action(name="kick", params={"direction": "up"})
    with pytest.raises(TaskDefinitionError, match="walk_arc angle 7 rad is above the maximum"):
        Action(name="walk_arc", params={"angle": 7.0})


@pytest.mark.parametrize("name", LEGS)
@pytest.mark.parametrize("robot_name", ["talos", "g1", "romeo", "icub"])
def test_defaults_compile_or_are_refused_in_task_terms(name, robot_name):
    """With default parameters each leg motion compiles on every built-in robot (phases and
    targets on the knot grid, exact JSON round trip), except the one-leg push-offs on the robots
    whose leg cannot, which are refused naming the robot, the leg's joint and the numbers."""
    from robots import load_robot

    robot = load_robot(robot_name)
    margin = {"hop": ONE_LEG_MARGIN, "jog": JOG_MARGIN}.get(name)
    if margin is not None and not one_leg_push(robot, G * 2 * 0.075 / 2).within(margin):
        with pytest.raises(TaskDefinitionError, match=rf"{robot_name} cannot (hop|jog)") as e:
            _spec(robot, name)
        assert "m/s^2" in str(e.value) and "torque limit" in str(e.value) and "\n" not in str(e.value)
        return
    spec = _spec(robot, name)
    assert spec_from_json(spec_to_json(spec)) == spec
    _on_grid(spec)
    assert spec.dynamic


@pytest.mark.parametrize("foot", ["left", "right"])
def test_a_refused_hop_names_a_joint_of_the_hopping_leg(talos, foot):
    """Talos cannot hop: the refusal names the limiting joint of the leg it was asked to hop on
    (the two-leg estimate finds one of either leg; its mirror is the same joint on the other side)."""
    import re

    with pytest.raises(BeyondCapability, match="talos cannot hop on one foot") as e:
        compile_actions([Action(name="hop", params={"foot": foot})], talos)
    (joint,) = re.findall(r"\((\S+) torque limit\)", str(e.value))
    assert talos.model.existJointName(joint) and f"_{foot}_" in joint


@pytest.mark.long  # in make test-long: the 2-core suite stays under 10 minutes (~19 s)
def test_one_leg_push_is_half_of_two(talos, g1):
    """One leg's static push is half the two-leg force. Talos' knee would need 0.60 of it for the
    shortest flight: refused for hops and jogs, with the numbers. G1's needs 0.24: within the hop
    margin (its hop passed the MuJoCo certificate, tests/sim/test_leg_sims.py) but not within the
    jog margin (its jog failed the certificate); the next hop height (a 3-knot flight) needs 0.45
    and is refused."""
    for robot, ratio in ((talos, 0.60), (g1, 0.24)):
        p = one_leg_push(robot, 0.736)
        bottom = min(takeoff_speeds(robot), key=lambda s: abs(s.com_drop - p.depth))
        assert p.available == pytest.approx((bottom.push_acceleration + G) / 2 - G)
        assert p.needed / p.available == pytest.approx(ratio, abs=0.01)
        assert p.feasible is (robot is g1) and p.within(ONE_LEG_MARGIN) is (robot is g1)
        assert not p.within(JOG_MARGIN)
    assert not one_leg_push(g1, G * 3 * 0.075 / 2).feasible
    assert "g1 cannot hop" not in robot_limits(g1)["hop"].get("count", "")
    assert "at most 0.03 m per hop and 2 hops forward on g1" in robot_limits(g1)["hop"]["forward"]
    assert "talos cannot hop" in robot_limits(talos)["hop"]["count"]
    for robot in (talos, g1):
        assert f"{robot.name} cannot jog" in robot_limits(robot)["jog"]["count"]
    with pytest.raises(TaskDefinitionError, match=r"a 0.05 m rise .* at most about 0.25 x 8.8 m/s\^2 .*ask for a lower hop"):
        _spec(g1, "hop", height=0.05)
    with pytest.raises(TaskDefinitionError, match=r"at most about 0.2 x 16.1 m/s\^2 .*g1 cannot jog or run; walk instead"):
        _spec(g1, "jog")


@pytest.mark.parametrize(("params", "message"), [
    ({"forward": 0.1}, r"hopping forward 0.1 m a hop on one foot is beyond the 0.03 m a hop certified in simulation "
                       r".*ask for \"hop forward 3 cm\" or hop in place"),
    ({"forward": 0.031, "count": 1}, r"beyond the 0.03 m a hop certified"),
    ({"forward": 0.2}, r"hopping forward 0.2 m a hop .* beyond the 0.03 m a hop"),  # not "ask for 0.10 m" (g1's stride)
    ({"forward": 0.03, "count": 3}, r"hopping forward 3 times on one foot is beyond the 2 forward hops certified "
                                    r"in simulation .*ask for 2 hops forward, or hop in place 3 times"),
    ({"forward": 0.01, "count": 10}, r"hopping forward 10 times"),
])
def test_forward_hops_beyond_the_certified_ones_are_refused(g1, params, message):
    """G1's forward hops are certified up to HOP_FORWARD_MAX = 0.03 m a hop and
    HOP_FORWARD_COUNT_MAX = 2 hops (tests/sim/test_leg_sims.py); beyond either, in distance or
    in count, the hop is refused as infeasible (exit 4) in one line naming the limit and what to
    ask instead; at the limits (and in place, any count) it compiles."""
    with pytest.raises(BeyondCapability, match=message) as e:
        _spec(g1, "hop", **params)
    assert "\n" not in str(e.value)
    assert classify(e.value) == ExitCode.INFEASIBLE
    for ok in ({"forward": 0.03, "count": 2}, {"forward": 0.03, "count": 1}, {"count": 10}):
        flights = [p for p in _spec(g1, "hop", **ok).phases if not p.contacts]
        assert len(flights) == ok["count"]


@pytest.mark.parametrize("robot_name", ["talos", "g1"])
def test_jog_and_run_are_refused_on_every_robot_as_infeasible(request, robot_name):
    """No robot is certified to jog (JOG_MARGIN): "jog in place", "run" and 原地慢跑 are refused
    as infeasible (exit 4) in one line naming the leg's push and its joint (romeo and icub: the
    defaults test)."""
    from language import parse

    robot = request.getfixturevalue(robot_name)
    for sentence in ("jog in place", "run", "原地慢跑", "run forward 1 meter"):
        with pytest.raises(BeyondCapability, match=rf"one of {robot_name}'s legs gives .* torque limit\); "
                                                   rf"{robot_name} cannot jog or run; walk instead") as e:
            compile_actions(parse(sentence).actions, robot)
        assert "\n" not in str(e.value) and classify(e.value) == ExitCode.INFEASIBLE


@pytest.fixture
def one_leg_flights_allowed(monkeypatch):
    """The two-leg margin for one-leg flights and no forward limit: G1's jog and longer forward hops compile
    (their structure is tested although G1 refuses them by default, see
    test_one_leg_push_is_half_of_two)."""
    import tasks.primitives.hop as hop

    monkeypatch.setattr(hop, "ONE_LEG_MARGIN", TORQUE_MARGIN)
    monkeypatch.setattr(hop, "JOG_MARGIN", TORQUE_MARGIN)
    monkeypatch.setattr(hop, "HOP_FORWARD_MAX", math.inf)
    monkeypatch.setattr(hop, "HOP_FORWARD_COUNT_MAX", 10)


@pytest.mark.parametrize(("direction", "axis"), [("forward", 0), ("side", 1)])
def test_kick_target(talos, direction, axis):
    """The kicking sole is asked (HARD) to be `height` above the ground and ahead/outwards at the
    middle of a phase where only the other sole is down, the CoM held over that sole."""
    spec = _spec(talos, "kick", leg="left", direction=direction, height=0.2)
    (t,) = spec.targets
    start = np.array(standing_feet(talos)[0].position)
    L = leg_length(talos)
    offset = np.array(t.position) - start
    assert offset[2] == pytest.approx(0.2)
    assert offset[axis] == pytest.approx(KICK_REACH_FRACTION * L if axis == 0 else 0.15 * L)
    assert offset[1 - axis] == pytest.approx(0.0, abs=1e-9)
    one = [p for p in spec.phases if len(p.contacts) == 1]
    assert len(one) == 1 and one[0].contacts[0].frame == talos.frame("right_foot")
    t0 = sum(p.duration for p in spec.phases[:spec.phases.index(one[0])])
    assert t0 < t.time < t0 + one[0].duration
    (over,) = [c for c in spec.com_targets if "over the right sole" in c.name]  # held while on one foot
    assert over.window == pytest.approx((t0, t0 + one[0].duration))


def test_leg_length_against_pinocchio(talos, g1):
    """Leg length = hip joint height above the sole at standing (independent: the hip joint
    named in the URDF)."""
    for robot, hip in ((talos, "leg_left_1_joint"), (g1, "left_hip_pitch_joint")):
        data = robot.data()
        pin.framesForwardKinematics(robot.model, data, robot.q_standing)
        z = data.oMi[robot.model.getJointId(hip)].translation[2]
        sole = data.oMf[robot.frame_id("left_foot")].translation[2]
        assert leg_length(robot) == pytest.approx(z - sole, abs=0.01)
    with pytest.raises(TaskDefinitionError, match=r"kick height 0.3 m is beyond talos's 0.22 m"):
        _spec(talos, "kick", height=0.3)
    assert KICK_HEIGHT_FRACTION * leg_length(talos) == pytest.approx(0.224, abs=0.005)


@pytest.mark.parametrize(("name", "params", "order"), [
    ("march", {"count": 5, "height": 0.1}, ["right", "left", "right", "left", "right"]),
    ("stomp", {"leg": "left", "count": 3, "height": 0.12}, ["left", "left", "left"]),
])
def test_lifts_in_place(g1, name, params, order):
    """Each lift is a single support on the other foot with the lifted sole clearing `height`;
    every contact stays at the standing placement; the feet alternate (march) or not (stomp)."""
    spec = _spec(g1, name, **params)
    one = [p for p in spec.phases if len(p.contacts) == 1]
    lifted = ["left" if p.contacts[0].frame == g1.frame("right_foot") else "right" for p in one]
    assert lifted == order
    assert all(p.swing_height == pytest.approx(params["height"]) for p in one)
    stand = {s: np.array(p.position) for s, p in zip(("left", "right"), standing_feet(g1), strict=True)}
    for p in spec.phases:
        for c in p.contacts:
            side = "left" if c.frame == g1.frame("left_foot") else "right"
            assert np.allclose(c.placement.position, stand[side], atol=1e-12)
    with pytest.raises(TaskDefinitionError, match=rf"{name} height 0.3 m is beyond g1's 0.20 m"):
        _spec(g1, name, height=0.3)


@pytest.mark.parametrize("robot_name", ["talos", "g1"])
@pytest.mark.parametrize(("side", "angle"), [("left", 2 * math.pi), ("right", math.pi / 2)])
def test_walk_arc_feet_on_their_circles(robot_name, side, angle, request):
    """Every foot placement stays on its own circle about the centre, turns with it, and the
    steps respect the limits; a full circle ends where it started."""
    robot = request.getfixturevalue(robot_name)
    r = 0.6
    spec = _spec(robot, "walk_arc", radius=r, side=side, angle=angle)
    left, right = (np.array(p.position) for p in standing_feet(robot))
    w = float(np.linalg.norm(left - right))
    sign = 1.0 if side == "left" else -1.0
    center = 0.5 * (left + right) + np.array([0.0, sign * r, 0.0])
    radius = {"left": r - sign * w / 2, "right": r + sign * w / 2}
    last = {}
    for p in spec.phases:
        for s in ("left", "right"):
            if any(c.frame == robot.frame(f"{s}_foot") for c in p.contacts):
                pos, yaw = _sole(robot, spec, p, s)
                assert np.linalg.norm((pos - center)[:2]) == pytest.approx(radius[s], abs=1e-9)
                if s in last:
                    step = np.linalg.norm((pos - last[s][0])[:2])
                    assert step <= 2 * ARC_STEP_FRACTION * robot.profile.step_length_max + 1e-9
                last[s] = (pos, yaw)
    for p in spec.phases:
        if len(p.contacts) == 2:
            yaws = [c.placement.rpy[2] for c in p.contacts]
            assert abs(math.remainder(yaws[0] - yaws[1], 2 * math.pi)) <= ARC_TURN_MAX + 1e-9
    end = spec.phases[-1]
    for s, start in (("left", left), ("right", right)):
        pos, yaw = _sole(robot, spec, end, s)
        expect = center + np.array([[math.cos(sign * angle), -math.sin(sign * angle), 0],
                                    [math.sin(sign * angle), math.cos(sign * angle), 0], [0, 0, 1]]) @ (start - center)
        assert pos == pytest.approx(expect, abs=1e-9)
        assert math.remainder(yaw - sign * angle, 2 * math.pi) == pytest.approx(0.0, abs=1e-9)
    with pytest.raises(TaskDefinitionError, match=rf"walk_arc radius 0.15 m is below {robot_name}'s"):
        _spec(robot, "walk_arc", radius=0.15)


def test_walk_arc_then_step_follows_the_new_heading(talos):
    """After a quarter circle to the left, 'forward' is world +y."""
    spec = compile_actions([Action(name="walk_arc", params={"angle": math.pi / 2}),
                            Action(name="step", params={"direction": "forward", "length": 0.1, "count": 1})], talos)
    end = spec.phases[-1].contacts
    arc_end = [p for p in spec.phases if p.name.startswith("1 walk_arc") and len(p.contacts) == 2][-1].contacts
    moved = np.array(end[0].placement.position) - np.array(arc_end[0].placement.position)
    assert moved[:2] == pytest.approx([0.0, 0.1], abs=1e-9)


@pytest.mark.parametrize(("direction", "axis", "sign"), [("forward", 0, 1.0), ("side", 1, -1.0)])
def test_lunge(g1, direction, axis, sign):
    """The right foot steps out by the robot's longest step, the CoM goes `depth` down (HARD) with
    both feet on the ground, and the foot comes back; too long or too deep is refused."""
    spec = _spec(g1, "lunge", leg="right", direction=direction, depth=0.12)
    start = np.array(standing_feet(g1)[1].position)
    out = [p for p in spec.phases if len(p.contacts) == 2 and "lunge down" in p.name]
    assert len(out) == 1
    pos, _ = _sole(g1, spec, out[0], "right")
    limit = 0.20 if direction == "forward" else 0.10
    assert (pos - start)[axis] == pytest.approx(sign * limit)
    (bottom,) = [c for c in spec.com_targets if "lunge bottom" in c.name]
    assert bottom.position[2] == pytest.approx(standing_geometry(g1).com[2] - 0.12)
    t0 = sum(p.duration for p in spec.phases[:spec.phases.index(out[0])])
    assert t0 < bottom.time < t0 + out[0].duration
    end = spec.phases[-1]
    assert _sole(g1, spec, end, "right")[0] == pytest.approx(start)
    with pytest.raises(TaskDefinitionError, match="lunge length 0.3 m is beyond g1's longest"):
        _spec(g1, "lunge", direction=direction, length=0.3)
    with pytest.raises(TaskDefinitionError, match="lunge depth 0.3 m is beyond g1's reachable 0.25 m"):
        _spec(g1, "lunge", depth=0.3)


def test_hop_on_g1(g1, one_leg_flights_allowed):
    """G1 hops on its left foot: `count` flights without contact of at least two knots, only the
    left sole down from the lift to the recovery, landings `forward` ahead, push-off targets."""
    spec = _spec(g1, "hop", foot="left", count=3, forward=0.05)
    flights = [p for p in spec.phases if not p.contacts]
    assert len(flights) == 3 and all(p.duration >= 2 * spec.dt - 1e-9 for p in flights)
    i0 = next(i for i, p in enumerate(spec.phases) if len(p.contacts) == 1)
    i1 = max(i for i, p in enumerate(spec.phases) if len(p.contacts) == 1)
    x0 = standing_feet(g1)[0].position[0]
    xs = []
    for p in spec.phases[i0:i1 + 1]:
        assert all(c.frame == g1.frame("left_foot") for c in p.contacts)
        if p.contacts:
            xs.append(p.contacts[0].placement.position[0] - x0)
    assert sorted(set(np.round(xs, 9))) == pytest.approx([0.0, 0.05, 0.10, 0.15])
    assert len([c for c in spec.com_targets if c.name.endswith("take-off")]) == 3
    with pytest.raises(TaskDefinitionError, match="hop forward 0.2 m is beyond g1's 0.10 m"):
        _spec(g1, "hop", forward=0.2)


def test_jog_on_g1(g1, one_leg_flights_allowed):
    """G1 jogs: `count` flights between single supports that alternate feet, in place by default;
    `forward` moves both feet that far; a stride beyond half the longest step is refused."""
    spec = _spec(g1, "jog", count=4)
    flights = [i for i, p in enumerate(spec.phases) if not p.contacts]
    assert len(flights) == 4
    before = [spec.phases[i - 1].contacts[0].frame for i in flights]
    after = [spec.phases[i + 1].contacts[0].frame for i in flights]
    assert before[1:] == after[:-1] and all(b != a for b, a in zip(before, after, strict=True))
    stand = [np.array(p.position) for p in standing_feet(g1)]
    for c in spec.phases[-1].contacts:
        assert any(np.allclose(c.placement.position, s, atol=1e-12) for s in stand)
    moved = _spec(g1, "jog", count=4, forward=0.3).phases[-1].contacts
    for c, s in zip(moved, stand, strict=True):
        assert np.array(c.placement.position) - s == pytest.approx([0.3, 0.0, 0.0], abs=1e-9)
    with pytest.raises(TaskDefinitionError, match="take at least 5 strides"):
        _spec(g1, "jog", count=4, forward=0.5)
