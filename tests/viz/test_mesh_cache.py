"""The HTML replay's mesh cache (viz/meshcache.py): a page drawn from a cache hit equals the page
drawn from the mesh files; damaged entries are rebuilt with one warning, stale ones silently.

The reference is the replay made with the cache off (``WBMP_MESH_CACHE=0``: every mesh parsed
from its file, the real visual model); scene commands are compared after meshcat's random
uuids (``uuid1`` per geometry and material) are replaced by one placeholder.
"""

from __future__ import annotations

import json
import logging

import numpy as np
import pytest

from viz import html as vh
from viz import meshcache
from viz._meshcat import umsgpack


def _canon(x):
    if isinstance(x, dict):
        return {k: ("uuid" if k in ("uuid", "geometry", "material") and isinstance(v, str) else _canon(v))
                for k, v in x.items()}
    if isinstance(x, list):
        return [_canon(v) for v in x]
    return x


def _page(robot, plan) -> dict:
    """The replay's data, decoded: scene commands (uuids masked), motions, durations, camera."""
    meshcache._cached.cache_clear()  # read the disk as a new process would
    text = f'<script type="application/octet-stream" id="wbmp-data">{vh.page_data(robot, plan)}</script>'
    d = vh.unpack_data(text)
    return {"scene": [_canon(umsgpack.unpackb(c)) for c in d["scene"]], "motions": d["motions"],
            "durations": d["durations"], "camera": d["camera"]}


