"""Solver builds that cannot pile up: one per cache at a time, none without the memory.

The scheduling runs for real (forked workers, the cache's flock, compiler processes in their own
sessions); the compiler is a small shell script given through the documented hook
(``PlannerSettings.compiler`` / ``$WBMP_COMPILER``) that logs its own start and end and sleeps, so
these tests take seconds and no gcc memory. The real gcc build goes through the same lock in
``test_cache_background.py``.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from planner import CacheSettings, PlannerSettings, plan
from planner.trajopt import builds, cache
from planner.trajopt.api import planned_layout
from planner.trajopt.cache import clear_memory_cache, solver_key
from tests.planner.planning_cases import squat_spec

pytestmark = pytest.mark.skipif(not (hasattr(os, "fork") and Path("/proc/self/cwd").exists()),
                                reason="needs fork and /proc")

ROOT = Path(__file__).resolve().parents[3]
SMALL = 1 << 20  # [bytes] the memory the fake compiler "needs": the machine's memory plays no part
WAIT = 120.0  # [s] generous bound on a few seconds of background work on a loaded 2-core machine


def _fake_compiler(tmp_path: Path, seconds: float) -> tuple[Path, Path]:
    """A compiler that appends ``start <time> <pid> <build folder>`` and ``end <time> <pid>`` to a
    log, sleeps ``seconds`` between them and fails (so no entry is published)."""
    log = tmp_path / "compiler.log"
    script = tmp_path / "fakecc"
    script.write_text(f"""#!/bin/sh
echo "start $(date +%s.%N) $$ $(basename "$PWD")" >> {log}
sleep {seconds}
echo "end $(date +%s.%N) $$" >> {log}
exit 1
""")
    script.chmod(0o755)
    return script, log


def _compilers(folder: Path) -> set[int]:
    """Process groups of the processes whose working folder is inside ``folder`` (the compilers:
    they run in the temporary build folders), read from /proc independently of the lock."""
    groups = set()
    for proc in Path("/proc").iterdir():
        if not proc.name.isdigit():
            continue
        try:
            cwd = os.readlink(proc / "cwd")
            if cwd.startswith(f"{folder}{os.sep}"):
                groups.add(os.getpgid(int(proc.name)))
        except OSError:
            continue
    return groups


def _intervals(log: Path) -> list[tuple[float, float, str]]:
    """(start, end, build folder) of each compiler run in the log."""
    starts: dict[str, tuple[float, str]] = {}
    out = []
    for line in log.read_text().splitlines() if log.exists() else []:
        kind, when, pid, *folder = line.split()
        if kind == "start":
            starts[pid] = (float(when), folder[0])
        else:
            begun, name = starts.pop(pid)
            out.append((begun, float(when), name))
    return out


def _compilers_gone(folder: Path) -> bool:
    """True once no process works in ``folder`` (a killed cc1 takes a moment to be torn down)."""
    deadline = time.monotonic() + WAIT
    while _compilers(folder) and time.monotonic() < deadline:
        time.sleep(0.05)
    return not _compilers(folder)


def _wait_idle(folder: Path) -> None:
    deadline = time.monotonic() + WAIT
    while builds.running(folder) is not None and time.monotonic() < deadline:
        time.sleep(0.1)
    assert builds.running(folder) is None, "the background build never ended"
    cache.wait_for_background(timeout=WAIT)


def test_mem_available_is_what_free_reports():
    """MemAvailable read from /proc/meminfo agrees with procps' ``free -b`` (available column)."""
    if shutil.which("free") is None:
        pytest.skip("no free(1)")
    ours = builds.mem_available()
    row = subprocess.run(["free", "-b"], capture_output=True, text=True, check=True).stdout.splitlines()[1]
    theirs = int(row.split()[6])
    assert ours is not None and abs(ours - theirs) < 256 << 20  # memory moves between the two reads


def test_memory_rule_arithmetic(tmp_path):
    """A build starts only with its estimate plus the margin available; unknown memory: no bound."""
    assert builds.memory_refusal(3_000_000_000, 1_000_000_000, available=4_100_000_000) is None
    reason = builds.memory_refusal(3_000_000_000, 1_000_000_000, available=3_900_000_000)
    assert reason is not None and "3.0 GB" in reason and "3.9 GB available" in reason
    available = builds.mem_available()
    assert available is not None and builds.mem_available(str(tmp_path / "meminfo")) is None
    assert builds.memory_refusal(2 * available, 0) is not None  # read now: this machine's memory
    assert builds.memory_refusal(SMALL, 0) is None


