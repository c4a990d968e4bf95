"""The robot's geometry models (collision, visual) cached on disk across processes.

Loading a URDF's meshes (assimp parsing, coal bounding-volume trees) takes seconds for Talos'
visual meshes; reading a geometry model back from Pinocchio's binary serialization is several
times quicker. Each kind is its own entry, a folder ``<cache dir>/robots/<key>/`` (the cache
dir is ``$WBMP_CACHE_DIR``, else ``~/.cache/wbmp``; ``WBMP_ROBOT_CACHE=0`` turns the cache off)
holding ``geometry.bin`` and ``manifest.json``, so a command that needs only the collision
model never reads the visual one (:class:`robots.model.Robot` loads its visual model on first use).

The key is a sha256 of everything the geometry is made from: the kind, the URDF's content and real path,
the package folders that resolve its ``package://`` URIs, this module's and
:mod:`robots.model`'s sources (the Collada up-axis correction is applied before storing), the
versions of wbmp, Pinocchio and coal (which holds the serialization code), and :data:`FORMAT`. The meshes a URDF names are only known
once it is loaded, so the manifest lists every mesh file with its sha256, and a hit requires each
to hash the same today: an edited mesh misses and is rebuilt. The manifest also holds the size
and sha256 of the binary file, checked before Pinocchio reads them; a damaged entry (bad
manifest, wrong hash, a file Pinocchio cannot read) is removed with one warning (logger
``robots.cache``) and rebuilt. Entries are written to a temporary folder and renamed into place;
a cache folder that cannot be written only costs the speed-up.

The entries are written, checked and capped by :mod:`robots.store`, the disk store every cache uses.
"""

from __future__ import annotations

import functools
import hashlib
import json
import logging
import os
import shutil
from collections.abc import Callable
from importlib import metadata
from pathlib import Path

import pinocchio as pin

from robots.safeio import read_json
from robots.store import (
    MAX_MANIFEST_BYTES,
    EntryDamaged,
    EntryStale,
    cache_folder,
    entry_vanished,
    file_sha256,
    mark_used,
    read_manifest,
    store_entry,
)

_log = logging.getLogger("robots.cache")

FORMAT = 1  # bump when an entry's layout changes
_BINARY = "geometry.bin"
KINDS = ("collision", "visual")
_SOURCES = ("cache.py", "model.py")


def cache_root() -> Path | None:
    """``$WBMP_CACHE_DIR/robots`` (else ``~/.cache/wbmp/robots``); None when turned off."""
    return cache_folder("robots", "WBMP_ROBOT_CACHE")


@functools.cache
def _environment() -> tuple[tuple[str, str], ...]:
    here = Path(__file__).resolve().parent
    out = [("format", str(FORMAT))]
    for name in _SOURCES:
        out.append((name, hashlib.sha256((here / name).read_bytes()).hexdigest()))
    try:
        out.append(("wbmp", metadata.version("wbmp")))
    except metadata.PackageNotFoundError:
        out.append(("wbmp", ""))
    import coal  # type: ignore[import-untyped]

    # the libraries' own version strings (metadata.version costs ~20 ms a call)
    out += [("pinocchio", pin.__version__), ("coal", str(getattr(coal, "__version__", "")))]
    return tuple(out)


def cache_environment() -> tuple[tuple[str, str], ...]:
    """What every entry's key holds besides its files: :data:`FORMAT`, the sources of this module
    and :mod:`robots.model` (the Collada up-axis correction), the versions of wbmp, Pinocchio and
    coal (the HTML replay's mesh cache, :mod:`viz.meshcache`, keys on it too)."""
    return _environment()


def geometry_key(urdf: str, package_dirs: tuple[str, ...], kind: str) -> str:
    """The entry key of a URDF's geometry of one kind (module docstring)."""
    blob = json.dumps({"kind": kind, "urdf": file_sha256(urdf), "path": os.path.realpath(urdf),
                       "package_dirs": [os.path.realpath(p) for p in package_dirs],
                       "environment": _environment()}, sort_keys=True)
    return hashlib.sha256(blob.encode()).hexdigest()


def mesh_files(gmodel: pin.GeometryModel) -> list[str]:
    """The mesh files of a geometry model (primitives such as boxes have none)."""
    paths = {g.meshPath for g in gmodel.geometryObjects}
    return sorted(p for p in paths if p and os.path.isfile(p))  # noqa: PTH113


def stored_mesh_files(urdf: str, package_dirs: tuple[str, ...], kind: str) -> list[str] | None:
    """The mesh files of the stored ``kind`` geometry of ``urdf``, read from its entry's manifest
    without loading the model (the motion cache hashes a robot's meshes this way); None when the
    cache is off or holds no readable entry (then load the model and ask :func:`mesh_files`).
    The list is not verified against the files here: the caller hashes them itself."""
    root = cache_root()
    if root is None:
        return None
    try:
        key = geometry_key(urdf, package_dirs, kind)
        manifest = read_json(root / key / "manifest.json", MAX_MANIFEST_BYTES)
        if not isinstance(manifest, dict) or manifest.get("key") != key or manifest.get("format") != FORMAT:
            return None
        return sorted(str(p) for p in manifest["meshes"])
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return None


def _read(entry: Path) -> pin.GeometryModel:
    size, digest = read_manifest(entry, FORMAT)
    path = entry / _BINARY
    try:
        if path.stat().st_size != size or file_sha256(path) != digest:
            raise EntryDamaged(f"{_BINARY} does not match its manifest (size or sha256)")
    except OSError as e:
        raise EntryDamaged(f"{_BINARY}: {e.strerror or e}") from None
    gmodel = pin.GeometryModel()
    try:
        gmodel.loadFromBinary(str(path))
    except (RuntimeError, ValueError, OSError) as e:
        raise EntryDamaged(f"Pinocchio cannot read {_BINARY}: {e}") from None
    return gmodel


def _write(root: Path, key: str, gmodel: pin.GeometryModel) -> None:
    store_entry(root, key, lambda tmp: gmodel.saveToBinary(str(tmp / _BINARY)),
                {"format": FORMAT, "meshes": {p: file_sha256(p) for p in mesh_files(gmodel)}}, data=_BINARY)


def cached_geometry(urdf: str, package_dirs: tuple[str, ...], kind: str,
                    build: Callable[[], pin.GeometryModel]) -> pin.GeometryModel:
    """The ``kind`` geometry model of ``urdf``: read from the disk cache when an intact,
    current entry holds it, else ``build()`` (and stored). Errors of ``build`` propagate."""
    root = cache_root()
    if root is None:
        return build()
    try:
        key = geometry_key(urdf, package_dirs, kind)
    except OSError:
        return build()
    entry = root / key
    if entry.is_dir():
        try:
            gmodel = _read(entry)
            mark_used(entry)
            return gmodel
        except EntryDamaged as e:
            if entry_vanished(entry):  # removed by another process while read: a miss
                return _build_and_store(root, key, build)
            _log.warning("wbmp: warning: robot cache entry %s is damaged (%s); removed it, the robot is loaded from its files", entry, e)
        except EntryStale as e:
            _log.info("robot cache: entry %s is out of date (%s); rebuilding it", entry, e)
        shutil.rmtree(entry, ignore_errors=True)
    return _build_and_store(root, key, build)


def _build_and_store(root: Path, key: str, build: Callable[[], pin.GeometryModel]) -> pin.GeometryModel:
    gmodel = build()
    try:
        _write(root, key, gmodel)
    except (OSError, RuntimeError) as e:
        _log.info("robot cache: cannot store %s (%s)", root / key, e)
    return gmodel


