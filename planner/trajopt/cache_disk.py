"""The on-disk half of the solver cache: check, publish, discard and sweep compiled entries.

An entry is a folder ``<cache_dir>/planner/<key>/`` holding

* ``nlp.so``: the compiled NLP functions (loaded by IPOPT through ``nlpsol``);
* ``meta.json``: the manifest written at build time, last: ``key``, ``sha256`` and ``size`` of
  the library, the problem sizes ``n_x`` and ``n_g``, CasADi version, gcc flags, time;
* ``verified``: the sha256 of a library that a short-lived child process has loaded and
  evaluated without crashing (written by the builder; rewritten by a loader when missing).

or, for a solver stored serialized (``"format": "casadi"`` in the manifest: the dynamic plans'
solvers, whose C code takes minutes to compile), ``nlp.casadi``: the NLP's functions written by
CasADi's serializer, read back with its deserializer (nothing is mapped as code, so no probe: the
size and checksum checks catch a truncated or altered file before it is read).

Loading a shared library maps it into the process: a truncated or forged one can kill the
process with SIGBUS or SIGSEGV before any Python code can react, so nothing is loaded in the
planning process before it passed, in this order: the folder is a real folder (no symlink);
the manifest is a small JSON object for this key; the library is a regular file of the
recorded size, a complete ELF file (every loadable segment and the section table lie inside
the file: the check that catches a truncation whatever the manifest says), with the recorded
checksum; and its ``verified`` marker names that checksum, or a child process loads it now.
A damaged entry is removed (moved aside if it cannot be removed) with one warning, and
rebuilt by the caller. Builds go to temporary folders ``.<key>.<random>/`` next to the
entries, renamed into place when complete; :func:`sweep` removes the ones whose builder is
gone.
"""

from __future__ import annotations

import json
import logging
import os
import re
import signal
import stat
import struct
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterable
from pathlib import Path

from robots import (
    EntryDamaged,
    file_sha256,
    open_regular,
    process_alive,
    read_bytes,
    remove_tree,
    sweep_stale,
    write_text_atomic,
)

LIBRARY = "nlp.so"
SERIALIZED = "nlp.casadi"
FORMATS = {"so": LIBRARY, "casadi": SERIALIZED}  # manifest "format" -> the entry's payload file
META = "meta.json"
VERIFIED = "verified"  # sha256 of the library that a child process loaded and evaluated
BUILDER_PID = "builder.pid"  # in a temporary build folder: the process that owns it
META_MAX_BYTES = 65536  # a manifest is ~250 bytes; a larger one is not ours
PROBE_TIMEOUT = 120.0  # [s] a healthy library loads and evaluates in ~1 s
_TEMP_NAME = re.compile(r"^\.[0-9a-f]{24}\.")
_ASIDE_PREFIX = ".damaged."
_PUBLISH_TRIES = 50  # rounds a publisher retries while racing others (each round moves one thing)
_MACH_O = (b"\xfe\xed\xfa\xce", b"\xfe\xed\xfa\xcf", b"\xce\xfa\xed\xfe", b"\xcf\xfa\xed\xfe",
           b"\xca\xfe\xba\xbe")

_log = logging.getLogger("planner.trajopt.cache")
_LOCK = threading.Lock()
_WARNED_FOLDERS: set[str] = set()


def warn(message: str) -> None:
    """One line on stderr (through :mod:`logging`: an application that configured logging gets
    it in its own handlers; otherwise Python prints the bare line)."""
    _log.warning("wbmp: warning: %s", message)


# -- checks -----------------------------------------------------------------------------------


def _read_small(path: Path, limit: int) -> bytes:
    """The bytes of a small regular file; EntryDamaged when it is anything else."""
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        raise EntryDamaged(f"{path.name} is missing") from None
    if not stat.S_ISREG(st.st_mode):  # a FIFO would block, a symlink may point anywhere
        raise EntryDamaged(f"{path.name} is not a regular file")
    if st.st_size > limit:
        raise EntryDamaged(f"{path.name} has {st.st_size} bytes (at most {limit} expected)")
    try:  # replaced by a FIFO or a device since the lstat: refused, never waited on
        return read_bytes(path, limit)
    except OSError as e:
        raise EntryDamaged(f"{path.name} cannot be read ({e})") from None


