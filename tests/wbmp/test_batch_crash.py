"""``wbmp batch`` when a worker process dies in the middle of an item: real processes, real deaths.

The worker planning item ``boom`` is killed (SIGKILL, or a real segmentation fault on Ray) by the
test-only hook ``WBMP_TEST_WORKER_DEATH`` (wbmp/batch/worker.py) when it commits that item's
motion file: after the temporary file was written, before it is renamed into place. The batch
must record ``boom`` as crashed (exit 1, one line), plan the other items (also the one that was in
flight in the dead pool), leave no temporary and no ``boom`` motion file, and exit 1.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import pytest

from viz.files import Staging
from wbmp.batch import worker
from wbmp.batch.backends import WORKER_DIED
from wbmp.cli import main


@pytest.fixture(autouse=True)
def _no_compilation(monkeypatch):
    """Solvers are built in memory; spawned workers (and local Ray workers) inherit the variables."""
    monkeypatch.setenv("WBMP_COMPILE", "0")


def _items(folder: Path) -> Path:
    lines = [{"id": "boom", "instruction": "bow"}, {"id": "squat", "instruction": "squat"},
             {"id": "wave", "instruction": "wave your right hand"}]
    path = folder / "items.jsonl"
    path.write_text("\n".join(json.dumps(x) for x in lines) + "\n")
    return path


def _check_library(out: Path, backend: str) -> dict:
    records = [json.loads(line) for line in (out / "index.jsonl").read_text().splitlines()]
    index = {r["id"]: r for r in records}
    assert list(index) == ["boom", "squat", "wave"]
    boom = index["boom"]
    assert (boom["status"], boom["exit_code"], boom["motion"], boom["sha256"]) == ("failed", 1, None, None)
    assert boom["message"].startswith(WORKER_DIED) and "\n" not in boom["message"]
    assert boom["backend"] == backend
    for name in ("squat", "wave"):
        rec = index[name]
        assert (rec["status"], rec["exit_code"], rec["motion"]) == ("ok", 0, f"{name}__talos.npz")
        assert rec["sha256"] == hashlib.sha256((out / rec["motion"]).read_bytes()).hexdigest()
    # nothing half-written: no temporary file of the dead worker, no motion file of boom
    assert sorted(p.name for p in out.iterdir()) == ["index.jsonl", "squat__talos.npz", "summary.md",
                                                      "wave__talos.npz"]
    assert "| boom | talos |" in (out / "summary.md").read_text()
    return index


def test_a_killed_local_worker_is_recorded_and_the_batch_goes_on(tmp_path, monkeypatch, capsys):
    """SIGKILL of the worker in the middle of ``boom`` (2 workers, ``squat`` in flight beside it):
    ``boom`` is recorded as crashed, ``squat`` and ``wave`` are planned, exit 1."""
    monkeypatch.setenv(worker.DEATH_VARIABLE, "kill:boom")
    out = tmp_path / "lib"
    code = main(["batch", str(_items(tmp_path)), "--out-dir", str(out), "--no-sim", "--workers", "2"])
    captured = capsys.readouterr()
    assert code == 1, captured.err
    _check_library(out, "local")
    assert f"failed: boom on talos (line 1), exit 1: {WORKER_DIED}" in captured.out
    assert "Traceback" not in captured.out + captured.err
    # the crash is not a result the input decides: a rerun plans boom again (and only boom)
    monkeypatch.delenv(worker.DEATH_VARIABLE)
    assert main(["batch", str(_items(tmp_path)), "--out-dir", str(out), "--no-sim", "--workers", "1",
                 "--quiet"]) == 0
    assert "1 planned now, 2 done before" in capsys.readouterr().out
    assert (out / "boom__talos.npz").is_file()


@pytest.mark.slow
def test_a_segfaulting_ray_worker_is_recorded_and_the_batch_goes_on(tmp_path, monkeypatch):
    """A segmentation fault in the Ray worker planning ``boom`` (retried once by Ray, dies again):
    recorded as crashed, the other items planned, Ray shut down, exit 1."""
    ray = pytest.importorskip("ray", reason="ray is not installed (pip install 'wbmp[ray]')")
    monkeypatch.setenv(worker.DEATH_VARIABLE, "segv:boom")
    out = tmp_path / "lib"
    code = main(["batch", str(_items(tmp_path)), "--out-dir", str(out), "--no-sim", "--workers", "2", "--ray",
                 "--quiet"])
    if code == 1 and not (out / "index.jsonl").exists():  # pragma: no cover - machine-dependent
        pytest.skip("Ray could not start a local instance on this machine")
    assert code == 1
    assert not ray.is_initialized()
    _check_library(out, "ray")


@pytest.mark.parametrize("value", ["", "kill", "kill:", "kill:other", "explode:boom", "KILL:boom", " kill:boom"])
def test_the_death_hook_is_inert_unless_set_exactly_for_this_item(value, monkeypatch):
    """Only ``HOW:ID`` with HOW in exit/kill/segv and the item's exact id arms the test hook;
    anything else leaves the motion file's commit alone (the process would not survive otherwise)."""
    monkeypatch.setenv(worker.DEATH_VARIABLE, value)
    original = Staging.commit
    with worker._death_hook("boom"):
        assert Staging.commit is original
    assert Staging.commit is original


def test_the_death_hook_arms_the_commit_and_is_removed_after(monkeypatch):
    """The armed hook replaces the commit only inside its block (checked without calling it)."""
    monkeypatch.setenv(worker.DEATH_VARIABLE, "exit:boom")
    original = Staging.commit
    with worker._death_hook("boom"):
        assert Staging.commit is not original
    assert Staging.commit is original


@pytest.mark.parametrize(("how", "returncode"), [("exit", 70), ("kill", -9), ("segv", -11)])
def test_the_hook_kills_a_real_process_with_the_temporary_file_written(how, returncode, tmp_path):
    """In a child process the armed hook ends the process at the commit, the temporary motion file
    written and left behind (what a batch's sweep must remove): SIGKILL, SIGSEGV or exit 70."""
    import os
    import subprocess
    import sys

    from wbmp.batch.run import sweep_temporary

    code = ("import sys; from pathlib import Path; from viz.files import Staging; from wbmp.batch import worker\n"
            "with worker._death_hook('boom'), Staging() as s:\n"
            "    s.add(Path(sys.argv[1]) / 'boom__talos.npz', lambda fh: fh.write(b'x' * 4096))\n"
            "    s.commit()\n")
    env = {**os.environ, worker.DEATH_VARIABLE: f"{how}:boom", "PYTHONPATH": str(Path(__file__).resolve().parents[2])}
    proc = subprocess.run([sys.executable, "-c", code, str(tmp_path)], env=env, capture_output=True, timeout=120)
    assert proc.returncode == returncode, proc.stderr
    left = [p for p in tmp_path.iterdir()]
    assert len(left) == 1 and left[0].name.startswith(".boom__talos.npz.") and left[0].stat().st_size == 4096
    assert sweep_temporary(tmp_path) == [left[0].name]
    assert not list(tmp_path.iterdir())