def test_held_lock_refuses_and_a_dead_holders_lock_is_taken_over(tmp_path):
    """A live process holding the lock: claim refuses and names its key and pid, and running()
    reports it. Killed (SIGKILL: no clean-up of its own), its lock is free: the next claim takes it
    over and the lock then names the new holder; a lock text naming a dead pid does not block."""
    folder = tmp_path / "planner"
    holder = subprocess.Popen(
        [sys.executable, "-c", "import sys, time; from planner.trajopt import builds; "
         "s = builds.claim(sys.argv[1], 'a' * 24); print(type(s).__name__, flush=True); time.sleep(120)",
         str(folder)], cwd=ROOT, stdout=subprocess.PIPE, text=True,
        env={**os.environ, "PYTHONPATH": str(ROOT)})
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "Slot"
        refused = builds.claim(folder, "b" * 24)
        assert isinstance(refused, str) and "a" * 24 in refused and f"pid {holder.pid}" in refused
        info = builds.running(folder)
        assert info is not None and info["key"] == "a" * 24 and info["pid"] == holder.pid
    finally:
        holder.kill()
        holder.wait()
        holder.stdout.close()
    assert builds.running(folder) is None
    slot = builds.claim(folder, "b" * 24)
    assert isinstance(slot, builds.Slot)
    info = builds.running(folder)
    assert info is not None and info["key"] == "b" * 24 and info["pid"] == os.getpid()
    slot.close()
    assert builds.running(folder) is None
    # a lock text that says "running" for a process that is gone: taken over too
    (builds.state_folder(folder) / builds.LOCK).write_text(json.dumps(
        {"key": "c" * 24, "pid": holder.pid, "state": "running", "since": time.time()}))
    slot = builds.claim(folder, "d" * 24)
    assert isinstance(slot, builds.Slot)
    slot.close()


@pytest.mark.slow
def test_back_to_back_new_structures_build_one_at_a_time(tmp_path, talos):
    """Four new structures planned one after another, as a user runs sentences: every plan is
    solved at once in memory, at most one compiler runs at any moment (polled in /proc, and the
    compilers' own log shows no overlap), the ones that found a build running are recorded as
    skipped, and a skipped structure planned again once the cache is idle is built then."""
    compiler, log = _fake_compiler(tmp_path, 2.5)
    settings = PlannerSettings(cache=CacheSettings(cache_dir=str(tmp_path / "cache"), compile=True, background_compile=True,
                                                   compiler=str(compiler), build_memory=SMALL, build_memory_margin=0))
    folder = tmp_path / "cache" / "planner"
    seen: list[int] = []
    stop = threading.Event()

    def poll() -> None:
        while not stop.is_set():
            seen.append(len(_compilers(folder)))
            time.sleep(0.05)

    specs = [squat_spec(talos, 0.05, duration=d, dt=0.1) for d in (0.6, 0.7, 0.8, 0.9)]
    keys = [solver_key(planned_layout(s, talos, settings), settings) for s in specs]
    assert len(set(keys)) == len(keys)
    clear_memory_cache()
    watcher = threading.Thread(target=poll, daemon=True)
    watcher.start()
    try:
        for i, spec in enumerate(specs):
            said: list[str] = []
            result = plan(spec, talos, settings=settings, progress=said.append)
            assert result.ok and result.stats.cache == "built"
            if i == 1:
                _wait_idle(folder)  # a pause between two sentences: the next one may build
        _wait_idle(folder)
        skipped = {r["key"] for r in builds.skipped(folder)}
        assert skipped and skipped < set(keys), skipped
        again = next(k for k in keys if k in skipped)
        clear_memory_cache()
        plan(specs[keys.index(again)], talos, settings=settings)
        _wait_idle(folder)
    finally:
        stop.set()
        watcher.join()
    runs = _intervals(log)
    assert max(seen) == 1 and len(seen) > 10, (max(seen), len(seen))
    for (_, end, _), (start, _, _) in zip(runs, runs[1:], strict=False):
        assert start >= end, runs  # each compiler started after the previous one ended
    built = [name.split(".")[1] for *_, name in runs]
    assert built[0] == keys[0] and keys[2] in built and built[-1] == again, (built, keys)
    assert again not in {r["key"] for r in builds.skipped(folder)}  # its build started: no longer skipped
    assert not [p for p in folder.iterdir() if p.name.startswith(".")]  # no build folder left


