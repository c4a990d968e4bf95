"""Spec-level behaviour of each primitive: where its targets are, when, and what it refuses."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given
from hypothesis import strategies as st

from tasks.actions import REGISTRY, Action
from tasks.compose import compile_actions, fit_actions
from tasks.exceptions import TaskDefinitionError
from tasks.primitives import PRIMITIVES, compile_action, standing_geometry, to_knot
from tasks.primitives import nominal_duration as nominal_duration_of
from tasks.primitives.posture import bowed_torso_rotation, raised_hand_position
from tasks.primitives.wave import wave_geometry
from tasks.serialize import spec_from_json, spec_to_json
from tasks.specs import Priority

# the actions on scene objects need a scene: tests/tasks/test_objects.py compiles them
AVAILABLE = sorted(n for n, p in PRIMITIVES.items()
                   if p.available and not p.dynamic and all(q.kind != "object" for q in REGISTRY[n].params))
PLACEHOLDERS = sorted(n for n, p in PRIMITIVES.items() if not p.available)
DEFAULT_PARAMS = {"reach": {"direction": "forward"}}


def _one(robot, name, **params):
    return compile_actions([Action(name=name, params={**DEFAULT_PARAMS.get(name, {}), **params})], robot)


def _targets(spec, contains):
    return [t for t in spec.targets if contains in t.name]


def test_every_registered_action_has_a_primitive():
    """The registry and the primitives cover the same names (the language layer relies on it)."""
    assert set(PRIMITIVES) == set(REGISTRY)
    assert not PLACEHOLDERS


@pytest.mark.parametrize("name", AVAILABLE)
@pytest.mark.parametrize("robot_name", ["talos", "g1", "romeo", "icub"])
def test_every_primitive_compiles_and_round_trips(name, robot_name):
    """Each available primitive compiles on each built-in robot (g1 has no neck) and the spec
    survives JSON exactly."""
    from robots import load_robot

    robot = load_robot(robot_name)
    if name in ("turn_head", "nod", "shake_head") and robot_name == "g1":
        with pytest.raises(TaskDefinitionError, match="g1 has no neck joint to (turn|nod|shake) its head"):
            _one(robot, name)
        return
    spec = _one(robot, name)
    assert spec_from_json(spec_to_json(spec)) == spec
    assert spec.robot == robot_name
    assert not spec.dynamic or name == "lean"  # a lean near the edge of the feet (icub's) is planned dynamically
    for p in spec.phases:
        assert to_knot(p.duration, spec.dt) >= 1
    for item in (*spec.targets, *spec.com_targets):
        for t in (item.time,) if item.window is None else item.window:
            assert t is not None and 0.0 < t <= spec.horizon + 1e-9
            to_knot(t, spec.dt)  # on the grid, raises otherwise


def test_squat_targets_depth_at_each_repetition(talos):
    """A 3-fold squat asks the CoM 0.2 m below standing at 3 bottoms and back up 3 times."""
    spec = _one(talos, "squat", depth=0.2, repeat=3, duration=1.5)
    z0 = standing_geometry(talos).com[2]
    bottoms = [c for c in spec.com_targets if "bottom" in c.name]
    tops = [c for c in spec.com_targets if "top" in c.name]
    assert len(bottoms) == len(tops) == 3
    for c in bottoms:
        assert c.position[:2] == (None, None) and c.position[2] == pytest.approx(z0 - 0.2)
        assert c.priority is Priority.HARD and c.tolerance == pytest.approx(0.01)
    for c in tops:
        assert c.position[2] == pytest.approx(z0)
    times = sorted(c.time for c in bottoms + tops)
    assert times == [c.time for c in sorted(bottoms + tops, key=lambda c: c.time)]
    # bottoms and tops alternate, 0.75 s apart (snapped to the 0.075 s grid)
    assert np.allclose(np.diff(times), 0.75, atol=spec.dt)
    assert all(len(p.contacts) == 2 for p in spec.phases)


@pytest.mark.parametrize(("robot_name", "depth", "limit"), [("talos", 0.5, 0.35), ("g1", 0.3, 0.25)])
def test_squat_beyond_the_robot_is_refused(robot_name, depth, limit):
    """A squat deeper than the profile's squat_depth_max names the robot and its limit."""
    from robots import load_robot

    with pytest.raises(TaskDefinitionError, match=f"squat depth {depth:g} m is beyond {robot_name}'s reachable {limit:g} m"):
        _one(load_robot(robot_name), "squat", depth=depth)


