"""Defaults fit the robot: a size the sentence does not state is chosen within the robot's limits.

Every action of the registry, with every choice of its direction-like parameter and nothing
else stated, compiles on every built-in robot (no planning), except where the robot lacks what
the action needs (a neck, legs strong enough to jump): then the refusal says so instead of
naming a default. A stated size beyond the limit is still refused, naming the limit.
"""

from __future__ import annotations

import re

import pytest

from language import parse
from robots import load_robot
from tasks.actions import HEAD_DIRECTIONS, REGISTRY, Action
from tasks.compose import compile_actions, fit_actions
from tasks.exceptions import TaskDefinitionError
from tasks.footsteps import step_length_limit
from tasks.primitives import get_primitive
from tasks.primitives.jump import max_jump_height
from tasks.primitives.posture import lean_limit

ROBOTS = ("talos", "g1", "romeo", "icub")

# The parameter that changes a robot's limits (a step's length depends on its direction).
VARIANTS: dict[str, list[dict]] = {
    "step": [{"direction": d} for d in ("forward", "backward", "left", "right")],
    "walk": [{"direction": d} for d in ("forward", "backward", "left", "right")],
    "lean": [{"direction": d} for d in ("forward", "backward", "left", "right")],
    "turn_head": [{"direction": d} for d in HEAD_DIRECTIONS],
    "reach": [{"direction": d} for d in ("forward", "up", "down", "left", "right", "backward")],
    "turn": [{"angle": 1.5707963267948966}, {"angle": -1.5707963267948966}],
}

# What a robot cannot do whatever the size: the refusal names the missing capability.
CANNOT = {
    ("g1", "turn_head"): "no neck joint",
    ("romeo", "jump"): "cannot jump",
    ("g1", "nod"): "no neck joint",
    ("g1", "shake_head"): "no neck joint",
    **{(r, "hop"): "cannot hop on one foot" for r in ("talos", "romeo", "icub")},  # g1 hops (certified in MuJoCo)
    **{(r, "jog"): "cannot jog or run" for r in ("talos", "g1", "romeo", "icub")},
    ("g1", "kneel"): "into its torso: its body does not fold that way",  # tests/tasks/test_kneel.py: the posture
    ("romeo", "kneel"): "into the floor: its legs do not fold that way",
    ("icub", "kneel"): "cannot reach a kneeling posture",
}


@pytest.fixture(scope="module")
def robots():
    return {name: load_robot(name) for name in ROBOTS}


# The actions on scene objects need a scene (tests/tasks/test_objects.py compiles them).
CASES = [(r, name, params) for r in ROBOTS for name in REGISTRY for params in VARIANTS.get(name, [{}])
         if all(p.kind != "object" for p in REGISTRY[name].params)]


@pytest.mark.parametrize(("robot_name", "name", "params"), CASES,
                         ids=[f"{r}-{n}-{'-'.join(str(v) for v in p.values()) or 'bare'}" for r, n, p in CASES])
def test_unstated_sizes_compile_on_every_robot(robots, robot_name, name, params):
    robot = robots[robot_name]
    action = Action(name=name, params=params)
    if (robot_name, name) in CANNOT:
        with pytest.raises(TaskDefinitionError, match=CANNOT[(robot_name, name)]):
            compile_actions([action], robot)
        return
    spec = compile_actions([action], robot)
    assert spec.horizon > 0
    (fitted,) = fit_actions([action], robot)
    limits = get_primitive(name).size_limits(dict(fitted.params), robot)
    for key, limit in limits.items():
        value = fitted.params[key]
        default = REGISTRY[name].param(key).default
        assert abs(value) <= limit + 1e-12, (key, value, limit)
        if abs(default) <= limit:  # the registry default when the robot allows it
            assert value == default
        else:  # else the limit, rounded down to 1 cm / 0.01 rad
            assert limit - 0.01 - 1e-9 < abs(value) < abs(default)


def test_default_step_fits_g1_side_step(robots):
    """The issue's sentence: two steps to the left on g1 (0.10 m side steps) plans 0.10 m steps."""
    g1 = robots["g1"]
    plan = parse("take two steps to the left")
    (action,) = fit_actions(plan.actions, g1)
    assert action.params["length"] == pytest.approx(step_length_limit(g1, "left")) == pytest.approx(0.10)
    assert "length" in action.defaulted
    spec = compile_actions(plan.actions, g1)
    feet = [c.placement.position[1] for p in spec.phases for c in p.contacts if "left" in c.frame]
    assert max(feet) - min(feet) == pytest.approx(2 * 0.10, abs=1e-6)  # two side steps of 0.10 m
    # talos keeps the registry's 0.15 m forward, g1's forward limit is 0.20 m: unchanged
    assert fit_actions(parse("take two steps forward").actions, g1)[0].params["length"] == pytest.approx(0.15)


def test_stated_size_beyond_the_limit_is_still_refused(robots):
    g1 = robots["g1"]
    with pytest.raises(TaskDefinitionError, match=re.escape("side step 0.15 m is beyond g1's 0.10 m")):
        compile_actions(parse("take two steps of 15 cm to the left").actions, g1)
    with pytest.raises(TaskDefinitionError, match="beyond icub's support polygon: at most 0.027 m"):
        compile_actions([Action(name="lean", params={"direction": "backward", "amount": 0.04})], robots["icub"])


def test_fitted_values_are_the_robot_limits(robots):
    icub, talos = robots["icub"], robots["talos"]
    lean = fit_actions([Action(name="lean", params={"direction": "backward"})], icub)[0]
    assert lean.params["amount"] == pytest.approx(0.02)  # 0.027 m rounded down to the 1 cm grid
    assert lean_limit(icub, "backward") == pytest.approx(0.027, abs=5e-4)
    jump = fit_actions([Action(name="jump")], icub)[0]
    assert jump.params["height"] == pytest.approx(min(0.05, max_jump_height(icub)))
    look_up = fit_actions([Action(name="turn_head", params={"direction": "up"})], talos)[0]
    assert look_up.params["angle"] == pytest.approx(0.26)  # talos's neck: 0.26 rad up
    # a stated value is never changed, even when beyond the limit (the check refuses it)
    stated = fit_actions([Action(name="squat", params={"depth": 0.5})], talos)[0]
    assert stated.params["depth"] == 0.5 and "depth" not in stated.defaulted
