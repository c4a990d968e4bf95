"""Files of ``wbmp batch`` and ``wbmp export`` honour the umask: a new file gets ``0o666 & ~umask``,
a new folder ``0o777 & ~umask`` (a motion library shared through a web server or with a colleague
must be readable; ``mkstemp`` would give 0600).

The batch runs with the umask set in this process: its spawned workers inherit it, so the motion
files they write are covered too. The item comes from the motion cache (planned once in the
module fixture), so each batch is a worker start-up, a cache read and the writes.
"""

from __future__ import annotations

import json
import os
import stat
from pathlib import Path

import pytest

from tests.badinput.conftest import umask
from wbmp.cli import main
from wbmp.motionfile import save_motion

UMASKS = (0o022, 0o077)


def _mode(path: Path) -> int:
    return stat.S_IMODE(path.lstat().st_mode)


@pytest.fixture(autouse=True)
def _no_compilation(monkeypatch):
    monkeypatch.setenv("WBMP_COMPILE", "0")


@pytest.fixture(scope="module")
def items(tmp_path_factory) -> Path:
    """A one-item batch file, its motion planned once into the motion cache (a first batch)."""
    folder = tmp_path_factory.mktemp("items")
    path = folder / "items.jsonl"
    path.write_text(json.dumps({"id": "squat", "instruction": "squat"}) + "\n")
    old = os.environ.get("WBMP_COMPILE")
    os.environ["WBMP_COMPILE"] = "0"
    try:
        assert main(["batch", str(path), "--out-dir", str(folder / "warm"), "--no-sim", "--workers", "1",
                     "--quiet"]) == 0
    finally:
        if old is None:
            os.environ.pop("WBMP_COMPILE", None)
        else:
            os.environ["WBMP_COMPILE"] = old
    return path


@pytest.mark.parametrize("mask", UMASKS, ids=[f"umask{m:03o}" for m in UMASKS])
def test_batch_folder_motion_index_and_summary_follow_the_umask(mask, items, tmp_path):
    """A new library folder, its motion file (written by a worker), index.jsonl and summary.md."""
    out = tmp_path / "lib"
    with umask(mask):
        assert main(["batch", str(items), "--out-dir", str(out), "--no-sim", "--workers", "1", "--quiet"]) == 0
    assert json.loads((out / "index.jsonl").read_text())["cached"] is True
    assert _mode(out) == 0o777 & ~mask
    names = sorted(p.name for p in out.iterdir())
    assert names == ["index.jsonl", "squat__talos.npz", "summary.md"]
    for name in names:
        assert _mode(out / name) == 0o666 & ~mask, f"{name}: {_mode(out / name):o}"


@pytest.fixture(scope="module")
def motion_path(tmp_path_factory, talos, synth_plan, synth_execution) -> Path:
    ex = synth_execution
    execution = ex
    return save_motion(tmp_path_factory.mktemp("motion") / "m.npz", synth_plan, talos, execution=execution,
                       report={"certificate": {"ok": True}})


@pytest.mark.parametrize("mask", UMASKS, ids=[f"umask{m:03o}" for m in UMASKS])
@pytest.mark.parametrize("fmt", ["mcap", "tracker", "csv", "json"])
def test_exports_follow_the_umask(fmt, mask, motion_path, tmp_path):
    """Every file `wbmp export` writes (the CSV's executed-motion file too) gets 0o666 & ~umask,
    with no temporary file left."""
    if fmt == "mcap":
        pytest.importorskip("mcap_ros2")
    with umask(mask):
        assert main(["export", str(motion_path), "--format", fmt, "--out", str(tmp_path / f"m.{fmt}.out")]) == 0
    written = sorted(tmp_path.iterdir())
    assert written and all(not p.name.endswith(".tmp") for p in written)
    assert len(written) == (2 if fmt == "csv" else 1)
    for p in written:
        assert _mode(p) == 0o666 & ~mask, f"{p.name}: {_mode(p):o}"
