"""Special files in place of cache files (issue 36): a FIFO (no writer: a blocking open waits
forever) or a link to ``/dev/zero`` (a read never ends) where a cache file should be is a damaged
entry: the command finishes in time, exit 0, no traceback, and the entry is rebuilt as a regular
file. Every case runs under a watchdog (SIGALRM) so a hang fails the test instead of the suite.
"""

from __future__ import annotations

import json
import os
import signal
import stat
from pathlib import Path

import numpy as np
import pytest

from tests.badinput.conftest import run_cli

REPO = Path(__file__).resolve().parents[2]
SPEC = REPO / "examples" / "specs" / "squat.json"
LIMIT = 120  # [s] generous: a case takes a few seconds, a hang forever


class Hang(Exception):
    """The watchdog went off: the command under test hangs."""


@pytest.fixture(autouse=True)
def watchdog():
    def ring(signum, frame):
        raise Hang(f"no answer within {LIMIT} s")

    old = signal.signal(signal.SIGALRM, ring)
    signal.alarm(LIMIT)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


@pytest.fixture(autouse=True)
def _memory_solvers(monkeypatch):
    monkeypatch.setenv("WBMP_COMPILE", "0")


def fifo(path: Path) -> None:
    path.unlink()
    os.mkfifo(path)


def dev_zero(path: Path) -> None:
    path.unlink()
    path.symlink_to("/dev/zero")


SPECIALS = {"fifo": fifo, "/dev/zero": dev_zero}


@pytest.fixture(scope="module")
def seeded(tmp_path_factory):
    """A cache folder holding one motion with its request record and HTML data."""
    root = tmp_path_factory.mktemp("seeded")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("WBMP_CACHE_DIR", str(root / "cache"))
        mp.setenv("WBMP_COMPILE", "0")
        from wbmp.cli import main

        code = main(["solve", "--spec", str(SPEC), "--no-sim", "--quiet", "--html", str(root / "p.html")])
    assert code == 0
    return root / "cache"


def _copy(seeded: Path, tmp_path: Path, monkeypatch) -> Path:
    import shutil

    cache = tmp_path / "cache"
    shutil.copytree(seeded, cache, symlinks=True)
    monkeypatch.setenv("WBMP_CACHE_DIR", str(cache))
    return cache


MOTION_FILES = {
    "motion": "motions/*.npz",
    "manifest": "motions/[0-9a-f]*[0-9a-f].json",
    "request record": "motions/requests/*.json",
    "page data": "motions/*.page",
    "page manifest": "motions/*.page.json",
}


@pytest.mark.parametrize("special", SPECIALS)
@pytest.mark.parametrize("which", MOTION_FILES)
def test_a_special_file_in_the_motion_cache_is_a_damaged_entry(seeded, tmp_path, monkeypatch, capsys,
                                                                which, special):
    cache = _copy(seeded, tmp_path, monkeypatch)
    [target] = [p for p in cache.glob(MOTION_FILES[which])
                if which != "manifest" or not p.name.endswith(".page.json")]
    SPECIALS[special](target)
    outcome = run_cli(["solve", "--spec", SPEC, "--no-sim", "--quiet", "--html", tmp_path / "p.html"], capsys)
    assert "Traceback" not in outcome.err
    assert outcome.code == 0, outcome.err
    assert stat.S_ISREG(os.lstat(target).st_mode)  # rebuilt as a regular file
    assert (tmp_path / "p.html").stat().st_size > 10_000


@pytest.mark.parametrize("special", SPECIALS)
def test_a_special_seed_or_escalation_record_is_removed(tmp_path, special):
    from planner.trajopt import library

    key = ("ab" if special == "fifo" else "cd") * 16  # one per case: the library keeps what it read in memory
    folder = tmp_path / library.FOLDER / key
    folder.mkdir(parents=True)
    good = {name: np.zeros(2) for name in library._FIELDS}
    seed = folder / "0123456789abcdef.npz"
    np.savez(seed, **good)
    SPECIALS[special](seed)
    record = folder / library.ESCALATION
    record.write_text("{}")
    SPECIALS[special](record)
    assert library._seeds_of(key, str(tmp_path)) == {}
    assert library.find_escalation(key, str(tmp_path)) is None
    assert not os.path.lexists(seed) and not os.path.lexists(record)


@pytest.mark.parametrize("special", SPECIALS)
def test_a_special_manifest_of_the_robot_or_mesh_cache_is_damaged(tmp_path, special):
    from robots.store import EntryDamaged, read_manifest

    entry = tmp_path / ("0" * 64)
    entry.mkdir()
    (entry / "manifest.json").write_text("{}")
    SPECIALS[special](entry / "manifest.json")
    with pytest.raises(EntryDamaged):
        read_manifest(entry, 1)


@pytest.mark.parametrize("special", SPECIALS)
def test_a_special_file_in_the_mujoco_model_cache_is_damaged(tmp_path, special):
    from sim import modelcache

    entry = tmp_path / ("0" * 64)
    entry.mkdir()
    for name in (modelcache._META, modelcache._BINARY):
        (entry / name).write_text("{}")
    SPECIALS[special](entry / modelcache._META)
    with pytest.raises(modelcache.EntryDamaged):
        modelcache._read(entry)
    (entry / modelcache._META).unlink()
    meta = {"key": entry.name, "format": modelcache.FORMAT, "size": 2, "sha256": "x", "fields": {}}
    (entry / modelcache._META).write_text(json.dumps(meta))
    SPECIALS[special](entry / modelcache._BINARY)
    with pytest.raises(modelcache.EntryDamaged):
        modelcache._read(entry)


