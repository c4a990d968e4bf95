"""``wbmp bench``: a benchmark whose tasks fail exits non-zero; its own options are checked first.

The issue: ``wbmp bench`` exited 0 when every task failed. Now the exit code is 0 only when every
task class that ran passed (``n/a (not implemented)`` does not count); otherwise the code
``wbmp solve`` would give for the first failing task: 3 spec, 4 plan, 5 simulation check. The
report is printed and the files written either way. The failure here is real, not a mock:
``--max-iterations 1`` stops IPOPT after one iteration, so no plan meets its constraints.

Bad options (counts, repeats, knot spacing, task names, robots, output paths, ``--from`` files)
are refused with one line before any work, and leave the folder as it was.
"""

from __future__ import annotations

import contextlib
import copy
import io
import json
import os
from pathlib import Path

import pytest

from tests.badinput.conftest import Outcome, Tree, assert_refused, run_cli

FAILING = ["bench", "--quick", "--tasks", "squat,reach", "--repeats", "1", "--dt", "0.5", "--no-compile",
           "--no-sim", "--no-e2e", "--max-iterations", "1", "--quiet"]
_ENV = ("WBMP_BENCH_COMPILE", "WBMP_COMPILE_BACKGROUND", "WBMP_CACHE_DIR")


@pytest.fixture(scope="module")
def failed_run(tmp_path_factory) -> tuple[Outcome, Path, Path]:
    """Every task of a real (tiny) benchmark fails: (outcome, JSON, Markdown)."""
    folder = tmp_path_factory.mktemp("bench-exit")
    from wbmp.cli import main

    out, err = io.StringIO(), io.StringIO()
    with pytest.MonkeyPatch.context() as mp:  # restores what the bench command sets, too
        for k in _ENV:
            if k in os.environ:
                mp.setenv(k, os.environ[k])
            else:
                mp.delenv(k, raising=False)
        mp.setenv("WBMP_CACHE_DIR", str(folder / "cache"))
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code = main([*FAILING, "--json", str(folder / "r.json"), "--markdown", str(folder / "r.md")])
    return Outcome(int(code), out.getvalue(), err.getvalue()), folder / "r.json", folder / "r.md"


def test_every_task_failing_exits_4_with_the_report(failed_run):
    outcome, json_path, md_path = failed_run
    assert_refused(outcome, 4, "wbmp bench: error:", "2 of 2 task classes failed", "squat, reach",
                   "squat: plan failed", "iteration limit")
    for name in ("squat", "reach"):  # the report is still printed...
        assert any(ln.startswith(name) for ln in outcome.out.splitlines()), outcome.out
    result = json.loads(json_path.read_text())  # ...and written
    assert {n: r["status"] for n, r in result["tasks"].items()} == {"squat": "plan failed", "reach": "plan failed"}
    # one iteration a solve: the first, and the fallback with the idle self-collision rows that a solve
    # stopped at the iteration limit gets (planner/trajopt/api.py)
    assert all(r["iterations"] in (1, 2) and r["checks_ok"] is False for r in result["tasks"].values())
    assert result["max_iterations"] == 1
    assert result["tasks"]["squat"]["cold_process_s"] is None  # a failed plan is not timed further
    assert "| squat |" in md_path.read_text()


def _from(result: dict, tmp_path: Path, capsys, *extra: str) -> Outcome:
    src = tmp_path / "in.json"
    src.write_text(json.dumps(result))
    tree = Tree(tmp_path)
    outcome = run_cli(["bench", "--from", str(src), *extra], capsys)
    tree.assert_unchanged()
    return outcome


def _edit(result: dict, **tasks: dict) -> dict:
    out = copy.deepcopy(result)
    for name, fields in tasks.items():
        out["tasks"][name].update(fields)
    return out


OK = {"status": "ok", "message": "", "checks_ok": True}