@pytest.mark.parametrize("arm", ["left", "right", "both"])
def test_wave_alternates_across_the_midline_above_the_shoulder(g1, arm):
    """repeat waves = 2 repeat + 1 swing targets alternating sides of the midline, all above the
    shoulder, at increasing times, plus a height band over the waving window."""
    spec = _one(g1, "wave", arm=arm, repeat=3)
    g = standing_geometry(g1)
    sides = ("left", "right") if arm == "both" else (arm,)
    for side in sides:
        w = wave_geometry(g, side)
        swings = sorted(_targets(spec, f"{side} hand swing"), key=lambda t: t.time)
        assert len(swings) == 7
        offsets = [float((np.array(t.position) - w["midline"]) @ w["outward"]) for t in swings]
        assert np.allclose(offsets, [(-1) ** (k + 1) * w["amplitude"] for k in range(7)])
        assert all(t.position[2] > g.position(f"{side}_shoulder")[2] + 0.05 for t in swings)
        assert np.all(np.diff([t.time for t in swings]) > 0)
        (band,) = _targets(spec, f"{side} hand above shoulder")
        assert band.axes == (False, False, True)
        assert band.window[0] <= swings[0].time and swings[-1].time <= band.window[1]
        assert band.position[2] - band.tolerance > g.position(f"{side}_shoulder")[2]
    other = {"left", "right"} - set(sides)
    assert not any(o in t.name for t in spec.targets for o in other)


def test_reach_target_is_in_the_base_frame(talos):
    """A base-frame point maps to the world by the base's standing position (heading axes)."""
    spec = _one(talos, "reach", hand="left", target=(0.4, 0.3, 0.2), direction=None)
    (t,) = _targets(spec, "reach point")
    base = standing_geometry(talos).position("base")
    assert np.allclose(t.position, base + np.array([0.4, 0.3, 0.2]))
    assert t.frame == talos.frame("left_hand") and t.window is not None and t.tolerance == pytest.approx(0.01)


@pytest.mark.parametrize(("direction", "axis"), [("forward", 0), ("left", 1), ("up", 2)])
def test_reach_direction_moves_from_the_standing_hand(g1, direction, axis):
    """reach(direction, distance) targets the standing hand position + distance along it."""
    spec = _one(g1, "reach", direction=direction, distance=0.15)
    (t,) = _targets(spec, "reach point")
    delta = np.array(t.position) - standing_geometry(g1).position("right_hand")
    expected = np.zeros(3)
    expected[axis] = 0.15
    assert np.allclose(delta, expected, atol=1e-12)


def test_reach_without_target_or_direction_reaches_forward(talos):
    """'reach out with your left hand': neither target nor direction reaches forward by the distance."""
    spec = _one(talos, "reach", direction=None, hand="left", distance=0.2)
    (t,) = _targets(spec, "reach point")
    delta = np.array(t.position) - standing_geometry(talos).position("left_hand")
    assert np.allclose(delta, 0.2 * standing_geometry(talos).heading_axis("forward"), atol=1e-12)


def test_reach_refuses_both_target_and_direction(talos):
    """Both is a clear error."""
    with pytest.raises(TaskDefinitionError, match="not both"):
        _one(talos, "reach", target=(0.3, 0.0, 0.3))


@pytest.mark.parametrize("robot_name", ["talos", "g1", "romeo", "icub"])
def test_raised_hands_are_above_the_head(robot_name):
    """raise_arms targets both hands above the robot's highest standing frame."""
    from robots import load_robot

    robot = load_robot(robot_name)
    spec = _one(robot, "raise_arms")
    raised = _targets(spec, "raised")
    assert len(raised) == 2
    for t in raised:
        assert t.position[2] - t.tolerance > robot.height()
    assert np.allclose(raised[0].position, raised_hand_position(robot, "left"))


def test_bow_pitches_the_torso_forward(talos, g1):
    """The bow target is the standing torso orientation pitched forward by the angle."""
    for robot in (talos, g1):
        spec = _one(robot, "bow", angle=0.4)
        (t,) = _targets(spec, "torso bowed")
        R = pin.rpy.rpyToMatrix(*t.rpy)
        R0 = standing_geometry(robot).rotation("torso")
        assert np.allclose(R, bowed_torso_rotation(robot, 0.4))
        # the torso's up axis now leans forward (+x) by 0.4 rad
        up = R @ R0.T @ np.array([0.0, 0.0, 1.0])
        assert np.arctan2(up[0], up[2]) == pytest.approx(0.4)
        assert t.position is None


def test_turn_head_yaws_the_head_and_respects_the_neck(talos):
    """Looking left turns the head frame about +z; beyond the neck's range is refused."""
    spec = _one(talos, "turn_head", direction="left", angle=0.6)
    (t,) = _targets(spec, "head turned")
    R = pin.rpy.rpyToMatrix(*t.rpy) @ standing_geometry(talos).rotation("head").T
    assert np.allclose(pin.log3(R), [0.0, 0.0, 0.6])
    with pytest.raises(TaskDefinitionError, match="beyond talos's neck range of 0.26 rad"):
        _one(talos, "turn_head", direction="up", angle=0.5)