def _is_int(value, low: int = 0) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and value >= low


def read_manifest(entry: Path, key: str) -> dict:
    """The entry's ``meta.json``, checked field by field; EntryDamaged otherwise."""
    raw = _read_small(entry / META, META_MAX_BYTES)
    try:
        meta = json.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, ValueError, RecursionError):
        raise EntryDamaged(f"{META} is not valid JSON") from None
    if not isinstance(meta, dict):
        raise EntryDamaged(f"{META} is not a JSON object")
    if meta.get("key") != key:
        raise EntryDamaged(f"{META} was written for another key ({str(meta.get('key'))[:40]!r})")
    sha = meta.get("sha256")
    if not (isinstance(sha, str) and re.fullmatch(r"[0-9a-f]{64}", sha)):
        raise EntryDamaged(f"{META} has no valid 'sha256'")
    for name, low in (("size", 1), ("n_x", 0), ("n_g", 0)):
        if not _is_int(meta.get(name), low):
            raise EntryDamaged(f"{META} has no valid {name!r}")
    return meta


def elf_problem(path: Path, size: int) -> str | None:
    """Why ``path`` is not a complete ELF shared object, or None.

    Reads only the headers: the ELF header, then the program headers; every loadable segment
    (what the dynamic loader maps) and the section header table (which gcc writes at the end
    of the file) must lie inside the file, so any truncation is found without mapping it.
    """
    with open_regular(path, 1 << 40) as f:  # a FIFO put there since the lstat is refused, never waited on
        head = f.read(64)
        if head[:4] in _MACH_O:
            return None  # macOS: the child-process probe is the check
        if len(head) < 52 or head[:4] != b"\x7fELF":
            return "is not a shared library (no ELF header)"
        elf_class, order = head[4], head[5]
        if elf_class not in (1, 2) or order not in (1, 2) or (elf_class == 2 and len(head) < 64):
            return "has an unknown ELF header"
        end = "<" if order == 1 else ">"
        if elf_class == 2:
            e_type, = struct.unpack_from(end + "H", head, 16)
            phoff, shoff = struct.unpack_from(end + "QQ", head, 32)
            phentsize, phnum, shentsize, shnum = struct.unpack_from(end + "HHHH", head, 54)
            ph_fmt, ph_fields = end + "IIQQQQ", (0, 2, 5)  # p_type, p_flags, p_offset, p_vaddr, p_paddr, p_filesz
        else:
            e_type, = struct.unpack_from(end + "H", head, 16)
            phoff, shoff = struct.unpack_from(end + "II", head, 28)
            phentsize, phnum, shentsize, shnum = struct.unpack_from(end + "HHHH", head, 42)
            ph_fmt, ph_fields = end + "IIIIII", (0, 1, 4)  # p_type, p_offset, p_vaddr, p_paddr, p_filesz
        if e_type != 3:  # ET_DYN
            return f"is not a shared library (ELF type {e_type})"
        if phnum == 0 or phentsize < struct.calcsize(ph_fmt) or phoff + phnum * phentsize > size:
            return f"is cut short: its program headers end past its {size} bytes"
        if shoff + shnum * shentsize > size:
            return f"is cut short: its section headers end at byte {shoff + shnum * shentsize}, past its {size} bytes"
        f.seek(phoff)
        table = f.read(phnum * phentsize)
    if len(table) < phnum * phentsize:
        return "is cut short (program headers)"
    for i in range(phnum):
        fields = struct.unpack_from(ph_fmt, table, i * phentsize)
        p_type, p_offset, p_filesz = (fields[j] for j in ph_fields)
        if p_type == 1 and p_offset + p_filesz > size:  # PT_LOAD
            return f"is cut short: a loadable segment ends at byte {p_offset + p_filesz}, past its {size} bytes"
    return None