@pytest.mark.parametrize(("tasks", "code", "words"), [
    ({}, 4, ["2 of 2", "squat: plan failed"]),
    ({"squat": OK}, 4, ["1 of 2", "(reach)", "reach: plan failed"]),
    ({"squat": OK, "reach": OK}, 0, []),
    ({"squat": dict(OK, certified=False, certificate_reason="fell at t = 1.20 s"), "reach": OK}, 5,
     ["1 of 2", "squat: simulation check failed", "fell at t = 1.20 s"]),
    ({"squat": {"status": "simulation failed", "message": "simulate: SimModelError: no floor"}, "reach": OK}, 5,
     ["squat: simulation failed", "no floor"]),
    ({"squat": {"status": "failed at parse/spec", "message": "parse/spec: TaskError: bad"}}, 3,
     ["squat: failed at parse/spec"]),
    ({"squat": dict(OK, e2e_exit_code=5), "reach": OK}, 5, ["`wbmp solve` exited 5"]),
    ({"squat": {"status": "n/a (not implemented)"}, "reach": {"status": "n/a (not implemented)"}}, 0, []),
    ({"squat": {"status": "n/a (not implemented)"}, "reach": dict(OK, certified=True)}, 0, []),
], ids=["all-fail", "one-fails", "all-ok", "not-certified", "sim-crashed", "spec", "e2e", "all-na", "na-and-ok"])
def test_exit_code_of_a_result(failed_run, tasks, code, words, tmp_path, capsys):
    """``--from`` applies the documented rule to a result (the real failed run, edited)."""
    result = _edit(json.loads(failed_run[1].read_text()), **tasks)
    outcome = _from(result, tmp_path, capsys)
    if code == 0:
        assert outcome.code == 0 and ": error:" not in outcome.err, outcome.err
        assert "squat" in outcome.out
    else:
        assert_refused(outcome, code, *words)
        assert "squat" in outcome.out and "reach" in outcome.out  # the report comes first


# ---- bench's own options: refused before any work ------------------------------------------

OPTIONS = [
    (["--tasks", ""], 2, ["--tasks names no task class", "squat"]),
    (["--tasks", ",,"], 2, ["--tasks names no task class"]),
    (["--tasks", " , "], 2, ["--tasks names no task class"]),
    (["--tasks", "moonwalk"], 2, ["'moonwalk'", "choose from"]),
    (["--tasks", "squat,moonwalk"], 2, ["'moonwalk'"]),
    (["--tasks", "squat,\x1b[31mred"], 2, ["\\x1b[31mred"]),
    (["--tasks", "x" * 100_000], 2, ["unknown task class"]),
    (["--repeats", "0"], 2, ["--repeats", "from 1 to 50", "got 0"]),
    (["--repeats", "-1"], 2, ["--repeats", "got -1"]),
    (["--repeats", "51"], 2, ["--repeats", "got 51"]),
    (["--repeats", "1000000000"], 2, ["--repeats", "got 1000000000"]),
    (["--dt", "nan"], 2, ["--dt", "0.005 to 0.5 s", "got nan"]),
    (["--dt", "inf"], 2, ["--dt", "got inf"]),
    (["--dt", "0"], 2, ["--dt", "got 0"]),
    (["--dt", "-0.1"], 2, ["--dt", "got -0.1"]),
    (["--dt", "1e-9"], 2, ["--dt", "got 1e-09"]),
    (["--dt", "10"], 2, ["--dt", "got 10"]),
    (["--max-iterations", "0"], 2, ["--max-iterations", "got 0"]),
    (["--max-iterations", "-5"], 2, ["--max-iterations", "got -5"]),
    (["--max-iterations", "100000"], 2, ["--max-iterations", "from 1 to 10000"]),
    (["--robot", ""], 2, ["--robot is empty"]),
    (["--robot", "  "], 2, ["--robot is empty"]),
    (["--robot", "NOPE", "--tasks", "squat"], 3, ["'NOPE'", "available"]),
    (["--robot", "\x1b[2J", "--tasks", "squat"], 3, ["\\x1b[2J"]),
    (["--peers-dir", ""], 2, ["--peers-dir is empty"]),
    (["--json", ""], 2, ["--json", "empty path"]),
    (["--json", "{tmp}"], 2, ["--json", "is a directory"]),
    (["--json", "{tmp}/nodir/r.json"], 2, ["--json", "does not exist"]),
    (["--json", "/dev/null"], 2, ["--json", "not a regular file"]),
    (["--markdown", "{tmp}/"], 2, ["--markdown"]),
    (["--json", "{tmp}/r.json", "--markdown", "{tmp}/r.json"], 2, ["same file"]),
    (["--plot", "{tmp}", "--scaling"], 2, ["--plot", "is a directory"]),
    (["--json", "{tmp}/nodir/r.json", "--quick"], 2, ["--json", "does not exist"]),
]


