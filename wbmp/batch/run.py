"""``wbmp batch``: check everything, skip what is done, run the rest, keep the index consistent.

:func:`prepare` does every check that needs no work (the batch file, the robots, the output
folder and every file name it will hold, Ray's presence) and raises :class:`CliError` with one
line; :func:`run_batch` then holds the output folder (an exclusive lock on the folder: a second
``wbmp batch`` on it is refused), runs the jobs that are not done, appends each record to the
index as it arrives, and at the end — also after Ctrl-C or SIGTERM — rewrites the index and the
summary atomically and removes temporary files of workers that were stopped and motion files
whose record did not reach the index (:func:`reconcile`; also at the start, after a kill).
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import re
import stat
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from wbmp.batch.index import (
    INDEX,
    SUMMARY,
    IndexWriter,
    final_records,
    index_text,
    is_done,
    read_index_report,
    summary_text,
)
from wbmp.batch.items import Job, check_robot, expand, read_items
from wbmp.errors import CliError, ExitCode, one_line

#: Temporary files of :class:`viz.files.Staging` for motion files: ``.<id>__<robot>.npz.<hex>.tmp``.
_STAGING_TMP = re.compile(r"^\..+__.+\.npz\.[0-9a-f]{8}\.tmp$")


@dataclass(kw_only=True)
class BatchPlan:
    """A checked batch: its jobs and where they go."""

    file: str
    out_dir: Path
    jobs: list[Job]
    n_items: int
    workers: int
    simulate: bool
    force: bool = False
    retry_failed: bool = False
    ray: bool = False
    ray_address: str | None = None
    cache: bool = True


@dataclass(kw_only=True)
class BatchOutcome:
    """What a batch did: the final records of its jobs and the counts."""

    records: list[dict[str, Any]]
    ran: int
    skipped: int
    pending: int
    wall_time: float
    index_path: Path
    summary_path: Path
    counts: dict[str, int] = field(default_factory=dict)

    @property
    def exit_code(self) -> int:
        """0 when every job succeeded; 1 when one crashed (the worker died, or a bug); else the
        code of the first failed job in the batch file's order (2 to 5, as ``wbmp solve``)."""
        failed = [r for r in self.records if r.get("status") != "ok"]
        if self.pending and not failed:
            return int(ExitCode.INTERNAL)  # pragma: no cover - only after an interrupt, which exits 130/143
        if not failed:
            return int(ExitCode.OK)
        if any(r.get("exit_code") == ExitCode.INTERNAL for r in failed):
            return int(ExitCode.INTERNAL)
        return int(failed[0].get("exit_code") or ExitCode.INTERNAL)


def parse_robots(text: str | None) -> list[str] | None:
    """``--robots talos,g1`` -> names; unknown ones are refused (exit 3), empty entries (exit 2)."""
    if text is None:
        return None
    names = [t.strip() for t in text.split(",")]
    if not text.strip() or any(not n for n in names):
        raise CliError(f"--robots {one_line(text)!r}: give robot names separated by commas, e.g. talos,g1",
                       ExitCode.USAGE)
    from robots import available_robots

    known = available_robots()
    for name in names:
        check_robot(name, known, "--robots")
    return list(dict.fromkeys(names))


def prepare(*, file: str, out_dir: str, robots: str | None, workers: int, simulate: bool, force: bool = False,
            retry_failed: bool = False, ray: bool = False, ray_address: str | None = None,
            cache: bool = True) -> BatchPlan:
    """Every check before any work (:class:`CliError`, one line, exit 2 or 3)."""
    from wbmp.outputs import check_distinct, check_output_dir, output_errors

    if workers < 1:
        raise CliError(f"--workers {workers}: give at least 1 worker", ExitCode.USAGE)
    if ray:
        try:
            import ray as _ray  # noqa: F401
        except ImportError:
            raise CliError("--ray needs Ray: pip install 'wbmp[ray]' (or pip install ray)", ExitCode.USAGE) from None
    names = parse_robots(robots)
    items = read_items(file)
    jobs = expand(items, names, simulate=simulate, file=file)
    with output_errors():
        folder = check_output_dir(out_dir, "--out-dir", [INDEX, SUMMARY, *(j.motion_name for j in jobs)])
        check_distinct({"--out-dir (index.jsonl)": folder / INDEX}, {"FILE": Path(file)})
    if ray and ray_address is not None:  # its form, then that it answers (one line, exit 2); auto resolved
        from wbmp.batch.raynet import check_reachable, parse_address

        ray_address = check_reachable(parse_address(ray_address)).target
    elif ray:
        from wbmp.batch.raynet import check_local_temp

        check_local_temp()
    return BatchPlan(file=file, out_dir=folder, jobs=jobs, n_items=len(items), workers=workers, simulate=simulate,
                     force=force, retry_failed=retry_failed, ray=ray, ray_address=ray_address, cache=cache)


@contextlib.contextmanager
def _locked(folder: Path) -> Iterator[None]:
    """An exclusive lock on the output folder for the batch's duration (flock on the folder)."""
    fd = os.open(folder, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0) | getattr(os, "O_CLOEXEC", 0))
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise CliError(f"--out-dir {str(folder)!r} is in use by another `wbmp batch`; wait for it or give "
                           "another folder", ExitCode.USAGE) from None
        yield
    finally:
        os.close(fd)


def sweep_temporary(folder: Path) -> list[str]:
    """Remove temporary motion files left by workers that were killed; returns their names."""
    removed = []
    with contextlib.suppress(OSError):
        for entry in os.scandir(folder):
            if _STAGING_TMP.match(entry.name) and entry.is_file(follow_symlinks=False):
                with contextlib.suppress(OSError):
                    Path(entry.path).unlink()
                    removed.append(entry.name)
    return removed


