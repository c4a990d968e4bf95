"""robots.safeio: regular files only, never blocking, never unbounded; paths kept in their folder."""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

import numpy as np
import pytest

from robots import safeio


@pytest.fixture
def fifo(tmp_path: Path) -> Path:
    path = tmp_path / "fifo.json"
    os.mkfifo(path)  # no writer: a blocking open would wait forever
    return path


@pytest.mark.parametrize("reader", [
    lambda p: safeio.read_bytes(p, "manifest"),
    lambda p: safeio.read_json(p),
    lambda p: safeio.sha256_file(p),
    lambda p: safeio.read_npz(p),
], ids=["bytes", "json", "sha256", "npz"])
def test_a_fifo_is_refused_at_once(fifo, reader):
    t0 = time.monotonic()
    with pytest.raises(safeio.NotRegularFile, match="FIFO"):
        reader(fifo)
    assert time.monotonic() - t0 < 5.0  # refused, not waited on


@pytest.mark.parametrize("target", ["/dev/zero", "/dev/null"])
def test_a_link_to_a_device_is_refused(tmp_path, target):
    link = tmp_path / "entry.npz"
    link.symlink_to(target)
    with pytest.raises(safeio.NotRegularFile, match="device"):
        safeio.read_bytes(link, "entry")
    with pytest.raises(OSError):
        safeio.sha256_file(link)


def test_a_directory_is_refused(tmp_path):
    with pytest.raises(safeio.NotRegularFile, match="directory"):
        safeio.read_bytes(tmp_path, "manifest")


def test_a_missing_file_is_file_not_found(tmp_path):
    with pytest.raises(FileNotFoundError):
        safeio.read_bytes(tmp_path / "nothing", "manifest")


def test_the_size_bound_of_each_kind(tmp_path):
    path = tmp_path / "big.json"
    path.write_bytes(b" " * 1001)
    with pytest.raises(safeio.FileTooLarge):
        safeio.read_bytes(path, 1000)
    assert safeio.read_bytes(path, 1001) == b" " * 1001
    with pytest.raises(safeio.FileTooLarge):
        safeio.sha256_file(path, 1000)
    assert set(safeio.LIMITS) >= {"manifest", "record", "spec", "profile", "scene", "mesh", "motion", "entry"}


def test_json_nested_too_deep_is_a_value_error(tmp_path):
    path = tmp_path / "deep.json"
    path.write_text("[" * 200_000 + "]" * 200_000)
    with pytest.raises(ValueError):
        safeio.read_json(path, 1 << 20)


def test_a_link_to_a_regular_file_is_read(tmp_path):
    real = tmp_path / "real.json"
    real.write_text(json.dumps({"a": 1}))
    link = tmp_path / "link.json"
    link.symlink_to(real)
    assert safeio.read_json(link) == {"a": 1}
    import hashlib

    assert safeio.sha256_file(link) == hashlib.sha256(real.read_bytes()).hexdigest()


def test_npz_members_and_declared_size(tmp_path):
    path = tmp_path / "a.npz"
    np.savez(path, x=np.arange(3.0), y=np.zeros(2))
    out = safeio.read_npz(path, names=("x", "y"))
    np.testing.assert_array_equal(out["x"], np.arange(3.0))
    with pytest.raises(ValueError, match="holds"):
        safeio.read_npz(path, names=("x",))
    with pytest.raises(ValueError, match="declares"):  # the arrays are more than the bound unpacked
        np.savez_compressed(path, z=np.zeros(100_000))
        safeio.read_npz(path, 50_000)
    path.write_bytes(b"PK\x03\x04 not a zip")
    with pytest.raises(ValueError, match="not a readable"):
        safeio.read_npz(path)
    np.save(tmp_path / "obj.npy", np.array([{}], dtype=object), allow_pickle=True)
    os.replace(tmp_path / "obj.npy", tmp_path / "obj.bin")
    import zipfile

    with zipfile.ZipFile(path, "w") as zf:
        zf.write(tmp_path / "obj.bin", "o.npy")
    with pytest.raises(ValueError):  # a pickle is never loaded
        safeio.read_npz(path)


@pytest.mark.parametrize(("text", "ok"), [
    ("0" * 64, True), ("a" * 64, True), ("A" * 64, False), ("g" * 64, False), ("0" * 63, False),
    ("../" + "0" * 61, False), ("0" * 63 + "\n", False), (None, False), (64, False),
])
def test_is_key(text, ok):
    assert safeio.is_key(text) is ok


def test_inside_and_confined(tmp_path):
    root = tmp_path / "cache"
    (root / "sub").mkdir(parents=True)
    (tmp_path / "outside").mkdir()
    assert safeio.path_inside(root, "sub/x.json")
    assert safeio.path_inside(root, root / "sub")
    assert not safeio.path_inside(root, "../outside/x.json")
    assert not safeio.path_inside(root, "sub/../../outside")
    assert not safeio.path_inside(root, "/etc/passwd")
    (root / "escape").symlink_to(tmp_path / "outside")  # a link inside that leads out
    assert not safeio.path_inside(root, "escape/x.json")
    assert safeio.confined(root, "sub/x.json") == root / "sub" / "x.json"
    with pytest.raises(safeio.PathEscapes):
        safeio.confined(root, "../outside")


def test_importing_it_loads_no_pinocchio():
    import subprocess
    import sys

    code = "import sys, robots.safeio; print('pinocchio' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                         cwd=Path(__file__).resolve().parents[2], check=True)
    assert out.stdout.strip() == "False"
