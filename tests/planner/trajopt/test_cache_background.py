"""Background compilation: the first plan runs at once in memory; the next one loads gcc's code."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest

from planner import CacheSettings, PlannerSettings, plan
from planner.trajopt import builds, cache
from planner.trajopt.api import planned_layout
from planner.trajopt.cache import clear_memory_cache, solver_key
from tests.planner.planning_cases import squat_spec

COMPILE_WAIT = 480.0  # [s] bound on gcc -O0 of a small Talos squat (25 s idle) on a loaded 2-core machine


@pytest.mark.slow
def test_background_compile_publishes_an_entry_the_next_plan_loads(tmp_path, talos):
    """Plan 1 solves in memory and returns before gcc ends; a forked child (C code, gcc) then
    publishes a checksummed entry, which plan 2 (a fresh process's view: memory cleared) loads
    from disk."""
    settings = PlannerSettings(cache=CacheSettings(cache_dir=str(tmp_path), compile=True, background_compile=True))
    spec = squat_spec(talos, 0.1, duration=2.0, dt=0.1)
    clear_memory_cache()
    first = plan(spec, talos, settings=settings)
    assert first.stats.cache == "built" and first.ok
    entry = Path(tmp_path) / "planner" / solver_key(planned_layout(spec, talos, settings), settings)
    building = builds.running(entry.parent)  # the build holds the cache's lock (planner/trajopt/builds.py)
    assert building is not None and building["key"] == entry.name and building["pid"] in cache._WRITERS
    compilers = set()
    deadline = time.monotonic() + COMPILE_WAIT
    while not (entry / "meta.json").exists() and time.monotonic() < deadline:
        compilers.add((builds.running(entry.parent) or {}).get("compiler_pid"))
        time.sleep(0.5)
    assert (entry / "meta.json").exists(), "the background compilation never published its entry"
    codes = cache.wait_for_background(timeout=120)  # published: the forked compiler is ending; reap it
    assert codes and all(code == 0 for code in codes), codes
    assert len(compilers - {None}) == 1 and builds.running(entry.parent) is None  # one gcc; lock free
    assert not any(p.name.startswith(".") for p in (Path(tmp_path) / "planner").iterdir()), "temporary dir left"
    clear_memory_cache()
    second = plan(spec, talos, settings=settings)
    assert second.stats.cache == "disk"
    np.testing.assert_allclose(second.q, first.q, atol=1e-6)
