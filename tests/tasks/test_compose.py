"""Composition: sequences, repetition, overlays, transitions through standing, timing."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from tasks.actions import Action
from tasks.compose import (
    STAND_TIME,
    TRANSITION_TIME,
    compile_actions,
    describe_actions,
    group_actions,
)
from tasks.exceptions import TaskDefinitionError
from tasks.primitives import compile_action, nominal_duration, standing_geometry, to_knot
from tasks.serialize import spec_from_json, spec_to_json


def _stand_contacts(robot, phase):
    return {c.frame for c in phase.contacts} == {robot.frame("left_foot"), robot.frame("right_foot")}


WAYPOINT_LABELS = ("start", "transition", "stand", "end")


def _items(spec):
    """The actions' own targets (the standing waypoints excluded)."""
    return tuple(t for t in (*spec.targets, *spec.com_targets, *spec.joint_targets)
                 if not t.name.startswith(WAYPOINT_LABELS))


def _waypoint_times(spec):
    """Label -> time of each standing waypoint (every one-dof joint at its standing angle)."""
    out: dict[str, set] = {}
    for t in spec.joint_targets:
        label = t.name.split(":")[0]
        if label.startswith(WAYPOINT_LABELS):
            out.setdefault(label, set()).add(t.time)
    return out


def _times(item):
    return (item.time,) if item.window is None else item.window


def test_sequence_starts_and_ends_standing_with_transitions(talos):
    """wave, then squat: stand, wave, transition, squat, stand; each action's targets inside its
    own phases; the horizon adds up."""
    actions = [Action(name="wave"), Action(name="squat")]
    spec = compile_actions(actions, talos)
    names = [p.name for p in spec.phases]
    assert names == ["stand", "1 wave: wave", "transition", "2 squat: squat", "stand"]
    assert all(_stand_contacts(talos, p) for p in spec.phases)
    assert spec.phases[0].duration == pytest.approx(STAND_TIME) and spec.phases[2].duration == pytest.approx(TRANSITION_TIME)
    wave_start, squat_start = spec.phase_start_times()[1], spec.phase_start_times()[3]
    expected = 2 * STAND_TIME + TRANSITION_TIME + sum(nominal_duration(a, talos) for a in actions)
    assert spec.horizon == pytest.approx(expected, abs=2 * spec.dt)
    for item in _items(spec):
        lo, hi = (wave_start, squat_start - TRANSITION_TIME) if item.name.startswith("1 wave") else (squat_start, spec.horizon - STAND_TIME)
        assert all(lo - 1e-9 <= t <= hi + 1e-9 for t in _times(item)), item.name
    # both actions end at the standing posture: squat top at its end, hand back at rest at the wave's end
    assert max(c.time for c in spec.com_targets if c.time is not None) == pytest.approx(spec.horizon - STAND_TIME)
    assert spec.name == "wave, then squat"
    # standing waypoints: end of the first stand, middle of the transition, start and end of the last stand
    times = _waypoint_times(spec)
    assert {k: min(v) for k, v in times.items() if len(v) == 1} == pytest.approx({
        "start": STAND_TIME, "transition 1": squat_start - TRANSITION_TIME / 2,
        "stand": spec.horizon - STAND_TIME, "end": spec.horizon})
    n_joints = sum(1 for j in talos.model.joints[2:] if j.nv == 1)
    assert len(spec.joint_targets) == 4 * n_joints
    q = {t.joint: t.value for t in spec.joint_targets}
    assert q["leg_left_4_joint"] == pytest.approx(talos.q_standing[talos.model.joints[talos.model.getJointId("leg_left_4_joint")].idx_q])


def test_repetition_of_an_action(g1):
    """The same action twice gives two fragments with distinct target names."""
    spec = compile_actions([Action(name="squat"), Action(name="squat")], g1)
    bottoms = [c for c in spec.com_targets if "bottom" in c.name]
    assert len(bottoms) == 2 and bottoms[0].name != bottoms[1].name
    assert bottoms[1].time - bottoms[0].time == pytest.approx(2.0 + TRANSITION_TIME, abs=2 * spec.dt)


