"""The HTML replay's robot meshes, prepared once and cached on disk across processes.

The replay sends every visual mesh decimated and quantized (:func:`viz.scene._compact_geometry`):
for Talos that is parsing ~5 MB of STL files into 52 meshes of ~90k triangles, clustering and
quantizing them, about a second of every ``wbmp solve --html``; and loading the visual model
(which the replay needs only for each geometry's joint, placement and colour) a few tenths more.
Both are kept here: one entry ``<cache dir>/viz/<key>/`` (``$WBMP_CACHE_DIR``, else
``~/.cache/wbmp``; ``WBMP_MESH_CACHE=0`` turns it off) holds ``meshes.npz`` (each geometry's
name, parent joint and frame, placement, colour, mesh scale and path, and its packed mesh:
16-bit positions, faces, static transform) and ``manifest.json``.

The key is a sha256 of the URDF's content and real path, the package folders, the sources of
this module and :mod:`viz.scene` (the decimation and quantization), the robot cache's
environment (:func:`robots.cache.cache_environment`: the up-axis correction, the Pinocchio and coal
versions), numpy's version and :data:`FORMAT`. The manifest lists every mesh file with its
sha256, and a hit requires each to hash the same today (an edited mesh misses and is rebuilt);
it also holds the size and sha256 of ``meshes.npz``, checked before numpy reads it. A damaged
entry is removed with one warning (logger ``viz.meshcache``) and rebuilt; an entry is written
to a temporary folder and renamed into place; a cache that cannot be written only costs the
speed-up. A hit renews the entry's use time and a store applies the size cap of the whole cache
(:func:`robots.store.enforce_cap`); an entry removed by another process while it is read is a miss.

A hit gives the replay a light visual model (:func:`replay_robot`): the same geometry objects
(names, joints, placements, colours) without their meshes, so the visual meshes are not loaded
at all. The page drawn from a hit equals the page drawn from the files (tests/viz/test_mesh_cache.py).
"""

from __future__ import annotations

import functools
import hashlib
import io
import json
import logging
import os
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from robots import (
    EntryDamaged,
    EntryStale,
    cache_environment,
    cache_folder,
    entry_vanished,
    file_sha256,
    mark_used,
    mesh_files,
    read_bytes,
    read_manifest,
    store_entry,
)

_log = logging.getLogger("viz.meshcache")

FORMAT = 1  # bump when an entry's layout changes
_DATA = "meshes.npz"
_SOURCES = ("meshcache.py", "scene.py")
MAX_DATA_BYTES = 256 << 20
# kinds: a packed mesh; a primitive (box, sphere, cylinder, capsule: ``shapes`` holds its sizes);
# another geometry (the replay needs the real visual model)
PACKED, PRIMITIVE, OTHER = 1, 2, 0
_PRIMITIVES = ("Box", "Sphere", "Cylinder", "Capsule")


def cache_root() -> Path | None:
    """``$WBMP_CACHE_DIR/viz`` (else ``~/.cache/wbmp/viz``); None when ``WBMP_MESH_CACHE=0``."""
    return cache_folder("viz", "WBMP_MESH_CACHE")


@dataclass(frozen=True, eq=False)
class ReplayGeometry:
    """A robot's visual geometry as the replay uses it.

    Attributes:
        arrays: ``meshes.npz``'s arrays (module docstring): per geometry ``names``, ``joints``,
            ``frames``, ``placements`` (G, 4, 4), ``colors`` (G, 4), ``scales`` (G, 3),
            ``paths``, ``kinds``, ``shapes`` (G, 4: primitive type index and sizes),
            ``statics`` (G, 4, 4), ``vcount``, ``fcount``; all meshes' ``positions`` (uint16)
            and ``faces`` (uint32) one after the other.
    """

    arrays: dict[str, np.ndarray]

    def meshes(self) -> list[tuple[Any, np.ndarray] | None]:
        """(packed mesh, static 4x4) of each geometry, or None where it is not packed."""
        from viz.scene import _PackedMesh

        a = self.arrays
        out: list[tuple[Any, np.ndarray] | None] = []
        v0 = f0 = 0
        for g in range(len(a["kinds"])):
            nv, nf = int(a["vcount"][g]), int(a["fcount"][g])
            if int(a["kinds"][g]) == PACKED:
                out.append((_PackedMesh(a["positions"][v0:v0 + nv], a["faces"][f0:f0 + nf]), a["statics"][g].copy()))
            else:
                out.append(None)
            v0, f0 = v0 + nv, f0 + nf
        return out

    def standalone(self) -> bool:
        """Every geometry is a packed mesh or a primitive (the replay needs no mesh file)."""
        return bool(np.all(self.arrays["kinds"] != OTHER))

    def visual_model(self) -> pin.GeometryModel:
        """The visual model's geometry objects without their meshes: names, parent joints and
        frames, placements, colours, mesh scales and paths, primitives as they are (a mesh
        becomes a 0-radius sphere: its packed form is in :meth:`meshes`)."""
        import coal  # type: ignore[import-untyped]

        a = self.arrays
        gmodel = pin.GeometryModel()
        for g in range(len(a["names"])):
            shape = coal.Sphere(0.0)
            if int(a["kinds"][g]) == PRIMITIVE:
                kind, *size = (float(x) for x in a["shapes"][g])
                name = _PRIMITIVES[int(kind)]
                shape = getattr(coal, name)(*size[:{"Box": 3, "Sphere": 1}.get(name, 2)])
            geom = pin.GeometryObject(str(a["names"][g]), int(a["joints"][g]), int(a["frames"][g]),
                                      pin.SE3(a["placements"][g]), shape, str(a["paths"][g]),
                                      np.array(a["scales"][g]), False, np.array(a["colors"][g]))
            gmodel.addGeometryObject(geom)
        return gmodel


