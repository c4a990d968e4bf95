"""Output files: check every path before any work, write through temporary files, rename together.

The rules (``docs/formats.md``, "Output files"):

* An output path must be a new file in an existing, writable folder, or an existing regular
  file that the user may write (it is replaced, and keeps its permission bits and owner).
* A symbolic link is refused, dangling or not: wbmp neither writes through a link nor replaces
  it by a file. A directory, a device, a FIFO or a socket is refused too. Links in the parent
  folders are followed as usual.
* An output folder (``--plots DIR``) is an existing writable folder (a link to one is fine: the
  link is not replaced) or a new folder whose parent exists; each file name it will hold is
  checked like an output file.
* A new file gets ``0o666 & ~umask`` (as ``open()`` would give it); wbmp does not use
  ``mkstemp``'s 0600.

:class:`Staging` writes every output of a command to a temporary file beside its target
(``.<name>.<random>.tmp``) and renames them all at the end: a failure or Ctrl-C before that
removes the temporary files and leaves the folder as it was. If a rename itself fails (the folder
changed under wbmp), the files this command created are removed again; a file it already
replaced keeps the new, complete content. Nothing is ever half-written.

This module is plain Python (no numpy, no wbmp import), so the CLI can check paths cheaply.
"""

from __future__ import annotations

import contextlib
import errno
import os
import secrets
import signal
import stat
import threading
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

from viz.exceptions import OutputPathError, OutputWriteError

TMP_SUFFIX = ".tmp"


def _show(path: str | os.PathLike) -> str:
    return repr(os.fspath(path))


def _why(err: OSError) -> str:
    return err.strerror or str(err)


@contextlib.contextmanager
def _signals_held() -> Iterator[None]:
    """SIGINT and SIGTERM wait (in this thread) until the block ends, then arrive."""
    signals = {signal.SIGINT, signal.SIGTERM}
    held = signal.pthread_sigmask(signal.SIG_BLOCK, signals) if hasattr(signal, "pthread_sigmask") else None
    try:
        yield
    finally:
        if held is not None:
            signal.pthread_sigmask(signal.SIG_SETMASK, held)


def _probe_folder(folder: Path) -> str | None:
    """None if a file can be created in ``folder``, else the reason (also right for root)."""
    probe = folder / f".wbmp-probe-{secrets.token_hex(4)}{TMP_SUFFIX}"
    # Ctrl-C or SIGTERM wait until the probe is gone: an interrupt between creating and removing it
    # would leave it in the user's folder.
    with _signals_held():
        try:
            fd = os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0), 0o600)
        except OSError as e:
            return _why(e)
        os.close(fd)
        try:
            os.unlink(probe)
        except OSError as e:  # pragma: no cover - created a moment ago in the same folder
            return _why(e)
        return None


def _check_parent(path: Path, option: str, shown: str) -> None:
    parent = path.parent
    try:
        st = parent.stat()
    except FileNotFoundError:
        raise OutputPathError(f"{option} {shown}: folder {_show(parent)} does not exist (create it first)") from None
    except NotADirectoryError:
        raise OutputPathError(f"{option} {shown}: a part of {_show(parent)} is a file, not a folder") from None
    except OSError as e:
        raise OutputPathError(f"{option} {shown}: cannot use folder {_show(parent)}: {_why(e)}") from None
    if not stat.S_ISDIR(st.st_mode):
        raise OutputPathError(f"{option} {shown}: {_show(parent)} is not a folder")
    reason = _probe_folder(parent)
    if reason is not None:
        raise OutputPathError(f"{option} {shown}: cannot write in folder {_show(parent)}: {reason}")


def _lstat(path: Path, option: str, shown: str) -> os.stat_result | None:
    try:
        return path.lstat()
    except FileNotFoundError:
        return None
    except NotADirectoryError:
        raise OutputPathError(f"{option} {shown}: a part of {_show(path.parent)} is a file, not a folder") from None
    except OSError as e:
        if e.errno == errno.ENAMETOOLONG:
            raise OutputPathError(f"{option} {shown}: file name too long") from None
        raise OutputPathError(f"{option} {shown}: {_why(e)}") from None


def _check_existing_file(path: Path, st: os.stat_result, option: str, shown: str) -> None:
    mode = st.st_mode
    if stat.S_ISLNK(mode):
        raise OutputPathError(f"{option} {shown}: is a symbolic link; wbmp does not write through or replace "
                              "links (give the link's target or another name)")
    if stat.S_ISDIR(mode):
        raise OutputPathError(f"{option} {shown}: is a directory; give a file name")
    if not stat.S_ISREG(mode):
        raise OutputPathError(f"{option} {shown}: not a regular file; wbmp writes only regular files")
    if not os.access(path, os.W_OK):
        raise OutputPathError(f"{option} {shown}: the file is read-only; wbmp does not replace it "
                              "(make it writable or give another name)")


