"""``wbmp batch``: refused input is one line before any work, and nothing is written."""

from __future__ import annotations

import pytest

from tests.badinput.conftest import assert_refused, run_cli


def _batch(tmp_path, text: str, name: str = "items.txt"):
    path = tmp_path / name
    path.write_text(text)
    return path


@pytest.mark.parametrize(("text", "name", "code", "words"), [
    ("", "items.txt", 2, ["holds no item"]),
    ("# only a comment\n\n   \n", "items.txt", 2, ["holds no item"]),
    ('{"instruction": "squat"}\n{"instruction": "wave"\n', "items.jsonl", 2, ["items.jsonl:2", "not a JSON object"]),
    ('{"instruction": "squat"}\n[1, 2]\n', "items.jsonl", 2, ["items.jsonl:2", "not an object"]),
    ('{"instuction": "squat"}\n', "items.jsonl", 2, [":1", "unknown key 'instuction'"]),
    ('{"instruction": "squat", "spec": "a.json"}\n', "items.jsonl", 2, ["exactly one"]),
    ('{"instruction": "squat", "id": "../x"}\n', "items.jsonl", 2, ['"id"', "motion file"]),
    ('{"instruction": "squat", "id": "a"}\n{"instruction": "wave", "id": "a"}\n', "items.jsonl", 2,
     [":2", "id 'a' is used by line 1"]),
    ('{"instruction": "squat", "robot": "robbie"}\n', "items.jsonl", 3, [":1", "unknown robot 'robbie'"]),
    ("squat\nmissing_spec.json\n", "items.txt", 2, ["items.txt:2", "spec file 'missing_spec.json' not found"]),
    ("squat\n{\"instruction\": \"wave\"}\n", "items.txt", 2, [":2", "JSONL"]),
])
def test_bad_batch_file_is_refused_with_its_line(tmp_path, capsys, tree, text, name, code, words):
    """A bad line is named by file and line number; exit 2 (3 for an unknown robot); nothing written."""
    items = _batch(tmp_path, text, name)
    tree.before = tree.snapshot()
    outcome = run_cli(["batch", items, "--out-dir", tmp_path / "lib", "--no-sim"], capsys)
    assert_refused(outcome, code, *words)
    tree.assert_unchanged()


@pytest.mark.parametrize(("extra", "code", "words"), [
    (["--robots", "talos,robbie"], 3, ["--robots", "unknown robot 'robbie'", "g1"]),
    (["--robots", "talos,"], 2, ["--robots", "separated by commas"]),
    (["--workers", "0"], 2, ["--workers", "1 to 1024"]),
    (["--workers", "two"], 2, ["--workers", "whole number"]),
    (["--ray", " "], 2, ["--ray", "address is empty"]),
])
def test_bad_options_are_refused_before_any_work(tmp_path, capsys, tree, extra, code, words):
    """--robots, --workers and --ray are checked before anything is planned or written."""
    items = _batch(tmp_path, "squat\n")
    tree.before = tree.snapshot()
    outcome = run_cli(["batch", items, "--out-dir", tmp_path / "lib", "--no-sim", *extra], capsys)
    assert_refused(outcome, code, *words)
    tree.assert_unchanged()


def test_missing_file_and_bad_out_dir(tmp_path, capsys, tree):
    """A missing FILE, an --out-dir whose parent is missing, a file as --out-dir, a read-only folder."""
    assert_refused(run_cli(["batch", tmp_path / "nope.txt", "--out-dir", tmp_path / "lib"], capsys), 2,
                   "nope.txt", "does not exist")
    items = _batch(tmp_path, "squat\n")
    (tmp_path / "afile").write_text("x")
    tree.before = tree.snapshot()
    assert_refused(run_cli(["batch", items, "--out-dir", tmp_path / "no" / "lib"], capsys), 2,
                   "--out-dir", "does not exist")
    assert_refused(run_cli(["batch", items, "--out-dir", tmp_path / "afile"], capsys), 2,
                   "--out-dir", "not a folder")
    assert_refused(run_cli(["batch", items, "--out-dir", ""], capsys), 2, "--out-dir", "empty path")
    tree.assert_unchanged()


def test_a_motion_name_taken_by_a_folder_is_refused(tmp_path, capsys):
    """A folder where a motion file will go is refused before any work, naming it."""
    items = _batch(tmp_path, '{"instruction": "squat", "id": "sq"}\n', "items.jsonl")
    lib = tmp_path / "lib"
    (lib / "sq__talos.npz").mkdir(parents=True)
    outcome = run_cli(["batch", items, "--out-dir", lib, "--no-sim"], capsys)
    assert_refused(outcome, 2, "--out-dir", "sq__talos.npz", "directory")
    assert sorted(p.name for p in lib.iterdir()) == ["sq__talos.npz"]
