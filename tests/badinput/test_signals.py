"""Signals and a closed stdout, with real child processes.

- Ctrl-C (SIGINT): ``wbmp: interrupted``, exit 130; SIGTERM: ``wbmp: terminated``, exit 143.
  Either one leaves no output file and no temporary file (in the output folder, in ``$TMPDIR``
  or in the solver cache), also while IPOPT runs or while ``wbmp bench`` holds a temporary
  solver cache.
- A reader that goes away (``wbmp robots | head -1``) ends the command quietly, exit 0.

Each child is signalled right after it prints a given progress line (read from its stderr), not
after a fixed sleep; the waits are generous for a loaded 2-core machine.
"""

from __future__ import annotations

import os
import queue
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from tests.badinput.conftest import REPO, Tree

LINE_TIMEOUT = 240.0  # [s] until the awaited progress line (imports and builds on a busy machine)
EXIT_TIMEOUT = 120.0  # [s] from the signal to the exit


def _env(tmp: Path) -> dict[str, str]:
    """A child environment with its own TMPDIR and solver cache (both checked afterwards)."""
    env = dict(os.environ)
    env.pop("PYTHONUNBUFFERED", None)  # as a user runs it: stdout block-buffered into a pipe
    (tmp / "tmpdir").mkdir()
    (tmp / "cache").mkdir()
    env.update(TMPDIR=str(tmp / "tmpdir"), WBMP_CACHE_DIR=str(tmp / "cache"), WBMP_COMPILE="0",
               PYTHONPATH=str(REPO))
    return env


def _signal_after(argv: list[str], wait_for: str, sig: int, tmp: Path) -> tuple[int, str]:
    """Start ``wbmp ARGV``, send ``sig`` once a stderr line contains ``wait_for``; (exit code, stderr)."""
    proc = subprocess.Popen([sys.executable, "-c", "from wbmp.cli import run; run()", *argv], cwd=tmp / "work",
                            env=_env(tmp), stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True)
    lines: queue.Queue[str | None] = queue.Queue()

    def read() -> None:
        for line in proc.stderr:
            lines.put(line)
        lines.put(None)

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    seen: list[str] = []
    try:
        deadline = time.monotonic() + LINE_TIMEOUT
        while True:
            line = lines.get(timeout=max(0.1, deadline - time.monotonic()))
            if line is None:
                pytest.fail(f"wbmp exited ({proc.wait()}) before printing {wait_for!r}: {''.join(seen)}")
            seen.append(line)
            if wait_for in line:
                break
        proc.send_signal(sig)
        code = proc.wait(timeout=EXIT_TIMEOUT)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        reader.join(timeout=EXIT_TIMEOUT)
        proc.stderr.close()
    while not lines.empty():
        line = lines.get()
        if line is not None:
            seen.append(line)
    return code, "".join(seen)


def _leftovers(root: Path) -> list[str]:
    return sorted(str(p.relative_to(root)) for p in root.rglob("*"))


@pytest.fixture
def work(tmp_path: Path) -> Path:
    (tmp_path / "work").mkdir()
    return tmp_path


CASES = [
    # (signal, expected exit, last line) x (argv, the line after which the signal is sent)
    pytest.param(signal.SIGINT, 130, "wbmp: interrupted", id="sigint-while-ipopt-solves",
                 marks=pytest.mark.long),  # make test-long (~12 s): SIGTERM below is the same path
    pytest.param(signal.SIGTERM, 143, "wbmp: terminated", id="sigterm-while-ipopt-solves"),
]


@pytest.mark.slow
@pytest.mark.parametrize(("sig", "code", "last"), CASES)
def test_signal_while_solving_leaves_nothing(sig, code, last, work):
    """Eight squats (18 s of motion) give IPOPT seconds of work after ``solving (...)`` is printed.

    CasADi catches the interrupt inside IPOPT and reports a failed solve; wbmp still stops at
    once (no "the solve failed: diagnosing", which would take as long again) with the signal's code.
    """
    out = work / "work"
    tree = Tree(out)
    got, err = _signal_after(["solve", "squat 8 times", "--no-sim", "--out", str(out / "m.npz"),
                              "--html", str(out / "m.html")], "solving (", sig, work)
    assert got == code, err
    assert err.rstrip().splitlines()[-1] == last, err
    assert "Traceback" not in err and ": error:" not in err
    assert "diagnosing" not in err and "writing" not in err
    tree.assert_unchanged()
    assert _leftovers(work / "tmpdir") == [] and _solver_leftovers(work / "cache") == []