def test_overlay_runs_alongside_and_stretches_the_shorter_action(talos):
    """squat while waving: one group, both start together; the 1 s squat is stretched to the
    3.6 s wave, so its bottom comes at the middle of the wave."""
    squat = Action(name="squat", params={"duration": 1.0})
    wave = Action(name="wave", params={"repeat": 2}, overlay=True)
    spec = compile_actions([squat, wave], talos)
    assert [p.name for p in spec.phases] == ["stand", "1 squat: squat", "stand"]
    length = nominal_duration(wave, talos)
    assert spec.phases[1].duration == pytest.approx(length, abs=spec.dt)
    (bottom,) = [c for c in spec.com_targets if "bottom" in c.name]
    assert bottom.time == pytest.approx(STAND_TIME + length / 2, abs=spec.dt)
    swings = [t for t in spec.targets if "swing" in t.name]
    assert swings[0].time < bottom.time < swings[-1].time
    assert spec.name == "squat while wave"


@pytest.mark.parametrize(
    ("actions", "message"),
    [
        ([Action(name="wave"), Action(name="reach", params={"direction": "up"}, overlay=True)],
         r"action 2 \(reach\) cannot run at the same time as action 1 \(wave\): both drive the right arm"),
        ([Action(name="squat"), Action(name="lean", overlay=True)], "both drive"),
        ([Action(name="balance"), Action(name="bow", overlay=True)], "both drive"),
        ([Action(name="wave", overlay=True)], "is an overlay but nothing runs before it"),
        ([Action(name="walk"), Action(name="wave", overlay=True)], "wave cannot run while walk moves the feet"),
        ([], "no action to compile"),
        ([Action(name="wave"), Action(name="squat", params={"depth": 0.5})],
         r"action 2 \(squat\): squat depth 0.5 m is beyond talos's reachable 0.35 m"),
    ],
)
def test_bad_compositions_are_refused(talos, actions, message):
    """Conflicting overlays, a leading overlay, an overlay on moving feet, nothing at all and
    out-of-range parameters are TaskDefinitionErrors naming the action."""
    with pytest.raises(TaskDefinitionError, match=message):
        compile_actions(actions, talos)


def test_overlays_on_different_parts_combine(talos):
    """Left-hand wave while the right hand reaches while the head turns: one group, three parts."""
    spec = compile_actions([
        Action(name="wave", params={"arm": "left"}),
        Action(name="reach", params={"hand": "right", "direction": "forward"}, overlay=True),
        Action(name="turn_head", overlay=True),
    ], talos)
    assert len(spec.phases) == 3
    assert {t.frame for t in spec.targets} == {talos.frame("left_hand"), talos.frame("right_hand"), talos.frame("head")}


def test_dict_actions_and_options(talos):
    """Actions may be given as dictionaries; dt, stand and transition times are honoured."""
    spec = compile_actions([{"action": "stand", "params": {"duration": 0.5}}, {"action": "stand"}], talos,
                           dt=0.05, stand_time=0.2, transition_time=0.0, description="stand twice")
    assert [p.duration for p in spec.phases] == pytest.approx([0.2, 0.5, 1.0, 0.2])
    assert spec.dt == 0.05 and spec.description == "stand twice"
    with pytest.raises(TaskDefinitionError, match="dt must be in"):
        compile_actions([Action(name="stand")], talos, dt=0.3)
    with pytest.raises(TaskDefinitionError, match="unknown action 'dance'"):
        compile_actions([{"action": "dance"}], talos)


