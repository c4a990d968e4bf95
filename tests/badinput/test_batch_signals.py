"""A user's stop of a running ``wbmp batch``: real processes, real signals.

A batch of four sentences runs on two spawned workers (``--no-cache``: each item is planned). Once
its first record is reported (the workers are up and busy), the batch gets SIGTERM, SIGINT (as
Ctrl-C would send it: the workers lead their own process groups) or SIGKILL. Every process below
the batch (the workers, the pool's resource tracker) must be gone within :data:`GONE_WITHIN`, the
batch must exit 143 / 130 within :data:`EXIT_WITHIN`, and the folder must be consistent: every
motion file named by a valid index record with its sha256, every ok record's file present, no
temporary file. After SIGKILL (no clean-up possible) the next run of the same batch makes it so.
Each run has its own ``WBMP_CACHE_DIR`` and ``TMPDIR``.
"""

from __future__ import annotations

import hashlib
import json
import os
import queue
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from tests.badinput.conftest import REPO
from wbmp.batch.index import read_index_report

LINE_TIMEOUT = 240.0  # [s] until the first record is reported (imports, plans on a busy machine)
EXIT_WITHIN = 20.0  # [s] from SIGTERM/SIGINT to the batch's exit (measured: ~1.5 s; was ~41 s)
GONE_WITHIN = 10.0  # [s] from the batch's exit to the last of its children gone

SENTENCES = ["squat", "wave your right hand", "bow", "wave your left hand"]


def _env(root: Path) -> dict[str, str]:
    env = dict(os.environ)
    env.update(WBMP_COMPILE="0", WBMP_CACHE_DIR=str(root / "cache"), PYTHONPATH=str(REPO),
               TMPDIR=str(root / "tmp"))
    return env


@pytest.fixture
def batch(tmp_path) -> tuple[Path, Path]:
    """(the batch file, the folder holding it and the run's own solver cache and tmp folders)."""
    root = tmp_path / "run"
    (root / "cache").mkdir(parents=True)
    (root / "tmp").mkdir()
    items = root / "items.jsonl"
    items.write_text("".join(json.dumps({"id": f"i{n}", "instruction": s}) + "\n" for n, s in enumerate(SENTENCES)))
    return items, root


def _parents() -> dict[int, int]:
    """pid -> parent pid of every process (from /proc)."""
    out = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                stat = Path(f"/proc/{entry}/stat").read_text()
            except OSError:
                continue
            out[int(entry)] = int(stat.rsplit(")", 1)[1].split()[1])
    return out


def _descendants(pid: int) -> dict[int, str]:
    """Every process below ``pid``: pid -> its start time (to tell a reused pid)."""
    parents = _parents()
    found: dict[int, str] = {}
    frontier = [pid]
    while frontier:
        parent = frontier.pop()
        for child, ppid in parents.items():
            if ppid == parent and child not in found:
                found[child] = _start_time(child) or ""
                frontier.append(child)
    return found


