"""The JSON-schema subset validator, on the registry's own schema and on small schemas."""

from __future__ import annotations

import pytest

from language.exceptions import SchemaViolation, UnsupportedSchema
from language.validate import errors, validate
from tasks.actions import actions_json_schema

SCHEMA = actions_json_schema()


def test_every_rule_parser_plan_is_valid():
    """What the rule parser produces passes the schema the LLM is held to."""
    from language import parse

    for text in ("wave your right hand twice, then squat", "wave while squatting", "turn right 45 degrees",
                 "reach forward with your left hand 30 cm", "深蹲三次", "jump forward 30 cm"):
        data = parse(text).to_dict()
        del data["backend"]
        assert errors(data, SCHEMA) == [], text


@pytest.mark.parametrize("instance, message", [
    ({}, "reply: missing required key 'actions'"),
    ({"actions": "wave"}, "actions: expected an array, got a string ('wave')"),
    ({"actions": []}, "actions: needs at least 1 item(s), got 0"),
    ({"actions": [{"action": "fly"}]}, "actions[0].action: 'fly' is not one of 'stand', 'squat'"),
    ({"actions": [{"params": {}}]}, "actions[0].action: '<missing>' is not one of"),
    ({"actions": [{"action": "squat", "params": {"depth": "deep"}}]}, "actions[0].params.depth: expected a number, got a string ('deep')"),
    ({"actions": [{"action": "squat", "params": {"depth": 0.9}}]}, "actions[0].params.depth: 0.9 is above the maximum 0.6"),
    ({"actions": [{"action": "squat", "params": {"repeat": 1.5}}]}, "actions[0].params.repeat: expected an integer, got a number (1.5)"),
    ({"actions": [{"action": "squat", "params": {"repeat": True}}]}, "actions[0].params.repeat: expected an integer, got a boolean (True)"),
    ({"actions": [{"action": "wave", "params": {"arm": "Left"}}]}, "actions[0].params.arm: must be one of 'left', 'right', 'both', got 'Left'"),
    ({"actions": [{"action": "wave", "params": {}, "speed": 1}]}, "actions[0]: unknown key 'speed' (allowed: action, params, overlay)"),
    ({"actions": [{"action": "wave", "overlay": "yes"}]}, "actions[0].overlay: expected a boolean, got a string ('yes')"),
    ({"actions": [{"action": "reach", "params": {"target": [0.3, 0.1]}}]}, "actions[0].params.target: needs at least 3 item(s), got 2"),
    ({"actions": [{"action": "turn", "params": {"angle": -4}}]}, "actions[0].params.angle: -4 is below the minimum -3.14159"),
])
def test_violations_name_the_place(instance, message):
    errs = errors(instance, SCHEMA)
    assert errs and errs[0].startswith(message), errs
    with pytest.raises(SchemaViolation) as info:
        validate(instance, SCHEMA)
    assert str(info.value).startswith(message)


def test_accepts_integral_float_for_integer_and_optional_overlay():
    validate({"actions": [{"action": "squat", "params": {"repeat": 2.0}}, {"action": "wave", "overlay": True}]}, SCHEMA)


def test_one_of_ambiguity_is_reported():
    schema = {"oneOf": [{"type": "number"}, {"type": "integer"}]}
    assert errors(1, schema) == ["reply: matches 2 alternatives, expected exactly one"]
    assert errors(1.5, schema) == []


def test_unknown_keyword_is_refused():
    """A schema keyword the validator does not implement fails loudly instead of being skipped."""
    with pytest.raises(UnsupportedSchema, match="pattern"):
        errors("x", {"type": "string", "pattern": "^a"})
    with pytest.raises(UnsupportedSchema, match="'date'"):
        errors("x", {"type": "date"})