def test_support_margin_follows_the_sole(talos, g1):
    """The spec's support-polygon margin is 2 cm, less on G1's narrow 5 cm sole."""
    assert compile_actions([Action(name="stand")], talos).com_bounds[0].margin == pytest.approx(0.02)
    assert compile_actions([Action(name="stand")], g1).com_bounds[0].margin == pytest.approx(0.0125)
    assert standing_geometry(g1).support_margin == pytest.approx(0.0125)


def test_compile_action_equals_its_one_action_spec(talos):
    """The fragment of compile_action is what compile_actions puts into the spec."""
    a = Action(name="squat", params={"repeat": 2})
    f = compile_action(a, talos, t0=STAND_TIME, label="1 squat")
    spec = compile_actions([a], talos)
    assert spec.com_targets == f.com_targets and spec.phases[1:-1] == f.phases


# --- properties ---------------------------------------------------------------------------

UPPER = st.one_of(
    st.builds(lambda arm, n, d: Action(name="wave", params={"arm": arm, "repeat": n, "duration": d}),
              st.sampled_from(["left", "right", "both"]), st.integers(1, 3), st.floats(0.3, 1.5)),
    st.builds(lambda hand, dist: Action(name="reach", params={"hand": hand, "direction": "forward", "distance": dist}),
              st.sampled_from(["left", "right"]), st.floats(0.0, 0.3)),
    st.builds(lambda arm: Action(name="raise_arms", params={"arm": arm}), st.sampled_from(["left", "right", "both"])),
    st.builds(lambda d: Action(name="turn_head", params={"direction": d, "angle": 0.2}),
              st.sampled_from(["left", "right", "down"])),
)
LOWER = st.one_of(
    st.builds(lambda depth, n, d: Action(name="squat", params={"depth": depth, "repeat": n, "duration": d}),
              st.floats(0.02, 0.35), st.integers(1, 3), st.floats(0.8, 3.0)),
    st.builds(lambda f, d: Action(name="balance", params={"foot": f, "duration": d}),
              st.sampled_from(["left", "right"]), st.floats(0.5, 3.0)),
    st.builds(lambda d: Action(name="lean", params={"direction": d, "amount": 0.02}),
              st.sampled_from(["forward", "backward", "left", "right"])),
    st.builds(lambda a: Action(name="bow", params={"angle": a}), st.floats(0.05, 1.0)),
    st.builds(lambda d: Action(name="stand", params={"duration": d}), st.floats(0.2, 2.0)),
)


@st.composite
def action_lists(draw):
    out = []
    for _ in range(draw(st.integers(1, 4))):
        lead = draw(st.one_of(LOWER, UPPER))
        out.append(lead)
        if draw(st.booleans()):
            over = draw(UPPER)
            out.append(Action(name=over.name, params=dict(over.params), overlay=True))
    return out