@pytest.mark.parametrize(("argv", "code", "words"), OPTIONS, ids=lambda v: repr(v)[:40])
def test_bad_options_are_refused_before_any_work(argv, code, words, tmp_path, capsys):
    tree = Tree(tmp_path)
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    outcome = run_cli(["bench", "--no-sim", "--no-e2e", "--no-compile", *argv], capsys)
    assert_refused(outcome, code, *words)
    assert outcome.out == "" and "planning" not in outcome.err
    tree.assert_unchanged()


def _deep(tmp: Path) -> Path:
    p = tmp / "deep.json"
    p.write_text("[" * 100_000 + "]" * 100_000)
    return p


FROM = [
    (lambda t: t / "missing.json", ["--from", "cannot read it"]),
    (lambda t: t, ["--from", "is a directory"]),
    (lambda t: _fifo(t), ["--from", "not a regular file"]),
    (lambda t: Path("/dev/zero"), ["--from", "not a regular file"]),
    (lambda t: _write(t, b"\xff\xfe{}"), ["--from", "not UTF-8"]),
    (lambda t: _write(t, b"{not json"), ["--from", "not JSON"]),
    (lambda t: _write(t, b""), ["--from", "not JSON"]),
    (lambda t: _write(t, b"[]"), ["not a `wbmp bench --json` result"]),
    (lambda t: _write(t, b'{"schema": "wbmp-bench/0"}'), ["not a `wbmp bench --json` result"]),
    (_deep, ["--from", "nested too deeply"]),
    (lambda t: _write(t, b'{"schema": "wbmp-bench/1", "tasks": []}'), ["--from", "'tasks'"]),
    (lambda t: _write(t, b'{"schema": "wbmp-bench/1", "tasks": {"squat": {"status": 1}}}'), ["--from", "'status'"]),
    (lambda t: _write(t, b'{"schema": "wbmp-bench/1", "tasks": {"squat": {"status": "ok"}}}'),
     ["--from", "incomplete or damaged"]),
]


def _fifo(tmp: Path) -> Path:
    os.mkfifo(tmp / "fifo.json")  # no writer: opening it for reading must not hang
    return tmp / "fifo.json"


def _write(tmp: Path, data: bytes) -> Path:
    p = tmp / "bad.json"
    p.write_bytes(data)
    return p


@pytest.mark.parametrize(("make", "words"), FROM, ids=[f"from-{i}" for i in range(len(FROM))])
def test_bad_from_files_are_refused(make, words, tmp_path, capsys):
    path = make(tmp_path)
    tree = Tree(tmp_path)
    outcome = run_cli(["bench", "--from", str(path), "--markdown", str(tmp_path / "out.md")], capsys)
    assert_refused(outcome, 2, *words)
    tree.assert_unchanged()


def test_from_and_json_on_one_file_is_refused(failed_run, tmp_path, capsys):
    src = tmp_path / "r.json"
    src.write_text(failed_run[1].read_text())
    tree = Tree(tmp_path)
    outcome = run_cli(["bench", "--from", str(src), "--json", str(src)], capsys)
    assert_refused(outcome, 2, "same file")
    tree.assert_unchanged()


def test_help_documents_the_exit_codes(capsys):
    """``wbmp bench --help`` says what a failing task means for the exit code."""
    outcome = run_cli(["bench", "--help"], capsys)
    assert outcome.code == 0
    assert "exit codes:" in outcome.out and "3/4/5" in outcome.out and "--max-iterations N" in outcome.out
