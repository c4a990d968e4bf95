"""Output files: written through temporary files and renamed together.

The CLI checks every output path before any work (``wbmp/outputs.py``; the rules in
``docs/formats.md``, "Output files"):

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

This module is plain Python (no numpy, no wbmp import): the viewers write through it, and so do
the CLI's writers.
"""

from __future__ import annotations

import contextlib
import errno
import os
import secrets
import signal
import stat
import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

from viz.exceptions import OutputWriteError

TMP_SUFFIX = ".tmp"


def _show(path: str | os.PathLike) -> str:
    return repr(os.fspath(path))


def _why(err: OSError) -> str:
    return err.strerror or str(err)


@contextlib.contextmanager
def signals_held() -> Iterator[None]:
    """SIGINT and SIGTERM wait (in this thread) until the block ends, then arrive."""
    signals = {signal.SIGINT, signal.SIGTERM}
    held = signal.pthread_sigmask(signal.SIG_BLOCK, signals) if hasattr(signal, "pthread_sigmask") else None
    try:
        yield
    finally:
        if held is not None:
            signal.pthread_sigmask(signal.SIG_SETMASK, held)


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
        with signals_held():
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