@pytest.fixture
def cache_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("WBMP_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.delenv("WBMP_MESH_CACHE", raising=False)
    meshcache._cached.cache_clear()
    yield tmp_path / "cache" / "viz"
    meshcache._cached.cache_clear()


@pytest.fixture(scope="module")
def reference(talos, synth_plan):
    """Talos' replay of the synthetic squat with the cache off (every mesh parsed from its file)."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("WBMP_MESH_CACHE", "0")
        return _page(talos, synth_plan)


def test_talos_page_from_a_warm_cache_equals_the_cold_one(cache_dir, talos, synth_plan, reference):
    """Cold: the meshes are packed from the files and stored; warm: the replay draws from a
    stand-in with no mesh loaded (its geometries sit where the real ones do). Both give the
    scene, motions and camera of the replay made with the cache off."""
    cold = _page(talos, synth_plan)
    assert cold == reference
    entries = list(cache_dir.iterdir())
    assert len(entries) == 1 and (entries[0] / "meshes.npz").is_file()

    stand_in = meshcache.replay_robot(talos)
    assert stand_in is not talos
    real, light = talos.visual_model.geometryObjects, stand_in.visual_model.geometryObjects
    assert [g.name for g in light] == [g.name for g in real]
    for a, b in zip(real, light, strict=True):
        assert a.parentJoint == b.parentJoint
        np.testing.assert_array_equal(a.placement.homogeneous, b.placement.homogeneous)
        if type(a.geometry).__name__ not in ("Box", "Sphere", "Cylinder", "Capsule"):
            assert b.geometry.radius == 0.0  # no mesh in the stand-in: the packed one is drawn

    warm = _page(talos, synth_plan)
    assert warm == reference
    assert len(list(cache_dir.iterdir())) == 1


def _entry(cache_dir):
    (entry,) = list(cache_dir.iterdir())
    return entry


@pytest.mark.parametrize("damage", ["data", "truncated", "manifest"])
def test_damaged_entry_is_rebuilt_with_one_warning(cache_dir, talos, synth_plan, reference, caplog, damage):
    """A damaged entry is never read into the page: one warning, a rebuild, the same page, and
    the next process hits."""
    assert _page(talos, synth_plan) == reference
    entry = _entry(cache_dir)
    data, manifest = entry / "meshes.npz", entry / "manifest.json"
    if damage == "data":
        raw = bytearray(data.read_bytes())
        raw[len(raw) // 2] ^= 0xFF
        data.write_bytes(bytes(raw))
    elif damage == "truncated":
        data.write_bytes(data.read_bytes()[:1000])
    else:
        manifest.write_text("{not json")
    caplog.set_level(logging.INFO, logger="viz.meshcache")
    assert _page(talos, synth_plan) == reference
    warnings = [r for r in caplog.records if r.levelno >= logging.WARNING]
    assert len(warnings) == 1 and "damaged" in warnings[0].getMessage()
    assert (_entry(cache_dir) / "meshes.npz").read_bytes() != b""
    caplog.clear()
    meshcache._cached.cache_clear()
    assert meshcache.replay_geometry(talos)[1]  # rebuilt: the next process hits
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING]


def test_changed_mesh_misses_without_a_warning_and_cache_off_writes_nothing(cache_dir, talos, synth_plan, reference,
                                                                          caplog, monkeypatch):
    """An entry made from a mesh file that has changed since is rebuilt (no warning: nothing is
    damaged); ``WBMP_MESH_CACHE=0`` writes nothing."""
    _page(talos, synth_plan)
    manifest = _entry(cache_dir) / "manifest.json"
    record = json.loads(manifest.read_text())
    mesh = next(iter(record["meshes"]))
    record["meshes"][mesh] = "0" * 64  # as if that mesh file had been edited since
    manifest.write_text(json.dumps(record))
    caplog.set_level(logging.INFO, logger="viz.meshcache")
    meshcache._cached.cache_clear()
    assert not meshcache.replay_geometry(talos)[1]  # a miss: prepared from the files and stored again
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING]
    assert json.loads((_entry(cache_dir) / "manifest.json").read_text())["meshes"][mesh] != "0" * 64
    assert _page(talos, synth_plan) == reference

    monkeypatch.setenv("WBMP_MESH_CACHE", "0")
    monkeypatch.setenv("WBMP_CACHE_DIR", str(cache_dir.parent.parent / "other"))
    assert _page(talos, synth_plan) == reference
    assert not (cache_dir.parent.parent / "other").exists()


def test_an_entry_removed_while_read_is_a_miss_without_a_warning(cache_dir, tmp_path, monkeypatch, caplog):
    """Another process (the cache's size cap, ``wbmp cache --clear``) removes the entry between
    the manifest and the data: a miss, no "damaged" warning; a hit renews the entry's use time."""
    import os
    import time

    import pinocchio as pin

    from robots.store import cache_usage, remove_entry

    urdf = tmp_path / "box.urdf"
    urdf.write_text('<robot name="box"><link name="base"><visual><geometry><box size="0.1 0.2 0.3"/></geometry>'
                    "</visual></link></robot>")
    model = pin.buildModelFromUrdf(str(urdf))
    visual = pin.buildGeomFromUrdf(model, str(urdf), pin.GeometryType.VISUAL)
    replay = meshcache.prepare(visual)
    assert replay.arrays["kinds"].tolist() == [meshcache.PRIMITIVE]
    key = meshcache.entry_key(str(urdf), ())
    meshcache._write(cache_dir, key, replay, [])
    os.utime(cache_dir / key, (1000.0, 1000.0))
    hit = meshcache._cached.__wrapped__(str(urdf), (), 0, 0, cache_dir)
    assert hit is not None and hit.arrays["shapes"][0].tolist() == pytest.approx([0.0, 0.1, 0.2, 0.3])
    assert os.lstat(cache_dir / key).st_mtime > time.time() - 60
    real = meshcache.read_manifest

    def racing(entry, fmt):
        out = real(entry, fmt)
        (victim,) = [e for f in cache_usage() for e in f.entries if e.name == entry.name]
        assert remove_entry(victim)
        return out

    monkeypatch.setattr(meshcache, "read_manifest", racing)
    with caplog.at_level(logging.INFO):
        assert meshcache._cached.__wrapped__(str(urdf), (), 0, 0, cache_dir) is None
    assert not (cache_dir / key).exists()
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING]
