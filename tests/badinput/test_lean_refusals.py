"""Leaning on a table without one, or on one too high for the robot: one line, exit 4, no plan."""

from __future__ import annotations

import json

from tests.badinput.conftest import assert_refused, run_cli


def test_leaning_without_a_table_or_on_one_too_high_is_refused_in_task_terms(tmp_path, capsys):
    out = tmp_path / "m.npz"
    ball = tmp_path / "ball.json"
    ball.write_text(json.dumps({"version": 1, "objects": [
        {"name": "ball", "shape": "sphere", "size": [0.1], "position": [0.6, 0.0, 0.1]}]}))
    outcome = run_cli(["solve", "双手撑着", "--scene", ball, "--no-sim", "--out", out], capsys)
    assert_refused(outcome, 4, "lean on: there is no table in the scene")
    assert not out.exists()
    far = tmp_path / "far.json"
    far.write_text(json.dumps({"version": 1, "objects": [
        {"name": "table", "shape": "box", "size": [0.6, 1.2, 0.62], "position": [2.0, 0.0, 0.31]}]}))
    outcome = run_cli(["solve", "lean on the table", "--scene", far, "--no-sim", "--out", out], capsys)
    assert_refused(outcome, 4, "lean on: the table's top is not within talos's reach ahead of its left hand")
    counter = tmp_path / "counter.json"
    counter.write_text(json.dumps({"version": 1, "objects": [
        {"name": "counter", "shape": "box", "size": [0.6, 1.2, 1.0], "position": [0.65, 0.0, 0.5], "aliases": ["桌子"]}]}))
    outcome = run_cli(["solve", "双手撑在桌子上", "--scene", counter, "--no-sim", "--out", out], capsys)
    assert_refused(outcome, 4, "lean on: the counter's top at 1.00 m is above talos's hands hanging")
    assert not out.exists()
