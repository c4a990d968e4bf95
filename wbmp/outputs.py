"""The files a request writes: the output-path rules checked before any work, and the writers of
``--out`` (the arrays of :func:`wbmp.pipeline.result_arrays`), ``--html`` and ``--plots`` (step 7
of :mod:`wbmp.pipeline`), staged so that a failure leaves the folders as they were."""

from __future__ import annotations

import contextlib
import errno
import os
import secrets
import stat
import time
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from viz import OutputPathError, signals_held
from wbmp.errors import CliError, ExitCode
from wbmp.pipeline import _REQUEST_KEYS, Progress, SolveResult, _silent, result_arrays

# -- the output-path rules: every output a command will write, checked before any work ---------
#
# Each refusal is one OutputPathError (exit 2) naming the option, the path and why: an empty path or
# one with a NUL, a folder where a file is wanted, a symbolic link (never written through or
# replaced), a device or other non-regular file, a read-only file, a missing or unwritable folder
# (probed by creating a file there: right for root too), two outputs on one file, an output on an
# input file. The writers (viz.Staging, viz.atomic_write) then write through temporary files
# renamed into place: nothing half-written.


def _show(path: str | os.PathLike) -> str:
    return repr(os.fspath(path))


def _why(err: OSError) -> str:
    return err.strerror or str(err)


def _probe_folder(folder: Path) -> str | None:
    """None if a file can be created in ``folder``, else the reason (also right for root)."""
    probe = folder / f".wbmp-probe-{secrets.token_hex(4)}.tmp"  # named like viz.Staging's temporaries
    # Ctrl-C or SIGTERM wait until the probe is gone: an interrupt between creating and removing it
    # would leave it in the user's folder.
    with signals_held():
        try:
            fd = os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0), 0o600)
        except OSError as e:
            return _why(e)
        os.close(fd)
        try:
            probe.unlink()
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



@contextlib.contextmanager
def output_errors() -> Iterator[None]:
    """Turn :class:`viz.files.OutputError` (a refused path, a failed write) into exit 2."""
    from viz import OutputError

    try:
        yield
    except OutputError as e:
        raise CliError(str(e), ExitCode.USAGE) from None


@dataclass(frozen=True, kw_only=True)
class OutputPaths:
    """The files a command will write, checked before any work (:func:`check_outputs`)."""

    out: Path | None = None
    html: Path | None = None
    plots: Path | None = None


def check_inputs_exist(*, spec: str | None = None, scene: str | None = None) -> None:
    """Refuse a spec or scene file that does not exist (exit 3, the readers' own message) before
    the outputs are checked: a missing input must not be reported as a missing output folder."""
    import os

    from tasks import TaskDefinitionError

    for what, path in (("spec", spec), ("scene", scene)):
        if path is not None and path != "-" and path.strip() and not os.path.lexists(path):
            raise TaskDefinitionError(f"{what} file {path!r} does not exist")


def check_outputs(*, out: str | None = None, html: str | None = None, plots: str | None = None,
                  inputs: dict[str, str | None] | None = None) -> OutputPaths:
    """Check every output path of ``solve``/``show``/``demo`` before any work.

    Refuses (:class:`CliError`, exit 2, one line naming the option, the path and why): an empty
    path, a directory, a symbolic link, a device or other non-regular file, a read-only file, a
    missing or unwritable folder, two outputs on one file, an output on an input file, and a
    motion file (``--out``) that does not end in ``.npz``. ``None`` means "not asked".
    """
    with output_errors():
        paths = OutputPaths(
            out=None if out is None else check_output_file(out, "--out"),
            html=None if html is None else check_output_file(html, "--html"),
            plots=None if plots is None else check_output_dir(plots, "--plots", _plot_files()),
        )
        if paths.out is not None and paths.out.suffix.lower() != ".npz":
            raise OutputPathError(f"--out {out!r}: a motion file ends in .npz (for JSON or CSV, write the "
                                  ".npz and run `wbmp export`)")
        files = {k: v for k, v in (("--out", paths.out), ("--html", paths.html)) if v is not None}
        if paths.plots is not None:
            files.update({f"--plots ({name})": paths.plots / name for name in _plot_files()})
        check_distinct(files, {k: Path(v) for k, v in (inputs or {}).items() if v})
    return paths