def check_files(entry: Path, key: str, seen: os.stat_result | None = None,
                expected_format: str | None = None) -> tuple[dict, str]:
    """Every check that needs no loading: (manifest, payload sha256), or EntryDamaged.

    ``seen`` is the entry's ``lstat`` (taken here when not given). The payload is the file of the
    manifest's ``format`` (``"so"`` when absent: :data:`FORMATS`); ``expected_format`` refuses
    any other.
    """
    if seen is None:
        seen = os.lstat(entry)
    if stat.S_ISLNK(seen.st_mode):
        raise EntryDamaged("it is a symbolic link, not a folder")
    if not stat.S_ISDIR(seen.st_mode):
        raise EntryDamaged("it is a file, not a folder")
    meta = read_manifest(entry, key)
    fmt = meta.get("format", "so")
    if not isinstance(fmt, str) or fmt not in FORMATS:
        raise EntryDamaged(f"{META} names an unknown format ({str(fmt)[:20]!r})")
    if expected_format is not None and fmt != expected_format:
        raise EntryDamaged(f"{META} is for a {fmt!r} entry, not {expected_format!r}")
    name = FORMATS[fmt]
    payload = entry / name
    try:
        st = os.lstat(payload)
    except FileNotFoundError:
        raise EntryDamaged(f"{name} is missing") from None
    if not stat.S_ISREG(st.st_mode):
        raise EntryDamaged(f"{name} is not a regular file")
    if st.st_size != meta["size"]:
        raise EntryDamaged(f"{name} has {st.st_size} bytes, {META} recorded {meta['size']}")
    if fmt == "so":
        problem = elf_problem(payload, st.st_size)
        if problem:
            raise EntryDamaged(f"{name} {problem}")
    digest = file_sha256(payload)
    if digest != meta["sha256"]:
        raise EntryDamaged(f"{name} does not match its checksum in {META}")
    return meta, digest


# -- the probe: load the library in a child process -------------------------------------------

_PROBE_CODE = """\
import sys
import casadi
print("ready", flush=True)
lib = sys.argv[1]
for name in sys.argv[2:]:
    f = casadi.external(name, lib)
    f.call([casadi.DM.zeros(f.sparsity_in(i)) for i in range(f.n_in())])
print("ok", flush=True)
"""


def probe(lib: Path, functions: Iterable[str], timeout: float = PROBE_TIMEOUT) -> str | None:
    """Load ``lib`` and evaluate ``functions`` once (zero inputs) in a short-lived child process.

    Returns None when it worked, ``"unavailable"`` when the child could not even start CasADi
    (then nothing is known about the library), else what went wrong (``"crashed the test load
    (SIGBUS)"``...). The child runs in its own process group, killed as a group on timeout.
    """
    try:
        proc = subprocess.Popen([sys.executable, "-c", _PROBE_CODE, str(lib), *functions],
                                stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                                start_new_session=True, text=True)
    except OSError:
        return "unavailable"
    try:
        out, _ = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
        return f"did not load within {timeout:.0f} s"
    except BaseException:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        raise
    lines = out.split()
    if proc.returncode == 0 and lines[-1:] == ["ok"]:
        return None
    if "ready" not in lines:
        return "unavailable"
    if proc.returncode < 0:
        try:
            name = signal.Signals(-proc.returncode).name
        except ValueError:
            name = f"signal {-proc.returncode}"
        return f"crashed the test load ({name})"
    return f"failed the test load (exit {proc.returncode})"


def verify_loadable(entry: Path, digest: str, functions: Iterable[str],
                    progress: Callable[[str], None] | None = None) -> None:
    """Make sure loading the entry's library cannot take this process down.

    Free when the ``verified`` marker names ``digest``; otherwise a :func:`probe`, remembered
    in the marker when it passes. EntryDamaged when the probe failed.
    """
    try:
        if _read_small(entry / VERIFIED, 256).decode("ascii", "replace").strip() == digest:
            return
    except (EntryDamaged, OSError):
        pass
    if progress:
        progress("checking the compiled solver in a separate process (once per cache entry)")
    problem = probe(entry / LIBRARY, functions)
    if problem == "unavailable":
        return  # the static checks passed; without a child process there is nothing more to learn
    if problem:
        raise EntryDamaged(f"{LIBRARY} {problem}")
    try:
        write_text_atomic(entry / VERIFIED, digest + "\n")
    except OSError:
        pass  # a read-only cache: the next process probes again


# -- removing, publishing, sweeping -----------------------------------------------------------


def _same(path: Path, seen: os.stat_result) -> bool:
    try:
        now = os.lstat(path)
    except OSError:
        return False
    return (now.st_dev, now.st_ino) == (seen.st_dev, seen.st_ino)


