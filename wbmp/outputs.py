"""The files a request writes: the output-path rules checked before any work, and the writers of
``--out`` (the arrays of :func:`wbmp.pipeline.result_arrays`), ``--html`` and ``--plots`` (step 7
of :mod:`wbmp.pipeline`), staged so that a failure leaves the folders as they were."""

from __future__ import annotations

import contextlib
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from wbmp.errors import CliError, ExitCode
from wbmp.pipeline import _REQUEST_KEYS, Progress, SolveResult, _silent, result_arrays


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
    See :mod:`viz.files` for the rules.
    """
    from viz import OutputPathError, check_distinct, check_output_dir, check_output_file

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
