"""The disk store every wbmp cache uses: where the caches live, how an entry is written, checked
and removed, and the size cap over all of them.

A cache entry is a folder ``<cache_base()>/<cache>/<key>/`` holding a data file and a
``manifest.json`` (:func:`store_entry` writes it through a temporary folder renamed into place;
:func:`read_manifest` validates it and raises :class:`EntryDamaged` or :class:`EntryStale`), or
small files written through a temporary file and a rename (:func:`write_text_atomic`). The
caches built on it: the robots' geometry (:mod:`robots.cache`), the collision fits
(:mod:`robots.collision`), the planner's compiled solvers and solution library
(``planner.trajopt.cache_disk``, ``planner.trajopt.library``), the MuJoCo models
(``sim.modelcache``), the HTML meshes (``viz.meshcache``) and the motions (``wbmp.motioncache``).
What a writer that died left (a temporary folder, an entry moved aside) is removed by
:func:`sweep_stale` (once per cache folder and process; :func:`process_alive` tells a live
writer). The size cap
(:func:`trim_cache`, :func:`enforce_cap`; docs/performance.md) removes the least recently used
entries over ``$WBMP_CACHE_MAX_SIZE``.

Standard library only (no Pinocchio): ``wbmp cache`` and a motion-cache hit use it without
loading a robot.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import logging
import os
import re
import shutil
import stat
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path

from robots.safeio import read_json, sha256_file

_log = logging.getLogger("robots.cache")  # the caches' one logger (robots.cache too)

MAX_MANIFEST_BYTES = 1 << 20


def cache_base() -> Path:
    """``$WBMP_CACHE_DIR``, else ``~/.cache/wbmp``: the folder of every wbmp disk cache."""
    env = os.environ.get("WBMP_CACHE_DIR")
    return Path(env) if env else Path.home() / ".cache" / "wbmp"


def cache_folder(name: str, switch: str | None = None) -> Path | None:
    """``<cache_base()>/<name>``; None when the environment variable ``switch`` turns that cache
    off (0, false, no, off). The solver, robot, MuJoCo, collision and motion caches share the base."""
    if switch is not None and os.environ.get(switch, "1").strip().lower() in ("0", "false", "no", "off"):
        return None
    return cache_base() / name


def file_sha256(path: str | Path, kind: str | int = "motion") -> str:
    """sha256 of a regular file of at most the bound of ``kind`` (:mod:`robots.safeio`; default
    1 GiB); OSError for a FIFO, a device, a directory or a larger file."""
    return sha256_file(path, kind)


class EntryDamaged(Exception):
    """A disk-cache entry that cannot be trusted (the reason is the message): the robot, MuJoCo
    and HTML mesh caches remove it with one warning and rebuild it."""


class EntryStale(Exception):
    """An intact disk-cache entry made from files that changed since (a mesh edited): rebuilt
    without a warning."""


def read_manifest(entry: Path, fmt: int) -> tuple[int, str]:
    """The (size, sha256) ``entry``'s manifest.json records for its data file, once the manifest
    names this entry and format ``fmt`` and every mesh file it lists still has its recorded sha256.

    Raises:
        EntryStale: No manifest (an interrupted write), or a listed mesh changed or is gone.
        EntryDamaged: The manifest is too large, not JSON, or names another entry or format.
    """
    try:
        manifest = read_json(entry / "manifest.json", MAX_MANIFEST_BYTES)
    except FileNotFoundError:
        raise EntryStale("no manifest (an interrupted write)") from None
    except (OSError, ValueError) as e:  # a FIFO, a device, too large, not JSON
        raise EntryDamaged(f"manifest.json cannot be read ({str(e)[:200]})") from None
    try:
        size, digest = int(manifest["size"]), str(manifest["sha256"])
        meshes = {str(p): str(h) for p, h in manifest["meshes"].items()}
        if manifest["key"] != entry.name or manifest["format"] != fmt:
            raise EntryDamaged("manifest.json names another entry")
    except (ValueError, KeyError, TypeError, AttributeError) as e:
        raise EntryDamaged(f"manifest.json is not a manifest ({type(e).__name__}: {e})") from None
    for mesh, mesh_digest in meshes.items():
        try:
            if file_sha256(mesh, "mesh") != mesh_digest:
                raise EntryStale(f"{mesh} changed")
        except OSError:
            raise EntryStale(f"{mesh} is gone") from None
    return size, digest


def store_entry(root: Path, key: str, write: Callable[[Path], object], manifest: dict, *,
                data: str, manifest_name: str = "manifest.json") -> None:
    """Store one cache entry ``root/key`` atomically: ``write(folder)`` writes the data file
    ``data`` into a temporary folder, ``manifest_name`` gets ``manifest`` plus the entry's key,
    and the data file's size and sha256, and the folder is renamed into place (an entry another
    process stored meanwhile is kept); then the cache's size cap is applied (:func:`trim_cache`).
    Raises what ``write`` or the file system raise."""
    root.mkdir(parents=True, exist_ok=True)
    sweep_stale(root)  # temporary folders of writers that died (once per process)
    tmp = Path(tempfile.mkdtemp(prefix=f".{key[:16]}-", dir=root))
    try:
        write(tmp)
        path = tmp / data
        record = {"key": key, **manifest, "size": path.stat().st_size, "sha256": file_sha256(path)}
        (tmp / manifest_name).write_text(json.dumps(record, indent=1), encoding="utf-8")
        entry = root / key
        if not entry.exists():  # else another process stored the same key meanwhile: keep its entry
            tmp.replace(entry)
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
    trim_cache(root)


def write_text_atomic(path: Path, text: str) -> None:
    """Write a small text file through a temporary file in its folder and a rename (never
    half-written); OSError when the folder cannot be written."""
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
        Path(tmp).replace(path)
    except BaseException:
        with contextlib.suppress(OSError):
            Path(tmp).unlink()
        raise


def process_alive(pid: object) -> bool:
    """Whether process ``pid`` (an int > 0) exists, this user's or another's: a cache's
    temporary folder or lock whose writer is gone can be removed."""
    if not isinstance(pid, int) or isinstance(pid, bool) or pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:
        return True  # it exists (another user's)
    return True



# -- removing and sweeping: what a writer that died left behind --------------------------------

TEMP_MAX_AGE = 3600.0  # [s] a temporary folder older than this whose writer is gone is removed
TEMP_ABANDONED_AGE = 86400.0  # [s] ... and older than this whatever its pid says (pids are reused)
_STORE_TEMP = re.compile(r"^\.[^.][^/]*-[a-z0-9_]{8}$")  # store_entry's tempfile.mkdtemp(prefix=".<key16>-")
_SWEPT: set[str] = set()
_SWEEP_LOCK = threading.Lock()


def remove_tree(path: Path) -> None:
    """Remove a file, a symbolic link (never its target) or a folder tree; OSError when it stays.
    A folder someone made unreadable (``chmod 000``) is made the owner's again first."""
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        return
    if not stat.S_ISDIR(st.st_mode):
        path.unlink()
        return
    try:
        shutil.rmtree(path)
        return
    except FileNotFoundError:
        return
    except OSError:
        pass
    path.chmod(0o700)
    for dirpath, dirnames, _ in os.walk(path):
        for d in dirnames:
            sub = Path(dirpath) / d
            if not sub.is_symlink():
                sub.chmod(0o700)
    shutil.rmtree(path)


