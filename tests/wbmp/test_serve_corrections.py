"""Corrections in words (wbmp.serve.corrections): which words, which parameters, by how much.

The reference values are the registry's own defaults and ranges (tasks.actions.REGISTRY) times the
documented factors, computed here independently of the module's rules.
"""

from __future__ import annotations

import pytest

from tasks.actions import REGISTRY, Action
from wbmp.serve import corrections as c


def actions(*items, given=None):
    acts = tuple(Action(name=n, params=p) for n, p in items)
    full = tuple(Action(name=a.name, params=dict(a.params)) for a in acts)  # every parameter, as the worker sends
    return c.Actions(actions=full, given=tuple(frozenset(g) for g in (given or [()] * len(acts))))


def default(action, param):
    return REGISTRY[action].param(param).default


@pytest.mark.parametrize("text, kinds", [
    ("slower", ("slower",)), ("Slower!", ("slower",)), ("a bit slower please", ("slower",)), ("慢一点", ("slower",)),
    ("慢一点。", ("slower",)), ("faster", ("faster",)), ("快点", ("faster",)), ("twice", ("twice",)),
    ("两次", ("twice",)), ("lower", ("lower",)), ("再低一点", ("lower",)), ("higher", ("higher",)),
    ("高一点", ("higher",)), ("bigger", ("bigger",)), ("with the left hand", ("left",)), ("用左手", ("left",)),
    ("with the right hand", ("right",)), ("again", ("again",)), ("再来一次", ("again",)), ("undo", ("undo",)),
    ("撤销", ("undo",)), ("slower and lower", ("slower", "lower")), ("slower, with the left hand", ("slower", "left")),
    ("慢一点，再低一点", ("slower", "lower")),
])
def test_correction_words(text, kinds):
    assert c.parse_correction(text) == kinds


@pytest.mark.parametrize("text", ["squat twice", "lower your arms", "wave slowly", "walk to the table", "深蹲两次",
                                  "then wave", "", "   ", "slower squat", "undo the squat"])
def test_sentences_are_not_corrections(text):
    assert c.parse_correction(text) is None


@pytest.mark.parametrize("text, rest", [("then wave", "wave"), ("Then, squat twice", "squat twice"),
                                        ("and then bow", "bow"), ("然后挥手", "挥手"), ("接着，深蹲", "深蹲"),
                                        ("wave then squat", None), ("then", None), ("thenceforth", None)])
def test_continuation(text, rest):
    assert c.continuation(text) == rest


def test_slower_scales_every_duration():
    acts = actions(("squat", {}), ("wave", {"arm": "left"}), given=[(), ("arm",)])
    new, changes = c.apply(("slower",), acts)
    assert new.actions[0].params["duration"] == pytest.approx(default("squat", "duration") * 1.5)
    assert new.actions[1].params["duration"] == pytest.approx(default("wave", "duration") * 1.5)
    assert new.actions[1].params["arm"] == "left"  # untouched
    assert [(ch.action, ch.name, ch.param) for ch in changes] == [(1, "squat", "duration"), (2, "wave", "duration")]
    assert changes[0].old == default("squat", "duration") and changes[0].unit == "s"
    assert "x1.5" in changes[0].describe() and "squat duration 2 s -> 3 s" in changes[0].describe()
    assert new.given == (frozenset({"duration"}), frozenset({"arm", "duration"}))  # the changed one is now stated
    assert {k for k in new.stated()[0].params if new.stated()[0].params[k] is not None and
            k not in new.stated()[0].defaulted} == {"duration"}


def test_faster_stops_at_the_registry_minimum_then_refuses():
    minimum = REGISTRY["squat"].param("duration").minimum
    acts = actions(("squat", {}))
    for _ in range(20):
        try:
            acts, changes = c.apply(("faster",), acts)
        except c.CorrectionError as e:
            assert "squat" in str(e) and "duration" in str(e) and "\n" not in str(e)
            break
        assert acts.actions[0].params["duration"] >= minimum
    else:
        pytest.fail("faster never reached the minimum")
    assert acts.actions[0].params["duration"] == minimum