def _start_time(pid: int) -> str | None:
    """The start time of a live (not zombie) process, None when it is gone."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return None
    return None if fields[0] in ("Z", "X") else fields[19]


def _workers_lead_their_groups(children: dict[int, str]) -> None:
    """Each pool worker (a ``spawn_main`` process) leads its own process group; the batch's
    group holds none of them (a terminal's Ctrl-C reaches the batch only)."""
    workers = []
    for pid in children:
        try:
            cmdline = Path(f"/proc/{pid}/cmdline").read_bytes()
        except OSError:
            continue
        if b"spawn_main" in cmdline:
            workers.append(pid)
    assert len(workers) == 2, children
    deadline = time.monotonic() + 60.0  # a worker that is still starting sets its group in its initializer
    while any(os.getpgid(pid) != pid for pid in workers) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert [os.getpgid(pid) for pid in workers] == workers


def _alive(children: dict[int, str]) -> list[int]:
    return [pid for pid, start in children.items() if _start_time(pid) == start]


def _stop_after_first_record(items: Path, root: Path, out: Path, sig: int,
                             extra: tuple[str, ...] = ()) -> tuple[int, float, dict[int, str], str]:
    """Start the batch, send ``sig`` once its first record is reported; (exit code, seconds from
    the signal to the exit, its children when signalled, stderr)."""
    proc = subprocess.Popen([sys.executable, "-m", "wbmp.cli", "batch", str(items), "--out-dir", str(out),
                             "--no-sim", "--no-cache", "--workers", "2", *extra], env=_env(root),
                            stdin=subprocess.DEVNULL,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    lines: queue.Queue[str | None] = queue.Queue()

    def read() -> None:
        assert proc.stderr is not None
        for line in proc.stderr:
            lines.put(line)
        lines.put(None)

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    seen: list[str] = []
    children: dict[int, str] = {}
    try:
        deadline = time.monotonic() + LINE_TIMEOUT
        while True:
            line = lines.get(timeout=max(0.1, deadline - time.monotonic()))
            if line is None:
                pytest.fail(f"the batch exited ({proc.wait()}) before its first record: {''.join(seen)}")
            seen.append(line)
            if "[1/" in line:
                break
        children = _descendants(proc.pid)
        if not extra:  # the local pool
            _workers_lead_their_groups(children)
        proc.send_signal(sig)
        t0 = time.monotonic()
        code = proc.wait(timeout=120)
        took = time.monotonic() - t0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        reader.join(timeout=30)
        if proc.stderr is not None:
            proc.stderr.close()
    while not lines.empty():
        line = lines.get()
        if line is not None:
            seen.append(line)
    return code, took, children, "".join(seen)


def _wait_gone(children: dict[int, str]) -> list[int]:
    deadline = time.monotonic() + GONE_WITHIN
    while _alive(children) and time.monotonic() < deadline:
        time.sleep(0.1)
    return _alive(children)


def _assert_consistent(out: Path) -> dict[tuple[str, str], dict]:
    """Every line a valid record; every motion file named by its record with its sha256; every
    ok record's file present; no temporary file."""
    records, damaged = read_index_report(out / "index.jsonl")
    assert damaged == []
    named = {rec["motion"]: rec for rec in records.values() if rec["motion"] is not None}
    files = {p.name for p in out.iterdir() if p.name.endswith(".npz")}
    assert files == set(named), (files, set(named))
    for name, rec in named.items():
        assert hashlib.sha256((out / name).read_bytes()).hexdigest() == rec["sha256"]
    assert not [p.name for p in out.iterdir() if p.name.startswith(".") or p.name.endswith(".tmp")]
    return records


@pytest.mark.slow
@pytest.mark.parametrize(("sig", "code", "last"), [
    (signal.SIGTERM, 143, "wbmp: terminated"),
    pytest.param(signal.SIGINT, 130, "wbmp: interrupted", marks=pytest.mark.long),  # the same path: make test-long
], ids=["sigterm", "sigint"])
def test_a_stopped_batch_ends_its_workers_at_once_and_leaves_a_consistent_folder(batch, tmp_path, sig, code, last):
    """SIGTERM / SIGINT: exit 143 / 130 within seconds, no child left, index and files agree
    (at least the first item recorded, the rest not half there)."""
    items, root = batch
    out = tmp_path / "lib"
    got, took, children, err = _stop_after_first_record(items, root, out, sig)
    assert got == code, err
    assert err.rstrip().splitlines()[-1] == last, err
    assert "Traceback" not in err
    assert took < EXIT_WITHIN, f"the batch took {took:.1f} s to stop"
    assert len(children) >= 3, children  # two workers and the resource tracker
    assert _wait_gone(children) == []
    records = _assert_consistent(out)
    assert 1 <= len(records) < len(SENTENCES)  # the first record kept; stopped before the end
    summary = (out / "summary.md").read_text()
    assert "not run (the batch was stopped)" in summary


@pytest.mark.long  # in make test-long: the 2-core suite stays under 10 minutes (~24 s); twin: the SIGTERM-stopped batch
# above (workers ended, a consistent folder)
def test_a_killed_batch_leaves_no_process_and_the_next_run_mends_the_folder(batch, tmp_path):
    """SIGKILL of the batch: its workers die with it (PR_SET_PDEATHSIG) and the resource tracker
    after them; the next run of the same batch plans what is left and finishes with an index and
    files that agree, every item ok."""
    items, root = batch
    out = tmp_path / "lib"
    got, _, children, err = _stop_after_first_record(items, root, out, signal.SIGKILL)
    assert got == -signal.SIGKILL, err
    assert len(children) >= 3, children
    assert _wait_gone(children) == [], "children outlived their killed batch"
    records, damaged = read_index_report(out / "index.jsonl")  # what the kill left: readable records
    assert len(damaged) <= 1  # at most a torn last line
    for rec in records.values():
        if rec["motion"] is not None:
            assert hashlib.sha256((out / rec["motion"]).read_bytes()).hexdigest() == rec["sha256"]
    proc = subprocess.run([sys.executable, "-m", "wbmp.cli", "batch", str(items), "--out-dir", str(out), "--no-sim",
                           "--workers", "2", "--quiet"], env=_env(root), capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    records = _assert_consistent(out)
    assert {key for key, rec in records.items() if rec["status"] == "ok"} == {(f"i{n}", "talos")
                                                                              for n in range(len(SENTENCES))}


@pytest.mark.long  # in make test-long: the 2-core suite stays under 10 minutes (~29 s)
@pytest.mark.slow
def test_a_stopped_ray_batch_exits_143_and_shuts_its_instance_down(batch, tmp_path):
    """SIGTERM to a batch on a local Ray instance: exit 143 (was: SIGABRT from Ray's signal
    handler, or exit 1 from the sys.exit Ray puts on SIGTERM), every Ray process it started gone,
    index and files agree."""
    pytest.importorskip("ray", reason="ray is not installed (pip install 'wbmp[ray]')")
    import shutil
    import tempfile

    items, root = batch
    out = tmp_path / "lib"
    short = tempfile.mkdtemp(prefix="wbmp-ray-", dir="/tmp")  # the tmp_path is too long for Ray's sockets
    try:
        with pytest.MonkeyPatch.context() as mp:
            mp.setenv("RAY_TMPDIR", short)
            got, took, children, err = _stop_after_first_record(items, root, out, signal.SIGTERM, ("--ray",))
    finally:
        shutil.rmtree(short, ignore_errors=True)
    assert got == 143, err
    assert err.rstrip().splitlines()[-1] == "wbmp: terminated", err
    assert took < EXIT_WITHIN, f"the batch took {took:.1f} s to stop"
    assert len(children) >= 3, children  # GCS, raylet, workers
    assert _wait_gone(children) == []
    assert 1 <= len(_assert_consistent(out)) < len(SENTENCES)
