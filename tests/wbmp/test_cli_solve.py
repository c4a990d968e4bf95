"""``wbmp solve --spec``: exit codes and outputs, through wbmp.cli.main."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tasks.serialize import spec_to_json
from tests.planner.planning_cases import squat_spec
from wbmp.cli import main
from wbmp.motionfile import load_motion

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "specs"


@pytest.fixture(autouse=True)
def _no_compilation(monkeypatch, tmp_path):
    """The CLI builds solvers in memory here (the disk cache has its own tests)."""
    monkeypatch.setenv("WBMP_COMPILE", "0")
    monkeypatch.setenv("WBMP_CACHE_DIR", str(tmp_path / "cache"))


def test_example_squat_solves_and_writes_the_motion_file(tmp_path, capsys):
    """Exit 0, the summary on stdout, progress on stderr, and a loadable motion file."""
    out = tmp_path / "squat.npz"
    code = main(["solve", "--spec", str(EXAMPLES / "squat.json"), "--no-sim", "--out", str(out)])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    assert "plan: solved" in captured.out and "solving (" in captured.err
    motion = load_motion(out)
    assert motion.plan.ok and motion.robot_name == "talos"


def test_json_output_and_quiet(tmp_path, capsys):
    """--json prints one JSON document; --quiet silences stderr."""
    code = main(["solve", "--spec", str(EXAMPLES / "squat.json"), "--no-sim", "--quiet", "--json"])
    captured = capsys.readouterr()
    assert code == 0 and captured.err == ""
    report = json.loads(captured.out)
    assert report["solver"]["status"] == "solved" and report["robot"] == "talos"


def test_infeasible_spec_exits_4_with_the_diagnosis(tmp_path, capsys, talos):
    """An impossible balance margin exits 4 with a one-line diagnosis naming the bound and phase."""
    path = tmp_path / "wide.json"
    path.write_text(spec_to_json(squat_spec(talos, 0.1, margin=0.3)))
    code = main(["solve", "--spec", str(path), "--no-sim", "--quiet"])
    err = capsys.readouterr().err
    assert code == 4
    assert err.count("\n") == 1 and "CoM bound 'balance' cannot hold in phase 'squat'" in err


def test_unknown_frame_exits_3(tmp_path, capsys):
    """A spec naming a frame the robot lacks is an invalid spec (exit 3), with a suggestion."""
    doc = json.loads((EXAMPLES / "reach.json").read_text())
    doc["targets"][0]["frame"] = "right_hnad"
    path = tmp_path / "typo.json"
    path.write_text(json.dumps(doc))
    assert main(["solve", "--spec", str(path), "--no-sim", "--quiet"]) == 3
    assert "right_hnad" in capsys.readouterr().err


def test_bad_json_exits_3(tmp_path, capsys):
    """Malformed JSON is an invalid spec (exit 3) with line and column."""
    path = tmp_path / "broken.json"
    path.write_text('{"phases": [')
    assert main(["solve", "--spec", str(path), "--no-sim"]) == 3
    assert "invalid JSON" in capsys.readouterr().err


def test_sentence_plus_spec_and_missing_input_are_usage_errors(capsys):
    """A sentence together with --spec, or no input at all, is a usage error: exit 2."""
    assert main(["solve", "squat twice", "--spec", str(EXAMPLES / "squat.json")]) == 2
    assert "not both" in capsys.readouterr().err
    assert main(["solve"]) == 2
    assert "give an instruction" in capsys.readouterr().err
    assert main(["solve", "fly to the moon", "--no-sim"]) == 2
    assert 'could not understand "fly"' in capsys.readouterr().err
    assert main(["solve", "squat", "--push", "80@1.5", "--no-sim"]) == 2
    assert main(["solve", "squat", "--push", "eighty"]) == 2
    assert "--push" in capsys.readouterr().err
