"""The options of ``wbmp bench`` checked before any work (exit 2), and a ``--from`` result read
safely (a FIFO, a device, non-UTF-8 bytes, deep nesting or a damaged record is exit 2, not a hang
or a traceback)."""

from __future__ import annotations

import json
import math
import os
from typing import Any

from wbmp.bench.tasks import QUICK_TASKS, SCHEMA, TASKS
from wbmp.errors import CliError, ExitCode

MAX_REPEATS = 50  # each repeat of a task also starts a new process (cached cold) and a `wbmp solve`
MAX_ITERATIONS = 10_000  # --max-iterations (the planner's default is 100)
MIN_DT, MAX_DT = 0.005, 0.5  # [s] --dt, as tasks.limits allows for a spec's knot spacing
MAX_RESULT_BYTES = 64 * 1024 * 1024  # a --from result is ~20 kB


def check_options(*, tasks: list[str] | None, quick: bool, repeats: int | None, dt: float | None,
                  max_iterations: int | None) -> tuple[list[str], int]:
    """(task classes, repeats) of a run, or :class:`CliError` (exit 2) naming the bad option."""
    names = list(dict.fromkeys(tasks)) if tasks is not None else (list(QUICK_TASKS) if quick else list(TASKS))
    if not names:
        raise CliError(f"--tasks names no task class; choose from {', '.join(TASKS)} (comma-separated)",
                       ExitCode.USAGE)
    unknown = [n for n in names if n not in TASKS]
    if unknown:
        shown = ", ".join(repr(n) if len(n) <= 40 else f"{n[:40]!r}..." for n in unknown[:5])
        raise CliError(f"unknown task class(es) {shown}; choose from {', '.join(TASKS)}", ExitCode.USAGE)
    reps = repeats if repeats is not None else (1 if quick else 3)
    if not 1 <= reps <= MAX_REPEATS:
        raise CliError(f"--repeats must be from 1 to {MAX_REPEATS}, got {reps}", ExitCode.USAGE)
    if dt is not None and not (math.isfinite(dt) and MIN_DT <= dt <= MAX_DT):
        raise CliError(f"--dt must be a knot spacing from {MIN_DT:g} to {MAX_DT:g} s, got {dt:g}", ExitCode.USAGE)
    if max_iterations is not None and not 1 <= max_iterations <= MAX_ITERATIONS:
        raise CliError(f"--max-iterations must be from 1 to {MAX_ITERATIONS}, got {max_iterations}", ExitCode.USAGE)
    return names, reps


def read_result(path: str) -> dict[str, Any]:
    """A ``--json`` result re-read for ``--from`` (CliError, exit 2, when it is not one)."""
    import stat

    shown = repr(path) if len(path) <= 200 else f"{path[:200]!r}..."
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))  # a FIFO must not block us
        with os.fdopen(fd, "rb") as fh:
            if not stat.S_ISREG(os.fstat(fd).st_mode):
                raise CliError(f"--from {shown}: not a regular file (give a `wbmp bench --json` result)",
                               ExitCode.USAGE)
            data = fh.read(MAX_RESULT_BYTES + 1)
    except OSError as e:
        raise CliError(f"--from {shown}: cannot read it: {e.strerror or e}", ExitCode.USAGE) from None
    if len(data) > MAX_RESULT_BYTES:
        raise CliError(f"--from {shown}: larger than {MAX_RESULT_BYTES >> 20} MiB; a bench result is a few kB",
                       ExitCode.USAGE)
    try:
        result = json.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, ValueError, RecursionError) as e:
        what = "not UTF-8" if isinstance(e, UnicodeDecodeError) else "nested too deeply" if isinstance(
            e, RecursionError) else f"not JSON ({e})"
        raise CliError(f"--from {shown}: {what}; give a `wbmp bench --json` result", ExitCode.USAGE) from None
    if not isinstance(result, dict) or result.get("schema") != SCHEMA:
        raise CliError(f"{path} is not a `wbmp bench --json` result ({SCHEMA})", ExitCode.USAGE)
    tasks = result.get("tasks")
    if not isinstance(tasks, dict) or not all(isinstance(r, dict) and isinstance(r.get("status"), str)
                                              for r in tasks.values()):
        raise CliError(f"--from {shown}: its 'tasks' are not task records with a 'status'", ExitCode.USAGE)
    return result

