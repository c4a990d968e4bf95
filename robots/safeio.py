"""Safe reading of every file wbmp reads: regular files only, never blocking, never unbounded.

A file a command reads may be something else than it looks: a FIFO put in a cache entry's place
(opening it for reading blocks until a writer comes, forever), a link to ``/dev/zero`` (reading
it never ends), a directory, or a file far larger than any wbmp writes. Every reader of the
project goes through :func:`open_regular`, which

* opens with ``O_NONBLOCK`` (a FIFO opens at once instead of waiting for a writer) and
  ``O_CLOEXEC``,
* refuses, after ``fstat`` of what was opened, anything but a regular file (FIFO, socket,
  character or block device, directory) with :class:`NotRegularFile`,
* refuses a file larger than the bound of its kind (:data:`LIMITS`) with :class:`FileTooLarge`;
  the helpers read at most the bound plus one byte, so a file that grows meanwhile is refused
  too.

Both errors are :class:`OSError` subclasses, so a reader's existing ``except OSError`` treats the
file as unreadable (a cache entry as damaged, an input with its one-line error); a missing file
is still :class:`FileNotFoundError`.

Paths read *from* a file (a cache record naming another entry) must stay inside the folder the
file belongs to: :func:`path_inside` resolves a path and says whether it does, :func:`confined`
raises :class:`PathEscapes` when it does not, and :func:`is_key` checks the hexadecimal keys
the caches name their entries by.

This module lives in ``robots/``, the lowest layer, so every package may import it; it imports
nothing but the standard library (``numpy`` only inside :func:`read_npz`), so a motion-cache hit
that imports it does not load Pinocchio.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import re
import stat
from pathlib import Path
from typing import IO, Any

# [bytes] the largest file of each kind wbmp reads; anything larger is refused unread
LIMITS: dict[str, int] = {
    "manifest": 1 << 20,  # a cache entry's manifest or record (JSON)
    "record": 1 << 20,  # a motion-cache request record, an escalation record
    "spec": 16 << 20,  # a spec file (JSON), a batch's JSONL input
    "profile": 1 << 20,  # a robot profile (TOML or JSON)
    "scene": 16 << 20,  # a scene file (JSON)
    "urdf": 64 << 20,  # a URDF or SRDF
    "mesh": 256 << 20,  # a mesh file (STL, DAE, OBJ)
    "motion": 1 << 30,  # a motion file (.npz)
    "entry": 256 << 20,  # a cache entry's data file (motion, seed, MJB, HTML data, mesh data)
    "bvh": 256 << 20,  # a motion-capture file
}


class NotRegularFile(OSError):
    """The path is a FIFO, socket, device or directory, not a regular file."""


class FileTooLarge(OSError):
    """The file is larger than the bound of its kind."""


class PathEscapes(ValueError):
    """A path read from a file resolves outside the folder it must stay in."""


def limit_of(kind: str | int) -> int:
    """The byte bound of ``kind`` (a key of :data:`LIMITS`, or a number of bytes)."""
    return kind if isinstance(kind, int) else LIMITS[kind]


def _kind_name(mode: int) -> str:
    if stat.S_ISDIR(mode):
        return "a directory"
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def open_regular(path: str | os.PathLike[str], kind: str | int) -> IO[bytes]:
    """A binary file object on the regular file ``path`` of at most ``limit_of(kind)`` bytes.

    Raises:
        FileNotFoundError: Nothing is there.
        NotRegularFile: It is a FIFO, socket, device or directory (a FIFO is not waited on).
        FileTooLarge: It is larger than the bound.
        OSError: It cannot be opened (permissions, a loop of links...).
    """
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(path, flags)
    except IsADirectoryError:
        raise NotRegularFile(f"{os.fspath(path)} is a directory, not a file") from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise NotRegularFile(f"{os.fspath(path)} is {_kind_name(st.st_mode)}, not a regular file")
        bound = limit_of(kind)
        if st.st_size > bound:
            raise FileTooLarge(f"{os.fspath(path)} is {st.st_size} bytes, more than the {bound} bytes "
                               "such a file may have")
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def read_bytes(path: str | os.PathLike[str], kind: str | int) -> bytes:
    """The content of a regular file of at most ``limit_of(kind)`` bytes (:func:`open_regular`)."""
    bound = limit_of(kind)
    with open_regular(path, bound) as f:
        data = f.read(bound + 1)
    if len(data) > bound:  # it grew while read
        raise FileTooLarge(f"{os.fspath(path)} is more than the {bound} bytes such a file may have")
    return data


def read_text(path: str | os.PathLike[str], kind: str | int, encoding: str = "utf-8") -> str:
    """The text of a regular file of bounded size; UnicodeDecodeError (a ValueError) when it is
    not ``encoding``."""
    return read_bytes(path, kind).decode(encoding)


def loads_json(text: str | bytes) -> Any:
    """JSON text as Python values; ValueError for anything that is not JSON (nesting too deep
    for the parser included), never RecursionError."""
    try:
        return json.loads(text)
    except RecursionError:
        raise ValueError("JSON nested too deeply") from None


def read_json(path: str | os.PathLike[str], kind: str | int = "manifest") -> Any:
    """A bounded regular file's JSON (:func:`loads_json`); OSError or ValueError otherwise."""
    return loads_json(read_bytes(path, kind))


