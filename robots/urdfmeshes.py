"""The mesh files a URDF names, resolved as Pinocchio resolves them, without loading a mesh.

The motion cache's key hashes the files of the robot's visual model; loading that model (assimp,
coal bounding-volume trees) only to list its files cost ~0.6 s of CPU for Talos on a fresh cache,
a planning command that never draws it. :func:`urdf_mesh_files` reads the ``<mesh filename=...>``
of the URDF's ``<visual>`` (or ``<collision>``) elements instead and resolves them the way
Pinocchio's URDF geometry parser does (``package://`` and relative names: the first package folder
holding the file; ``file://`` and absolute names as given). It answers only when that resolution is
proven on the same URDF: the collision model Pinocchio loaded (``check``) must list exactly the
files this resolution gives for the ``<collision>`` elements; otherwise, with ROS's package path
variables set (Pinocchio also searches them), or when a name does not resolve to a file, it gives
None and the caller loads the model.
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET

import pinocchio as pin

_ROS_PATHS = ("ROS_PACKAGE_PATH", "AMENT_PREFIX_PATH")  # Pinocchio appends their folders to the search


def _resolve(name: str, package_dirs: tuple[str, ...]) -> str | None:
    """The file a URDF mesh name stands for, or None (an unknown scheme, nothing found)."""
    scheme, sep, rest = name.partition("://")
    if sep:
        if scheme == "file":
            return rest
        if scheme not in ("package", "model"):
            return None
    elif os.path.isabs(name):  # noqa: PTH117
        return name
    else:
        rest = name
    for d in package_dirs:
        path = f"{d}/{rest}"
        if os.path.exists(path):  # noqa: PTH110
            return os.path.normpath(path)
    return None


def _mesh_names(root: ET.Element, kind: str) -> list[str]:
    return [mesh.get("filename", "") for link in root.iter("link") for element in link.iter(kind)
            for mesh in element.iter("mesh")]


def _files(names: list[str], package_dirs: tuple[str, ...]) -> list[str] | None:
    out = set()
    for name in names:
        path = _resolve(name, package_dirs)
        if path is None or not os.path.isfile(path):  # noqa: PTH113
            return None
        out.add(path)
    return sorted(out)


def urdf_mesh_files(urdf: str, package_dirs: tuple[str, ...], kind: str,
                    check: pin.GeometryModel) -> list[str] | None:
    """The mesh files of the URDF's ``kind`` (``"visual"`` or ``"collision"``) geometry, as
    :func:`robots.mesh_files` of the loaded model lists them; None when the resolution cannot be
    trusted (``check``, the URDF's collision model loaded by Pinocchio, lists other files than it
    gives for the collision elements) or a name does not resolve: then load the model."""
    if any(os.environ.get(v) for v in _ROS_PATHS):
        return None
    try:
        root = ET.parse(urdf).getroot()
    except (OSError, ET.ParseError):
        return None
    loaded = sorted({g.meshPath for g in check.geometryObjects if g.meshPath and os.path.isfile(g.meshPath)})  # noqa: PTH113
    if _files(_mesh_names(root, "collision"), package_dirs) != loaded:
        return None
    return _files(_mesh_names(root, kind), package_dirs)
