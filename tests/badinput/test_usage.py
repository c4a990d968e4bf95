"""Plain usage errors of every subcommand: the documented exit code, one line, no traceback.

Unknown options, missing arguments, unknown and empty names, very long arguments, NUL bytes,
control characters, ANSI escapes and undecodable (non-UTF-8) bytes in what the user typed.
Whatever the user typed is never sent raw to the terminal: the error line shows it escaped
(``\\x1b``, ``\\x00``, ``\\udcff``) and cut when it is huge. argparse's own errors print the
command's usage block, then one ``wbmp <command>: error:`` line (exit 2).

Exit codes: 2 bad usage (an option argparse refuses, an empty name, a sentence that is not
understood or too long), 3 an unknown robot or primitive (as ``wbmp solve`` gives for an unknown
robot). Every case here is refused before any planning, and leaves its folder as it was.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from tests.badinput.conftest import REPO, Tree, assert_refused, run_cli

RAW_UNSAFE = re.compile(r"[\x00-\x08\x0b-\x1f\x7f\x80-\x9f\u200b-\u200f\u202a-\u202e\u2066-\u2069\ud800-\udfff]")
SQ = REPO / "examples" / "specs" / "squat.json"
HUGE = "x" * 1_000_000


@pytest.fixture(autouse=True)
def _in_tmp(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Each case runs in an empty folder (``wbmp demo`` writes demo.html there by default)."""
    monkeypatch.chdir(tmp_path)


def _line(outcome) -> str:
    return next(ln for ln in outcome.err.splitlines() if ": error:" in ln)


def _assert_clean(outcome, limit: int = 1500) -> None:
    """No raw control, format or surrogate character anywhere on stderr; a bounded error line."""
    assert not RAW_UNSAFE.search(outcome.err), repr(outcome.err[-300:])
    assert len(_line(outcome)) <= limit, len(_line(outcome))


# ---- argparse's own usage errors: usage block + one error line, exit 2 ------------------------

ARGPARSE = [
    (["robots", "--nope"], ["wbmp robots: error:", "unrecognized arguments: --nope"]),
    (["actions", "--nope"], ["wbmp actions: error:", "--nope"]),
    (["demo", "--bogus"], ["wbmp demo: error:", "--bogus"]),
    (["solve", "squat", "--bogus"], ["wbmp solve: error:", "--bogus"]),
    (["parse", "squat", "--colour"], ["wbmp parse: error:", "--colour"]),
    (["bench", "--tasks", "squat", "--fast"], ["wbmp bench: error:", "--fast"]),
    (["show", "m.npz", "--port", "x"], ["wbmp show: error:", "--port", "'x'"]),
    (["export", "m.npz", "--format", "xml"], ["wbmp export: error:", "'xml'"]),
    (["parse"], ["wbmp parse: error:", "required", "text"]),
    (["show"], ["wbmp show: error:", "required", "motion"]),
    (["export"], ["wbmp export: error:", "required"]),
    (["actions", "--robot"], ["wbmp actions: error:", "--robot", "expected one argument"]),
    (["solve", "--spec"], ["wbmp solve: error:", "--spec", "expected one argument"]),
    (["solve", "squat", "--parser", "gpt"], ["wbmp solve: error:", "invalid choice", "'gpt'"]),
    (["bench", "--repeats", "x"], ["wbmp bench: error:", "--repeats", "'x'"]),
    (["bench", "--repeats", "1.5"], ["wbmp bench: error:", "--repeats", "'1.5'"]),
    (["bench", "--dt", "fast"], ["wbmp bench: error:", "--dt", "'fast'"]),
    (["bench", "--max-iterations", "1e3"], ["wbmp bench: error:", "--max-iterations", "'1e3'"]),
    (["robots", "--json=yes"], ["wbmp robots: error:", "--json"]),
    (["nope"], ["wbmp: error:", "invalid choice", "'nope'"]),
    ([], ["wbmp: error:", "give a command", "solve", "robots"]),
    (["robots", "--x\x1b[2J"], ["wbmp robots: error:", "--x\\x1b[2J"]),
    (["actions", "--\u202eevil"], ["wbmp actions: error:", "\\u202e"]),
    (["demo", "--bad\udcff"], ["wbmp demo: error:", "\\udcff"]),
    (["robots", "--" + "y" * 100_000], ["wbmp robots: error:", "characters cut"]),
]


