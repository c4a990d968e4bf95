"""The smaller cases of issue 36: joint names a bag or tracker file cannot carry, a terminal
that cannot show Chinese, and a missing input named as such (not as a missing output folder)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from tests.badinput.conftest import REPO, Tree, assert_refused, run_cli, run_cli_process
from wbmp.errors import ExitCode


def _names(src: Path, dst: Path, change) -> Path:
    with np.load(src) as z:
        arrays = {k: z[k] for k in z.files}
    names = [str(n) for n in arrays["joint_names"]]
    arrays["joint_names"] = np.array(change(names), dtype=str)
    np.savez(dst, **arrays)
    return dst


NAMES = {
    "duplicate": (lambda n: [n[0], n[0], *n[2:]], "twice"),
    "empty": (lambda n: ["", *n[1:]], "unusable name"),
    "blank": (lambda n: [*n[:-1], "   "], "unusable name"),
    "control character": (lambda n: [n[0] + "\x1b[31m", *n[1:]], "unusable name"),
}


@pytest.mark.parametrize("fmt", ["mcap", "tracker"])
@pytest.mark.parametrize("case", NAMES)
def test_joint_names_a_bag_or_tracker_cannot_carry_are_refused(motion_file, tmp_path, capsys, case, fmt):
    change, words = NAMES[case]
    motion = _names(motion_file, tmp_path / "m.npz", change)
    tree = Tree(tmp_path)
    outcome = run_cli(["export", motion, "--format", fmt, "--out", tmp_path / f"m.{fmt}"], capsys)
    assert_refused(outcome, ExitCode.USAGE, "joint_names", words)
    tree.assert_unchanged()


def test_json_export_keeps_whatever_names_the_file_has(motion_file, tmp_path, capsys):
    motion = _names(motion_file, tmp_path / "m.npz", NAMES["duplicate"][0])
    assert run_cli(["export", motion, "--format", "json", "--out", tmp_path / "m.json"], capsys).code == 0


@pytest.mark.parametrize("argv", [["parse", "挥手三次"], ["parse", "挥手三次", "--json"], ["parse", "挥手 xyz"]],
                         ids=["text", "json", "error"])
def test_an_ascii_terminal_gets_escapes_not_a_traceback(argv):
    outcome = run_cli_process(argv, env={"PYTHONIOENCODING": "ascii", "PYTHONPATH": str(REPO)}, timeout=120)
    assert "Traceback" not in outcome.err
    assert outcome.code == (ExitCode.USAGE if "xyz" in argv[1] else ExitCode.OK), outcome.err
    if argv[-1] == "--json":
        assert json.loads(outcome.out)["actions"] == [{"action": "wave", "params": {"repeat": 3}}]
    elif outcome.code == 0:
        assert "\\u6325\\u624b" in outcome.out  # 挥手, escaped


@pytest.mark.parametrize(("argv", "code", "words"), [
    (["export", "{d}/gone/m.npz"], ExitCode.USAGE, ("motion file", "gone/m.npz", "does not exist")),
    (["export", "{d}/gone/m.npz", "--out", "{d}/gone/m.json"], ExitCode.USAGE, ("motion file", "does not exist")),
    (["show", "{d}/gone/m.npz", "--html", "{d}/gone/m.html"], ExitCode.USAGE, ("motion file", "does not exist")),
    (["solve", "--spec", "{d}/gone/s.json", "--out", "{d}/gone/m.npz"], ExitCode.INVALID_SPEC,
     ("spec file", "does not exist")),
    (["solve", "wave", "--scene", "{d}/gone/s.json", "--out", "{d}/gone/m.npz"], ExitCode.INVALID_SPEC,
     ("scene file", "does not exist")),
], ids=["export", "export --out", "show --html", "solve --spec", "solve --scene"])
def test_a_missing_input_is_named_not_the_output_folder(tmp_path, capsys, monkeypatch, argv, code, words):
    monkeypatch.setenv("WBMP_CACHE_DIR", str(tmp_path / "cache"))
    tree = Tree(tmp_path)
    outcome = run_cli([a.format(d=tmp_path) for a in argv], capsys)
    assert_refused(outcome, code, *words)
    assert "folder" not in outcome.err
    tree.assert_unchanged()
