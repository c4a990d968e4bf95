"""``wbmp cache``: the listing, ``--clear``, ``--json``, refused input; the motion cache's side of
the size cap (a load renews the use time; an entry removed while read is a miss).

Real files in a temporary ``$WBMP_CACHE_DIR``; sizes are checked against ``os.walk``.
"""

from __future__ import annotations

import json
import logging
import os
import time
import types

import pytest

from robots.store import CACHE_FOLDERS, cache_usage, remove_entry
from wbmp import motioncache
from wbmp.cli import main
from wbmp.commands.cache import FOLDERS_TEXT

PLANNER_KEY = "0123456789abcdef01234567"
KEY = "ab" * 32


@pytest.fixture
def base(tmp_path, monkeypatch):
    root = tmp_path / "cache"
    monkeypatch.setenv("WBMP_CACHE_DIR", str(root))
    monkeypatch.delenv("WBMP_CACHE_MAX_SIZE", raising=False)
    entry = root / "planner" / PLANNER_KEY
    entry.mkdir(parents=True)
    (entry / "nlp.so").write_bytes(b"\0" * 300_000)
    (entry / "meta.json").write_bytes(b"{}")
    for suffix in ("npz", "json", "page", "page.json"):
        (root / "motions").mkdir(exist_ok=True)
        (root / "motions" / f"{KEY}.{suffix}").write_bytes(b"\0" * 1000)
    (root / "motions" / "requests").mkdir()
    (root / "motions" / "requests" / f"{'cd' * 32}.json").write_bytes(b"{}")
    (root / "collision").mkdir()
    (root / "collision" / "talos-0123456789abcdef0123.json").write_bytes(b"\0" * 500)
    (root / "motions" / "README").write_text("not wbmp's")
    return root


def _size(folder) -> int:
    return sum(os.path.getsize(os.path.join(d, f)) for d, _, fs in os.walk(folder) for f in fs)


def test_the_listing_gives_each_folder_its_entries_and_bytes(base, capsys):
    assert main(["cache", "--json", "--entries"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["cache_dir"] == str(base) and out["cap"] == 4 << 30
    folders = {f["name"]: f for f in out["folders"]}
    assert list(folders) == list(CACHE_FOLDERS)
    assert folders["planner"]["entries"] == 1 and folders["planner"]["size"] == _size(base / "planner") == 300_002
    assert folders["motions"]["entries"] == 2  # one motion (4 files) and one request record
    assert folders["motions"]["size"] == _size(base / "motions") - len("not wbmp's")
    assert folders["collision"]["size"] == 500 and folders["robots"]["entries"] == 0
    assert out["total"] == 300_002 + 4002 + 500
    assert main(["cache"]) == 0
    text = capsys.readouterr().out.splitlines()
    assert text[0] == str(base)
    rows = {line.split()[0]: line.split()[1:] for line in text[2:]}
    assert rows["planner"][:3] == ["1", "293.0", "KiB"] and rows["motions"][:3] == ["2", "3.9", "KiB"]
    assert rows["total"][:3] == ["4", "297.4", "KiB"] and "cap 4.0 GiB" in " ".join(rows["total"])


def test_clear_empties_the_folders_named_in_one_line(base, capsys):
    assert main(["cache", "--clear", "motions", "collision"]) == 0
    out = capsys.readouterr().out
    assert out.count("\n") == 1 and "removed 3 entries (4.4 KiB) from collision, motions" in out
    assert sorted(os.listdir(base / "motions")) == ["README", "requests"]  # what is not wbmp's stays
    assert not os.listdir(base / "motions" / "requests") and not os.listdir(base / "collision")
    assert _size(base / "planner") == 300_002
    assert main(["cache", "--clear", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["removed"] == 1
    assert not os.listdir(base / "planner")


@pytest.mark.parametrize(("argv", "env", "says"), [
    (["cache", "plannr"], None, "unknown cache folder 'plannr'"),
    (["cache", "--clear", "../etc"], None, "unknown cache folder '../etc'"),
    (["cache"], "lots", "WBMP_CACHE_MAX_SIZE='lots' is not a size"),
])
def test_bad_input_is_one_line_and_exit_2(base, capsys, monkeypatch, argv, env, says):
    if env is not None:
        monkeypatch.setenv("WBMP_CACHE_MAX_SIZE", env)
    assert main(argv) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err.count("\n") == 1
    assert captured.err.startswith("wbmp cache: error: ") and says in captured.err
    assert _size(base / "planner") == 300_002  # nothing touched


def test_help_names_every_cache_folder(capsys):
    assert FOLDERS_TEXT == ", ".join(CACHE_FOLDERS)
    with pytest.raises(SystemExit) as stop:
        main(["cache", "--help"])
    assert stop.value.code == 0 and "--clear" in capsys.readouterr().out


def test_a_motion_removed_while_read_is_a_miss_and_a_request_hit_marks_use(base, monkeypatch, caplog):
    cache = motioncache.MotionCache(base / "motions")
    (base / "motions" / f"{KEY}.json").write_text(json.dumps({"key": KEY, "format": motioncache.FORMAT}))

    def racing_loads(raw, **kw):  # the manifest is read, then another process removes the entry
        out = json.loads(raw, **kw)
        (victim,) = [e for f in cache_usage() for e in f.entries if e.name == KEY]
        assert remove_entry(victim)
        return out

    monkeypatch.setattr(motioncache, "json", types.SimpleNamespace(loads=racing_loads, dumps=json.dumps))
    with caplog.at_level(logging.WARNING):
        assert cache.load(KEY) is None
    assert not caplog.records and not list((base / "motions").glob(f"{KEY}*"))
    monkeypatch.setattr(motioncache, "json", json)
    (base / "motions" / f"{KEY}.json").write_text(json.dumps({"key": KEY, "format": motioncache.FORMAT}))
    with caplog.at_level(logging.WARNING):  # a manifest without its motion file is damage: one warning
        assert cache.load(KEY) is None
    assert len(caplog.records) == 1 and "lacks its motion file" in caplog.records[0].getMessage()
    robot_file = base / "profile.toml"
    robot_file.write_text("x")
    record = base / "motions" / "requests" / f"{'ef' * 32}.json"
    cache.store_request("ef" * 32, KEY, {str(robot_file): motioncache._sha256_file(robot_file)}, "digest")
    os.utime(record, (1000.0, 1000.0))
    assert cache.lookup_request("ef" * 32) == (KEY, "digest", None)
    assert os.lstat(record).st_mtime > time.time() - 60