def sweep_stale(folder: Path, *, temporary: re.Pattern[str] = _STORE_TEMP, moved_aside: tuple[str, ...] = (),
                owner_alive: Callable[[Path], bool] | None = None, now: float | None = None) -> list[str]:
    """Remove what writers that died left in a cache folder; the names removed.

    Runs once per folder and process (later calls return ``[]``): a listing, not a walk. Removed:
    every name that starts with one of ``moved_aside`` (entries moved aside to be deleted), and each
    temporary folder or file (a name ``temporary`` matches) older than :data:`TEMP_MAX_AGE` whose
    writer is gone (``owner_alive(path)`` False; without ``owner_alive``, a writer that records no
    pid: the age alone), or older than :data:`TEMP_ABANDONED_AGE` whatever it says. Entries and
    names that are not the cache's are never touched; a name that cannot be removed is left.
    """
    with _SWEEP_LOCK:
        if str(folder) in _SWEPT:
            return []
        _SWEPT.add(str(folder))
    now = time.time() if now is None else now
    removed: list[str] = []
    try:
        paths = list(Path(folder).iterdir())
    except OSError:
        return removed
    for path in paths:
        name = path.name
        if moved_aside and name.startswith(moved_aside):
            stale = True
        elif temporary.match(name):
            try:
                age = now - os.lstat(path).st_mtime
            except OSError:
                continue
            stale = age > TEMP_ABANDONED_AGE or (
                age > TEMP_MAX_AGE and (owner_alive is None or not owner_alive(path)))
        else:
            continue
        if stale:
            try:
                remove_tree(path)
                removed.append(name)
            except OSError:
                pass
    return removed


