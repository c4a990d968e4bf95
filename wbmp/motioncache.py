"""The motion cache: a repeated ``wbmp solve`` answers from the stored result in a fraction of a second.

A finished solve (plan, simulated execution, report) is stored as a motion file
(:mod:`wbmp.motionfile`) under ``<cache dir>/motions/`` (the cache dir is ``$WBMP_CACHE_DIR``,
else ``~/.cache/wbmp``, beside the solver cache's ``planner/``):

* ``<key>.npz``: the motion file, ``<key>.json``: its manifest (key, size and sha256 of the
  ``.npz``, the wbmp version); ``<key>.page``: the HTML replay's data (:mod:`viz.html`), made
  the first time a hit asks for ``--html``, with ``<key>.page.json`` (its size and sha256).
* ``requests/<request key>.json``: which motion a request (the exact sentence or spec file,
  robot, options) led to, with the sha256 of every robot file it depended on (profile, URDF,
  meshes) and the sentence's parsed actions (:meth:`language.ActionPlan.to_record`). A repeat
  is answered from it without loading the robot or parsing the sentence again.

The motion key (:func:`motion_key`) is a sha256 of everything that determines the numbers: the
compiled TaskSpec's JSON without its description (two phrasings of one spec share an entry; its
scene included, with the sha256 of the scene's mesh files),
the robot (profile, and the sha256 of its URDF and mesh files), the simulate flag and the push,
the solver's environment switches (``WBMP_COMPILE``), the versions of wbmp and of the numeric
libraries, and a hash of the sources of ``language/ tasks/ robots/ planner/ sim/`` and of the
pipeline (:func:`source_hash`). The request key adds the request's own text (and the content
of its ``--scene`` file; a scene with meshes takes the ordinary path).

Nothing is trusted blindly: an entry is used only when the sha256 of its file matches its
manifest and :func:`wbmp.motionfile.motion_from_arrays` accepts every key, and when the spec it
holds hashes back to its key. A damaged entry is removed with one warning (logger
``wbmp.motioncache``) and the motion is computed again. A hit renews the use time of the entry's
manifest (and of the request record); a store applies the size cap of the whole cache
(:func:`robots.store.enforce_cap`: least recently used entries removed, manifest first), and an
entry removed by another process while it is read is a miss. Every file is written atomically
(:mod:`viz.files`); a cache folder that cannot be written only costs the speed-up.
"""

from __future__ import annotations

import functools
import hashlib
import io
import json
import logging
import os
import stat
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

from robots import mark_used
from wbmp import __version__

if TYPE_CHECKING:
    from wbmp.motionfile import MotionFile

_log = logging.getLogger("wbmp.motioncache")

FORMAT = 1  # bump when an entry's layout changes
MAX_ENTRY_BYTES = 256 << 20  # [bytes] an entry larger than this is damaged
_MAX_RECORD_BYTES = 1 << 20  # [bytes] a manifest or request record larger than this is damaged
_REPO = Path(__file__).resolve().parents[1]
_SOURCE_DIRS = ("language", "tasks", "robots", "planner", "sim")
_SOURCE_FILES = ("wbmp/pipeline.py", "wbmp/motionfile.py", "wbmp/motioncache.py")
_VIZ_DIR = "viz"
_LIBRARIES = ("numpy", "scipy", "casadi", "pin", "mujoco")
_ENV = ("WBMP_COMPILE",)


def cache_root() -> Path:
    """``$WBMP_CACHE_DIR/motions``, else ``~/.cache/wbmp/motions``."""
    from robots import cache_base

    return cache_base() / "motions"


def _tree_hash(h: hashlib._Hash, folder: Path) -> None:
    for path in sorted(folder.rglob("*")):
        if path.suffix in (".py", ".toml", ".json", ".html", ".urdf") and "__pycache__" not in path.parts:
            h.update(str(path.relative_to(_REPO)).encode())
            h.update(path.read_bytes())


