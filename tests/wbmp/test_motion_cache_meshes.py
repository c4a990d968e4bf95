"""The motion cache hashes a robot's visual meshes without loading its visual model (the robot
cache's manifest lists them, or the URDF's mesh names resolved as Pinocchio does), and an edited
mesh file still misses.

A one-link URDF written here, with an STL visual mesh and an STL collision mesh, loaded by
Pinocchio through the real robot cache (``WBMP_CACHE_DIR`` in ``tmp_path``).
"""

from __future__ import annotations

import dataclasses
import hashlib

import numpy as np
import pinocchio as pin

import robots
from robots import load_robot
from robots.cache import mesh_files
from robots.model import Robot, _geometry, _Lazy
from wbmp.motioncache import MotionCache, robot_files, robot_hash

URDF = """<robot name="block">
  <link name="base">
    <inertial><mass value="1"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial>
    <visual><geometry><mesh filename="package://block/looks.stl"/></geometry></visual>
    <collision><geometry><mesh filename="package://block/hull.stl"/></geometry></collision>
  </link>
</robot>
"""


def stl(height: float) -> str:
    """An ASCII STL tetrahedron of the given height [m]."""
    v = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, height)]
    faces = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]
    body = "".join("facet normal 0 0 0\n outer loop\n" + "".join(f"  vertex {x} {y} {z}\n" for x, y, z in (v[i] for i in f))
                   + " endloop\nendfacet\n" for f in faces)
    return f"solid t\n{body}endsolid t\n"


def robot_of(urdf: str, root: str, loads: list[str]) -> Robot:
    """A fresh Robot (talos' profile) over the block URDF; ``loads`` records visual model loads."""
    base = load_robot("talos")

    def visual() -> pin.GeometryModel:
        loads.append("visual")
        return _geometry("block", urdf, (root,), "visual")

    return dataclasses.replace(base, model=pin.buildModelFromUrdf(urdf), urdf_path=urdf, package_dirs=(root,),
                               collision_model=_geometry("block", urdf, (root,), "collision"), _visual=_Lazy(visual),
                               q_standing=np.zeros(7), _frame_ids={})


def test_visual_meshes_come_from_the_robot_cache_and_an_edit_misses(tmp_path, monkeypatch):
    monkeypatch.setenv("WBMP_CACHE_DIR", str(tmp_path / "cache"))
    package = tmp_path / "pkg" / "block"
    package.mkdir(parents=True)
    (package / "looks.stl").write_text(stl(1.0), encoding="ascii")
    (package / "hull.stl").write_text(stl(0.5), encoding="ascii")
    urdf = tmp_path / "block.urdf"
    urdf.write_text(URDF, encoding="utf-8")
    root = str(tmp_path / "pkg")

    loads: list[str] = []
    first = robot_of(str(urdf), root, loads)
    files = robot_files(first)  # no visual entry in the robot cache yet: listed from the URDF (robots.urdf_mesh_files)
    assert loads == []
    looks, hull = str((package / "looks.stl").resolve()), str((package / "hull.stl").resolve())
    assert {looks, hull, str(urdf)} <= set(files)
    assert mesh_files(first.visual_model) == [str(package / "looks.stl")]  # loaded (and stored) here
    assert loads == ["visual"]
    assert files[looks] == hashlib.sha256((package / "looks.stl").read_bytes()).hexdigest()

    loads.clear()
    second = robot_of(str(urdf), root, loads)
    with monkeypatch.context() as patch:
        patch.setattr(robots, "urdf_mesh_files", lambda *args: None)  # the manifest alone answers now
        assert robot_files(second) == files  # the same files and hashes, listed by the cache's manifest
        assert loads == []  # ... without loading the visual model
        patch.setattr(robots, "stored_mesh_files", lambda *args: None)  # neither answers: the model is loaded
        assert robot_files(robot_of(str(urdf), root, loads)) == files and loads == ["visual"]
    loads.clear()

    cache = MotionCache(tmp_path / "cache" / "motions")
    key = "a" * 64
    cache.store_request("b" * 64, key, files, robot_hash(second, files))
    assert cache.lookup_request("b" * 64) == (key, robot_hash(second, files), None)
    (package / "looks.stl").write_text(stl(1.2), encoding="ascii")  # an edited visual mesh
    assert cache.lookup_request("b" * 64) is None  # the request misses
    third = robot_of(str(urdf), root, loads)
    edited = robot_files(third)
    assert loads == [] and set(edited) == set(files) and edited[looks] != files[looks]
    assert robot_hash(third, edited) != robot_hash(second, files)  # so does the motion key
