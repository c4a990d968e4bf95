"""The compiled MuJoCo model cached on disk across processes.

Building Talos' model (URDF rewrite, ``MjSpec``, two compilations for the self-collision pairs,
the contacts at rest) takes ~0.2-0.8 s; reading the compiled model back from MuJoCo's binary
format (MJB) takes ~0.02 s. An entry is a folder ``<cache dir>/mujoco/<key>/`` (the cache dir is
``$WBMP_CACHE_DIR``, else ``~/.cache/wbmp``; ``WBMP_MUJOCO_CACHE=0`` turns the cache off)
holding ``model.mjb`` and ``meta.json`` (the index maps of :class:`sim.model.SimModel`, and the
size and sha256 of ``model.mjb``).

The key is a sha256 of everything the model is made from: the rewritten URDF (which names every
mesh file by its absolute path) and the sha256 of each mesh file it names, of the robot's
collision meshes and of the scene's meshes; the robot's profile, standing posture and effort
limits; the timestep, the joint-friction flag, the scene and the collision pairs; the sources of
:mod:`sim.model`, this module and :mod:`robots.contact`; the versions of wbmp, MuJoCo and
Pinocchio; and :data:`FORMAT`. An edited file therefore misses. An entry whose ``model.mjb``
does not match its size and sha256, or whose ``meta.json`` is unreadable or does not fit the
model, is removed with one warning (logger ``sim.modelcache``) and rebuilt. Entries are written
to a temporary folder and renamed into place; a cache folder that cannot be written only costs
the speed-up. A hit renews the entry's use time and a store applies the size cap of the whole
cache (:func:`robots.store.enforce_cap`); an entry removed by another process while it is read is
a miss.
"""

from __future__ import annotations

import functools
import hashlib
import json
import logging
import os
import re
import shutil
from collections.abc import Callable
from importlib import metadata
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import pinocchio as pin

from robots import (
    EntryDamaged,
    cache_folder,
    entry_vanished,
    file_sha256,
    mark_used,
    read_bytes,
    store_entry,
)

_log = logging.getLogger("sim.modelcache")

FORMAT = 1  # bump when an entry's layout changes
_BINARY = "model.mjb"
_META = "meta.json"
MAX_META_BYTES = 16 << 20
_MESH_FILE = re.compile(r'filename="([^"]+)"')


def cache_root() -> Path | None:
    """``$WBMP_CACHE_DIR/mujoco`` (else ``~/.cache/wbmp/mujoco``); None when turned off."""
    return cache_folder("mujoco", "WBMP_MUJOCO_CACHE")


@functools.cache
def _environment() -> tuple[tuple[str, str], ...]:
    root = Path(__file__).resolve().parents[1]
    out = [("format", str(FORMAT))]
    for name in ("sim/model.py", "sim/urdf.py", "sim/modelcache.py", "robots/contact.py"):
        out.append((name, hashlib.sha256((root / name).read_bytes()).hexdigest()))
    try:
        out.append(("wbmp", metadata.version("wbmp")))
    except metadata.PackageNotFoundError:
        out.append(("wbmp", ""))
    out += [("mujoco", mujoco.__version__), ("pinocchio", pin.__version__)]  # (metadata.version: ~20 ms each)
    return tuple(out)