# -- the size cap: least recently used entries removed ----------------------------------------
#
# Every disk cache of wbmp lives in one folder of cache_base() (CACHE_FOLDERS). An entry is a
# folder named by its key (planner, seeds, robots, mujoco, viz), or the files that share a key before
# their first dot (collision: ``<robot>-<key>.json``; motions: ``<key>.npz``, ``<key>.json``,
# ``<key>.page``, ``<key>.page.json``; ``motions/requests/<key>.json``). Its use time is its
# modification time, which a load renews (mark_used); names starting with a dot are temporary
# folders and files being written, never removed here. Anything else (a name that is not a key,
# a symbolic link) is not wbmp's and is left alone.

CACHE_FOLDERS = ("planner", "seeds", "robots", "mujoco", "viz", "collision", "motions")
_NESTED = {"motions": ("requests",)}  # folders of file entries inside a cache folder
MAX_SIZE_ENV = "WBMP_CACHE_MAX_SIZE"
DEFAULT_MAX_BYTES = 4 << 30  # [bytes] 4 GiB
TRIM_FRACTION = 0.9  # over the cap, entries are removed until the cache is under this fraction of it
RECENT_USE = 300.0  # [s] an entry used (stored or loaded) this recently is never removed by the cap
_EVICTED = ".evicted."  # an entry being removed: renamed to this prefix first, then deleted
_KEY_NAME = re.compile(r"^(?:[^/]*-)?[0-9a-f]{16,64}$")
MAX_SIZE_BYTES = 1 << 60  # [bytes] the largest cap accepted (1 EiB)
_UNITS = {"": 1, "k": 1 << 10, "m": 1 << 20, "g": 1 << 30, "t": 1 << 40}
_UNLIMITED = ("0", "unlimited", "none", "off", "no")
_WARNED: set[str] = set()


def parse_size(text: str) -> int | None:
    """A size such as ``4G``, ``500M``, ``2.5GiB``, ``1048576`` [bytes] (K, M, G and T are powers
    of 1024, with or without ``B``/``iB``); None for no cap (``0``, ``unlimited``, ``none``, ``off``).

    Raises:
        ValueError: Not a size (the message says what is accepted).
    """
    value = text.strip().lower().replace(" ", "")
    if value in _UNLIMITED:
        return None
    match = re.fullmatch(r"(\d+(?:\.\d*)?|\.\d+)([kmgt]?)(i?b)?", value)
    if match is None or (match.group(3) and not match.group(2) and match.group(3) != "b"):
        raise ValueError(f"{text!r} is not a size: give e.g. 4G, 500M, 2.5GiB or a number of bytes "
                         "(0 or 'unlimited': no cap)")
    value_bytes = float(match.group(1)) * _UNITS[match.group(2)]  # inf for 309+ digits: never int()
    if not value_bytes <= MAX_SIZE_BYTES:
        raise ValueError(f"{text[:40]!r}{'...' if len(text) > 40 else ''} is larger than any cache may be "
                         f"(at most {MAX_SIZE_BYTES >> 60} EiB): give e.g. 4G, or 'unlimited' for no cap")
    size = int(value_bytes)
    return size if size > 0 else None


def max_cache_bytes(strict: bool = False) -> int | None:
    """The cap of the whole cache [bytes] from ``$WBMP_CACHE_MAX_SIZE`` (:func:`parse_size`),
    default :data:`DEFAULT_MAX_BYTES`; None: no cap. A value that is not a size raises ValueError
    when ``strict``, else gives one warning and the default."""
    text = os.environ.get(MAX_SIZE_ENV)
    if text is None or not text.strip():
        return DEFAULT_MAX_BYTES
    try:
        return parse_size(text)
    except ValueError as e:
        if strict:
            raise ValueError(f"{MAX_SIZE_ENV}={e}") from None
        if text not in _WARNED:
            _WARNED.add(text)
            _log.warning("wbmp: warning: %s=%s; the cache is capped at the default %s", MAX_SIZE_ENV, e,
                         format_size(DEFAULT_MAX_BYTES))
        return DEFAULT_MAX_BYTES