def _solver_leftovers(cache: Path) -> list[str]:
    """What the interrupted solve left in the cache. The entries published before the solve started
    are complete and not counted: the collision model (whole JSON), the robot's geometry
    (``robots/<key>/``: ``manifest.json`` and ``geometry.bin``) and the MuJoCo model
    (``mujoco/<key>/``: ``meta.json`` and ``model.mjb``); each manifest must be whole JSON."""
    import json

    for path in (cache / "collision").glob("*.json"):
        json.loads(path.read_text(encoding="utf-8"))
    complete = {"robots": ("geometry.bin", "manifest.json"), "mujoco": ("model.mjb", "meta.json")}
    allowed = {"collision"} | set(complete)
    for kind, (binary, manifest) in complete.items():
        for entry in (cache / kind).glob("*"):
            if (entry / binary).is_file() and (entry / manifest).is_file():
                json.loads((entry / manifest).read_text(encoding="utf-8"))
                allowed |= {f"{kind}/{entry.name}", f"{kind}/{entry.name}/{binary}", f"{kind}/{entry.name}/{manifest}"}
    return [p for p in _leftovers(cache) if p not in allowed
            and not (p.startswith("collision/") and p.endswith(".json") and p.count("/") == 1)]


@pytest.mark.slow
def test_sigterm_while_building_leaves_nothing(work):
    out = work / "work"
    tree = Tree(out)
    got, err = _signal_after(["solve", "squat 5 times", "--no-sim", "--out", str(out / "m.npz")],
                             "building the solver", signal.SIGTERM, work)
    assert got == 143, err
    assert err.rstrip().splitlines()[-1] == "wbmp: terminated" and "Traceback" not in err
    tree.assert_unchanged()
    assert _leftovers(work / "tmpdir") == []


@pytest.mark.slow
def test_sigterm_during_bench_removes_its_temporary_solver_cache(work):
    """``wbmp bench`` (not --quick) plans each task with a fresh solver cache in $TMPDIR."""
    out = work / "work"
    tree = Tree(out)
    got, err = _signal_after(["bench", "--tasks", "squat", "--repeats", "1", "--no-compile", "--no-sim", "--no-e2e",
                              "--no-scaling", "--json", str(out / "r.json")],
                             "planning (first-ever", signal.SIGTERM, work)
    assert got == 143, err
    assert err.rstrip().splitlines()[-1] == "wbmp: terminated" and "Traceback" not in err
    tree.assert_unchanged()
    assert _leftovers(work / "tmpdir") == []


@pytest.mark.parametrize("argv", [["robots"], ["robots", "--json"], ["actions"], ["actions", "--json"],
                                  ["actions", "squat", "--robot", "g1"]], ids=" ".join)
def test_closed_stdout_is_quiet(argv, tmp_path):
    """``wbmp robots | head -0``: stdout's reader is gone before the first write."""
    read_end, write_end = os.pipe()
    os.close(read_end)
    try:
        proc = subprocess.run([sys.executable, "-c", "from wbmp.cli import run; run()", *argv], cwd=tmp_path,
                              env={k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"},
                              stdin=subprocess.DEVNULL, stdout=write_end, stderr=subprocess.PIPE, text=True,
                              timeout=300)
    finally:
        os.close(write_end)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""  # no "Exception ignored ... BrokenPipeError", no traceback


def test_output_through_head_is_the_first_line(tmp_path):
    """The real pipeline: ``wbmp robots | head -1`` prints talos's line, and wbmp says nothing."""
    proc = subprocess.run(f"{sys.executable} -c 'from wbmp.cli import run; run()' robots | head -1",
                          shell=True, cwd=tmp_path, capture_output=True, text=True, timeout=300,
                          env={k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"})
    assert proc.returncode == 0
    assert proc.stdout.startswith("talos ") and "(default)" in proc.stdout and proc.stdout.count("\n") == 1
    assert proc.stderr == ""
