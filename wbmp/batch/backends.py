"""Where the jobs of a batch run: a local process pool, or a Ray cluster.

Both keep at most ``workers`` jobs in flight, hand each finished record to ``on_record`` in the
calling (main) thread, and stop their workers when the batch stops (Ctrl-C, SIGTERM):
:meth:`Backend.run` returns normally only when every job has a record.

* :class:`LocalPool`: ``concurrent.futures.ProcessPoolExecutor`` on a ``spawn`` context (a fresh
  interpreter per worker: each loads its own robots and solver caches; no state forked from the
  parent's threads). A worker that dies (killed, out of memory, a crash in native code) breaks
  the pool: the jobs that were in flight are run again one at a time in a fresh one-worker pool,
  so that the job that kills its worker is the one recorded (exit 1, "the worker process
  died"), and the batch goes on.
* :class:`RayPool`: one Ray task per job (``num_cpus=1``); a worker that dies is retried once by
  Ray, then recorded. Without an address, ``ray.init()`` starts a local instance with
  ``num_cpus=workers``, no dashboard and no worker logs on the terminal; it is shut down at the
  end. With an address, the cluster must have wbmp installed.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Any

from wbmp.batch.worker import DEATH_VARIABLE, failure_record, init_worker, run_job, worker_env

OnRecord = Callable[[dict[str, Any]], None]

WORKER_DIED = ("the worker process died while planning this item (killed by a signal, out of memory, "
               "or a crash in native code)")
#: How long stopped workers get to remove their temporary files before they are killed [s].
STOP_GRACE = 10.0


def run_job_local(job: Any, out_dir: str, simulate: bool, cache: bool) -> dict[str, Any]:
    """:func:`run_job` in a local-pool worker: on SIGTERM the job unwinds (its temporary file is
    removed), then the worker exits at once (no traceback from the pool's loop)."""
    from wbmp.errors import Terminated

    global _BUSY
    _BUSY = True
    try:
        return run_job(job, out_dir, simulate, cache)
    except (Terminated, KeyboardInterrupt):
        os._exit(143)
    finally:
        _BUSY = False


_BUSY = False


def init_local_worker() -> None:
    """Local-pool worker set-up: thread limits; SIGINT ignored (the parent stops the workers);
    SIGTERM unwinds a running job, or ends an idle worker at once."""
    import signal

    init_worker()

    def _on_term(signum, frame) -> None:  # noqa: ARG001 - the signal-handler signature
        if not _BUSY:
            os._exit(143)
        from wbmp.errors import Terminated

        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        raise Terminated()

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, _on_term)


class Backend:
    """Runs jobs; see the module docstring."""

    name = "?"

    def run(self, jobs: list[Any], on_record: OnRecord) -> None:
        """Run every job, calling ``on_record`` with each record as it finishes."""
        raise NotImplementedError


class LocalPool(Backend):
    """A local process pool of ``workers`` processes."""

    name = "local"

    def __init__(self, workers: int, out_dir: Path, simulate: bool, cache: bool = True) -> None:
        self.workers = workers
        self.out_dir = str(out_dir)
        self.simulate = simulate
        self.cache = cache

    def _pool(self, workers: int) -> ProcessPoolExecutor:
        import multiprocessing

        return ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
                                   initializer=init_local_worker)

    def run(self, jobs: list[Any], on_record: OnRecord) -> None:  # noqa: D102 - see Backend.run
        pending = list(reversed(jobs))
        suspects: list[Any] = []
        pool = self._pool(self.workers)
        try:
            in_flight: dict[Future, tuple[Any, float]] = {}
            while pending or in_flight:
                while pending and len(in_flight) < self.workers:
                    job = pending.pop()
                    in_flight[pool.submit(run_job_local, job, self.out_dir, self.simulate, self.cache)] = (job, time.perf_counter())
                done, _ = wait(in_flight, return_when=FIRST_COMPLETED)
                broken = False
                for fut in done:
                    job, _start = in_flight.pop(fut)
                    try:
                        record = fut.result()
                    except BrokenProcessPool:
                        broken = True
                        suspects.append(job)
                        continue
                    except Exception as e:  # noqa: BLE001 - e.g. a record that cannot be sent back
                        record = failure_record(job, 1, f"internal error: {type(e).__name__}: {e}",
                                                elapsed=time.perf_counter() - _start)
                    on_record(record)
                if broken:  # every job in flight is lost with the pool: each is a suspect
                    suspects.extend(job for job, _ in in_flight.values())
                    in_flight.clear()
                    _stop(pool)
                    pool = self._pool(self.workers)
        finally:
            _stop(pool)
        for job in suspects:  # one at a time: the job that kills its worker is the one recorded
            t0 = time.perf_counter()
            single = self._pool(1)
            try:
                on_record(single.submit(run_job_local, job, self.out_dir, self.simulate, self.cache).result())
            except BrokenProcessPool:
                on_record(failure_record(job, 1, WORKER_DIED, elapsed=time.perf_counter() - t0))
            finally:
                _stop(single)


