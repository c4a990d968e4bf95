"""Stairs too steep for the robot, bad stairs in a scene file, sitting without a seat: one line, its exit code, no plan."""

from __future__ import annotations

import json

import pytest

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


def _heightmap_scene(tmp_path, grid_text: str | None, name: str = "g.csv", **extra):
    if grid_text is not None:
        (tmp_path / name).write_text(grid_text)
    path = tmp_path / "hm.json"
    path.write_text(json.dumps({"version": 1, "heightmaps": [
        {"name": "ramp", "file": name, "cell": 0.1, "origin": [0.15, -0.5], **extra}]}))
    return path


@pytest.mark.parametrize("grid,extra,message", [
    (None, {}, "heightmaps[0].file: the grid file"),
    ("0,0.01\n0,nan\n", {}, "heightmaps[0].file: row 1, column 1 is nan, not a number"),
    ("0,0.01\n0,1e9\n", {}, "heightmaps[0].file: row 1, column 1 is 1e+09 m; heights are in [0, 2] m"),
    ("0,0.01,0.02\n0,0.01\n", {}, "heightmaps[0].file: row 1 has 2 heights, row 0 has 3"),
    ("0,0.01\n0,0.01\n", {"extent": [1.0, 1.0]}, "heightmaps[0].extent: is"),
])
def test_a_bad_height_map_is_refused_naming_the_field(tmp_path, capsys, grid, extra, message):
    outcome = run_cli(["solve", "walk up the ramp", "--scene", _heightmap_scene(tmp_path, grid, **extra),
                       "--no-sim"], capsys)
    assert_refused(outcome, 3, message)


def test_up_the_stairs_then_down_in_one_sentence_is_refused_in_task_terms(tmp_path, capsys):
    for text in ("walk up the stairs, then walk down the stairs", "走上楼梯，然后走下楼梯"):
        outcome = run_cli(["solve", text, "--scene", _scene(tmp_path, aliases=["楼梯"]), "--no-sim"], capsys)
        assert_refused(outcome, 4, "step_down: the stairs.1 is behind the robot (it stands on the stairs.3, facing "
                                   "away from it) and it neither turns around on a tread nor walks down backwards")
