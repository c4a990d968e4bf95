"""``wbmp batch``: refused input is one line before any work, and nothing is written."""

from __future__ import annotations

from pathlib import Path

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
    ('{"instruction": "squat"}\n{"spec": {"phases": [{"duration": NaN}]}}\n', "items.jsonl", 2,
     ["items.jsonl:2", "NaN is not finite"]),
    ('{"spec": {"phases": [{"duration": 1e999}]}}\n', "items.jsonl", 2, [":1", "1e999 is not finite"]),
    ('{"instruction": "squat", "id": Infinity}\n', "items.jsonl", 2, [":1", "Infinity is not finite"]),
    ('{"instruction": "squat", "robot": ' + "9" * 5000 + "}\n", "items.jsonl", 2, [":1", "too many digits"]),
    ('{"instruction": "squat \\udc80"}\n', "items.jsonl", 2, [":1", "lone surrogate"]),
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


def _jsonl(tmp_path, *records: dict) -> Path:
    import json

    path = tmp_path / "items.jsonl"
    path.write_text("".join(json.dumps(r) + "\n" for r in records))
    return path


def test_a_damaged_index_is_reported_and_mended_not_crashed_on(tmp_path, capsys):
    """Resume over an index whose record lacks a field (was: KeyError), a torn line and a NaN:
    each damaged line is named on stderr, its item planned again, the index rewritten with valid
    records only; the exit code is the item's own (2: not understood)."""
    import json

    from wbmp.batch.index import read_index_report

    items = _jsonl(tmp_path, {"id": "moon", "instruction": "fly to the moon"})
    lib = tmp_path / "lib"
    argv = ["batch", items, "--out-dir", lib, "--no-sim", "--workers", "1"]
    assert run_cli(argv, capsys).code == 2
    record = json.loads((lib / "index.jsonl").read_text())
    del record["message"]
    damaged = json.dumps(record) + "\n" + '{"id": "moon", "robot": "ta' + "\n"
    damaged += json.dumps({**record, "message": "x", "line": float("nan")}) + "\n"
    (lib / "index.jsonl").write_text(damaged)
    outcome = run_cli(argv, capsys)
    assert "Traceback" not in outcome.err and outcome.code == 2, outcome.err
    assert "3 damaged lines left out" in outcome.err and "line 1: 'message' is missing" in outcome.err
    assert "1 planned now, 0 done before" in outcome.out
    records, notes = read_index_report(lib / "index.jsonl")
    assert notes == [] and list(records) == [("moon", "talos")]
    assert records[("moon", "talos")]["message"].startswith("could not understand")


def test_files_and_records_that_disagree_are_mended_at_the_start(tmp_path, capsys):
    """What a killed batch can leave: a motion file of an item with no record (removed), a
    record naming a motion file that is gone (dropped), a temporary file (removed); a motion
    file of no item of this batch is left alone."""
    import json

    items = _jsonl(tmp_path, {"id": "moon", "instruction": "fly to the moon"})
    lib = tmp_path / "lib"
    lib.mkdir()
    (lib / "moon__talos.npz").write_bytes(b"a motion a killed worker wrote")
    (lib / ".moon__talos.npz.0123abcd.tmp").write_bytes(b"half")
    (lib / "mine__talos.npz").write_bytes(b"not the batch's")
    gone = {"id": "gone", "robot": "talos", "line": 1, "instruction": "bow", "status": "ok", "exit_code": 0,
            "certificate": None, "message": "", "timings": {}, "cached": False, "motion": "gone__talos.npz",
            "sha256": "0" * 64, "input_sha256": "1" * 64, "worker": None}
    (lib / "index.jsonl").write_text(json.dumps(gone) + "\n")
    outcome = run_cli(["batch", items, "--out-dir", lib, "--no-sim", "--workers", "1"], capsys)
    assert "Traceback" not in outcome.err and outcome.code == 2, outcome.err
    assert "moon__talos.npz removed (no record of it in the index)" in outcome.err
    assert "record of gone__talos.npz dropped (the file is missing)" in outcome.err
    assert sorted(p.name for p in lib.iterdir()) == ["index.jsonl", "mine__talos.npz", "summary.md"]
    ids = [json.loads(line)["id"] for line in (lib / "index.jsonl").read_text().splitlines()]
    assert ids == ["moon"]