@pytest.mark.parametrize(("argv", "words"), ARGPARSE, ids=lambda v: repr(v)[:40])
def test_argparse_usage_errors(argv, words, capsys, tmp_path):
    tree = Tree(tmp_path)
    outcome = run_cli(argv, capsys)
    assert_refused(outcome, 2, *words)
    assert "usage: wbmp" in outcome.err  # the command's usage block comes first
    _assert_clean(outcome)
    assert outcome.out == ""
    tree.assert_unchanged()


# ---- names: robots, actions -----------------------------------------------------------------

NAMES = [
    (["robots", ""], 2, ["robot name is empty", "talos"]),
    (["robots", "   "], 2, ["robot name is empty"]),
    (["robots", "talos", ""], 2, ["robot name is empty"]),
    (["robots", "NOPE"], 3, ["'NOPE'", "talos, g1"]),
    (["robots", "talos", "NOPE"], 3, ["'NOPE'"]),
    (["robots", "\x1b[31mred"], 3, ["\\x1b[31mred"]),
    (["robots", "a\x00b"], 3, ["a\\x00b"]),
    (["robots", "bad\udcff"], 3, ["\\udcff"]),
    (["robots", HUGE], 3, ["unknown robot"]),
    (["actions", "NOPE"], 3, ["'NOPE'", "known actions", "squat"]),
    (["actions", "squat", "NOPE"], 3, ["'NOPE'"]),
    (["actions", ""], 2, ["action name is empty", "wbmp actions"]),
    (["actions", "\t"], 2, ["action name is empty"]),
    (["actions", "\x07bell"], 3, ["\\x07bell"]),
    (["actions", "--robot", ""], 2, ["--robot is empty", "talos"]),
    (["actions", "--robot", " "], 2, ["--robot is empty"]),
    (["actions", "--robot", "NOPE"], 3, ["'NOPE'", "available"]),
    (["actions", "squat", "--robot", "\x1b]0;owned\x07"], 3, ["\\x1b]0;owned\\x07"]),
    (["actions", HUGE], 3, ["unknown action"]),
]


@pytest.mark.parametrize(("argv", "code", "words"), NAMES, ids=lambda v: repr(v)[:40])
def test_bad_names(argv, code, words, capsys, tmp_path):
    tree = Tree(tmp_path)
    outcome = run_cli(argv, capsys)
    assert_refused(outcome, code, *words)
    _assert_clean(outcome)
    assert outcome.out == ""  # every name is checked before anything is listed
    tree.assert_unchanged()


# ---- sentences: solve, parse, demo ----------------------------------------------------------

SENTENCES = [
    ("fly to the moon \x1b[31mnow\x1b[0m", ["could not understand", "\\x1b"]),
    ("squat \x00 twice", ["\\x00"]),
    ("jump \x07 \x1b]0;title\x07", ["\\x07"]),
    ("wave\nrm -rf /", ["could not understand"]),
    ("squat \u202eevil", ["\\u202e"]),
    ("squat \x9b31m", ["\\x9b"]),
    ("squat \udcff\udcfe", ["\\udcff"]),  # bytes 0xff 0xfe in argv (surrogateescape)
    ("glorp", ["could not understand", "glorp"]),
]


@pytest.mark.parametrize("command", ["solve", "parse"])
@pytest.mark.parametrize(("sentence", "words"), SENTENCES, ids=lambda v: repr(v)[:30])
def test_sentences_with_control_characters_are_escaped(command, sentence, words, capsys, tmp_path):
    tree = Tree(tmp_path)
    extra = ["--no-sim", "--out", str(tmp_path / "m.npz")] if command == "solve" else []
    outcome = run_cli([command, sentence, *extra], capsys)
    assert_refused(outcome, 2, *words)
    _assert_clean(outcome)
    assert "planning" not in outcome.err
    tree.assert_unchanged()


