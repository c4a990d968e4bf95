"""The size cap of the whole disk cache (robots/store.py): least recently used entries go first.

Real files in a temporary ``$WBMP_CACHE_DIR``: entries of every layout (a folder per key; files
sharing a key), their use times set with ``os.utime``; what remains is checked against the
file system itself (``os.walk``), not against the cache's own accounting.
"""

from __future__ import annotations

import logging
import os
import time
from pathlib import Path

import pinocchio as pin
import pytest

from planner.trajopt import cache_disk
from robots import cache, store

URDF = """<robot name="probe">
  <link name="base"><inertial><mass value="1"/><inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><geometry><box size="0.1 0.2 0.3"/></geometry></collision></link>
</robot>
"""
KEY = "0123456789abcdef"  # a key-like name: 16 hex digits and more


def _key(i: int) -> str:
    return f"{i:02d}" + KEY + "ab" * 23


@pytest.fixture
def base(tmp_path, monkeypatch) -> Path:
    root = tmp_path / "cache"
    root.mkdir()
    monkeypatch.setenv("WBMP_CACHE_DIR", str(root))
    monkeypatch.setenv(store.MAX_SIZE_ENV, "10000")
    monkeypatch.delenv("WBMP_ROBOT_CACHE", raising=False)
    return root


def _folder_entry(base: Path, folder: str, name: str, size: int, age: float) -> Path:
    entry = base / folder / name
    entry.mkdir(parents=True)
    (entry / "data.bin").write_bytes(b"\0" * (size - 100))
    (entry / "manifest.json").write_bytes(b"{" + b" " * 98 + b"}")
    used = time.time() - age
    os.utime(entry, (used, used))
    return entry


def _file_entry(base: Path, folder: str, name: str, size: int, age: float) -> list[Path]:
    (base / folder).mkdir(parents=True, exist_ok=True)
    files = [base / folder / f"{name}.npz", base / folder / f"{name}.json"]
    files[0].write_bytes(b"\0" * (size - 100))
    files[1].write_bytes(b"\0" * 100)
    used = time.time() - age
    for f in files:
        os.utime(f, (used, used))
    return files


def _bytes_on_disk(base: Path) -> int:
    """Bytes of every regular file below ``base`` (the independent count)."""
    return sum(os.lstat(os.path.join(d, f)).st_size for d, _, fs in os.walk(base) for f in fs
               if os.path.isfile(os.path.join(d, f)) and not os.path.islink(os.path.join(d, f)))


@pytest.mark.parametrize(("text", "expected"), [
    ("4G", 4 << 30), ("500M", 500 << 20), ("2.5GiB", int(2.5 * (1 << 30))), ("1048576", 1 << 20), ("1k", 1024),
    (" 2 gb ", 2 << 30), ("10000", 10000), ("0", None), ("unlimited", None), ("OFF", None),
])
def test_sizes_are_parsed_with_binary_units(text, expected):
    assert store.parse_size(text) == expected


@pytest.mark.parametrize("text", ["abc", "4X", "-1", "4ib", "G", "1.2.3"])
def test_a_bad_size_is_refused_and_the_default_kept_with_one_warning(text, monkeypatch, caplog):
    with pytest.raises(ValueError, match="is not a size"):
        store.parse_size(text)
    monkeypatch.setenv(store.MAX_SIZE_ENV, text)
    with pytest.raises(ValueError, match=store.MAX_SIZE_ENV):
        store.max_cache_bytes(strict=True)
    store._WARNED.discard(text)
    with caplog.at_level(logging.WARNING, logger="robots.cache"):
        assert store.max_cache_bytes() == store.DEFAULT_MAX_BYTES
        assert store.max_cache_bytes() == store.DEFAULT_MAX_BYTES
    assert len([r for r in caplog.records if store.MAX_SIZE_ENV in r.getMessage()]) == 1


def test_the_least_recently_used_entries_go_until_under_90_percent_of_the_cap(base):
    a = _folder_entry(base, "planner", _key(1)[:24], 3000, age=4 * 3600)
    b = _file_entry(base, "motions", _key(2), 3000, age=3 * 3600)
    c = _folder_entry(base, "mujoco", _key(3), 3000, age=2 * 3600)
    d = _file_entry(base, "collision", "talos-" + _key(4)[:20], 3000, age=3600)
    e = _folder_entry(base, "viz", _key(5), 3000, age=10)  # used seconds ago
    assert _bytes_on_disk(base) == 15000
    removed = store.enforce_cap()
    # oldest first: a (15000 -> 12000), b (-> 9000 = 90 % of 10000): then it stops
    assert [r.name for r in removed] == [a.name, _key(2)]
    assert not a.exists() and not any(p.exists() for p in b)
    assert c.is_dir() and all(p.exists() for p in d) and e.is_dir()
    assert _bytes_on_disk(base) == 9000 <= 0.9 * 10000
    assert store.enforce_cap() == []  # under the cap: nothing more
    assert not [p for p in (base / "planner").iterdir()]  # nothing left aside


