"""Solver cache: in-memory hits, compiled entries on disk, corrupt or stale entries rebuilt."""

from __future__ import annotations

import json

import numpy as np
import pytest

from planner import CacheSettings, PlannerSettings, plan
from planner.trajopt.api import planned_layout
from planner.trajopt.cache import clear_memory_cache, get_solver, solver_key
from planner.trajopt.layout import make_layout
from tests.planner.planning_cases import squat_spec


@pytest.fixture(scope="module")
def cached(tmp_path_factory, talos):
    """A short squat planned once with a fresh disk cache (compiled with gcc)."""
    settings = PlannerSettings(cache=CacheSettings(cache_dir=str(tmp_path_factory.mktemp("wbmp_cache")), compile=True))
    spec = squat_spec(talos, 0.1, duration=2.0, dt=0.1)
    clear_memory_cache()
    first = plan(spec, talos, settings=settings)
    return settings, spec, first


def _entry(settings, talos, spec):
    from pathlib import Path

    return Path(settings.cache.cache_dir) / "planner" / solver_key(planned_layout(spec, talos, settings), settings)


def test_first_plan_builds_and_stores_a_compiled_entry(cached, talos):
    """The first solve builds ('built') and leaves a library + checksum in the cache directory."""
    settings, spec, first = cached
    assert first.ok and first.stats.cache == "built"
    entry = _entry(settings, talos, spec)
    meta = json.loads((entry / "meta.json").read_text())
    assert (entry / "nlp.so").stat().st_size > 0 and len(meta["sha256"]) == 64


def test_same_structure_hits_memory_then_disk(cached, talos):
    """Same structure, other values: 'memory' in-process; after clearing memory, 'disk'; both plans
    solve their own values (a deeper squat is deeper)."""
    settings, spec, first = cached
    deeper = squat_spec(talos, 0.14, duration=2.0, dt=0.1)
    warm = plan(deeper, talos, settings=settings)
    assert warm.stats.cache == "memory" and warm.ok
    clear_memory_cache()
    cold = plan(deeper, talos, settings=settings)
    assert cold.stats.cache == "disk" and cold.ok
    assert np.abs(cold.q - warm.q).max() < 1e-6
    k = len(first.t) // 2
    assert first.com[k, 2] - cold.com[k, 2] == pytest.approx(0.04, abs=0.021)


@pytest.mark.long  # in make test-long: the 2-core suite stays under 10 minutes (~16 s; tests/badinput/test_solver_cache.py damages entries every way)
def test_corrupt_library_is_rebuilt_not_trusted(cached, talos):
    """Garbage in the cached library fails its checksum: the entry is rebuilt and the plan is right."""
    settings, spec, first = cached
    entry = _entry(settings, talos, spec)
    clear_memory_cache()
    # a new file over the old name (rewriting a loaded library in place would crash this process)
    (entry / "garbage").write_bytes(b"not a shared library")
    (entry / "garbage").replace(entry / "nlp.so")
    again = plan(spec, talos, settings=settings)
    assert again.stats.cache == "built" and again.ok
    assert np.abs(again.q - first.q).max() < 1e-6
    meta = json.loads((entry / "meta.json").read_text())
    import hashlib

    assert hashlib.sha256((entry / "nlp.so").read_bytes()).hexdigest() == meta["sha256"]


def test_stale_entry_is_deleted(cached, talos):
    """An entry whose recorded key differs (stale) is refused and removed; the next get rebuilds."""
    from planner.trajopt.cache import _load_entry

    settings, spec, _ = cached
    lay = make_layout(spec, talos)
    key = solver_key(lay, settings)
    entry = _entry(settings, talos, spec)
    meta_path = entry / "meta.json"
    meta = json.loads(meta_path.read_text())
    meta["key"] = "0" * 24
    meta_path.write_text(json.dumps(meta))
    assert _load_entry(lay, entry, key, settings, None) is None
    assert not entry.exists()


def test_structure_changes_change_the_key(talos):
    """A different structure (a target at another time) gets another key; values do not."""
    settings = PlannerSettings(cache=CacheSettings(compile=False))
    a = make_layout(squat_spec(talos, 0.10), talos)
    b = make_layout(squat_spec(talos, 0.12), talos)
    c = make_layout(squat_spec(talos, 0.10, duration=2.4), talos)
    assert solver_key(a, settings) == solver_key(b, settings) != solver_key(c, settings)


def test_cache_disabled_builds_every_time(talos):
    """use_cache=False never reuses a solver."""
    settings = PlannerSettings(cache=CacheSettings(use_cache=False, compile=False))
    lay = make_layout(squat_spec(talos, 0.1, duration=2.0, dt=0.1), talos)
    assert get_solver(lay, settings).origin == "built"
    assert get_solver(lay, settings).origin == "built"


def test_unwritable_cache_directory_still_plans(tmp_path, talos):
    """A cache directory that cannot be created (a file is in the way) only costs the disk cache."""
    blocker = tmp_path / "file"
    blocker.write_text("not a directory")
    settings = PlannerSettings(cache=CacheSettings(cache_dir=str(blocker / "cache"), compile=True, use_cache=False))
    result = plan(squat_spec(talos, 0.05, duration=2.0, dt=0.1), talos, settings=settings)
    assert result.ok and result.stats.cache == "built"