@functools.cache
def source_hash() -> str:
    """sha256 of the sources that determine a motion's numbers (an edited planner misses)."""
    h = hashlib.sha256()
    for name in _SOURCE_DIRS:
        _tree_hash(h, _REPO / name)
    for name in _SOURCE_FILES:
        h.update((_REPO / name).read_bytes())
    return h.hexdigest()


@functools.cache
def viz_hash() -> str:
    """sha256 of ``viz/`` (the HTML replay's data depends on it, the motion does not)."""
    h = hashlib.sha256()
    _tree_hash(h, _REPO / _VIZ_DIR)
    return h.hexdigest()


@functools.cache
def _versions() -> tuple[tuple[str, str], ...]:
    out = [("wbmp", __version__)]
    for name in _LIBRARIES:
        try:
            out.append((name, metadata.version(name)))
        except metadata.PackageNotFoundError:
            out.append((name, ""))
    return tuple(out)


def _environment() -> dict[str, Any]:
    return {"format": FORMAT, "versions": _versions(), "sources": source_hash(),
            "env": {k: os.environ.get(k, "") for k in _ENV}}


def _open_regular(path: str | Path, limit: int):
    """A binary file object on a regular file of at most ``limit`` bytes; OSError otherwise
    (:func:`robots.safeio.open_regular`: a FIFO put in a file's place cannot hang the command)."""
    from robots import open_regular

    return open_regular(path, limit)


def _read_json(path: Path) -> Any:
    """A manifest or record: a regular file of at most 1 MiB (:mod:`robots.safeio`) holding JSON;
    OSError or ValueError otherwise."""
    from robots import read_bytes

    raw = read_bytes(path, _MAX_RECORD_BYTES)
    try:
        return json.loads(raw)
    except RecursionError:
        raise ValueError("JSON nested too deeply") from None


def _sha256_file(path: str | Path, limit: int = MAX_ENTRY_BYTES) -> str:
    from robots import sha256_file

    return sha256_file(path, limit)


def _digest(obj: Any) -> str:
    return hashlib.sha256(json.dumps(obj, sort_keys=True, default=str).encode()).hexdigest()


# -- keys ---------------------------------------------------------------------------------------

def _visual_meshes(robot) -> list[str]:
    """The visual model's mesh files: from the robot cache's manifest when it holds the visual
    geometry (loading the visual model costs ~0.16 s of CPU for Talos from that cache, ~1 s from
    the meshes, and a solve never needs it), else from the URDF's mesh names resolved as Pinocchio
    does (:func:`robots.urdf_mesh_files`, checked against the loaded collision model), else from
    the model itself."""
    from robots import mesh_files, stored_mesh_files, urdf_mesh_files

    listed = stored_mesh_files(robot.urdf_path, robot.package_dirs, "visual")
    if listed is None:
        listed = urdf_mesh_files(robot.urdf_path, robot.package_dirs, "visual", robot.collision_model)
    return listed if listed is not None else mesh_files(robot.visual_model)


def robot_files(robot) -> dict[str, str]:
    """{path: sha256} of every file the robot was built from (profile, URDF, the meshes of its
    visual and collision models)."""
    paths = {str(robot.urdf_path)}
    source = getattr(robot.profile, "source", "")
    if source:
        paths.add(str(Path(source).resolve()))
    meshes = [g.meshPath for g in robot.collision_model.geometryObjects] + _visual_meshes(robot)
    for mesh in meshes:
        if mesh and os.path.isfile(mesh):  # noqa: PTH113
            paths.add(str(Path(mesh).resolve()))
    return {p: _sha256_file(p) for p in sorted(paths)}


def robot_hash(robot, files: dict[str, str] | None = None) -> str:
    """sha256 of a robot: its profile's fields and the content of its files."""
    return _digest({"profile": repr(robot.profile), "files": files if files is not None else robot_files(robot)})


def spec_identity(spec) -> str:
    """The spec's JSON without its description (the sentence): two phrasings share a motion."""
    import dataclasses

    from tasks import spec_to_json

    return spec_to_json(dataclasses.replace(spec, description=""), indent=None)