@given(actions=action_lists(), dt=st.sampled_from([0.05, 0.075, 0.1]))
def test_composition_timing_properties(talos, actions, dt):
    """For any action list: phases tile the horizon on the knot grid, every target time is a knot
    inside its own group's span, groups follow in order with standing in between, names are
    unique, and the spec survives JSON."""
    try:
        spec = compile_actions(actions, talos, dt=dt)
    except TaskDefinitionError as e:
        assert "both drive" in str(e)  # the only refusal possible here: an overlay on a busy part
        return
    total = 0
    for p in spec.phases:
        n = to_knot(p.duration, dt)
        assert n >= 1
        total += n
    assert to_knot(spec.horizon, dt) == total
    groups = group_actions(actions)
    starts = spec.phase_start_times()
    assert spec.phases[0].name == "stand" and spec.phases[-1].name == "stand"
    assert _stand_contacts(talos, spec.phases[0]) and _stand_contacts(talos, spec.phases[-1])
    spans = []
    for group in groups:
        first = group[0][0] + 1
        idx = [i for i, p in enumerate(spec.phases) if p.name.split(":")[0] in {f"{i + 1} {a.name}" for i, a in group}]
        assert idx, f"group starting at action {first} has no phase"
        lo, hi = starts[idx[0]], starts[idx[-1]] + spec.phases[idx[-1]].duration
        longest = max(nominal_duration(a, talos) for _, a in group)
        assert hi - lo >= longest - 1e-9 and hi - lo <= longest + 2 * dt + 1e-9
        spans.append((lo, hi, {f"{i + 1} {a.name}" for i, a in group}))
    for (_, hi0, _), (lo1, _, _) in zip(spans, spans[1:]):
        assert lo1 - hi0 == pytest.approx(TRANSITION_TIME, abs=dt)
    for label, times in _waypoint_times(spec).items():
        (t,) = times
        to_knot(t, dt)
        if label.startswith("transition"):
            i = int(label.split()[1])
            assert spans[i - 1][1] <= t <= spans[i][0]
    for item in _items(spec):
        label = item.name.split(":")[0]
        (lo, hi) = next((lo, hi) for lo, hi, labels in spans if label in labels)
        for t in _times(item):
            to_knot(t, dt)
            assert lo - 1e-9 <= t <= hi + 1e-9, item.name
    assert spec_from_json(spec_to_json(spec)) == spec
    assert spec.name == describe_actions(actions)


def test_actions_after_a_turn_follow_the_new_heading(talos):
    """After turn(pi/2), reach forward points along the world's +y, from the turned hand's rest
    position; the closing stand phase holds the feet where the turn put them."""
    import math

    spec = compile_actions([Action(name="turn", params={"angle": math.pi / 2}),
                            Action(name="reach", params={"direction": "forward", "distance": 0.2})], talos)
    (point,) = [t for t in spec.targets if "reach point" in t.name]
    (rest,) = [t for t in spec.targets if "back at rest" in t.name]
    assert np.allclose(np.subtract(point.position, rest.position), [0.0, 0.2, 0.0], atol=1e-9)
    last = spec.phases[-1]
    assert all(abs(c.placement.rpy[2] - math.pi / 2) < 1e-6 for c in last.contacts)


@pytest.mark.parametrize("sentence", ["walk two steps forward, then wave the right hand",
                                      "wave the right hand, then walk two steps forward",
                                      "walk two steps forward, then squat"])
def test_a_sequence_with_a_walk_is_dynamic_as_a_whole(talos, sentence):
    """One dynamic motion makes the whole spec dynamic: the planner adds contact forces and the
    CoM dynamics at every knot, the upper-body and squat parts included."""
    from language import parse

    spec = compile_actions(parse(sentence).actions, talos)
    assert spec.dynamic


def test_arms_only_groups_hold_the_com_where_the_robot_stands(talos):
    """The wave after two 0.15 m steps asks (soft) for the CoM at the point the walk brings it back
    to, over the wave's window; a squat (which owns the CoM) and the walk get no such target."""
    from language import parse
    from tasks.compose import STILL_WEIGHT
    from tasks.specs import Priority

    spec = compile_actions(parse("walk two steps forward, then wave the right hand, then squat").actions, talos)
    still = [t for t in spec.com_targets if t.name.endswith("CoM still")]
    assert [t.name for t in still] == ["2 wave: CoM still"]
    (t,) = still
    (home,) = [c for c in spec.com_targets if c.name == "1 step: CoM back over the feet"]
    assert t.position[:2] == pytest.approx(home.position[:2], abs=1e-9) and t.position[2] is None
    assert t.priority is Priority.SOFT and t.weight == STILL_WEIGHT
    starts = spec.phase_start_times()
    (i,) = [j for j, p in enumerate(spec.phases) if p.name == "2 wave: wave"]
    assert t.window == pytest.approx((starts[i], starts[i] + spec.phases[i].duration))
    assert t.position[0] == pytest.approx(standing_geometry(talos).com[0] + 0.30, abs=0.02)  # two 0.15 m steps