def discard(entry: Path, seen: os.stat_result, reason: str) -> None:
    """Remove a damaged entry (or move it aside) with one warning; the caller rebuilds it.

    Only the object that was checked is removed: when another process has meanwhile replaced
    it (a rebuilt entry), nothing is touched.
    """
    if not _same(entry, seen):
        return
    try:
        remove_tree(entry)
        warn(f"solver cache entry {entry} is damaged ({reason}); removed it, the solver is rebuilt")
        return
    except OSError as e:
        error = e
    aside = entry.parent / f"{_ASIDE_PREFIX}{entry.name}.{os.getpid()}.{time.monotonic_ns()}"
    try:
        os.rename(entry, aside)
        warn(f"solver cache entry {entry} is damaged ({reason}); moved it aside to {aside.name}, the solver "
             "is rebuilt")
    except OSError:
        warn(f"solver cache entry {entry} is damaged ({reason}); could not remove it ({error.strerror or error}): "
             "delete it by hand; planning without it")


def publish(tmp: Path, entry: Path, key: str) -> bool:
    """Rename a complete build folder into place; True when a good entry is there afterwards.

    A healthy entry that another process published first stays (the caller drops ``tmp``);
    anything else in the way (a file, a symlink, a damaged folder) is first renamed aside to a
    name of this call's own, and only then removed: a check-then-delete on ``entry`` itself
    could delete a healthy entry another publisher renamed into place in between. Many
    publishers may race (each one retries while the others move things); none ever removes
    a healthy entry.
    """
    for attempt in range(_PUBLISH_TRIES):
        try:
            os.rename(tmp, entry)
            return True
        except OSError:
            pass
        try:
            seen = os.lstat(entry)
        except FileNotFoundError:
            continue
        except OSError:
            return False
        try:
            check_files(entry, key, seen)
            return True
        except (EntryDamaged, OSError):
            pass
        aside = entry.parent / f"{_ASIDE_PREFIX}{entry.name}.{os.getpid()}.{threading.get_ident()}.{attempt}"
        try:
            os.rename(entry, aside)
        except FileNotFoundError:
            continue  # someone else moved it meanwhile
        except OSError:
            return False
        try:
            check_files(aside, key)
            healthy = True
        except (EntryDamaged, OSError):
            healthy = False
        if healthy:  # a good entry arrived between our check and our rename: put it back
            try:
                os.rename(aside, entry)
            except OSError:
                pass  # something is in place again; the next round checks it
            else:
                return True
        try:
            remove_tree(aside)
        except OSError:
            pass  # left for the sweep (it removes every moved-aside name)
    return False


def _builder_alive(folder: Path) -> bool:
    try:
        pid = int(_read_small(folder / BUILDER_PID, 64).decode("ascii").strip())
    except (EntryDamaged, OSError, ValueError):
        return False
    return process_alive(pid)


def sweep(folder: Path, *, now: float | None = None) -> list[str]:
    """Remove stale temporary build folders and moved-aside entries below ``folder``
    (:func:`robots.store.sweep_stale`: once per folder and process). A temporary build folder is
    stale when it is older than an hour and its builder process is gone (:data:`BUILDER_PID`), or
    older than a day. Returns the names removed."""
    return sweep_stale(folder, temporary=_TEMP_NAME, moved_aside=(_ASIDE_PREFIX,), owner_alive=_builder_alive,
                       now=now)


def usable_folder(folder: Path) -> bool:
    """Create ``folder`` if needed; False (with one warning per folder and process) when the
    cache cannot write there, so solvers are built in memory only."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        blocker = next((p for p in (folder, *folder.parents) if os.path.lexists(p)), None)
        if blocker is not None and not blocker.is_dir():
            warn_unusable(folder, f"{blocker} is not a folder")
        else:
            warn_unusable(folder, (e.strerror or str(e)).lower())
        return False
    if not os.access(folder, os.W_OK | os.X_OK):
        warn_unusable(folder, "permission denied")
        return False
    return True


def warn_unusable(folder: Path, reason: str) -> None:
    """The one warning (per folder and process) of a solver cache folder that cannot be written."""
    with _LOCK:
        if str(folder) in _WARNED_FOLDERS:
            return
        _WARNED_FOLDERS.add(str(folder))
    warn(f"solver cache folder {folder} is not usable ({reason}); solvers are built in memory "
         "(set WBMP_CACHE_DIR to a writable folder)")