def test_lean_stays_in_the_support_polygon(g1):
    """lean shifts the CoM target horizontally; too far is refused with the limit."""
    spec = _one(g1, "lean", direction="left", amount=0.05)
    (t,) = [c for c in spec.com_targets if "lean left" in c.name]
    com = standing_geometry(g1).com
    assert t.position[2] is None
    assert np.allclose(t.position[:2], com[:2] + [0.0, 0.05])
    with pytest.raises(TaskDefinitionError, match=r"lean amount 0.1 m forward is beyond g1's support polygon: at most 0.080 m"):
        _one(g1, "lean", direction="forward", amount=0.1)


@pytest.mark.parametrize("foot", ["left", "right"])
def test_balance_stands_on_one_sole(talos, foot):
    """balance: double support, then only the stance sole in contact with the other foot held up
    and the CoM held over the stance sole through the one-foot phase, then double support again."""
    spec = _one(talos, "balance", foot=foot, duration=3.0)
    stance, free = talos.frame(f"{foot}_foot"), talos.frame(f"{'right' if foot == 'left' else 'left'}_foot")
    contact_sets = [tuple(c.frame for c in p.contacts) for p in spec.phases]
    single = [i for i, cs in enumerate(contact_sets) if len(cs) == 1]
    assert len(single) == 1 and contact_sets[single[0]] == (stance,)
    assert len(contact_sets[single[0] - 1]) == 2 and len(contact_sets[single[0] + 1]) == 2
    starts = spec.phase_start_times()
    ph = spec.phases[single[0]]
    assert ph.duration == pytest.approx(3.0, abs=2 * spec.dt)
    (over,) = [c for c in spec.com_targets if f"over the {foot} sole" in c.name]
    assert np.allclose(over.position[:2], standing_geometry(talos).sole_centers[foot][:2])
    assert over.time is None
    assert over.window == pytest.approx((starts[single[0]], starts[single[0]] + ph.duration))
    (lift,) = [t for t in spec.targets if t.frame == free]
    assert lift.axes == (False, False, True) and lift.position[2] == pytest.approx(0.05)
    assert starts[single[0]] < lift.window[0] < lift.window[1] < starts[single[0]] + ph.duration
    assert ph.swing_height == pytest.approx(0.05)


def test_compile_action_places_a_fragment_on_the_grid(talos):
    """compile_action starts at t0, stretches to a requested duration and never shortens."""
    a = Action(name="squat", params={"duration": 1.0})
    f = compile_action(a, talos, t0=0.3, dt=0.05)
    assert f.t0 == pytest.approx(0.3) and f.duration == pytest.approx(1.0) and f.t_end == pytest.approx(1.3)
    long = compile_action(a, talos, t0=0.3, dt=0.05, duration=2.0)
    assert long.duration == pytest.approx(2.0)
    assert [c.time for c in long.com_targets] == pytest.approx([1.3, 2.3])
    assert compile_action(a, talos, t0=0.0, dt=0.05, duration=0.5).duration == pytest.approx(1.0)
    with pytest.raises(TaskDefinitionError, match="not on the knot grid"):
        compile_action(a, talos, t0=0.31, dt=0.05)


@st.composite
def registry_actions(draw, names=tuple(AVAILABLE)):
    """Any action of the registry with parameters drawn from its declared ranges and choices."""
    schema = REGISTRY[draw(st.sampled_from(names))]
    params = {}
    for p in schema.params:
        if draw(st.booleans()):
            continue  # keep the default
        if p.kind == "float":
            params[p.name] = draw(st.floats(p.minimum, p.maximum, allow_nan=False))
        elif p.kind == "int":
            params[p.name] = draw(st.integers(int(p.minimum), int(p.maximum)))
        elif p.kind == "choice":
            params[p.name] = draw(st.sampled_from(p.choices))
        elif p.kind == "vec3":
            params[p.name] = tuple(draw(st.floats(-1.0, 1.0)) for _ in range(3))
    return Action(name=schema.name, params=params)


@given(action=registry_actions(), robot_name=st.sampled_from(["talos", "g1"]))
def test_any_registry_parameters_compile_or_are_refused_clearly(action, robot_name):
    """Whatever the registry accepts either compiles to a spec whose targets lie within a few
    metres of the robot, or is refused with a message that names the action and, for robot
    limits, the robot."""
    from robots import load_robot

    robot = load_robot(robot_name)
    try:
        spec = compile_actions([action], robot)
    except TaskDefinitionError as e:
        msg = str(e)
        assert action.name in msg or "reach needs" in msg or robot_name in msg, msg
        assert "\n" not in msg
        return
    for t in spec.targets:
        if t.position is not None:
            assert np.linalg.norm(np.array(t.position) - standing_geometry(robot).com) < 3.0
    (fitted,) = fit_actions([action], robot)  # unstated sizes within the robot's limits
    assert spec.horizon >= nominal_duration_of(fitted, robot)
