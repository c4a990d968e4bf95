"""The motion library's index (``index.jsonl``), its resume rule, and the summary (``summary.md``).

While a batch runs, each finished job appends one JSON line to ``index.jsonl`` and the file is
flushed to disk (``fsync``) before the next: an interrupted or killed batch leaves every record
of a finished job, and at most a torn last line, which the reader skips. At the end (also after
Ctrl-C or SIGTERM) the index is rewritten atomically with one record per job, in the batch
file's order (records of jobs no longer in the batch file are kept after them), and
``summary.md`` beside it.

Resume rule (:func:`is_done`): a job is skipped when the index holds a record for it with the
same ``input_sha256`` (same item, spec file content, robot and simulation switch) whose outcome
is a result of the input — status ``ok``, or ``failed`` with exit code 2 to 5 — and whose motion
file, when it has one, exists with the recorded sha256. Anything else is planned again: a
crashed item (exit 1), a missing or damaged motion file, a changed input.

A line of the index that is not a valid record (:func:`record_problem`: a field missing or of the
wrong type, a motion file named outside the folder, NaN, a torn line) is reported by
:func:`read_index_report` and left out: its item is planned again.

The index and the files agree (:func:`wbmp.batch.run.reconcile`): a worker writes the motion file
first (renamed into place), then the parent appends its record; a stop between the two leaves a
motion file without a record, which the batch removes when it ends (and, after a kill, when it
next starts), as it drops a record whose motion file is missing.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
from collections import Counter
from pathlib import Path
from typing import Any

INDEX = "index.jsonl"
SUMMARY = "summary.md"
#: Exit codes of a failure that the input decides (it would fail again the same way).
FINAL_CODES = (2, 3, 4, 5)


#: Longest index read [bytes] (a record is ~0.5 kB: two million records).
MAX_INDEX_BYTES = 1024 * 1024 * 1024
_HEX64 = frozenset("0123456789abcdef")


def _sha(value: Any) -> bool:
    return isinstance(value, str) and len(value) == 64 and set(value) <= _HEX64


def _int(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def record_problem(rec: Any) -> str | None:
    """Why ``rec`` is not a usable index record (None when it is one).

    A record names its item (``id``, ``robot``, ``line``), its outcome (``status`` ok or
    failed, ``exit_code``: 0 for ok, 1 to 255 for failed, ``message``), ``timings``, the input
    hash, and its motion file: ``<id>__<robot>.npz`` in the library folder (never a path
    elsewhere) with its sha256 for ok, none for failed.
    """
    from wbmp.batch.items import SEPARATOR

    if not isinstance(rec, dict):
        return f"a JSON {type(rec).__name__}, not an object"
    for key in ("id", "robot"):
        value = rec.get(key)
        if not isinstance(value, str) or not value or "/" in value or "\\" in value or "\0" in value:
            return f"{key!r} is missing or not a name"
    if not _int(rec.get("line")) or rec["line"] < 1:
        return "'line' is missing or not a line number"
    status, code = rec.get("status"), rec.get("exit_code")
    if status not in ("ok", "failed"):
        return "'status' is missing or neither ok nor failed"
    if not isinstance(code, int) or isinstance(code, bool) or not (code == 0 if status == "ok" else 1 <= code <= 255):
        return f"'exit_code' is missing or does not fit status {status}"
    if not isinstance(rec.get("message"), str):
        return "'message' is missing or not text"
    if not isinstance(rec.get("timings"), dict):
        return "'timings' is missing or not an object"
    if not _sha(rec.get("input_sha256")):
        return "'input_sha256' is missing or not a sha256"
    motion, sha = rec.get("motion"), rec.get("sha256")
    if status == "ok" or motion is not None:
        if motion != f"{rec['id']}{SEPARATOR}{rec['robot']}.npz" or motion.startswith("."):
            return "'motion' is not the item's motion file name, <id>__<robot>.npz"
        if not _sha(sha):
            return "'sha256' is missing or not a sha256"
    elif sha is not None:
        return "'sha256' without a motion file"
    return None


def _reject_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a number JSON allows")


def _finite(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise ValueError(f"{text} is not a finite number")
    return value


def _read_bounded(path: Path) -> bytes | None:
    """The bytes of a regular file (never blocking on a special file), None when missing.

    Raises:
        CliError: ``path`` is not a regular file, or is larger than :data:`MAX_INDEX_BYTES`.
    """
    import stat

    from wbmp.errors import CliError, ExitCode

    shown = repr(str(path))
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
                     | getattr(os, "O_NOFOLLOW", 0))
    except FileNotFoundError:
        return None
    except OSError as e:
        raise CliError(f"{shown}: cannot read the index: {e.strerror or e}; move it away to start the "
                       "library's index afresh", ExitCode.USAGE) from None
    with os.fdopen(fd, "rb") as fh:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise CliError(f"{shown}: the index is not a regular file; remove it (it is rebuilt as the "
                           "items are planned again)", ExitCode.USAGE)
        if st.st_size > MAX_INDEX_BYTES:
            raise CliError(f"{shown}: the index is larger than {MAX_INDEX_BYTES // 2**20} MiB; split the "
                           "library into several folders", ExitCode.USAGE)
        return fh.read(MAX_INDEX_BYTES + 1)[:MAX_INDEX_BYTES]


def read_index_lines(text: str) -> tuple[dict[tuple[str, str], dict[str, Any]], list[str]]:
    """The last valid record of each (id, robot) in index text, and one note per damaged line
    (``line N: why``); a damaged line is left out, never raised on."""
    records: dict[tuple[str, str], dict[str, Any]] = {}
    damaged: list[str] = []
    for n, line in enumerate(text.splitlines(), 1):
        if not line.strip():
            continue
        try:
            rec = json.loads(line, parse_constant=_reject_constant, parse_float=_finite)
        except RecursionError:
            damaged.append(f"line {n}: nested too deeply")
            continue
        except ValueError as e:  # JSONDecodeError, NaN/Infinity, an integer of too many digits
            why = e.msg if isinstance(e, json.JSONDecodeError) else str(e)
            damaged.append(f"line {n}: not a JSON record ({why})")
            continue
        problem = record_problem(rec)
        if problem is not None:
            damaged.append(f"line {n}: {problem}")
            continue
        records[(rec["id"], rec["robot"])] = rec
    return records, damaged


def read_index_report(path: Path) -> tuple[dict[tuple[str, str], dict[str, Any]], list[str]]:
    """:func:`read_index_lines` of an index file (nothing for a missing one).

    Raises:
        CliError: the index is not a regular file, or too large (exit 2).
    """
    raw = _read_bounded(path)
    if raw is None:
        return {}, []
    return read_index_lines(raw.decode("utf-8", errors="replace"))


def read_index(path: Path) -> dict[tuple[str, str], dict[str, Any]]:
    """The last valid record of each (id, robot) in an index file; damaged lines are skipped."""
    return read_index_report(path)[0]


def is_done(record: dict[str, Any] | None, job: Any, out_dir: Path, *, retry_failed: bool = False) -> bool:
    """True when ``job`` need not run again (the module's resume rule)."""
    from robots import file_sha256

    if record is None or record.get("input_sha256") != job.input_sha256:
        return False
    status, code = record.get("status"), record.get("exit_code")
    if status == "ok":
        pass
    elif status == "failed" and code in FINAL_CODES and not retry_failed:
        pass
    else:
        return False
    motion = record.get("motion")
    if motion is None:
        return status != "ok"
    if motion != job.motion_name:
        return False
    path = out_dir / motion
    try:
        if not path.is_file() or path.is_symlink():
            return False
        return file_sha256(path) == record.get("sha256")
    except OSError:
        return False


class IndexWriter:
    """Appends records to ``index.jsonl``, each flushed to disk before :meth:`append` returns."""

    def __init__(self, path: Path) -> None:
        self.path = path
        flags = os.O_WRONLY | os.O_APPEND | os.O_CREAT | getattr(os, "O_CLOEXEC", 0)
        self._fd = os.open(path, flags, 0o666)  # the umask applies, as for every output
        with contextlib.suppress(OSError):
            size = os.fstat(self._fd).st_size
            if size:  # a torn last line of a killed run: start on a fresh line
                with open(path, "rb") as fh:
                    fh.seek(size - 1)
                    if fh.read(1) != b"\n":
                        os.write(self._fd, b"\n")

    def append(self, record: dict[str, Any]) -> None:
        """Write one record as a line and fsync."""
        data = (json.dumps(record, ensure_ascii=False, sort_keys=False) + "\n").encode("utf-8")
        view = memoryview(data)
        while view:
            n = os.write(self._fd, view)
            view = view[n:]
        os.fsync(self._fd)

    def close(self) -> None:
        """Close the file."""
        if self._fd >= 0:
            os.close(self._fd)
            self._fd = -1


def final_records(jobs: list[Any], records: dict[tuple[str, str], dict[str, Any]]) -> list[dict[str, Any]]:
    """One record per job in batch order (jobs without a record are left out), then the others."""
    ordered = [records[job.key] for job in jobs if job.key in records]
    keys = {job.key for job in jobs}
    ordered += [rec for key, rec in records.items() if key not in keys]
    return ordered


def index_text(records: list[dict[str, Any]]) -> str:
    """The compacted index: one JSON line per record."""
    return "".join(json.dumps(rec, ensure_ascii=False) + "\n" for rec in records)


def _cell(text: Any) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def summary_text(records: list[dict[str, Any]], *, title: str, pending: int = 0) -> str:
    """``summary.md``: counts by status and robot, then every failure with its message."""
    by_robot: dict[str, Counter] = {}
    for rec in records:
        by_robot.setdefault(rec["robot"], Counter())[rec.get("status", "?")] += 1
    total = Counter(rec.get("status", "?") for rec in records)
    lines = [f"# Motion library: {title}", ""]
    lines.append(f"{len(records)} records: {total.get('ok', 0)} ok, {total.get('failed', 0)} failed"
                 + (f", {pending} not run (the batch was stopped)" if pending else "") + ".")
    lines += ["", "| robot | ok | failed | total |", "|---|---:|---:|---:|"]
    for robot in sorted(by_robot):
        c = by_robot[robot]
        lines.append(f"| {_cell(robot)} | {c.get('ok', 0)} | {c.get('failed', 0)} | {sum(c.values())} |")
    lines.append(f"| **all** | {total.get('ok', 0)} | {total.get('failed', 0)} | {len(records)} |")
    lines += _figures_lines(records)
    codes = Counter(rec.get("exit_code") for rec in records if rec.get("status") != "ok")
    if codes:
        lines += ["", "Failures by exit code (docs/cli.md): "
                  + ", ".join(f"{code}: {n}" for code, n in sorted(codes.items(), key=lambda kv: str(kv[0]))) + "."]
    failed = [rec for rec in records if rec.get("status") != "ok"]
    if failed:
        lines += ["", "## Failures", "", "| id | robot | line | exit | message |", "|---|---|---:|---:|---|"]
        for rec in failed:
            lines.append(f"| {_cell(rec['id'])} | {_cell(rec['robot'])} | {rec.get('line', '')} | "
                         f"{rec.get('exit_code', '')} | {_cell(rec.get('message', ''))} |")
    return "\n".join(lines) + "\n"


def _figures_lines(records: list[dict[str, Any]]) -> list[str]:
    """The task success rate over the records, and the mean evaluation figures of the simulated ones
    (:func:`sim.figures.summarize_figures`, docs/safety.md); nothing when no record has figures."""
    rows = [(rec.get("status") == "ok", rec["figures"]) for rec in records if isinstance(rec.get("figures"), dict)]
    if not records:
        return []
    rate = sum(1 for rec in records if rec.get("status") == "ok") / len(records)
    lines = ["", f"Task success rate: {100 * rate:.1f} % ({len(records)} records)."]
    if rows:
        from sim import FIGURES, summarize_figures

        s = summarize_figures(rows)
        lines += ["", f"Evaluation figures, mean over the {len(rows)} simulated records (docs/safety.md):", "",
                  "| figure | mean | unit |", "|---|---:|---|"]
        for key, (unit, _) in FIGURES.items():
            value = s[key] if key == "estop_count" else s[f"mean_{key}"]
            lines.append(f"| {key}{' (total)' if key == 'estop_count' else ''} | {value:.4g} | {unit} |")
    return lines
