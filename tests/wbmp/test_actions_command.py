"""``wbmp actions``: every primitive with its parameters, units, defaults and ranges."""

from __future__ import annotations

import json

from tasks.actions import REGISTRY
from wbmp.cli import main


def test_actions_json_lists_every_primitive_with_its_schema(capsys):
    """--json gives each registered primitive with typed parameters, units, defaults, ranges."""
    assert main(["actions", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert [r["name"] for r in rows] == list(REGISTRY)
    squat = next(r for r in rows if r["name"] == "squat")
    depth = next(p for p in squat["params"] if p["name"] == "depth")
    assert depth == {"name": "depth", "type": "float", "unit": "m", "default": 0.15, "minimum": 0.02,
                     "maximum": 0.6, "description": "how far the centre of mass goes down"}
    wave = next(r for r in rows if r["name"] == "wave")
    assert next(p for p in wave["params"] if p["name"] == "arm")["choices"] == ["left", "right", "both"]
    assert all(r["available"] for r in rows)


def test_actions_table_with_robot_limits(capsys):
    """NAME filters; --robot adds the robot's own limits (deepest squat, no neck on G1)."""
    assert main(["actions", "squat", "turn_head", "--robot", "g1"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("squat (lower body)")
    assert "depth [m]        default 0.15     range 0.02..0.6" in out
    assert "g1 limit on depth: at most 0.25 m on g1" in out
    assert "g1 has no neck joint" in out
    assert "wave" not in out


def test_actions_json_robot_limits(capsys):
    """The JSON form carries the same robot limits."""
    assert main(["actions", "lean", "--json", "--robot", "talos"]) == 0
    (row,) = json.loads(capsys.readouterr().out)
    assert row["robot"] == "talos" and "forward" in row["robot_limits"]["amount"]


def test_unknown_action_is_a_one_line_error(capsys):
    """A misspelled name exits 3 with a suggestion, no traceback."""
    assert main(["actions", "sqat"]) == 3
    err = capsys.readouterr().err
    assert err.strip() == "wbmp actions: error: unknown action 'sqat'; did you mean squat?"