def format_size(size: float) -> str:
    """``4.0 GiB``, ``12.3 MiB``, ``512 B``."""
    for unit in ("B", "KiB", "MiB", "GiB"):
        if abs(size) < 1024 or unit == "GiB":
            return f"{size:.0f} {unit}" if unit == "B" else f"{size:.1f} {unit}"
        size /= 1024
    return f"{size:.1f} TiB"  # pragma: no cover - the loop returns


def mark_used(path: str | Path) -> None:
    """Renew the use time of a cache entry (its folder, or its manifest file) after a load: the
    cap removes the least recently used entries first. One ``utime``; a read-only cache is fine."""
    try:
        os.utime(path, follow_symlinks=os.utime not in os.supports_follow_symlinks)  # a link: not its target
    except OSError:
        pass


def entry_vanished(entry: str | Path) -> bool:
    """True when nothing is at ``entry`` any more: another process removed it (the cap, ``wbmp
    cache --clear``) while this one read it. A reader treats that as a miss, not as damage."""
    return not os.path.lexists(entry)


@dataclasses.dataclass(frozen=True)
class CacheEntry:
    """One entry of a cache folder.

    Attributes:
        folder: The cache folder's name (``planner``, ``motions/requests``...).
        name: The entry's key (folder name, or the files' common name before their first dot).
        paths: What the entry is: its folder, or its files (the manifest first: a reader that
            finds no manifest sees a miss).
        size: Bytes of its files.
        used: Its use time [s since the epoch]: the latest modification time of the folder or files.
    """

    folder: str
    name: str
    paths: tuple[Path, ...]
    size: int
    used: float


@dataclasses.dataclass(frozen=True)
class FolderUsage:
    """A cache folder's entries, and the bytes of its temporary files (being written)."""

    name: str
    path: Path
    entries: tuple[CacheEntry, ...]
    pending: int
    link: bool = False  # a symbolic link: not followed, neither counted nor cleared

    @property
    def size(self) -> int:
        """Bytes of its entries and temporary files."""
        return sum(e.size for e in self.entries) + self.pending


def _tree_size(path: str) -> int:
    """Bytes of the regular files below a folder (symbolic links not followed)."""
    total = 0
    try:
        with os.scandir(path) as it:
            for item in it:
                try:
                    if item.is_dir(follow_symlinks=False):
                        total += _tree_size(item.path)
                    elif item.is_file(follow_symlinks=False):
                        total += item.stat(follow_symlinks=False).st_size
                except OSError:
                    pass
    except OSError:
        pass
    return total


def _scan(folder: Path, label: str, now: float, nested: tuple[str, ...] = ()) -> tuple[list[CacheEntry], int]:
    entries: list[CacheEntry] = []
    pending = 0
    groups: dict[str, list[tuple[Path, os.stat_result]]] = {}
    try:
        items = list(os.scandir(folder))
    except OSError:
        return entries, pending
    for item in items:
        try:
            st = item.stat(follow_symlinks=False)
        except OSError:
            continue
        is_dir = stat.S_ISDIR(st.st_mode)
        if item.name.startswith("."):  # being written, moved aside, or being removed
            if item.name.startswith(_EVICTED) and now - st.st_mtime > RECENT_USE:
                _remove_path(Path(item.path))  # left by a process that stopped while removing it
            else:
                pending += _tree_size(item.path) if is_dir else st.st_size if stat.S_ISREG(st.st_mode) else 0
        elif is_dir and item.name in nested:
            sub, sub_pending = _scan(Path(item.path), f"{label}/{item.name}", now)
            entries += sub
            pending += sub_pending
        elif is_dir and _KEY_NAME.match(item.name):
            entries.append(CacheEntry(label, item.name, (Path(item.path),), _tree_size(item.path), st.st_mtime))
        elif stat.S_ISREG(st.st_mode) and _KEY_NAME.match(item.name.split(".", 1)[0]):
            groups.setdefault(item.name.split(".", 1)[0], []).append((Path(item.path), st))
    for name, files in groups.items():
        # the manifest (<key>.json) first, then the rest: a reader without a manifest sees a miss
        files.sort(key=lambda f: (f[0].name != f"{name}.json", f[0].name))
        entries.append(CacheEntry(label, name, tuple(p for p, _ in files), sum(s.st_size for _, s in files),
                                  max(s.st_mtime for _, s in files)))
    return entries, pending


