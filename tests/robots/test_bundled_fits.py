"""The collision-model fits shipped in robots/fits (robots.collision.BUNDLED): current, used by an
empty cache instead of fitting, and equal to fits made now (the long test)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import robots.collision as rc


def _same(a: rc.CollisionModel, b: rc.CollisionModel) -> None:
    assert a.pairs == b.pairs and a.skipped == b.skipped and a.covers == b.covers
    for mine, theirs in ((a.capsules, b.capsules), (a.alternatives, b.alternatives)):
        assert [(c.link, c.joint, c.cover) for c in mine] == [(c.link, c.joint, c.cover) for c in theirs]
        for c, d in zip(mine, theirs, strict=True):
            assert c.length == d.length and c.radius == d.radius  # json round-trips floats exactly
            assert np.array_equal(c.placement.homogeneous, d.placement.homogeneous)


def _bundled(robot) -> rc.CollisionModel:
    return _bundled_in(robot, rc.BUNDLED)


def _bundled_in(robot, folder: Path) -> rc.CollisionModel:
    path = folder / f"{robot.name}-{rc.cache_key(robot)}.json"
    assert path.is_file(), (f"no fit of {robot.name} for its current URDF/profile/FIT_VERSION in {rc.BUNDLED}: "
                            "regenerate it with robots.collision.write_bundled_fit")
    return rc._from_json(json.loads(path.read_text()), robot)


def test_bundled_fits_are_current(talos, g1):
    for robot in (talos, g1):
        model = _bundled(robot)
        assert len(model.capsules) >= len({c.link for c in model.capsules}) > 10
        assert len(list(rc.BUNDLED.glob(f"{robot.name}-*.json"))) == 1  # older keys removed


def test_an_empty_cache_takes_the_bundled_fit(tmp_path, monkeypatch, g1):
    monkeypatch.setenv("WBMP_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(rc, "_MEMORY", {})
    fitted = []
    real_build = rc._build

    def build(robot):
        fitted.append(robot.name)
        return real_build(robot)

    monkeypatch.setattr(rc, "_build", build)
    cm = rc.collision_model(g1)
    assert fitted == []
    _same(cm, _bundled(g1))
    stored = list(rc.cache_dir().glob("g1-*.json"))  # and stored in the user's cache
    assert len(stored) == 1
    _same(rc._from_json(json.loads(stored[0].read_text()), g1), cm)


@pytest.mark.long  # ~15 s of CPU: two fits; fast twin: test_an_empty_cache_takes_the_bundled_fit
def test_bundled_fits_equal_fits_made_now_and_an_unknown_key_fits(tmp_path, monkeypatch, talos, g1):
    _same(rc._build(talos), _bundled(talos))
    monkeypatch.setenv("WBMP_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(rc, "_MEMORY", {})
    monkeypatch.setattr(rc, "BUNDLED", tmp_path / "none")  # no fit for the key (e.g. a URDF that changed)
    _same(rc.collision_model(g1), _bundled_in(g1, Path(__file__).parents[2] / "robots" / "fits"))
    assert len(list(rc.cache_dir().glob("g1-*.json"))) == 1
