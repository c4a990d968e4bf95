"""Solver builds that cannot pile up: at most one per cache at a time, none without the memory.

A gcc -O0 build of a Talos solver holds 2.5-3.7 GB in ``cc1`` for 5-70 s, and each ``wbmp solve``
of a new structure starts one that outlives the command: a user running one sentence after
another had seven ``cc1`` at once (10 GB). Two rules now hold for every build of a compiled
entry (:func:`planner.trajopt.cache.get_solver`, background or not):

* **One at a time per cache.** The build holds ``<cache_dir>/builds/lock`` with
  ``flock``: the forked worker and the compiler it runs (which inherits the descriptor), so the
  lock lives exactly as long as the last of them. A process that finds it held does not start a
  build: the structure is *skipped* (``builds/skipped/<key>.json`` says why and when), its plan
  runs on the in-memory solver, and the next solve of that structure that finds no build running
  builds it. A lock whose holder died is free (the kernel releases it): the next build takes it
  over and rewrites what it says.
* **Only with the memory.** A build starts only when ``MemAvailable`` (``/proc/meminfo``) is at
  least the build's estimate (:data:`BUILD_MEMORY`, ``PlannerSettings.build_memory``) plus a
  margin left to everything else (:data:`MEMORY_MARGIN`); while the compiler runs, it is stopped
  when ``MemAvailable`` falls below half the margin (:data:`STOP_FRACTION`). Either way the reason
  is recorded as a skip. Where ``/proc/meminfo`` cannot be read (not Linux) memory is not checked.

``wbmp cache`` shows the running build (key, pid, the compiler's pid, since when, what it does)
and the skipped structures (:func:`build_status`). The lock file's text is JSON written by the holder;
it is informative only: whether a build runs is the lock itself.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import time
from dataclasses import dataclass
from pathlib import Path

from robots import process_alive

try:
    import fcntl
except ImportError:  # pragma: no cover - not POSIX: no lock (and no fork: builds run in the foreground)
    fcntl = None  # type: ignore[assignment]

BUILD_MEMORY = 3_700_000_000  # [bytes] peak of one gcc -O0 cc1 on a Talos solver (2.5-3.7 GB seen)
MEMORY_MARGIN = 1_000_000_000  # [bytes] MemAvailable a starting build must leave to everything else
STOP_FRACTION = 0.5  # a running compiler is stopped when MemAvailable < this x the margin
WATCH_PERIOD = 0.5  # [s] how often a running compiler's memory is looked at
STATE = "builds"  # next to <cache_dir>/planner/: the lock and the skip records (not cache entries)
LOCK = "lock"
SKIPPED = "skipped"
SKIP_MAX_AGE = 7 * 86400.0  # [s] older skip records are dropped when listed
MEMINFO = "/proc/meminfo"
_KEY = re.compile(r"^[0-9a-f]{24}$")


def mem_available(meminfo: str = MEMINFO) -> int | None:
    """``MemAvailable`` [bytes] from ``/proc/meminfo``; None when it cannot be read."""
    try:
        with open(meminfo, encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    value, *unit = line.split(":", 1)[1].split()
                    return int(value) * (1024 if unit and unit[0].lower() == "kb" else 1)
    except (OSError, ValueError, UnicodeDecodeError):
        return None
    return None


def _gb(size: float) -> str:
    return f"{size / 1e9:.1f} GB"


def memory_refusal(need: int, margin: int, available: int | None = None) -> str | None:
    """Why a build of ``need`` bytes must not start now (None: it may): it would leave less than
    ``margin`` of ``MemAvailable``."""
    available = mem_available() if available is None else available
    if available is None or available >= need + margin:
        return None
    return (f"not enough free memory: a build needs {_gb(need)} (WBMP_BUILD_MEMORY) and leaves "
            f"{_gb(margin)} to the rest, {_gb(available)} available")


def memory_low(margin: int) -> bool:
    """True when a running build must stop: ``MemAvailable`` below ``STOP_FRACTION x margin``."""
    available = mem_available()
    return available is not None and available < STOP_FRACTION * margin


# -- the lock ------------------------------------------------------------------------------------


def state_folder(folder: Path) -> Path:
    """``<cache_dir>/builds``: the build state of the solver cache folder ``folder``
    (``<cache_dir>/planner``); outside it, so that listing, capping or clearing the cache never
    meets it."""
    return Path(folder).parent / STATE


def _read_info(path: Path) -> dict:
    try:
        with open(path, "rb") as f:
            info = json.loads(f.read(4096) or b"{}")
    except (OSError, ValueError):
        return {}
    return info if isinstance(info, dict) else {}


def describe_build(info: dict, now: float | None = None) -> str:
    """``3f2a... (pid 1234, compiler pid 1240, since 10:41:02, 35 s: compiling)`` from a lock's text."""
    now = time.time() if now is None else now
    parts = [f"pid {info.get('pid', '?')}"]
    if info.get("compiler_pid"):
        parts.append(f"compiler pid {info['compiler_pid']}")
    since = info.get("since")
    if isinstance(since, (int, float)):
        parts.append(f"since {time.strftime('%H:%M:%S', time.localtime(since))}, {max(0.0, now - since):.0f} s")
    text = f"{info.get('key', '?')} ({', '.join(parts)}"
    return text + (f": {info['phase']})" if info.get("phase") else ")")


