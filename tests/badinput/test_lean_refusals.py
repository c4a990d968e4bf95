"""Leaning on a table without one, or on one too high for the robot: one line, exit 4, no plan."""

from __future__ import annotations

import json

from tests.badinput.conftest import assert_refused, run_cli


def test_leaning_without_a_table_or_on_one_too_high_is_refused_in_task_terms(tmp_path, capsys):
    out = tmp_path / "m.npz"
    outcome = run_cli(["solve", "lean on the table with both hands", "--no-sim", "--out", out], capsys)
    assert_refused(outcome, 4, "lean on: there is no table in the scene")
    assert not out.exists()
    counter = tmp_path / "counter.json"
    counter.write_text(json.dumps({"version": 1, "objects": [
        {"name": "counter", "shape": "box", "size": [0.6, 1.2, 1.0], "position": [0.65, 0.0, 0.5]}]}))
    outcome = run_cli(["solve", "双手撑在桌子上", "--scene", counter, "--no-sim", "--out", out], capsys)
    assert_refused(outcome, 4, "lean on: the counter's top at 1.00 m is above talos's hands hanging")
    assert not out.exists()
