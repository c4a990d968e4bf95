"""The disk store's writes and sweep (robots/store.py): an entry appears whole or not at all, and
what a writer that died left behind is removed by the next writer, never an entry or a stranger."""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

import pytest

from robots import remove_tree, store_entry, sweep_stale

HOUR = 3600.0


def _aged(path: Path, age: float, now: float) -> Path:
    os.utime(path, (now - age, now - age))
    return path


def _temporary(root: Path, name: str, age: float, now: float) -> Path:
    folder = root / name
    folder.mkdir(parents=True)
    (folder / "data.bin").write_bytes(b"half written")
    return _aged(folder, age, now)


def test_store_entry_writes_the_manifest_of_its_data(tmp_path):
    root = tmp_path / "robots"
    store_entry(root, "a" * 32, lambda tmp: (tmp / "data.bin").write_bytes(b"x" * 100), {"format": 1},
                data="data.bin")
    manifest = json.loads((root / ("a" * 32) / "manifest.json").read_text(encoding="utf-8"))
    assert manifest["key"] == "a" * 32 and manifest["size"] == 100 and manifest["format"] == 1
    assert sorted(p.name for p in root.iterdir()) == ["a" * 32]  # no temporary folder left


def test_the_next_store_sweeps_what_a_dead_writer_left(tmp_path):
    """A temporary folder older than an hour (its writer died mid-write) goes with the next store
    into that folder; a fresh one (a writer at work), an entry and a name not ours stay."""
    now = time.time()
    root = tmp_path / "mujoco"
    stale = _temporary(root, ".0123456789abcdef-k2j3h4g5", 2 * HOUR, now)
    fresh = _temporary(root, ".fedcba9876543210-a1b2c3d4", 60.0, now)
    stranger = root / ".keep-me"
    stranger.write_text("not ours")
    _aged(stranger, 10 * 24 * HOUR, now)
    store_entry(root, "b" * 32, lambda tmp: (tmp / "data.bin").write_bytes(b"y"), {}, data="data.bin")
    assert not stale.exists()
    assert fresh.exists() and stranger.read_text() == "not ours" and (root / ("b" * 32)).is_dir()


@pytest.mark.parametrize(("age", "owner", "removed"), [
    (2 * HOUR, None, True), (2 * HOUR, False, True), (2 * HOUR, True, False),
    (60.0, False, False), (3 * 24 * HOUR, True, True),
], ids=["old-no-owner", "old-owner-gone", "old-owner-alive", "fresh", "abandoned"])
def test_sweep_takes_a_temporary_by_age_and_owner(tmp_path, age, owner, removed):
    now = time.time()
    folder = _temporary(tmp_path, ".0123456789abcdef-k2j3h4g5", age, now)
    alive = None if owner is None else (lambda _path, owner=owner: owner)
    assert sweep_stale(tmp_path, owner_alive=alive, now=now) == ([folder.name] if removed else [])
    assert folder.exists() is not removed


def test_sweep_runs_once_per_folder_and_takes_moved_aside_entries(tmp_path):
    now = time.time()
    aside = tmp_path / ".damaged.abc"
    aside.mkdir()
    assert sweep_stale(tmp_path, moved_aside=(".damaged.",), now=now) == [aside.name]
    late = tmp_path / ".damaged.def"
    late.mkdir()
    assert sweep_stale(tmp_path, moved_aside=(".damaged.",), now=now) == [] and late.exists()


@pytest.mark.skipif(os.geteuid() == 0, reason="root reads a chmod 000 folder anyway")
def test_remove_tree_takes_a_folder_made_unreadable(tmp_path):
    folder = tmp_path / "entry"
    (folder / "inner").mkdir(parents=True)
    (folder / "inner" / "f").write_bytes(b"x")
    (folder / "inner").chmod(0)
    remove_tree(folder)
    assert not folder.exists()


def test_remove_tree_removes_a_link_not_its_target(tmp_path):
    target = tmp_path / "target"
    target.mkdir()
    (target / "keep").write_text("kept")
    link = tmp_path / "link"
    link.symlink_to(target)
    remove_tree(link)
    assert not link.exists() and (target / "keep").read_text() == "kept"