class Slot:
    """The held build lock of one cache folder (:func:`claim`); :meth:`note` rewrites its text."""

    def __init__(self, fd: int, path: Path, key: str) -> None:
        self.fd = fd
        self.path = path
        self.info: dict = {"key": key, "pid": os.getpid(), "since": time.time()}

    def note(self, **info) -> None:
        """Update what the lock says (pid, compiler_pid, phase); never raises."""
        self.info.update(info)
        data = json.dumps(self.info).encode()
        with contextlib.suppress(OSError):
            os.ftruncate(self.fd, 0)
            os.pwrite(self.fd, data, 0)

    def close(self) -> None:
        """Close this process's descriptor: the lock is free once no process holds one."""
        if self.fd >= 0:
            with contextlib.suppress(OSError):
                os.close(self.fd)
            self.fd = -1


def _try_lock(fd: int, path: Path) -> bool:
    """Lock ``fd`` with flock; where the file system has no flock, the text's pid decides (alive: held)."""
    if fcntl is None:  # pragma: no cover - not POSIX
        return True
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        return True
    except BlockingIOError:
        return False
    except OSError:  # no flock here (some network file systems)
        info = _read_info(path)
        return info.get("state") != "running" or not process_alive(info.get("pid"))


def claim(folder: Path, key: str) -> Slot | str:
    """Take the build lock of the solver cache folder ``folder`` for the structure ``key``: the
    held :class:`Slot`, or why not (another build runs: which; the folder is not writable)."""
    state = state_folder(folder)
    path = state / LOCK
    try:
        state.mkdir(parents=True, exist_ok=True)
        fd = os.open(path, os.O_RDWR | os.O_CREAT | getattr(os, "O_CLOEXEC", 0), 0o644)
    except OSError as e:
        return f"the build lock {path} cannot be opened ({(e.strerror or str(e)).lower()})"
    if not _try_lock(fd, path):
        os.close(fd)
        return f"another build is running: {describe_build(_read_info(path))}"
    slot = Slot(fd, path, key)
    slot.note(state="running", phase="starting")
    clear_skip(folder, key)
    return slot


def running(folder: Path) -> dict | None:
    """What the running build of ``folder`` says (key, pid, compiler_pid, since, phase), or None.

    The lock is tested with a shared non-blocking ``flock`` taken and released at once."""
    path = state_folder(folder) / LOCK
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_CLOEXEC", 0))
    except OSError:
        return None
    try:
        if fcntl is None:  # pragma: no cover - not POSIX
            return None
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            return _read_info(path) or {"key": "?", "pid": "?"}
        except OSError:
            info = _read_info(path)
            return info if info.get("state") == "running" and process_alive(info.get("pid")) else None
        fcntl.flock(fd, fcntl.LOCK_UN)
        return None
    finally:
        os.close(fd)


# -- skipped structures --------------------------------------------------------------------------


def record_skip(folder: Path, key: str, reason: str) -> None:
    """Remember that the build of ``key`` was not started (or stopped), and why; never raises."""
    path = state_folder(folder) / SKIPPED / f"{key}.json"
    text = json.dumps({"key": key, "reason": reason, "when": time.time(), "pid": os.getpid()})
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{key}.{os.getpid()}")
        tmp.write_text(text)
        tmp.replace(path)
    except OSError:
        pass


def clear_skip(folder: Path, key: str) -> None:
    """Forget the skip record of ``key`` (its build starts or its entry is in place)."""
    with contextlib.suppress(OSError):
        (state_folder(folder) / SKIPPED / f"{key}.json").unlink()


def skipped(folder: Path, now: float | None = None) -> list[dict]:
    """The skip records of ``folder``, oldest first: structures whose build waits for the next
    solve of them. Records of structures now in the cache, or older than :data:`SKIP_MAX_AGE`,
    are removed."""
    now = time.time() if now is None else now
    base = state_folder(folder) / SKIPPED
    try:
        names = [p.name for p in base.iterdir()]
    except OSError:
        return []
    out = []
    for name in names:
        key = name.removesuffix(".json")
        if not (name.endswith(".json") and _KEY.match(key)):
            continue
        info = _read_info(base / name)
        when = info.get("when")
        if (Path(folder) / key).is_dir() or not isinstance(when, (int, float)) or now - when > SKIP_MAX_AGE:
            clear_skip(folder, key)
            continue
        out.append(info)
    return sorted(out, key=lambda r: r["when"])


@dataclass(frozen=True, slots=True)
class BuildStatus:
    """What ``wbmp cache`` shows of a solver cache folder's builds.

    Attributes:
        running: The running build's lock text (key, pid, compiler_pid, since, phase), or None.
        skipped: Skip records (key, reason, when, pid), oldest first.
        available: ``MemAvailable`` [bytes], None when unknown.
        need: A build's memory estimate [bytes].
        margin: What a starting build must leave free [bytes].
    """

    running: dict | None
    skipped: list[dict]
    available: int | None
    need: int
    margin: int


def build_status(folder: Path, need: int = BUILD_MEMORY, margin: int = MEMORY_MARGIN) -> BuildStatus:
    """The builds of the solver cache folder ``folder`` (``<cache_dir>/planner``)."""
    return BuildStatus(running(folder), skipped(folder), mem_available(), need, margin)