def _primitive(shape) -> list[float] | None:
    """[type index, sizes...] of a coal primitive as its constructor takes them, else None."""
    name = type(shape).__name__
    if name == "Box":
        size = [2.0 * float(h) for h in shape.halfSide]
    elif name == "Sphere":
        size = [float(shape.radius), 0.0, 0.0]
    elif name in ("Cylinder", "Capsule"):
        size = [float(shape.radius), 2.0 * float(shape.halfLength), 0.0]
    else:
        return None
    return [float(_PRIMITIVES.index(name)), *size]


def prepare(gmodel: pin.GeometryModel) -> ReplayGeometry:
    """Pack every geometry of a visual model (:func:`viz.scene._compact_geometry`)."""
    from viz.scene import _compact_geometry

    geoms = list(gmodel.geometryObjects)
    kinds, shapes, statics, vcount, fcount, positions, faces = [], [], [], [], [], [], []
    for geom in geoms:
        packed = _compact_geometry(geom)
        if packed is None:
            primitive = _primitive(geom.geometry)
            kinds.append(OTHER if primitive is None else PRIMITIVE)
            shapes.append(primitive or [0.0] * 4)
            statics.append(np.eye(4))
            vcount.append(0)
            fcount.append(0)
            continue
        mesh, static = packed
        kinds.append(PACKED)
        shapes.append([0.0] * 4)
        statics.append(static)
        vcount.append(len(mesh.positions))
        fcount.append(len(mesh.faces))
        positions.append(mesh.positions)
        faces.append(mesh.faces.astype(np.uint32))
    arrays = {
        "names": np.array([g.name for g in geoms], dtype=str),
        "joints": np.array([int(g.parentJoint) for g in geoms], dtype=np.int64),
        "frames": np.array([int(g.parentFrame) for g in geoms], dtype=np.int64),
        "placements": np.array([g.placement.homogeneous for g in geoms], dtype=float).reshape(-1, 4, 4),
        "colors": np.array([np.asarray(g.meshColor, dtype=float) for g in geoms]).reshape(-1, 4),
        "scales": np.array([np.asarray(g.meshScale, dtype=float) for g in geoms]).reshape(-1, 3),
        "paths": np.array([g.meshPath or "" for g in geoms], dtype=str),
        "kinds": np.array(kinds, dtype=np.int8),
        "shapes": np.array(shapes, dtype=float).reshape(-1, 4),
        "statics": np.array(statics, dtype=float).reshape(-1, 4, 4),
        "vcount": np.array(vcount, dtype=np.int64),
        "fcount": np.array(fcount, dtype=np.int64),
        "positions": np.concatenate(positions) if positions else np.zeros((0, 3), np.uint16),
        "faces": np.concatenate(faces) if faces else np.zeros((0, 3), np.uint32),
    }
    return ReplayGeometry(arrays)


@functools.cache
def _sources() -> tuple[tuple[str, str], ...]:
    here = Path(__file__).resolve().parent
    return tuple((name, hashlib.sha256((here / name).read_bytes()).hexdigest()) for name in _SOURCES)


def entry_key(urdf: str, package_dirs: tuple[str, ...]) -> str:
    """The entry key of a URDF's replay geometry (module docstring)."""
    blob = json.dumps({"format": FORMAT, "urdf": file_sha256(urdf), "path": os.path.realpath(urdf),
                       "package_dirs": [os.path.realpath(p) for p in package_dirs],
                       "sources": _sources(), "robots": cache_environment(), "numpy": np.__version__},
                      sort_keys=True)
    return hashlib.sha256(blob.encode()).hexdigest()




_FIELDS = ("names", "joints", "frames", "placements", "colors", "scales", "paths", "kinds", "shapes", "statics",
           "vcount", "fcount", "positions", "faces")


