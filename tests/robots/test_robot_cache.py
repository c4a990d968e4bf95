"""The robot geometry's disk cache (robots/cache.py): hit, miss, invalidation, damaged entries.

A small URDF with one STL mesh written here; every geometry the cache returns is compared with
Pinocchio loading the same files directly (the independent reference).
"""

from __future__ import annotations

import logging
import struct

import numpy as np
import pinocchio as pin
import pytest

from robots import cache
from robots.model import _load_geometry

URDF = """<robot name="probe">
  <link name="base"><inertial><mass value="1"/><inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><origin xyz="0 0 {z}"/><geometry><mesh filename="package://probe/part.stl"/></geometry></collision>
    <visual><geometry><mesh filename="package://probe/part.stl"/></geometry></visual></link>
  <link name="arm"><inertial><mass value="1"/><inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><geometry><box size="0.1 0.2 0.3"/></geometry></collision></link>
  <joint name="j" type="revolute"><parent link="base"/><child link="arm"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="10" velocity="1"/></joint>
</robot>
"""


def _stl(path, tip: float) -> None:
    """A binary STL tetrahedron whose apex is at height ``tip`` [m]."""
    p = np.array([[0, 0, 0], [0.1, 0, 0], [0, 0.1, 0], [0, 0, tip]], dtype="<f4")
    faces = [(0, 2, 1), (0, 1, 3), (1, 2, 3), (0, 3, 2)]
    data = b"\0" * 80 + struct.pack("<I", len(faces))
    for f in faces:
        data += np.zeros(3, "<f4").tobytes() + p[list(f)].tobytes() + b"\0\0"
    path.write_bytes(data)


@pytest.fixture
def probe(tmp_path, monkeypatch):
    monkeypatch.setenv("WBMP_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.delenv("WBMP_ROBOT_CACHE", raising=False)
    (tmp_path / "share" / "probe").mkdir(parents=True)
    _stl(tmp_path / "share" / "probe" / "part.stl", 0.1)
    urdf = tmp_path / "probe.urdf"
    urdf.write_text(URDF.format(z=0.0))
    return str(urdf), (str(tmp_path / "share"),), tmp_path


def _direct(urdf, dirs, kind):
    model = pin.buildModelFromUrdf(urdf, pin.JointModelFreeFlyer())
    gtype = pin.GeometryType.COLLISION if kind == "collision" else pin.GeometryType.VISUAL
    return pin.buildGeomFromUrdf(model, urdf, gtype, package_dirs=list(dirs))


def _same(a, b) -> None:
    assert [g.name for g in a.geometryObjects] == [g.name for g in b.geometryObjects]
    for ga, gb in zip(a.geometryObjects, b.geometryObjects, strict=True):
        np.testing.assert_array_equal(ga.placement.homogeneous, gb.placement.homogeneous)
        assert ga.meshPath == gb.meshPath and ga.parentJoint == gb.parentJoint
        if hasattr(ga.geometry, "vertices"):
            np.testing.assert_array_equal(ga.geometry.vertices(), gb.geometry.vertices())


def _load(urdf, dirs, kind="collision"):
    builds = []

    def build():
        builds.append(kind)
        return _load_geometry(urdf, dirs, kind)

    return cache.cached_geometry(urdf, dirs, kind, build), len(builds)


def test_robot_cache_hit_miss_and_invalidation(probe, caplog):
    """A first load builds and stores; a second reads the entry (no build) and equals Pinocchio's
    own load; an edited mesh or URDF misses and gives the new geometry; nothing is logged as
    damaged on the way."""
    urdf, dirs, tmp = probe
    caplog.set_level(logging.INFO, logger="robots.cache")
    for kind in ("collision", "visual"):
        gm, built = _load(urdf, dirs, kind)
        assert built == 1
        gm, built = _load(urdf, dirs, kind)
        assert built == 0
        _same(gm, _direct(urdf, dirs, kind))
    assert len(list((tmp / "cache" / "robots").iterdir())) == 2

    _stl(tmp / "share" / "probe" / "part.stl", 0.25)  # the mesh changed: its apex is higher
    gm, built = _load(urdf, dirs)
    assert built == 1
    assert gm.geometryObjects[0].geometry.vertices()[:, 2].max() == pytest.approx(0.25)
    _same(gm, _direct(urdf, dirs, "collision"))
    assert _load(urdf, dirs)[1] == 0

    (tmp / "probe.urdf").write_text(URDF.format(z=0.5))  # the URDF changed: the mesh moved up
    gm, built = _load(urdf, dirs)
    assert built == 1
    assert gm.geometryObjects[0].placement.translation[2] == pytest.approx(0.5)
    _same(gm, _direct(urdf, dirs, "collision"))
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING]


@pytest.mark.parametrize("damage", ["binary", "manifest", "truncated"])
def test_robot_cache_damaged_entry_is_rebuilt_with_one_warning(probe, caplog, damage):
    """A damaged entry is never read into Pinocchio: one warning, a rebuild, the right geometry,
    and the next load is a clean hit."""
    urdf, dirs, tmp = probe
    _load(urdf, dirs)
    entry = next((tmp / "cache" / "robots").iterdir())
    binary, manifest = entry / "geometry.bin", entry / "manifest.json"
    if damage == "binary":
        data = bytearray(binary.read_bytes())
        data[len(data) // 2] ^= 0xFF
        binary.write_bytes(bytes(data))
    elif damage == "manifest":
        manifest.write_text("{not json")
    else:
        binary.write_bytes(binary.read_bytes()[:100])
    caplog.set_level(logging.INFO, logger="robots.cache")
    gm, built = _load(urdf, dirs)
    assert built == 1
    _same(gm, _direct(urdf, dirs, "collision"))
    warnings = [r for r in caplog.records if r.levelno >= logging.WARNING]
    assert len(warnings) == 1 and "damaged" in warnings[0].getMessage()
    caplog.clear()
    assert _load(urdf, dirs)[1] == 0
    assert not caplog.records


def test_robot_cache_off_and_unwritable(probe, monkeypatch):
    """WBMP_ROBOT_CACHE=0 builds every time and writes nothing; an unwritable cache folder
    still gives the geometry."""
    urdf, dirs, tmp = probe
    monkeypatch.setenv("WBMP_ROBOT_CACHE", "0")
    assert _load(urdf, dirs)[1] == 1 and _load(urdf, dirs)[1] == 1
    assert not (tmp / "cache").exists()
    monkeypatch.delenv("WBMP_ROBOT_CACHE")
    (tmp / "cache").write_text("a file where the folder should be")
    gm, built = _load(urdf, dirs)
    assert built == 1
    _same(gm, _direct(urdf, dirs, "collision"))