def _regular_file(path: Path) -> bool:
    try:
        return stat.S_ISREG(path.lstat().st_mode)
    except OSError:
        return False


def reconcile(folder: Path, jobs: list[Job], records: dict[tuple[str, str], dict[str, Any]], *,
              verify: bool) -> list[str]:
    """Make the index (``records``, changed in place) and the motion files of ``jobs`` agree;
    returns one note per change.

    A record that names a motion file which is missing is dropped (its item is planned again).
    A job's motion file that no record names is removed: a worker wrote it and was stopped (or
    the batch was killed) before its record reached the index. With ``verify`` the file's
    sha256 must also be the record's, else both go (a stopped run replaced the file).
    """
    notes: list[str] = []
    for key, rec in list(records.items()):
        motion = rec.get("motion")
        if motion is not None and not _regular_file(folder / motion):
            del records[key]
            notes.append(f"record of {motion} dropped (the file is missing)")
    for job in jobs:
        path = folder / job.motion_name
        if not _regular_file(path):
            continue
        known = records.get(job.key)
        named = known is not None and known.get("motion") == job.motion_name
        if named and verify and known is not None:
            from robots import file_sha256

            try:
                named = file_sha256(path) == known.get("sha256")
            except OSError:
                named = False
            if not named:
                del records[job.key]
        if not named:
            with contextlib.suppress(FileNotFoundError):
                path.unlink()
            notes.append(f"{job.motion_name} removed (no record of it in the index)")
    return notes


def run_batch(plan: BatchPlan, progress: Any) -> BatchOutcome:
    """Run a checked batch; see the module docstring. Ctrl-C and SIGTERM propagate after the
    index and the summary were written."""
    from viz import atomic_write_text
    from wbmp.batch.backends import LocalPool, RayPool

    t0 = time.perf_counter()
    folder = plan.out_dir
    folder.mkdir(exist_ok=True)  # 0o777 & ~umask; the parent was checked
    index_path, summary_path = folder / INDEX, folder / SUMMARY
    with _locked(folder):
        sweep_temporary(folder)
        old, damaged = read_index_report(index_path)
        if damaged:
            more = f" (and {len(damaged) - 3} more)" if len(damaged) > 3 else ""
            progress(f"{index_path}: {len(damaged)} damaged line{'s' if len(damaged) > 1 else ''} left out, "
                     f"their items are planned again: {'; '.join(damaged[:3])}{more}")
        for note in reconcile(folder, plan.jobs, old, verify=False):  # what a killed batch left
            progress(f"{folder}: {note}")
        records = dict(old)
        todo: list[Job] = []
        skipped = 0
        for job in plan.jobs:
            if not plan.force and is_done(old.get(job.key), job, folder, retry_failed=plan.retry_failed):
                records[job.key] = {**old[job.key], "skipped": True}
                skipped += 1
            else:
                todo.append(job)
        state = {"done": 0, "ok": 0, "failed": 0}
        total = len(todo)
        backend = (RayPool(plan.workers, folder, plan.simulate, plan.ray_address, cache=plan.cache) if plan.ray
                   else LocalPool(plan.workers, folder, plan.simulate, cache=plan.cache))
        writer = IndexWriter(index_path)

        fresh: set[tuple[str, str]] = set()

        def on_record(record: dict[str, Any]) -> None:
            fresh.add((record["id"], record["robot"]))
            record["skipped"] = False
            record["backend"] = backend.name
            record["finished"] = datetime.now(UTC).isoformat(timespec="seconds")
            writer.append(record)
            records[(record["id"], record["robot"])] = record
            state["done"] += 1
            state["ok" if record["status"] == "ok" else "failed"] += 1
            what = "ok" if record["status"] == "ok" else f"failed (exit {record['exit_code']})"
            message = (f"[{state['done']}/{total}] {record['id']} on {record['robot']}: {what} "
                       f"in {record['timings'].get('total', 0.0):.1f} s; {state['ok']} ok, {state['failed']} failed")
            _report(progress, state["done"] / max(total, 1), message)

        title = f"{plan.file} ({len(plan.jobs)} jobs)"
        try:
            with progress.stage(f"batch of {total} jobs on {plan.workers} "
                                f"{'Ray ' if plan.ray else ''}worker{'s' if plan.workers > 1 else ''}"):
                if skipped:
                    progress(f"{skipped} of {len(plan.jobs)} jobs done before (index and motion files checked): skipped")
                if todo:
                    backend.run(todo, on_record)
        finally:
            writer.close()
            sweep_temporary(folder)
            # a job stopped after its file was written, before its record came back
            reconcile(folder, [job for job in todo if job.key not in fresh], records, verify=True)
            ordered = final_records(plan.jobs, records)
            ours = {job.key for job in plan.jobs}
            pending = sum(1 for job in plan.jobs if job.key not in records)
            atomic_write_text(index_path, index_text(ordered))
            atomic_write_text(summary_path, summary_text([r for r in ordered if (r["id"], r["robot"]) in ours],
                                                         title=title, pending=pending))
    mine = [records[job.key] for job in plan.jobs if job.key in records]
    counts = {"jobs": len(plan.jobs), "items": plan.n_items, "ok": sum(r["status"] == "ok" for r in mine),
              "failed": sum(r["status"] != "ok" for r in mine), "skipped": skipped, "ran": state["done"]}
    return BatchOutcome(records=mine, ran=state["done"], skipped=skipped, pending=0,
                        wall_time=time.perf_counter() - t0, index_path=index_path, summary_path=summary_path,
                        counts=counts)


def _report(progress: Any, fraction: float, message: str) -> None:
    if getattr(progress, "mode", "bar") == "json":
        progress.update(fraction, message)
        return
    progress.update(fraction)
    progress(message)