def cache_usage(base: Path | None = None, folders: tuple[str, ...] = CACHE_FOLDERS,
                now: float | None = None) -> list[FolderUsage]:
    """The entries of each cache folder of ``base`` (default :func:`cache_base`): one scan of
    the folders' top levels (and ``motions/requests``) and of each entry's files."""
    base = cache_base() if base is None else base
    now = time.time() if now is None else now
    out = []
    for name in folders:
        path = base / name
        if os.path.islink(path):  # noqa: PTH114 - never followed out of the cache
            out.append(FolderUsage(name, path, (), 0, link=True))
            continue
        entries, pending = _scan(path, name, now, _NESTED.get(name, ()))
        out.append(FolderUsage(name, path, tuple(sorted(entries, key=lambda e: e.used)), pending))
    return out


def _remove_path(path: Path) -> bool:
    """Remove a file, or a folder tree (symbolic links inside are removed, never followed)."""
    try:
        remove_tree(path)
        return True
    except OSError:  # cannot be removed
        return False


def remove_entry(entry: CacheEntry, *, unless_used_after: float | None = None) -> bool:
    """Remove one entry: a folder is first renamed aside (``.evicted.<key>.<pid>``), so that a
    reader finds either the whole entry or nothing; files go manifest first. With
    ``unless_used_after``, an entry whose use time is now later (a reader marked it meanwhile)
    is kept. True when this call removed it."""
    first = entry.paths[0]
    if unless_used_after is not None:
        try:
            if os.lstat(first).st_mtime > unless_used_after:
                return False
        except OSError:
            return False
    if len(entry.paths) == 1 and os.path.isdir(first) and not os.path.islink(first):  # noqa: PTH112, PTH114
        aside = first.parent / f"{_EVICTED}{first.name}.{os.getpid()}"
        try:
            first.rename(aside)
        except OSError:
            return False  # gone already (another process), or cannot be moved
        _remove_path(aside)
        return True
    removed = False
    for path in entry.paths:
        removed = _remove_path(path) or removed
    return removed


def enforce_cap(base: Path | None = None, *, now: float | None = None) -> list[CacheEntry]:
    """When the cache folders of ``base`` (default :func:`cache_base`) hold more than the cap
    (:func:`max_cache_bytes`), remove the least recently used entries until they hold less than
    :data:`TRIM_FRACTION` of it. Entries used in the last :data:`RECENT_USE` seconds and
    temporary files stay. Returns the entries removed; never raises (a store must not fail)."""
    cap = max_cache_bytes()
    if cap is None:
        return []
    now = time.time() if now is None else now
    try:
        usage = cache_usage(base, now=now)
        total = sum(f.size for f in usage)
        if total <= cap:
            return []
        old = sorted((e for f in usage for e in f.entries if now - e.used > RECENT_USE), key=lambda e: e.used)
        removed: list[CacheEntry] = []
        for entry in old:
            if total <= TRIM_FRACTION * cap:
                break
            if remove_entry(entry, unless_used_after=now - RECENT_USE):
                removed.append(entry)
                total -= entry.size
    except OSError:
        return []
    if removed:
        _log.info("cache: removed %d least recently used entries (%s) to stay under %s=%s",
                  len(removed), format_size(sum(e.size for e in removed)), MAX_SIZE_ENV, format_size(cap))
    return removed


def trim_cache(folder: str | Path) -> list[CacheEntry]:
    """Call after storing an entry in the cache folder ``folder`` (``<base>/<name>``): applies the
    cap (:func:`enforce_cap`) when ``<base>`` is the wbmp cache folder (:func:`cache_base`), never
    to a folder a caller chose elsewhere (``CacheSettings(cache_dir=...)``)."""
    try:
        base = Path(folder).parent
        if os.path.realpath(base) != os.path.realpath(cache_base()):
            return []
    except (OSError, ValueError):
        return []
    return enforce_cap(base)