def model_key(robot: Any, xml: str, *, timestep: float, joint_friction: bool, scene: Any,
              pairs: tuple[tuple[str, str], ...], floor_timeconst: float | None = None) -> str:
    """The entry key of a MuJoCo model (module docstring); OSError when a file cannot be read."""
    files = set(_MESH_FILE.findall(xml))
    files.update(g.meshPath for g in robot.collision_model.geometryObjects)
    if scene is not None:
        files.update(o.mesh for o in scene.objects if o.mesh)
    meshes = {p: file_sha256(p, "mesh") for p in sorted(f for f in files if f and os.path.isfile(f))}  # noqa: PTH113
    extra = {} if floor_timeconst is None else {"floor_timeconst": float(floor_timeconst)}
    blob = json.dumps({**extra,
        "xml": hashlib.sha256(xml.encode()).hexdigest(), "meshes": meshes,
        "profile": repr(robot.profile), "q_standing": np.asarray(robot.q_standing, dtype=float).tobytes().hex(),
        "effort": np.asarray(robot.model.effortLimit, dtype=float).tobytes().hex(),
        "names": list(robot.model.names), "timestep": float(timestep), "joint_friction": bool(joint_friction),
        "scene": repr(scene), "pairs": [list(p) for p in pairs], "environment": _environment(),
    }, sort_keys=True)
    return hashlib.sha256(blob.encode()).hexdigest()



def _read(entry: Path) -> tuple[mujoco.MjModel, dict[str, Any]]:
    try:
        raw = read_bytes(entry / _META, MAX_META_BYTES)
    except FileNotFoundError:
        raise EntryDamaged(f"no {_META}") from None
    except OSError as e:  # a FIFO, a device, too large
        raise EntryDamaged(f"{_META}: {e.strerror or e}") from None
    try:
        meta = json.loads(raw)
        if meta["key"] != entry.name or meta["format"] != FORMAT:
            raise EntryDamaged(f"{_META} names another entry")
        size, digest, fields = int(meta["size"]), str(meta["sha256"]), dict(meta["fields"])
    except (ValueError, KeyError, TypeError) as e:
        raise EntryDamaged(f"{_META} is not a manifest ({type(e).__name__}: {e})") from None
    path = entry / _BINARY
    try:
        data = read_bytes(path, "entry")
    except OSError as e:
        raise EntryDamaged(f"{_BINARY}: {e.strerror or e}") from None
    if len(data) != size or hashlib.sha256(data).hexdigest() != digest:
        raise EntryDamaged(f"{_BINARY} does not match its manifest (size or sha256)")
    try:
        model = mujoco.MjModel.from_binary_path(str(path))
    except (ValueError, RuntimeError, OSError) as e:
        raise EntryDamaged(f"MuJoCo cannot read {_BINARY}: {e}") from None
    return model, fields


def _write(root: Path, key: str, model: mujoco.MjModel, fields: dict[str, Any]) -> None:
    store_entry(root, key, lambda tmp: mujoco.mj_saveModel(model, str(tmp / _BINARY), None),
                {"format": FORMAT, "fields": fields}, data=_BINARY, manifest_name=_META)


def cached_model(key: str | None, build: Callable[[], tuple[mujoco.MjModel, dict[str, Any]]],
                 check: Callable[[mujoco.MjModel, dict[str, Any]], Any]) -> Any:
    """``check(model, fields)`` of the entry ``key`` when it is intact, else of ``build()``
    (stored under ``key``). ``check`` turns the pair into the caller's object and raises
    KeyError, TypeError, ValueError or IndexError when the fields do not fit the model (a
    damaged entry). ``key`` None: no cache."""
    root = cache_root()
    if root is None or key is None:
        return check(*build())
    entry = root / key
    if entry.is_dir():
        try:
            try:
                result = check(*_read(entry))
            except (KeyError, TypeError, ValueError, IndexError) as e:
                raise EntryDamaged(f"{_META} does not fit the model ({type(e).__name__}: {e})") from None
            mark_used(entry)
            return result
        except EntryDamaged as e:
            if not entry_vanished(entry):  # else removed by another process while read: a miss
                _log.warning("wbmp: warning: MuJoCo model cache entry %s is damaged (%s); removed it, the model is built again",
                             entry, e)
                shutil.rmtree(entry, ignore_errors=True)
    model, fields = build()
    result = check(model, fields)
    try:
        _write(root, key, model, fields)
    except (OSError, ValueError, RuntimeError) as e:
        _log.info("MuJoCo model cache: cannot store %s (%s)", entry, e)
    return result
