"""The action registry: typed parameters, defaults, ranges and a JSON schema for every backend."""

from __future__ import annotations

import json

import pytest

from tasks.actions import REGISTRY, Action, actions_json_schema, get_action
from tasks.exceptions import TaskDefinitionError, UnknownAction


def test_registry_covers_the_documented_primitives():
    """Every primitive of the first design (the registry's founding set) is registered."""
    expected = {"squat", "wave", "reach", "bow", "step", "walk", "turn", "jump", "balance", "raise_arms",
                "turn_head", "lean", "stand"}
    assert expected <= set(REGISTRY)


def test_defaults_filled_and_round_trip():
    """Unspecified parameters take the schema default; to_dict/from_dict round-trips."""
    a = Action(name="squat", params={"repeat": 3})
    assert a.params["repeat"] == 3
    assert a.params["depth"] == get_action("squat").param("depth").default
    assert Action.from_dict(json.loads(json.dumps(a.to_dict()))) == a
    w = Action(name="wave", params={"arm": "left"}, overlay=True)
    assert w.to_dict()["overlay"] is True and Action.from_dict(w.to_dict()) == w


@pytest.mark.parametrize(
    ("name", "params", "message"),
    [
        ("squat", {"depth": 0.9}, "squat depth 0.9 m is above the maximum 0.6 m"),
        ("squat", {"repeat": 0}, "below the minimum"),
        ("squat", {"repeat": 1.5}, "whole number"),
        ("wave", {"arm": "middle"}, "must be one of left, right, both"),
        ("squat", {"height": 1}, "squat has no parameter 'height'"),
        ("reach", {"target": [1, 2]}, "three numbers"),
        ("jump", {"height": True}, "must be a number"),
    ],
)
def test_bad_parameters_are_named(name, params, message):
    """Out-of-range or mistyped parameters are TaskDefinitionErrors that say which and why."""
    with pytest.raises(TaskDefinitionError, match=message):
        Action(name=name, params=params)


def test_unknown_action_suggests_close_names():
    """A misspelled action name suggests the closest registered one."""
    with pytest.raises(UnknownAction, match="did you mean squat"):
        Action(name="sqat")


def test_params_are_read_only():
    """An Action cannot be mutated after construction."""
    a = Action(name="squat")
    with pytest.raises(TypeError):
        a.params["depth"] = 0.3  # type: ignore[index]


def test_json_schema_lists_every_action():
    """The schema the LLM backend sends names every action and its parameters with ranges."""
    schema = actions_json_schema()
    items = schema["properties"]["actions"]["items"]["oneOf"]
    assert {i["properties"]["action"]["const"] for i in items} == set(REGISTRY)
    squat = next(i for i in items if i["properties"]["action"]["const"] == "squat")
    depth = squat["properties"]["params"]["properties"]["depth"]
    assert depth["type"] == "number" and depth["maximum"] == 0.6 and "[m]" in depth["description"]