def test_lower_and_higher_depend_on_the_action():
    acts = actions(("squat", {}), ("kick", {}))
    lower, changes = c.apply(("lower",), acts)
    assert lower.actions[0].params["depth"] == pytest.approx(default("squat", "depth") * 1.3)  # the body goes lower
    assert lower.actions[1].params["height"] == pytest.approx(default("kick", "height") * 0.75)  # the foot, lower
    higher, _ = c.apply(("higher",), lower)
    assert higher.actions[0].params["depth"] == pytest.approx(default("squat", "depth"))
    assert higher.actions[1].params["height"] == pytest.approx(default("kick", "height"))
    with pytest.raises(c.CorrectionError, match="wave"):
        c.apply(("lower",), actions(("wave", {})))


def test_twice_sets_the_count_or_repeats_the_sequence():
    new, changes = c.apply(("twice",), actions(("squat", {}), ("march", {})))
    assert new.actions[0].params["repeat"] == 2 and new.actions[1].params["count"] == 2
    new, changes = c.apply(("twice",), actions(("bow", {}), ("raise_arms", {})))
    assert [a.name for a in new.actions] == ["bow", "raise_arms", "bow", "raise_arms"]
    assert changes[0].param == "copies"


def test_hand_and_bigger():
    new, changes = c.apply(("left",), actions(("wave", {}), ("touch", {}), ("squat", {})))
    assert new.actions[0].params["arm"] == "left" and new.actions[1].params["hand"] == "left"
    assert [ch.name for ch in changes] == ["wave", "touch"]
    new, _ = c.apply(("bigger",), actions(("arm_circles", {})))
    assert new.actions[0].params["radius"] == pytest.approx(default("arm_circles", "radius") * 1.3)
    maximum = REGISTRY["bow"].param("angle").maximum
    new, _ = c.apply(("bigger",), actions(("bow", {"angle": maximum * 0.95})))
    assert new.actions[0].params["angle"] == maximum  # clamped to the registry's range


def test_again_and_undo_change_nothing():
    acts = actions(("squat", {}))
    for kind in ("again", "undo"):
        new, changes = c.apply((kind,), acts)
        assert new == acts and changes == []


def test_slower_on_a_walk_changes_the_robots_pace():
    acts = c.Actions(actions=actions(("walk", {}), ("squat", {})).actions, given=(frozenset(), frozenset()),
                     step_duration=0.8)
    new, changes = c.apply(("slower",), acts)
    assert new.step_duration == pytest.approx(1.2)
    assert [(ch.name, ch.param) for ch in changes] == [("squat", "duration"), ("robot", "step_duration")]
    assert changes[1].describe() == "robot step_duration 0.8 s -> 1.2 s (x1.5)"
    back, _ = c.apply(("faster",), new)
    assert back.step_duration == pytest.approx(0.8)
    with pytest.raises(c.CorrectionError, match="walk"):  # the pace unknown: nothing to change
        c.apply(("slower",), actions(("walk", {})))
    assert c.apply(("slower",), c.Actions(actions=actions(("squat", {})).actions, given=(frozenset(),),
                                          step_duration=0.8))[0].step_duration == 0.8  # nothing steps


def test_paced_actions_are_those_timed_by_the_step_duration(talos):
    """PACED against the compiler: with the profile's step_duration x 1.5, a lower- or whole-body
    action's horizon grows exactly when it is in PACED (actions on scene objects, walk_to, need a
    scene and are left out; upper-body actions never step, and their inverse kinematics is slow)."""
    import dataclasses

    from robots import load_robot
    from tasks.compose import compile_actions, fit_actions
    from tasks.exceptions import BeyondCapability

    paced = load_robot(dataclasses.replace(talos.profile, step_duration=1.5 * talos.profile.step_duration))
    grows = set()
    assert not {name for name, schema in REGISTRY.items() if schema.body == "upper"} & set(c.PACED)
    for name, schema in REGISTRY.items():
        if any(p.name == "object" for p in schema.params) or schema.body == "upper":
            continue
        try:
            before = compile_actions(fit_actions([Action(name=name)], talos), talos).horizon
        except BeyondCapability:  # hop, jog: not on talos
            continue
        after = compile_actions(fit_actions([Action(name=name)], paced), paced).horizon
        if after > before + 1e-9:
            grows.add(name)
    assert grows == set(c.PACED) - {"walk_to"}
