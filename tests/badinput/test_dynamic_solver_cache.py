"""The dynamic plans' serialized solver cache: a solver read from disk plans what the built one
planned, and a damaged entry is removed with one warning and rebuilt, never trusted.

One real entry is written once for the module by the forked writer (the default path: the
building process forks a child that serializes the NLP's functions while the parent solves) from
the smallest dynamic task (G1, one 5 cm side step on a 0.1 s grid: ~2000 variables). Each damage
case copies it into a fresh cache folder, damages the copy and fetches the solver again
(:func:`planner.trajopt.cache.get_solver`, no solve: the rebuild writes in the foreground).
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import time
from pathlib import Path

import numpy as np
import pytest

from planner import CacheSettings, PlannerSettings, plan
from planner.trajopt import cache, cache_disk
from planner.trajopt.api import _formulation, planned_layout
from planner.trajopt.cache import clear_memory_cache, get_solver, solver_key
from tasks.actions import Action
from tasks.compose import compile_actions

STEP = [Action(name="step", params={"direction": "left", "length": 0.05, "count": 1})]
DT = 0.1
WRITER_TIMEOUT = 300.0  # [s] the forked writer needs ~2 s of CPU; a loaded machine is slow


def small_spec(robot):
    return compile_actions(STEP, robot, dt=DT)


def settings_for(cache_dir: Path, *, background: bool) -> PlannerSettings:
    return PlannerSettings(cache=CacheSettings(cache_dir=str(cache_dir), compile=True, background_compile=background))


def wait_for_writers() -> None:
    """Wait for the forked writers of this process (each publishes its entry, then exits)."""
    deadline = time.monotonic() + WRITER_TIMEOUT
    for pid in list(cache._WRITERS):
        while time.monotonic() < deadline:
            done, status = os.waitpid(pid, os.WNOHANG)
            if done:
                assert os.waitstatus_to_exitcode(status) == 0
                cache._WRITERS.remove(pid)
                break
            time.sleep(0.1)
        else:
            pytest.fail(f"the forked writer {pid} did not finish within {WRITER_TIMEOUT:.0f} s")


class Golden:
    def __init__(self, folder: Path, key: str, q: np.ndarray, forces: dict) -> None:
        self.folder, self.key, self.q, self.forces = folder, key, q, forces

    def install(self, cache_dir: Path) -> Path:
        entry = cache_dir / "planner" / self.key
        entry.parent.mkdir(parents=True, exist_ok=True)
        shutil.copytree(self.folder, entry)
        return entry


def dynamic_settings(spec, robot, cache_dir: Path) -> PlannerSettings:
    """The settings the dynamic solve uses (what keys its entry)."""
    return _formulation(spec, robot, settings_for(cache_dir, background=False))[1]


@pytest.fixture(scope="module")
def golden(tmp_path_factory, g1) -> Golden:
    """Plan the small step with a new solver (the forked writer stores it), then again from disk."""
    cache_dir = tmp_path_factory.mktemp("dyn_cache")
    spec = small_spec(g1)
    clear_memory_cache()
    first = plan(spec, g1, settings=settings_for(cache_dir, background=True))
    assert first.ok and first.stats.cache == "built"
    wait_for_writers()
    settings = dynamic_settings(spec, g1, cache_dir)
    assert settings.cache.serialize and not settings.cache.compile
    key = solver_key(planned_layout(spec, g1, settings), settings)
    entry = cache_dir / "planner" / key
    assert sorted(p.name for p in entry.iterdir()) == ["meta.json", "nlp.casadi"]
    meta = json.loads((entry / "meta.json").read_text())
    assert meta["format"] == "casadi"
    assert meta["sha256"] == hashlib.sha256((entry / "nlp.casadi").read_bytes()).hexdigest()
    assert not [p for p in entry.parent.iterdir() if p.name.startswith(".")]  # no temporary folder left
    kept = tmp_path_factory.mktemp("dyn_entry") / key
    shutil.copytree(entry, kept)
    clear_memory_cache()
    again = plan(spec, g1, settings=settings_for(cache_dir, background=True))
    assert again.ok and again.stats.cache == "disk"
    assert not cache._WRITERS  # a hit writes nothing
    clear_memory_cache()
    return Golden(kept, key, first.q, first.forces)


def test_solver_read_from_disk_plans_what_the_built_one_planned(golden, g1, tmp_path):
    """Same functions, same IPOPT options: the same iterates, so the same plan (to 1e-9, not just
    to the solver's tolerance)."""
    golden.install(tmp_path)
    p = plan(small_spec(g1), g1, settings=settings_for(tmp_path, background=True))
    clear_memory_cache()
    assert p.ok and p.stats.cache == "disk"
    np.testing.assert_allclose(p.q, golden.q, atol=1e-9)
    for frame, f in golden.forces.items():
        np.testing.assert_allclose(p.forces[frame], f, atol=1e-6)  # [N]


def _truncate(entry: Path) -> None:
    data = (entry / "nlp.casadi").read_bytes()
    (entry / "nlp.casadi").write_bytes(data[: len(data) // 3])


def _forged_header(entry: Path) -> None:
    """The file's start overwritten and a manifest that agrees with it: only CasADi's reader can
    tell (a flipped constant deep inside would load: the checksum is what guards the contents)."""
    data = bytearray((entry / "nlp.casadi").read_bytes())
    data[:4096] = bytes(4096)
    (entry / "nlp.casadi").write_bytes(bytes(data))
    meta = json.loads((entry / "meta.json").read_text())
    meta.update(sha256=hashlib.sha256(bytes(data)).hexdigest(), size=len(data))
    (entry / "meta.json").write_text(json.dumps(meta))


@pytest.mark.parametrize(("damage", "word"), [
    (_truncate, "bytes"),
    (_forged_header, "did not load"),
])
def test_damaged_entry_is_removed_with_one_warning_and_rebuilt(golden, g1, tmp_path, caplog, damage, word):
    entry = golden.install(tmp_path)
    damage(entry)
    spec = small_spec(g1)
    settings = dynamic_settings(spec, g1, tmp_path)
    lay = planned_layout(spec, g1, settings)
    assert solver_key(lay, settings) == golden.key
    clear_memory_cache()
    solver = get_solver(lay, settings)
    clear_memory_cache()
    assert solver.origin == "built"
    warnings = [r.getMessage() for r in caplog.records if r.name == "planner.trajopt.cache"]
    assert len(warnings) == 1 and "is damaged" in warnings[0] and word in warnings[0], warnings
    meta, _ = cache_disk.check_files(entry, golden.key, expected_format="casadi")  # rebuilt, healthy
    assert meta["sha256"] == json.loads((golden.folder / "meta.json").read_text())["sha256"]  # the same bytes
    again = get_solver(lay, settings)
    clear_memory_cache()
    assert again.origin == "disk"