def sha256_file(path: str | os.PathLike[str], kind: str | int = "entry") -> str:
    """sha256 of a regular file of bounded size, read in 1 MiB blocks."""
    bound = limit_of(kind)
    h = hashlib.sha256()
    seen = 0
    with open_regular(path, bound) as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            seen += len(block)
            if seen > bound:
                raise FileTooLarge(f"{os.fspath(path)} is more than the {bound} bytes such a file may have")
            h.update(block)
    return h.hexdigest()


def is_regular(path: str | os.PathLike[str]) -> bool:
    """True when ``path`` is a regular file (links followed); False on any error."""
    try:
        return stat.S_ISREG(os.stat(path).st_mode)  # noqa: PTH116 - str or Path alike
    except (OSError, ValueError):
        return False


def read_npz(path: str | os.PathLike[str], kind: str | int = "entry", *,
             names: tuple[str, ...] | None = None) -> dict[str, Any]:
    """The arrays of a bounded ``.npz`` (no pickles); with ``names``, exactly those members or
    ValueError. An archive whose members declare more than the bound uncompressed is refused
    (ValueError) before anything is decompressed."""
    import zipfile

    import numpy as np

    bound = limit_of(kind)
    data = read_bytes(path, bound)
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as zf:
            if sum(i.file_size for i in zf.infolist()) > bound:
                raise ValueError(f"{os.fspath(path)} declares more than {bound} bytes of arrays")
        with np.load(io.BytesIO(data), allow_pickle=False) as npz:
            if names is not None and sorted(npz.files) != sorted(names):
                raise ValueError(f"{os.fspath(path)} holds {sorted(npz.files)}, not {sorted(names)}")
            return {name: np.array(npz[name]) for name in npz.files}
    except ValueError:
        raise
    except Exception as e:  # noqa: BLE001 - zipfile and numpy raise many kinds on damaged bytes
        raise ValueError(f"{os.fspath(path)} is not a readable .npz ({type(e).__name__}: {e})") from None


_KEY = re.compile(r"[0-9a-f]+")


def is_key(text: object, length: int | tuple[int, int] = 64) -> bool:
    """True when ``text`` is a lower-case hexadecimal key of ``length`` characters (or of a length
    in the closed range ``(low, high)``): a name that cannot climb out of a folder."""
    if not isinstance(text, str) or _KEY.fullmatch(text) is None:
        return False
    low, high = (length, length) if isinstance(length, int) else length
    return low <= len(text) <= high


def path_inside(folder: str | os.PathLike[str], path: str | os.PathLike[str]) -> bool:
    """True when ``path`` (relative paths are taken from ``folder``), links resolved, is inside
    ``folder`` (or is it)."""
    try:
        root = Path(os.path.realpath(folder))
        target = Path(os.path.realpath(Path(folder) / path))
    except (OSError, ValueError):
        return False
    return target == root or root in target.parents


def confined(folder: str | os.PathLike[str], path: str | os.PathLike[str]) -> Path:
    """``folder / path`` when it resolves inside ``folder`` (:func:`path_inside`).

    Raises:
        PathEscapes: It resolves outside.
    """
    if not path_inside(folder, path):
        raise PathEscapes(f"{os.fspath(path)!r} leads outside {os.fspath(folder)}")
    return Path(folder) / path