def test_recent_entries_temporaries_and_foreign_files_stay_even_over_the_cap(base, tmp_path):
    for i in range(4):
        _folder_entry(base, "robots", _key(i), 3000, age=60)  # used a minute ago
    temp = base / "planner" / f".{_key(9)[:24]}.x7"  # a build in progress, old
    temp.mkdir(parents=True)
    (temp / "nlp.c").write_bytes(b"\0" * 20000)
    os.utime(temp, (0, 0))
    foreign = base / "robots" / "notes"  # not a key: not wbmp's
    foreign.mkdir()
    (foreign / "todo.txt").write_bytes(b"\0" * 5000)
    os.utime(foreign, (0, 0))
    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "precious").write_bytes(b"\0" * 5000)
    (base / "viz").symlink_to(outside)  # a folder that is a link: never followed
    (base / "robots" / _key(7)).symlink_to(outside)  # an entry name that is a link
    old_left = base / "mujoco" / f".evicted.{_key(8)}.123"  # left by a process stopped while removing
    old_left.mkdir(parents=True)
    os.utime(old_left, (0, 0))
    before = _bytes_on_disk(base)
    assert store.enforce_cap() == []
    assert _bytes_on_disk(base) == before  # 4 x 3000 + 20000 (+ the foreign 5000) > 10000, nothing removed
    assert temp.is_dir() and foreign.is_dir() and (outside / "precious").exists()
    assert not old_left.exists()
    usage = {f.name: f for f in store.cache_usage()}
    assert usage["viz"].link and usage["viz"].size == 0
    assert len(usage["robots"].entries) == 4 and usage["planner"].pending == 20000
    assert sum(f.size for f in usage.values()) == 4 * 3000 + 20000


def test_no_cap_when_turned_off_and_only_in_the_wbmp_cache_folder(base, tmp_path, monkeypatch):
    for i in range(4):
        _folder_entry(base, "robots", _key(i), 3000, age=3600 * (i + 1))
    elsewhere = tmp_path / "mine"  # a cache_dir a caller chose (CacheSettings(cache_dir=...))
    for i in range(4):
        _folder_entry(elsewhere, "planner", _key(i)[:24], 3000, age=3600 * (i + 1))
    monkeypatch.setenv(store.MAX_SIZE_ENV, "unlimited")
    assert store.trim_cache(base / "robots") == []
    monkeypatch.setenv(store.MAX_SIZE_ENV, "10k")  # 10240 bytes: 12000 is over it
    assert store.trim_cache(elsewhere / "planner") == []
    assert _bytes_on_disk(elsewhere) == 12000
    removed = store.trim_cache(base / "robots")
    assert [r.name for r in removed] == [_key(3)]  # the oldest: 9000 <= 90 % of 10240
    assert _bytes_on_disk(base) == 9000


def _probe(tmp_path) -> str:
    urdf = tmp_path / "probe.urdf"
    urdf.write_text(URDF)
    return str(urdf)


def _build(urdf: str, count: list[int]):
    def build():
        count.append(1)
        model = pin.buildModelFromUrdf(urdf)
        return pin.buildGeomFromUrdf(model, urdf, pin.GeometryType.COLLISION)
    return build


def test_a_robot_cache_store_applies_the_cap_and_a_load_marks_the_entry_used(base, tmp_path):
    urdf, builds = _probe(tmp_path), []
    old = _folder_entry(base, "mujoco", _key(1), 10000, age=3600)  # at the cap
    assert store.enforce_cap() == []
    g = cache.cached_geometry(urdf, (), "collision", _build(urdf, builds))
    assert len(builds) == 1 and not old.exists()  # the store went over the cap: the old entry went
    entry = base / "robots" / cache.geometry_key(urdf, (), "collision")
    assert entry.is_dir()
    os.utime(entry, (1000.0, 1000.0))
    hit = cache.cached_geometry(urdf, (), "collision", _build(urdf, builds))
    assert len(builds) == 1  # a hit
    assert os.lstat(entry).st_mtime > time.time() - 60  # its use time renewed
    assert [o.name for o in hit.geometryObjects] == [o.name for o in g.geometryObjects] == ["base_0"]
    assert hit.geometryObjects[0].geometry.halfSide.tolist() == pytest.approx([0.05, 0.1, 0.15])


def test_a_robot_entry_removed_while_read_is_a_miss_without_a_warning(base, tmp_path, monkeypatch, caplog):
    urdf, builds = _probe(tmp_path), []
    cache.cached_geometry(urdf, (), "collision", _build(urdf, builds))
    real = store.read_manifest

    def racing(entry, fmt):  # the manifest is read, then another process removes the entry
        out = real(entry, fmt)
        (victim,) = [e for f in store.cache_usage() for e in f.entries if e.name == entry.name]
        assert store.remove_entry(victim)
        return out

    monkeypatch.setattr(cache, "read_manifest", racing)
    with caplog.at_level(logging.INFO):
        g = cache.cached_geometry(urdf, (), "collision", _build(urdf, builds))
    assert len(builds) == 2 and [o.name for o in g.geometryObjects] == ["base_0"]
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING]
    monkeypatch.setattr(cache, "read_manifest", real)
    entry = base / "robots" / cache.geometry_key(urdf, (), "collision")
    (entry / "geometry.bin").write_bytes(b"cut")  # a damaged entry still warns (the check above can fail)
    with caplog.at_level(logging.WARNING):
        cache.cached_geometry(urdf, (), "collision", _build(urdf, builds))
    assert any("is damaged" in r.getMessage() for r in caplog.records)


def test_a_solver_entry_removed_while_checked_is_dropped_without_a_warning(base, caplog):
    entry = _folder_entry(base, "planner", _key(1)[:24], 1000, age=3600)
    seen = os.lstat(entry)
    (victim,) = store.cache_usage()[0].entries
    assert store.remove_entry(victim) and not entry.exists()
    with pytest.raises(OSError):
        cache_disk.check_files(entry, victim.name, None)
    with caplog.at_level(logging.WARNING):
        cache_disk.discard(entry, seen, "meta.json is missing")
    assert not caplog.records