def scene_files(spec) -> dict[str, str | None]:
    """sha256 of each mesh file of the spec's scene (None: unreadable); the scene's own numbers
    are in the spec's JSON."""
    scene = getattr(spec, "scene", None)
    if scene is None:
        return {}
    out: dict[str, str | None] = {}
    for obj in scene.objects:
        if obj.mesh is not None:
            try:
                out[obj.mesh] = _sha256_file(obj.mesh)
            except (OSError, ValueError):
                out[obj.mesh] = None
    return out


def motion_key(spec, robot_digest: str, *, simulate: bool, push: Any) -> str:
    """The key of a motion: a sha256 of everything that determines it (module docstring)."""
    meshes = scene_files(spec)
    return _digest({"spec": spec_identity(spec), "robot": robot_digest, "simulate": bool(simulate),
                    "push": None if push is None else repr(push), **({"scene_meshes": meshes} if meshes else {}),
                    **_environment()})


MAX_INPUT_BYTES = 16 << 20  # [bytes] a spec or profile file larger than this takes no fast path


def _input_digest(path: str) -> str | None:
    """sha256 of a regular input file of sane size, or None (a pipe, ``-``, a device such as
    ``/dev/zero``, a missing or huge file: the request then takes the ordinary path, which checks
    and refuses it; nothing is read from anything but a regular file)."""
    try:
        with _open_regular(path, MAX_INPUT_BYTES) as f:
            data = f.read(MAX_INPUT_BYTES + 1)
    except (OSError, ValueError):
        return None
    if len(data) > MAX_INPUT_BYTES:
        return None
    return hashlib.sha256(data).hexdigest()


def request_key(request) -> str | None:
    """The key of a request's exact inputs, or None when it cannot be repeated (an LLM parser,
    a spec read from a pipe or a device)."""
    if request.parser != "rules":
        return None
    spec_text = None
    if request.spec_path is not None:
        if request.spec_path == "-" or not _is_regular(request.spec_path):
            return None
        spec_text = _input_digest(request.spec_path)
        if spec_text is None:
            return None
    scene_text = None
    scene_path = getattr(request, "scene_path", None)
    if scene_path is not None:
        if scene_path == "-" or not _is_regular(scene_path):
            return None
        scene_text = _input_digest(scene_path)
        if scene_text is None:
            return None
        try:
            with _open_regular(scene_path, MAX_INPUT_BYTES) as f:
                if b'"mesh"' in f.read(MAX_INPUT_BYTES):
                    return None  # the mesh files it names count too: the ordinary path hashes them (motion_key)
        except (OSError, ValueError):
            return None
    robot = request.robot
    robot_text = None
    if robot is not None and _is_regular(robot):  # a profile file: its content counts
        robot_text = _input_digest(robot)
        if robot_text is None:
            return None
        robot = str(Path(robot).resolve())
    extra = {"scene": scene_text} if scene_text is not None else {}
    return _digest({"instruction": request.instruction, "spec": spec_text, **extra, "robot": robot,
                    "robot_file": robot_text, "simulate": bool(request.simulate), "push": request.push,
                    **_environment()})


def _is_regular(path: str) -> bool:
    try:
        return stat.S_ISREG(os.stat(path).st_mode)  # noqa: PTH116 - False on any OSError
    except (OSError, ValueError):
        return False


# -- entries ------------------------------------------------------------------------------------

class Request(NamedTuple):
    """What a request record says: the motion it led to, the robot digest, the parsed actions
    (:meth:`language.ActionPlan.to_record`, None in a record without them)."""

    motion: str
    robot: str
    actions: dict[str, Any] | None = None


@dataclass(eq=False)
class Hit:
    """A verified entry: the motion file's arrays (as stored) and their validated form."""

    key: str
    arrays: dict[str, Any]
    motion: MotionFile
    path: Path
    data: bytes = field(default=b"", repr=False)  # the verified bytes of the .npz