def test_memory_rule_starts_no_build_and_says_why(tmp_path, talos):
    """A build estimate above the memory available: no build starts (no worker, no build folder,
    no lock held), the plan still solves in memory, and the reason is visible in the progress, in
    the skip record and in ``wbmp cache``."""
    settings = PlannerSettings(cache=CacheSettings(cache_dir=str(tmp_path), compile=True, background_compile=True,
                                                   build_memory=1 << 50))
    spec = squat_spec(talos, 0.05, duration=0.5, dt=0.1)
    folder = tmp_path / "planner"
    clear_memory_cache()
    workers = list(cache._WRITERS)
    said: list[str] = []
    result = plan(spec, talos, settings=settings, progress=said.append)
    assert result.ok and result.stats.cache == "built"
    assert cache._WRITERS == workers and builds.running(folder) is None
    assert list(folder.iterdir()) == []  # no entry, no build folder
    key = solver_key(planned_layout(spec, talos, settings), settings)
    (record,) = builds.skipped(folder)
    assert record["key"] == key and "not enough free memory" in record["reason"]
    assert any("not enough free memory" in line for line in said), said
    env = {**os.environ, "WBMP_CACHE_DIR": str(tmp_path), "PYTHONPATH": str(ROOT)}
    out = subprocess.run([sys.executable, "-m", "wbmp", "cache", "planner"], cwd=ROOT, env=env,
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert key in out.stdout and "not enough free memory" in out.stdout and "none running" in out.stdout


def test_solve_returns_while_its_build_runs(tmp_path, talos):
    """``wbmp solve`` read through a pipe returns while the build it started still compiles (the
    build does not hold the command open), and ``wbmp cache`` shows that build: key, pid."""
    compiler, log = _fake_compiler(tmp_path, 60.0)
    # the session's cache (the talos fixture filled its robot folder): a cold one costs ~15 s more;
    # only this test compiles there, and its compiler fails, so no solver entry is left behind
    base = Path(os.environ["WBMP_CACHE_DIR"])
    env = {**os.environ, "WBMP_COMPILE": "1", "WBMP_COMPILE_BACKGROUND": "1", "WBMP_COMPILER": str(compiler),
           "WBMP_BUILD_MEMORY": "1M", "PYTHONPATH": str(ROOT)}
    folder = base / "planner"
    _wait_idle(folder)
    try:
        solve = subprocess.run([sys.executable, "-m", "wbmp", "solve", "squat", "--no-sim", "--quiet", "--no-cache"],
                               cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
        assert solve.returncode == 0, solve.stderr
        info = builds.running(folder)
        assert info is not None, "the build ended with the command"
        shown = subprocess.run([sys.executable, "-m", "wbmp", "cache", "planner"], cwd=ROOT, env=env,
                               capture_output=True, text=True, timeout=120)
        assert f"running {info['key']} (pid {info['pid']}" in shown.stdout, shown.stdout
        deadline = time.monotonic() + WAIT
        while not log.exists() and time.monotonic() < deadline:
            time.sleep(0.1)
        assert log.read_text().startswith("start")  # the compiler of that build runs
        assert not _intervals(log)  # ... and has not ended: the command did not wait for it
    finally:
        for group in _compilers(folder):
            os.killpg(group, signal.SIGKILL)  # the compiler this test started; its worker then ends
    _wait_idle(folder)


def test_a_build_stops_when_memory_runs_short(tmp_path):
    """The watchdog: a real gcc compile (-O2 of 4,000 chained functions: seconds) with a margin that
    this machine's free memory cannot cover is killed at once, and the lock says why."""
    gcc = shutil.which("gcc")
    if gcc is None:
        pytest.skip("needs gcc")
    build = tmp_path / "build"
    build.mkdir()
    body = "\n".join(f"double f{i}(double x) {{ return x * {i}.5 + f{i - 1}(x) * 0.5; }}" for i in range(1, 4000))
    (build / "nlp.c").write_text("double f0(double x) { return x; }\n" + body + "\n")
    slot = builds.claim(tmp_path / "planner", "e" * 24)
    assert isinstance(slot, builds.Slot)
    available = builds.mem_available()
    assert available is not None
    t0 = time.monotonic()
    ok = cache._run_gcc([gcc, "-fPIC", "-shared", "-O2", "nlp.c", "-o", "nlp.so"], build, 600,
                        margin=4 * available, slot=slot)
    slot.close()
    assert not ok and not (build / "nlp.so").exists()
    assert time.monotonic() - t0 < 60  # stopped at the first look, not at the time limit
    assert "free memory fell below" in slot.info["stopped"]
    assert _compilers_gone(build.parent)  # the compiler's whole group is gone


def test_the_lock_lasts_as_long_as_the_compiler(tmp_path):
    """The compiler inherits the lock: a worker killed mid-build (SIGKILL) leaves its compiler
    running, and no second build may start until that compiler ends too."""
    compiler, log = _fake_compiler(tmp_path, 60.0)
    folder = tmp_path / "planner"
    build = folder / ".0123456789abcdef01234567.test"
    build.mkdir(parents=True)
    slot = builds.claim(folder, "0123456789abcdef01234567")
    assert isinstance(slot, builds.Slot)
    cache._fork_worker(build, lambda: cache._run_gcc([str(compiler)], build, 600, slot=slot), slot=slot)
    try:
        deadline = time.monotonic() + WAIT
        while not log.exists() and time.monotonic() < deadline:
            time.sleep(0.05)
        worker = builds.running(folder)["pid"]
        os.kill(worker, signal.SIGKILL)
        assert cache.wait_for_background(timeout=WAIT) == [-signal.SIGKILL]
        assert _compilers(folder), "the compiler went with its worker"
        assert builds.running(folder) is not None
        assert isinstance(builds.claim(folder, "f" * 24), str)
    finally:
        for group in _compilers(folder):
            os.killpg(group, signal.SIGKILL)
    deadline = time.monotonic() + WAIT
    while builds.running(folder) is not None and time.monotonic() < deadline:
        time.sleep(0.05)
    assert builds.running(folder) is None
