"""The URDF's mesh files listed without loading a mesh (robots.urdf_mesh_files) are the files of the
geometry model Pinocchio loads from it (``package://`` names searched in the package folders in order,
relative, ``file://`` and absolute names), and the listing gives up (None) whenever it cannot be
sure: a collision model that lists other files, a name that resolves to nothing, ROS's package path.

A small URDF written here (ASCII STL tetrahedra); Talos's and G1's own visual models in the long test.
"""

from __future__ import annotations

import os

import pinocchio as pin
import pytest

from robots import load_robot, mesh_files, urdf_mesh_files

LINK = """  <link name="{name}">
    <inertial><mass value="1"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial>
    <visual><geometry><mesh filename="{visual}"/></geometry></visual>
    <visual><geometry><box size="0.1 0.1 0.1"/></geometry></visual>
    <collision><geometry><mesh filename="{collision}"/></geometry></collision>
  </link>
"""
JOINT = """  <joint name="j{i}" type="revolute"><parent link="l{p}"/><child link="l{i}"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
"""
TETRA = ("solid t\n" + "".join("facet normal 0 0 0\n outer loop\n" + "".join(f"  vertex {' '.join(map(str, v))}\n" for v in f)
                               + " endloop\nendfacet\n" for f in (((0, 0, 0), (0, 1, 0), (1, 0, 0)), ((0, 0, 0), (1, 0, 0), (0, 0, 1)),
                                                                  ((0, 0, 0), (0, 0, 1), (0, 1, 0)), ((1, 0, 0), (0, 1, 0), (0, 0, 1))))
         + "endsolid t\n")


def write_urdf(tmp_path, visuals: list[str], collisions: list[str]) -> str:
    links = [LINK.format(name=f"l{i}", visual=v, collision=c) for i, (v, c) in enumerate(zip(visuals, collisions, strict=True))]
    joints = [JOINT.format(i=i, p=i - 1) for i in range(1, len(links))]
    path = tmp_path / "robot.urdf"
    path.write_text('<robot name="r">\n' + "".join(links) + "".join(joints) + "</robot>\n", encoding="utf-8")
    return str(path)


def loaded(urdf: str, dirs: tuple[str, ...], kind: pin.GeometryType) -> pin.GeometryModel:
    return pin.buildGeomFromUrdf(pin.buildModelFromUrdf(urdf), urdf, kind, package_dirs=list(dirs))


@pytest.fixture
def folders(tmp_path, monkeypatch):
    """Two package folders: ``a`` first; ``pkg/shared.stl`` in both, ``pkg/late.stl`` only in ``b``."""
    for v in ("ROS_PACKAGE_PATH", "AMENT_PREFIX_PATH"):
        monkeypatch.delenv(v, raising=False)
    a, b = tmp_path / "a", tmp_path / "b"
    for folder, names in ((a, ("shared", "hull", "rel")), (b, ("shared", "late", "hull2"))):
        (folder / "pkg").mkdir(parents=True)
        for n in names:
            (folder / "pkg" / f"{n}.stl").write_text(TETRA, encoding="ascii")
    (tmp_path / "abs.stl").write_text(TETRA, encoding="ascii")
    return str(a), str(b)


def test_the_listing_resolves_mesh_names_as_pinocchio_does(tmp_path, folders):
    dirs = folders
    visuals = ["package://pkg/shared.stl", "package://pkg/late.stl", "pkg/rel.stl",
               f"file://{tmp_path}/abs.stl", str(tmp_path / "abs.stl")]
    collisions = ["package://pkg/hull.stl", "package://pkg/hull2.stl", "package://pkg/shared.stl",
                  "package://pkg/hull.stl", "pkg/rel.stl"]
    urdf = write_urdf(tmp_path, visuals, collisions)
    collision = loaded(urdf, dirs, pin.GeometryType.COLLISION)
    want = mesh_files(loaded(urdf, dirs, pin.GeometryType.VISUAL))
    got = urdf_mesh_files(urdf, dirs, "visual", collision)
    assert got == want
    # the first folder wins for shared.stl, the second holds late.stl: both folders appear
    assert os.path.join(dirs[0], "pkg", "shared.stl") in got and os.path.join(dirs[1], "pkg", "late.stl") in got
    assert urdf_mesh_files(urdf, dirs, "collision", collision) == mesh_files(collision)
    # the folders the other way round: shared.stl now comes from b (Pinocchio agrees)
    swapped = dirs[::-1]
    again = urdf_mesh_files(urdf, swapped, "visual", loaded(urdf, swapped, pin.GeometryType.COLLISION))
    assert again == mesh_files(loaded(urdf, swapped, pin.GeometryType.VISUAL)) != got


def test_the_listing_gives_up_when_it_cannot_be_sure(tmp_path, folders, monkeypatch):
    dirs = folders
    urdf = write_urdf(tmp_path, ["package://pkg/shared.stl"], ["package://pkg/hull.stl"])
    collision = loaded(urdf, dirs, pin.GeometryType.COLLISION)
    assert urdf_mesh_files(urdf, dirs, "visual", collision) == [os.path.join(dirs[0], "pkg", "shared.stl")]
    # a collision model with other files than the URDF's collision names resolve to
    other = loaded(write_urdf(tmp_path / "a", ["package://pkg/shared.stl"], ["package://pkg/shared.stl"]),
                   dirs, pin.GeometryType.COLLISION)
    assert urdf_mesh_files(urdf, dirs, "visual", other) is None
    assert urdf_mesh_files(urdf, dirs, "visual", pin.GeometryModel()) is None
    # a visual name that resolves to nothing, an unknown scheme
    for name in ("package://pkg/missing.stl", "http://example/pkg/shared.stl"):
        broken = write_urdf(tmp_path / "b", [name], ["package://pkg/hull.stl"])
        assert urdf_mesh_files(broken, dirs, "visual", collision) is None
    # Pinocchio also searches ROS's package path: not followed here
    monkeypatch.setenv("ROS_PACKAGE_PATH", str(tmp_path))
    assert urdf_mesh_files(urdf, dirs, "visual", collision) is None


@pytest.mark.long
def test_the_listing_equals_the_loaded_visual_models_of_talos_and_g1():
    # fast twin: test_the_listing_resolves_mesh_names_as_pinocchio_does (same resolution on a small URDF)
    for name in ("talos", "g1"):
        robot = load_robot(name)
        listed = urdf_mesh_files(robot.urdf_path, robot.package_dirs, "visual", robot.collision_model)
        assert listed is not None and listed == mesh_files(robot.visual_model), name