@pytest.mark.parametrize("special", SPECIALS)
def test_a_scene_mesh_that_is_a_special_file_is_left_out_of_the_viewer(tmp_path, special):
    from tasks.scene import SceneObject
    from viz.scene import _object_geometry

    mesh = tmp_path / "cup.stl"
    mesh.write_bytes(b"\0" * 84)
    obj = SceneObject(name="cup", shape="mesh", size=(1.0, 1.0, 1.0), position=(0.5, 0.0, 0.8), mesh=str(mesh))
    geometry, _ = _object_geometry(obj)
    assert geometry is not None  # the regular file is drawn
    SPECIALS[special](mesh)
    geometry, _ = _object_geometry(obj)
    assert geometry is None


@pytest.mark.parametrize("option", ["--spec", "--scene"])
def test_a_named_pipe_without_a_writer_as_spec_or_scene_is_empty_not_a_hang(tmp_path, capsys, monkeypatch, option):
    from tests.badinput.conftest import Tree, assert_refused

    monkeypatch.setenv("WBMP_CACHE_DIR", str(tmp_path / "cache"))
    pipe = tmp_path / "input.json"
    os.mkfifo(pipe)
    tree = Tree(tmp_path)
    argv = ["solve", "--spec", pipe] if option == "--spec" else ["solve", "wave", "--scene", pipe]
    outcome = run_cli([*argv, "--no-sim", "--quiet"], capsys)
    assert_refused(outcome, 3, "input.json", "is empty")
    tree.assert_unchanged()


def test_dev_zero_as_a_spec_is_too_large(tmp_path, capsys, monkeypatch):
    from tests.badinput.conftest import assert_refused

    monkeypatch.setenv("WBMP_CACHE_DIR", str(tmp_path / "cache"))
    assert_refused(run_cli(["solve", "--spec", "/dev/zero", "--no-sim", "--quiet"], capsys), 3, "/dev/zero", "larger")


@pytest.mark.parametrize("special", SPECIALS)
def test_show_html_of_a_scene_whose_mesh_is_a_special_file_finishes(motion_file, tmp_path, capsys, monkeypatch,
                                                                    special):
    """The mesh is left out of the replay (the page is written, exit 0): never waited on or read
    without bound."""
    monkeypatch.setenv("WBMP_CACHE_DIR", str(tmp_path / "cache"))
    mesh = tmp_path / "cup.stl"
    mesh.write_bytes(b"")
    SPECIALS[special](mesh)
    with np.load(motion_file) as z:
        arrays = {k: z[k] for k in z.files}
    spec = json.loads(str(arrays["spec_json"]))
    spec["scene"] = {"name": "a cup", "floor_friction": 0.8, "objects": [
        {"name": "cup", "shape": "mesh", "size": [1, 1, 1], "position": [0.6, 0.0, 0.8], "mesh": str(mesh)}]}
    arrays["spec_json"] = np.array(json.dumps(spec))
    np.savez(tmp_path / "m.npz", **arrays)
    outcome = run_cli(["show", tmp_path / "m.npz", "--html", tmp_path / "m.html", "--quiet"], capsys)
    assert "Traceback" not in outcome.err
    assert outcome.code == 0, outcome.err
    assert (tmp_path / "m.html").stat().st_size > 10_000


@pytest.mark.parametrize("special", SPECIALS)
def test_a_spec_whose_scene_mesh_is_a_special_file_is_refused(tmp_path, capsys, monkeypatch, special):
    from tests.badinput.conftest import Tree, assert_refused

    monkeypatch.setenv("WBMP_CACHE_DIR", str(tmp_path / "cache"))
    mesh = tmp_path / "cup.stl"
    mesh.write_bytes(b"")
    SPECIALS[special](mesh)
    spec = json.loads(SPEC.read_text(encoding="utf-8"))
    spec["scene"] = {"name": "a cup", "floor_friction": 0.8, "objects": [
        {"name": "cup", "shape": "mesh", "size": [1, 1, 1], "position": [0.6, 0.0, 0.8], "mesh": str(mesh)}]}
    (tmp_path / "spec.json").write_text(json.dumps(spec), encoding="utf-8")
    tree = Tree(tmp_path)
    outcome = run_cli(["solve", "--spec", tmp_path / "spec.json", "--no-sim", "--quiet"], capsys)
    assert_refused(outcome, 3, "scene.objects[0].mesh", "not a regular file")
    tree.assert_unchanged()


@pytest.mark.parametrize("special", SPECIALS)
def test_a_batch_item_whose_spec_is_a_special_file_is_refused(tmp_path, capsys, monkeypatch, special):
    """A batch line naming a FIFO (no writer) or a link to /dev/zero as its spec is refused by its
    line before any work (it said 'not found'); nothing reads it, so nothing blocks."""
    from tests.badinput.conftest import Tree, assert_refused

    monkeypatch.setenv("WBMP_CACHE_DIR", str(tmp_path / "cache"))
    spec = tmp_path / "spec.json"
    spec.write_text("{}")
    SPECIALS[special](spec)
    items = tmp_path / "items.jsonl"
    items.write_text(json.dumps({"spec": "spec.json", "id": "s"}) + "\n")
    tree = Tree(tmp_path)
    outcome = run_cli(["batch", items, "--out-dir", tmp_path / "lib", "--no-sim"], capsys)
    assert_refused(outcome, 2, "items.jsonl:1", "'spec.json' is not a regular file")
    tree.assert_unchanged()
