"""Stairs too steep for the robot, bad stairs in a scene file, sitting without a seat: one line, its exit code, no plan."""

from __future__ import annotations

import json

from tests.badinput.conftest import assert_refused, run_cli


def _scene(tmp_path, **stairs):
    path = tmp_path / "steep.json"
    path.write_text(json.dumps({"version": 1, "stairs": [{"position": [0.15, 0.0], **stairs}]}))
    return path


def test_walk_up_stairs_too_high_for_talos_is_refused_in_task_terms(tmp_path, capsys):
    out = tmp_path / "m.npz"
    outcome = run_cli(["solve", "walk up the stairs", "--scene", _scene(tmp_path, rise=0.3), "--no-sim",
                       "--out", out], capsys)
    assert_refused(outcome, 4, "the 0.30 m rise onto the stairs.1 is above talos's 0.20 m step")
    assert not out.exists()


def test_bad_stairs_in_a_scene_file_name_the_field(tmp_path, capsys):
    outcome = run_cli(["solve", "walk up the stairs", "--scene", _scene(tmp_path, count=0), "--no-sim"], capsys)
    assert_refused(outcome, 3, "stairs[0].count")


def test_sitting_down_without_a_seat_is_refused_in_task_terms(tmp_path, capsys):
    out = tmp_path / "m.npz"
    outcome = run_cli(["solve", "sit down", "--no-sim", "--out", out], capsys)
    assert_refused(outcome, 4, 'sit down: there is no seat in the scene (a chair or a bench: an object with "seat": true)')
    assert not out.exists()
    table = tmp_path / "table.json"
    table.write_text(json.dumps({"version": 1, "objects": [
        {"name": "table", "shape": "box", "size": [0.6, 1.2, 0.62], "position": [0.65, 0.0, 0.31]}]}))
    outcome = run_cli(["solve", "sit on the table", "--scene", table, "--no-sim"], capsys)
    assert_refused(outcome, 4, "sit down: the table is not a seat")
    outcome = run_cli(["solve", "stand up from the chair", "--scene", table, "--no-sim"], capsys)
    assert_refused(outcome, 4, "stand up: the robot is not sitting")