def _plot_files() -> tuple[str, ...]:
    from viz import PLOT_FILES

    return PLOT_FILES


def _write_html(path: Path, result: SolveResult, staging: Any, *, cache_dir: str | Path | None) -> None:
    """The HTML replay; its data is reused from (or stored into) the motion cache when the
    result is in it (the page's data does not depend on the title)."""
    from viz import page_data, render_page

    title = result.spec.description or result.spec.name
    data = None
    motions = None
    if result.cache_key is not None:
        from wbmp.motioncache import MotionCache

        motions = MotionCache(cache_dir)
        data = motions.load_page(result.cache_key)
    if data is None:
        data = page_data(result.model(), result.plan, execution=result.execution)
        if motions is not None and result.cache_key is not None:
            motions.store_page(result.cache_key, data)
    text = render_page(data, result.robot_name, result.plan, execution=result.execution, title=title)
    raw = text.encode("utf-8")
    staging.add(path, lambda fh: fh.write(raw))


def write_outputs(result: SolveResult, *, out: str | None = None, html: str | None = None,
                  plots: str | None = None, progress: Progress = _silent,
                  cache_dir: str | Path | None = None) -> dict[str, str]:
    """Write the requested files; returns {kind: path}.

    The paths are checked again (:func:`check_outputs`), every file is made in a temporary file
    beside its target, and all are renamed into place at the end: a failure (or Ctrl-C) while
    making them leaves the folders as they were. The time each file took is added to
    ``result.timings`` (``npz``, ``html``: the ``--json`` report shows them).
    """
    from viz import Staging
    from wbmp.motionfile import npz_replacing, savez_fast

    paths = check_outputs(out=out, html=html, plots=plots)
    written: dict[str, str] = {}
    with output_errors(), Staging() as staging:
        if paths.out is not None:
            t0 = time.perf_counter()
            progress(f"writing {out}")
            arrays = result_arrays(result)
            copied = None
            # the stored file (a cached result, or a fresh one just stored), with this request's JSON
            stored = result.cached.data if result.cached is not None and result.cached.data else result.motion_file
            if stored:
                copied = npz_replacing(stored, {k: arrays[k] for k in _REQUEST_KEYS})
            if copied is not None:
                data = copied
                staging.add(paths.out, lambda fh: fh.write(data))
            else:
                # zlib level 1: the 1 kHz execution (float64) hardly compresses (6.2 MB at level 6, 6.2 MB
                # at level 1, 6.4 MB raw for four steps) and level 6 costs ~25 % more CPU; when a page or
                # plots follow, the file is compressed in a thread (zlib releases the GIL) beside them
                staging.add(paths.out, lambda fh: savez_fast(fh, arrays),
                            background=paths.html is not None or paths.plots is not None)
            written["motion"] = str(paths.out)
            result.timings["npz"] = time.perf_counter() - t0
        if paths.html is not None:
            t0 = time.perf_counter()
            progress(f"writing {html}")
            _write_html(paths.html, result, staging, cache_dir=cache_dir)
            written["html"] = str(paths.html)
            result.timings["html"] = time.perf_counter() - t0
        if paths.plots is not None:
            from viz import write_plots

            progress(f"writing plots to {plots}")
            files = write_plots(paths.plots, result.model(), result.plan, execution=result.execution,
                                staging=staging)
            written["plots"] = ", ".join(str(p) for p in files)
        if paths.out is not None:
            t0 = time.perf_counter()
            staging.wait()  # the motion file's background write (its time beyond the page's counts as npz)
            result.timings["npz"] += time.perf_counter() - t0
        staging.commit()
    return written