def _text(path: str | os.PathLike | None, option: str) -> str:
    text = "" if path is None else os.fspath(path)
    if isinstance(text, bytes):  # pragma: no cover - the CLI passes str
        text = os.fsdecode(text)
    if not text.strip():
        raise OutputPathError(f"{option}: empty path")
    if "\0" in text:
        raise OutputPathError(f"{option} {_show(text)}: the path contains a NUL character")
    return text


def check_output_file(path: str | os.PathLike, option: str) -> Path:
    """The path of an output file that may be written, or :class:`OutputPathError` saying why not.

    Args:
        path: The path as the user gave it.
        option: The option it came from (``--out``), named in the message.
    """
    text = _text(path, option)
    shown = _show(text)
    if text.endswith(("/", os.sep)):
        raise OutputPathError(f"{option} {shown}: ends in '/', which names a folder; give a file name")
    out = Path(text)
    if out.name in ("", ".", ".."):
        raise OutputPathError(f"{option} {shown}: names a directory; give a file name")
    st = _lstat(out, option, shown)
    if st is not None:
        _check_existing_file(out, st, option, shown)
    _check_parent(out, option, shown)
    return out


def check_output_dir(path: str | os.PathLike, option: str, names: Iterable[str] = ()) -> Path:
    """The path of an output folder, with every file ``names`` it will hold checked.

    A missing folder is fine when its parent exists and is writable (it is created when the
    outputs are committed). A link to a folder is followed (the link itself is never replaced).
    """
    text = _text(path, option)
    shown = _show(text)
    out = Path(text)
    st = _lstat(out, option, shown)
    if st is None:
        _check_parent(out, option, shown)
        return out
    if stat.S_ISLNK(st.st_mode):
        try:
            st = out.stat()
        except OSError:
            raise OutputPathError(f"{option} {shown}: is a dangling symbolic link") from None
    if not stat.S_ISDIR(st.st_mode):
        raise OutputPathError(f"{option} {shown}: exists and is not a folder")
    reason = _probe_folder(out)
    if reason is not None:
        raise OutputPathError(f"{option} {shown}: cannot write in this folder: {reason}")
    for name in names:
        inner = out / name
        inner_shown = _show(inner)
        st_inner = _lstat(inner, option, shown)
        if st_inner is not None:
            try:
                _check_existing_file(inner, st_inner, option, inner_shown)
            except OutputPathError as e:
                raise OutputPathError(f"{option} {shown}: {str(e)[len(option) + 1:]}") from None
    return out


def _key(path: Path) -> str:
    return os.path.normcase(os.path.realpath(path))


def check_distinct(outputs: Mapping[str, Path], inputs: Mapping[str, Path] | None = None) -> None:
    """Refuse two outputs on one file, or an output on an input (``OutputPathError``)."""
    seen: dict[str, str] = {}
    for option, path in (inputs or {}).items():
        seen.setdefault(_key(path), option)
    for option, path in outputs.items():
        k = _key(path)
        if k in seen:
            other = seen[k]
            raise OutputPathError(f"{option} {_show(path)}: the same file as {other}; give another name")
        seen[k] = option


@dataclass
class _Staged:
    tmp: Path
    target: Path
    existed: bool
    new_folders: tuple[Path, ...]