def _stop(pool: ProcessPoolExecutor) -> None:
    """Stop a pool now: SIGTERM to its workers (a running job removes its temporary file and the
    worker exits), SIGKILL to one still alive after :data:`STOP_GRACE`."""
    processes = list(getattr(pool, "_processes", {}).values())  # no public API before Python 3.14
    pool.shutdown(wait=False, cancel_futures=True)
    for proc in processes:
        if proc.is_alive():
            proc.terminate()
    deadline = time.monotonic() + STOP_GRACE
    for proc in processes:
        proc.join(max(0.0, deadline - time.monotonic()))
        if proc.is_alive():
            proc.kill()
            proc.join(5.0)


def local_pythonpath() -> str:
    """The folder wbmp is imported from (and the current path), for workers of a local Ray."""
    import wbmp

    root = str(Path(wbmp.__file__).resolve().parents[1])
    rest = os.environ.get("PYTHONPATH", "")
    return os.pathsep.join([root, rest]) if rest else root


class RayPool(Backend):
    """Ray tasks, on a local instance (``address`` None) or a running cluster."""

    name = "ray"

    def __init__(self, workers: int, out_dir: Path, simulate: bool, address: str | None, cache: bool = True) -> None:
        self.workers = workers
        self.out_dir = str(out_dir)
        self.simulate = simulate
        self.address = address
        self.cache = cache

    def run(self, jobs: list[Any], on_record: OnRecord) -> None:  # noqa: D102 - see Backend.run
        import ray

        env = worker_env()
        options: dict[str, Any] = {"include_dashboard": False, "log_to_driver": False,
                                   "logging_level": "ERROR", "configure_logging": True}
        if self.address is None:
            env["PYTHONPATH"] = local_pythonpath()
            for name in ("WBMP_CACHE_DIR", "WBMP_COMPILE", "WBMP_COMPILE_BACKGROUND", DEATH_VARIABLE):
                if name in os.environ:
                    env[name] = os.environ[name]
            options["num_cpus"] = self.workers
        else:
            options["address"] = self.address
        ray.init(runtime_env={"env_vars": env}, **options)
        try:
            task = ray.remote(num_cpus=1, max_retries=1)(run_job)
            pending = list(reversed(jobs))
            in_flight: dict[Any, tuple[Any, float]] = {}
            try:
                while pending or in_flight:
                    while pending and len(in_flight) < self.workers:
                        job = pending.pop()
                        in_flight[task.remote(job, self.out_dir, self.simulate, self.cache)] = (job, time.perf_counter())
                    done, _ = ray.wait(list(in_flight), num_returns=1, timeout=1.0)
                    for ref in done:
                        job, start = in_flight.pop(ref)
                        try:
                            record = ray.get(ref)
                        except ray.exceptions.RayError as e:
                            from wbmp.errors import one_line

                            record = failure_record(job, 1, one_line(f"{WORKER_DIED}: {type(e).__name__}: {e}", 400),
                                                    elapsed=time.perf_counter() - start)
                        on_record(record)
            finally:
                for ref in in_flight:  # stopped (Ctrl-C, SIGTERM): the sweep removes their temporary files
                    ray.cancel(ref, force=True)
        finally:
            ray.shutdown()