class MotionCache:
    """The ``motions/`` folder of the cache (see the module docstring)."""

    def __init__(self, root: str | Path | None = None) -> None:
        self.root = Path(root) if root is not None else cache_root()

    # paths
    def _npz(self, key: str) -> Path:
        return self.root / f"{key}.npz"

    def _manifest(self, key: str) -> Path:
        return self.root / f"{key}.json"

    def _request(self, rkey: str) -> Path:
        return self.root / "requests" / f"{rkey}.json"

    def _page(self, key: str) -> Path:
        return self.root / f"{key}.page"

    # reading
    def lookup_request(self, rkey: str) -> Request | None:
        """The motion a request led to (its key, the robot digest, the parsed actions), when every
        robot file is unchanged."""
        from robots import is_key

        if not is_key(rkey):
            return None
        path = self._request(rkey)
        try:
            record = _read_json(path)
            key, files, digest = record["motion"], record["files"], record["robot"]
            # the motion key names files of this folder: a hexadecimal key, never a path
            if not (is_key(key) and isinstance(files, dict) and isinstance(digest, str)
                    and all(isinstance(p, str) and isinstance(h, str) for p, h in files.items())):
                raise ValueError("malformed")
        except FileNotFoundError:
            return None
        except (OSError, ValueError, KeyError, TypeError) as e:
            self._discard([path], f"request record {path.name} is damaged ({type(e).__name__})")
            return None
        try:
            if any(_sha256_file(p) != sha for p, sha in files.items()):
                return None  # a robot file changed: a miss, the record is replaced after the solve
        except OSError:
            return None
        mark_used(path)
        actions = record.get("actions")
        return Request(key, digest, actions if isinstance(actions, dict) else None)

    def load(self, key: str, *, spec_check: bool = True) -> Hit | None:
        """The verified entry of ``key``, or None (missing; damaged: removed with one warning)."""
        from robots import is_key
        from wbmp.errors import MotionFileError
        from wbmp.motionfile import motion_from_arrays

        if not is_key(key):  # a key names files of this folder, never a path out of it
            return None
        npz, manifest = self._npz(key), self._manifest(key)
        try:
            meta = _read_json(manifest)
        except FileNotFoundError:
            return None
        except (OSError, ValueError) as e:
            self._discard([npz, manifest], f"motion cache entry {npz} is damaged (unreadable manifest: {e})")
            return None
        try:
            if not isinstance(meta, dict) or meta.get("key") != key or meta.get("format") != FORMAT:
                raise ValueError("its manifest does not describe it")
            with _open_regular(npz, MAX_ENTRY_BYTES) as fh:
                size = os.fstat(fh.fileno()).st_size
                if size != meta.get("size"):
                    raise ValueError(f"size {size} bytes, the manifest says {meta.get('size')}")
                data = fh.read(MAX_ENTRY_BYTES + 1)
            if hashlib.sha256(data).hexdigest() != meta.get("sha256"):
                raise ValueError("sha256 mismatch")
            from wbmp.motionfile import read_npz_bytes

            arrays = read_npz_bytes(data, str(npz))
            motion = motion_from_arrays(arrays, source=str(npz))
            if spec_check and meta.get("spec") != hashlib.sha256(spec_identity(motion.plan.spec).encode()).hexdigest():
                raise ValueError("the spec it holds is not the one of its key")
        except FileNotFoundError:
            if not manifest.exists():
                return None  # removed by another process while read (the size cap): a miss
            self._discard([manifest], f"motion cache entry {key[:16]} lacks its motion file")
            return None
        except (OSError, ValueError, MotionFileError) as e:
            self._discard([npz, manifest, self._page(key), Path(f"{self._page(key)}.json")],
                          f"motion cache entry {npz} is damaged ({str(e)[:200]})")
            return None
        mark_used(manifest)
        return Hit(key=key, arrays=arrays, motion=motion, path=npz, data=data)

    def load_page(self, key: str) -> str | None:
        """The stored HTML replay data of ``key`` (verified), or None."""
        from robots import is_key, read_bytes

        if not is_key(key):
            return None
        page, meta_path = self._page(key), Path(f"{self._page(key)}.json")
        try:
            meta = _read_json(meta_path)
            data = read_bytes(page, MAX_ENTRY_BYTES)
        except FileNotFoundError:
            return None
        except (OSError, ValueError) as e:
            self._discard([page, meta_path], f"HTML data of motion cache entry {key[:16]} is unreadable ({e})")
            return None
        if (not isinstance(meta, dict) or meta.get("viz") != viz_hash()
                or hashlib.sha256(data).hexdigest() != meta.get("sha256")):
            if isinstance(meta, dict) and meta.get("viz") != viz_hash():
                return None  # made by another viz: rebuilt and replaced, not damaged
            self._discard([page, meta_path], f"HTML data of motion cache entry {key[:16]} is damaged")
            return None
        try:
            return data.decode("ascii")
        except UnicodeDecodeError:
            self._discard([page, meta_path], f"HTML data of motion cache entry {key[:16]} is damaged")
            return None

    # writing (failures only cost the speed-up)
    def store(self, key: str, arrays: dict[str, Any], spec) -> None:
        """Store a motion file's arrays under ``key`` (the file first, then its manifest)."""
        import numpy as np

        buf = io.BytesIO()
        np.savez_compressed(buf, **arrays)
        self.store_file(key, buf.getvalue(), spec)

    def store_file(self, key: str, data: bytes, spec) -> None:
        """Store a motion file's bytes (an ``.npz``) under ``key``, the file first, then its manifest."""
        meta = {"key": key, "format": FORMAT, "size": len(data), "sha256": hashlib.sha256(data).hexdigest(),
                "spec": hashlib.sha256(spec_identity(spec).encode()).hexdigest(), "wbmp": __version__}
        self._write(self._npz(key), data)
        self._write(self._manifest(key), json.dumps(meta).encode())
        _trim(self.root)

    def store_request(self, rkey: str, key: str, files: dict[str, str], robot_digest: str,
                      actions: dict[str, Any] | None = None) -> None:
        """Remember that request ``rkey`` led to motion ``key`` with these robot files (and its
        parsed actions, :meth:`language.ActionPlan.to_record`: a repeat does not parse again)."""
        record: dict[str, Any] = {"motion": key, "files": files, "robot": robot_digest}
        if actions is not None:
            record["actions"] = actions
        self._write(self._request(rkey), json.dumps(record).encode())

    def store_page(self, key: str, data: str) -> None:
        """Store the HTML replay data of ``key``."""
        raw = data.encode("ascii")
        self._write(self._page(key), raw)
        self._write(Path(f"{self._page(key)}.json"),
                    json.dumps({"sha256": hashlib.sha256(raw).hexdigest(), "viz": viz_hash()}).encode())
        _trim(self.root)

    def _write(self, path: Path, data: bytes) -> None:
        from viz import OutputError, atomic_write

        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            atomic_write(path, lambda fh: fh.write(data))
        except (OSError, OutputError) as e:
            _warn_once(f"cannot write the motion cache in {self.root} ({e}); the motion is not cached")

    def _discard(self, paths: list[Path], why: str) -> None:
        from robots import path_inside

        for p in paths:
            if not path_inside(self.root, p.parent):  # never remove anything outside the cache
                continue
            try:
                p.unlink()
            except FileNotFoundError:
                pass
            except OSError as e:
                _log.warning("wbmp: warning: %s; could not remove %s (%s)", why, p, e.strerror or e)
                return
        _log.warning("wbmp: warning: %s; removed it, the motion is computed again", why)


def _trim(root: Path) -> None:
    """Apply the whole cache's size cap after a store (:func:`robots.store.trim_cache`)."""
    from robots import trim_cache

    trim_cache(root)


_WARNED: set[str] = set()


def _warn_once(message: str) -> None:
    if message not in _WARNED:
        _WARNED.add(message)
        _log.warning("wbmp: warning: %s", message)