class Staging:
    """Outputs written to temporary files now, renamed into place together by :meth:`commit`.

    Use as a context manager: whatever is not committed when the block ends (an exception,
    Ctrl-C) is removed.

    Example::

        with Staging() as staging:
            staging.add(Path("a.json"), lambda fh: fh.write(b"{}"))
            staging.add(Path("plots/b.png"), fig_writer)
            staging.commit()
    """

    def __init__(self) -> None:
        self._staged: list[_Staged] = []
        self._pending: list[tuple[threading.Thread, list[BaseException]]] = []  # add(..., background=True)

    def __enter__(self) -> Staging:
        return self

    def __exit__(self, *exc) -> None:
        self.discard()

    def add(self, path: str | os.PathLike, write: Callable[[BinaryIO], object], *, background: bool = False) -> Path:
        """Write an output to a temporary file beside ``path`` with ``write(binary_file)``.

        With ``background``, ``write`` runs in a thread while the caller goes on (a ``write`` that
        spends its time in code that releases the GIL, such as zlib, then overlaps the caller's work
        on another core); :meth:`wait` (which :meth:`commit` calls) waits for it and raises its error.

        The temporary file gets the mode the final file will have: the existing file's mode
        when ``path`` is a regular file, else ``0o666 & ~umask``. When ``path``'s folder does
        not exist yet (a new ``--plots`` folder), the temporary file goes to the nearest existing
        folder above it and the missing folders are created by :meth:`commit`.

        Returns:
            ``path`` (as a ``Path``).
        """
        target = Path(path)
        folder = target.parent
        missing: list[Path] = []
        while not folder.is_dir() and folder != folder.parent:
            missing.append(folder)
            folder = folder.parent
        try:
            st = target.lstat()
        except FileNotFoundError:
            st = None
        existed = st is not None and stat.S_ISREG(st.st_mode)
        # Ctrl-C or SIGTERM wait until the new temporary file is on the list that discard() empties
        # (they arrive when the mask is restored): one between creating and listing it would leave it
        with _signals_held():
            try:
                tmp = self._create(folder, target.name)
            except OSError as e:
                self.discard()
                raise OutputWriteError(f"cannot write in {_show(folder)}: {_why(e)}; nothing was written") from e
            self._staged.append(_Staged(tmp=tmp, target=target, existed=existed, new_folders=tuple(reversed(missing))))
        if background:
            errors: list[BaseException] = []
            thread = threading.Thread(target=self._write_into, args=(tmp, target, st if existed else None, write, errors),
                                      name=f"wbmp-write-{target.name}", daemon=True)
            self._pending.append((thread, errors))
            thread.start()
            return target
        try:
            self._write_into(tmp, target, st if existed else None, write, None)
        except BaseException:
            self.discard()
            raise
        return target

    @staticmethod
    def _write_into(tmp: Path, target: Path, st: os.stat_result | None, write: Callable[[BinaryIO], object],
                    errors: list[BaseException] | None) -> None:
        """``write`` into the temporary file ``tmp`` (with the mode and owner of the file it replaces,
        ``st``), flushed to disk; an error goes to ``errors`` when given (a background write), else up."""
        try:
            fd = os.open(tmp, os.O_WRONLY | getattr(os, "O_CLOEXEC", 0))
            if st is not None:
                os.fchmod(fd, stat.S_IMODE(st.st_mode))
                if (st.st_uid, st.st_gid) != (os.geteuid(), os.getegid()):
                    try:
                        os.fchown(fd, st.st_uid, st.st_gid)
                    except OSError:  # not ours to give away: the new file is the user's
                        pass
            with os.fdopen(fd, "wb") as fh:
                write(fh)
                fh.flush()
                os.fsync(fh.fileno())
        except OSError as e:
            error = OutputWriteError(f"cannot write {_show(target)}: {_why(e)}; nothing was written")
            error.__cause__ = e
            if errors is None:
                raise error from e
            errors.append(error)
        except BaseException as e:
            if errors is None:
                raise
            errors.append(e)

    def wait(self) -> None:
        """Wait for the background writes (:meth:`add`); the first that failed raises its error, after
        every temporary file was removed."""
        pending, self._pending = self._pending, []
        failed: list[BaseException] = []
        for thread, errors in pending:
            thread.join()
            failed.extend(errors)
        if failed:
            self.discard()
            raise failed[0]

    @staticmethod
    def _create(folder: Path, name: str) -> Path:
        for _ in range(100):
            tmp = folder / f".{name[:100]}.{secrets.token_hex(4)}{TMP_SUFFIX}"
            try:
                fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0), 0o666)
            except FileExistsError:  # pragma: no cover - 32 random bits
                continue
            os.close(fd)  # the kernel applied the umask to 0o666
            return tmp
        raise FileExistsError(errno.EEXIST, "no free temporary name", str(folder))  # pragma: no cover

    def commit(self) -> list[Path]:
        """Rename every staged file onto its target; on failure undo what this command created."""
        self.wait()
        done: list[_Staged] = []
        made: list[Path] = []
        try:
            for item in self._staged:
                for folder in item.new_folders:
                    if not folder.is_dir():
                        folder.mkdir()  # 0o777 & ~umask
                        made.append(folder)
                st = None
                try:
                    st = item.target.lstat()
                except FileNotFoundError:
                    pass
                if st is not None and not stat.S_ISREG(st.st_mode):
                    raise OutputWriteError(f"{_show(item.target)} changed while wbmp was working: it is no "
                                           "longer a regular file; nothing was written")
                os.replace(item.tmp, item.target)
                done.append(item)
        except BaseException as e:
            for item in done:
                if not item.existed:
                    item.target.unlink(missing_ok=True)
            self._staged = [s for s in self._staged if s not in done]
            self.discard()
            for folder in reversed(made):
                try:
                    folder.rmdir()
                except OSError:
                    pass
            if isinstance(e, OSError):
                raise OutputWriteError(f"cannot write {_show(item.target)}: {_why(e)}; the files this "
                                       "command created were removed") from e
            raise
        self._staged = []
        return [item.target for item in done]

    def discard(self) -> None:
        """Remove every temporary file not yet renamed (after the background writes ended)."""
        pending, self._pending = self._pending, []
        for thread, _ in pending:
            thread.join()
        for item in self._staged:
            try:
                item.tmp.unlink(missing_ok=True)
            except OSError:  # pragma: no cover - the folder went away
                pass
        self._staged = []


def atomic_write(path: str | os.PathLike, write: Callable[[BinaryIO], object]) -> Path:
    """Write one file atomically (a :class:`Staging` of one); returns its path."""
    with Staging() as staging:
        staging.add(path, write)
        staging.commit()
    return Path(path)


def atomic_write_text(path: str | os.PathLike, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically; returns its path."""
    data = text.encode("utf-8")
    return atomic_write(path, lambda fh: fh.write(data))