SOLVE = [
    (["solve", ""], 2, ["give an instruction"]),
    (["solve", "   "], 2, ["give an instruction"]),
    (["solve"], 2, ["give an instruction"]),
    (["solve", "squat", "--spec", str(SQ)], 2, ["either an instruction or --spec"]),
    (["solve", "squat", "--robot", ""], 2, ["--robot is empty"]),
    (["solve", "--spec", str(SQ), "--robot", "  "], 2, ["--robot is empty"]),
    (["solve", "squat", "--robot", "NOPE"], 3, ["'NOPE'", "available"]),
    (["solve", HUGE], 2, ["1,000,000 characters", "at most 10,000"]),
    (["solve", "squat " * 3000], 2, ["17,999 characters"]),
    (["parse", HUGE], 2, ["1,000,000 characters", "at most 10,000"]),  # solve's bound (issue 36)
    (["demo", ""], 2, ["sentence is empty"]),
    (["demo", " \t "], 2, ["sentence is empty"]),
    (["demo", "--robot", ""], 2, ["--robot is empty"]),
    (["demo", HUGE], 2, ["1,000,000 characters"]),
    (["demo", "--html", ""], 2, ["--html", "empty path"]),
    (["demo", "--out", ""], 2, ["--out", "empty path"]),
    (["demo", "--out", "demo.json"], 2, ["--out", "ends in .npz"]),
    (["demo", "--html", "nodir/d.html"], 2, ["--html", "does not exist"]),
    (["demo", "--html", "."], 2, ["--html"]),
    (["demo", "--html", "same.npz", "--out", "same.npz"], 2, ["same file"]),
    (["demo", "--robot", "NOPE", "--no-sim"], 3, ["'NOPE'"]),
]


@pytest.mark.parametrize(("argv", "code", "words"), SOLVE, ids=lambda v: repr(v)[:40])
def test_solve_and_demo_usage(argv, code, words, capsys, tmp_path):
    tree = Tree(tmp_path)
    outcome = run_cli(argv, capsys)
    assert_refused(outcome, code, *words)
    _assert_clean(outcome)
    assert "planning" not in outcome.err
    if argv[0] == "demo" and code == 2:
        assert outcome.out == ""  # refused before the banner
    tree.assert_unchanged()


def test_the_error_line_of_a_huge_argument_keeps_both_ends(capsys):
    """A long sentence quoted back is cut in the middle: its start and the hint at the end stay
    (the longest sentence wbmp reads, 10,000 characters; a longer one is refused unquoted)."""
    outcome = run_cli(["parse", "glorp" + "x" * 9_990 + "zz"], capsys)
    line = _line(outcome)
    assert line.startswith("wbmp parse: error: could not understand")
    assert "characters cut" in line and line.rstrip().endswith("wave")  # "... known actions are ..., wave"
    assert len(line) <= 1100


@pytest.mark.parametrize("argv", [
    [b"parse", b"squat \xff\xfe twice"],
    [b"solve", b"wave \xc3\x28", b"--no-sim"],
    [b"robots", b"tal\xffos"],
    [b"actions", b"\xe9quat"],
], ids=lambda v: repr(v)[:40])
def test_non_utf8_argv_in_a_real_process(argv, tmp_path):
    """Bytes that are not UTF-8 reach Python as lone surrogates; the error line shows them
    escaped and stderr stays valid UTF-8."""
    import os
    import subprocess
    import sys

    tree = Tree(tmp_path)
    proc = subprocess.run([sys.executable.encode(), b"-c", b"from wbmp.cli import run; run()", *argv],
                          cwd=tmp_path, capture_output=True, timeout=300,
                          env=dict(os.environ, PYTHONPATH=str(REPO)))
    err = proc.stderr.decode("utf-8")  # raises if a raw undecodable byte was echoed
    assert proc.returncode in (2, 3), err
    assert "Traceback" not in err
    errors = [ln for ln in err.splitlines() if ": error:" in ln]
    assert len(errors) == 1 and "\\udc" in errors[0], err
    tree.assert_unchanged()