def _read(entry: Path) -> ReplayGeometry:
    size, digest = read_manifest(entry, FORMAT)
    try:
        data = read_bytes(entry / _DATA, MAX_DATA_BYTES)
    except OSError as e:
        raise EntryDamaged(f"{_DATA}: {e.strerror or e}") from None
    if len(data) != size or hashlib.sha256(data).hexdigest() != digest:
        raise EntryDamaged(f"{_DATA} does not match its manifest (size or sha256)")
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as npz:
            arrays = {name: npz[name] for name in _FIELDS}
    except (ValueError, KeyError, OSError, EOFError) as e:
        raise EntryDamaged(f"numpy cannot read {_DATA}: {e}") from None
    g = len(arrays["names"])
    if (any(len(arrays[k]) != g for k in _FIELDS[:12])
            or int(arrays["vcount"].sum()) != len(arrays["positions"])
            or int(arrays["fcount"].sum()) != len(arrays["faces"])):
        raise EntryDamaged(f"{_DATA}'s arrays do not fit together")
    return ReplayGeometry(arrays)


def _write(root: Path, key: str, replay: ReplayGeometry, meshes: list[str]) -> None:
    buf = io.BytesIO()
    np.savez(buf, allow_pickle=False, **replay.arrays)
    store_entry(root, key, lambda tmp: (tmp / _DATA).write_bytes(buf.getvalue()),
                {"format": FORMAT, "meshes": {p: file_sha256(p) for p in meshes}}, data=_DATA)


def _hashable(robot) -> tuple[str, tuple[str, ...]]:
    return str(robot.urdf_path), tuple(str(p) for p in robot.package_dirs)


@functools.lru_cache(maxsize=8)
def _cached(urdf: str, package_dirs: tuple[str, ...], _mtime_ns: int, _size: int, root: Path) -> ReplayGeometry | None:
    """The replay geometry of a hit (read once a process), or None (no intact, current entry)."""
    try:
        key = entry_key(urdf, package_dirs)
    except OSError:
        return None
    entry = root / key
    if not entry.is_dir():
        return None
    try:
        replay = _read(entry)
        mark_used(entry)
        return replay
    except EntryDamaged as e:
        if entry_vanished(entry):  # removed by another process while read: a miss
            return None
        _log.warning("wbmp: warning: HTML mesh cache entry %s is damaged (%s); removed it, the meshes are "
                     "prepared from their files", entry, e)
    except EntryStale as e:
        _log.info("mesh cache: entry %s is out of date (%s); rebuilding it", entry, e)
    shutil.rmtree(entry, ignore_errors=True)
    return None


def replay_geometry(robot) -> tuple[ReplayGeometry, bool]:
    """``(geometry, hit)``: the robot's replay geometry from the disk cache (``hit`` True), else
    prepared from ``robot.visual_model`` (and stored)."""
    root = cache_root()
    urdf, dirs = _hashable(robot)
    if root is not None:
        try:
            st = Path(urdf).stat()
        except OSError:
            root = None
    if root is None:
        return prepare(robot.visual_model), False
    found = _cached(urdf, dirs, st.st_mtime_ns, st.st_size, root)
    if found is not None:
        return found, True
    replay = prepare(robot.visual_model)
    try:
        _write(root, entry_key(urdf, dirs), replay, mesh_files(robot.visual_model))
        _cached.cache_clear()
    except (OSError, ValueError) as e:
        _log.info("mesh cache: cannot store an entry in %s (%s)", root, e)
    return replay, False


class _ReplayRobot:
    """A robot whose visual model is the light one of a cache hit (everything else is the robot's)."""

    def __init__(self, robot, replay: ReplayGeometry) -> None:
        self._robot = robot
        self.replay = replay
        self.visual_model = replay.visual_model()

    def __getattr__(self, attr: str) -> Any:
        return getattr(self._robot, attr)


def replay_robot(robot):
    """The robot for drawing a replay: on a cache hit whose geometries are all packed meshes or
    primitives, a stand-in whose ``visual_model`` holds no mesh (none is loaded); else the
    robot itself."""
    if isinstance(robot, _ReplayRobot):
        return robot
    replay, hit = replay_geometry(robot)
    if hit and replay.standalone():
        return _ReplayRobot(robot, replay)
    return robot


def compact_meshes(robot) -> list[tuple[Any, np.ndarray] | None]:
    """(packed mesh, static 4x4) of each geometry of ``robot.visual_model`` (None: not packed),
    from the disk cache when it holds them."""
    if isinstance(robot, _ReplayRobot):
        return robot.replay.meshes()
    replay, _ = replay_geometry(robot)
    if list(replay.arrays["names"]) != [g.name for g in robot.visual_model.geometryObjects]:
        return prepare(robot.visual_model).meshes()  # not this visual model's entry (never expected)
    return replay.meshes()
