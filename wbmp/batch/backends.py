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

  Process hygiene: each worker leads its own process group (what it starts, a compiler for
  instance, is in it too), so a stop reaches the whole group (``killpg``) and a Ctrl-C typed in
  the terminal reaches the parent only. A stop (the end of the batch, Ctrl-C, SIGTERM) sends
  SIGTERM to each group, and SIGKILL after :data:`STOP_GRACE`. A worker dies with its parent:
  on Linux the kernel sends it SIGKILL when the parent dies (``prctl(PR_SET_PDEATHSIG)``, set
  in the worker's initializer, which then checks that the parent did not die before), and
  elsewhere a thread polls the parent's pid. The pool's resource tracker ends when the last of
  them has gone (it reads a pipe they hold).
* :class:`RayPool`: one Ray task per job (``num_cpus=1``); a worker that dies is retried once by
  Ray, then recorded. Without an address, ``ray.init()`` starts a local instance with
  ``num_cpus=workers``, no dashboard and no worker logs on the terminal; it is shut down at the
  end. With an address, the cluster must have wbmp installed.
"""

from __future__ import annotations

import contextlib
import os
import signal
import threading
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
#: How long stopped workers get to remove their temporary files before they are killed [s]
#: (what a killed worker leaves, the batch's sweep removes).
STOP_GRACE = 1.0
#: How often a worker checks that its parent is alive where the kernel cannot tell it [s].
PARENT_POLL = 0.5
#: ``prctl`` option: the signal this process gets when its parent dies (linux/prctl.h).
_PR_SET_PDEATHSIG = 1


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


def die_with_parent(parent: int) -> None:
    """End this process when process ``parent`` (its parent) dies: SIGKILL from the kernel on
    Linux (``PR_SET_PDEATHSIG``), else a daemon thread polling the parent's pid; if the parent
    is already gone, exit now."""
    import sys

    armed = False
    if sys.platform.startswith("linux"):
        import ctypes

        try:
            libc = ctypes.CDLL(None, use_errno=True)
            armed = libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0) == 0
        except (OSError, AttributeError):  # pragma: no cover - a libc without prctl
            armed = False
    if os.getppid() != parent:  # the parent died before the request reached the kernel
        os._exit(143)
    if armed:
        return

    def watch() -> None:  # pragma: no cover - not Linux
        while os.getppid() == parent:
            time.sleep(PARENT_POLL)
        os._exit(143)

    threading.Thread(target=watch, name="wbmp-parent-watch", daemon=True).start()


def init_local_worker(parent: int | None = None) -> None:
    """Local-pool worker set-up: its own process group; death with the parent (``parent``, its
    pid); thread limits; SIGINT ignored (the parent stops the workers); SIGTERM unwinds a running
    job, or ends an idle worker at once."""
    if parent is not None:
        die_with_parent(parent)
    with contextlib.suppress(OSError):  # already a group leader (or not allowed): the pid is used
        os.setpgid(0, 0)
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
                                   initializer=init_local_worker, initargs=(os.getpid(),))

    def run(self, jobs: list[Any], on_record: OnRecord) -> None:  # noqa: D102 - see Backend.run
        pending = list(reversed(jobs))
        suspects: list[Any] = []
        pool = self._pool(self.workers)
        in_flight: dict[Future, tuple[Any, float]] = {}
        try:
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
            for fut in in_flight:  # stopped: keep the results that came back
                if fut.done() and not fut.cancelled() and fut.exception() is None:
                    on_record(fut.result())
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
    """Stop a pool now: SIGTERM to each worker's process group (a running job removes its
    temporary file and the worker exits), SIGKILL to the groups still alive after
    :data:`STOP_GRACE`."""
    processes = list(getattr(pool, "_processes", {}).values())  # no public API before Python 3.14
    pool.shutdown(wait=False, cancel_futures=True)
    for proc in processes:
        _signal_group(proc, signal.SIGTERM)
    deadline = time.monotonic() + STOP_GRACE
    for proc in processes:
        proc.join(max(0.0, deadline - time.monotonic()))
    for proc in processes:  # the groups too: what a worker started outlives it otherwise
        _signal_group(proc, signal.SIGKILL)
    for proc in processes:
        proc.join(5.0)


def _signal_group(proc: Any, sig: int) -> None:
    """Send ``sig`` to a worker and its process group (the worker leads it; see the module)."""
    pid = proc.pid
    if pid is None:
        return
    with contextlib.suppress(OSError):  # no such group: the worker has not set it up yet, or all are gone
        os.killpg(pid, sig)
    with contextlib.suppress(OSError, ValueError):
        if proc.exitcode is None:
            os.kill(pid, sig)


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
        from wbmp.batch.raynet import driver, parse_address

        address = None if self.address is None else parse_address(self.address)
        local = address is None or address.on_loopback
        with driver(local=local):
            self._run(jobs, on_record, None if address is None else address.target, local=local)

    def _run(self, jobs: list[Any], on_record: OnRecord, address: str | None, *, local: bool) -> None:
        import ray

        from wbmp.batch.raynet import LOOPBACK, LOOPBACK_ENV
        from wbmp.errors import CliError, ExitCode, one_line

        env = worker_env()
        options: dict[str, Any] = {"include_dashboard": False, "log_to_driver": False,
                                   "logging_level": "ERROR", "configure_logging": True}
        if local:  # this machine's instance: node address 127.0.0.1, its workers keep to it too
            env.update(LOOPBACK_ENV)
            options["_node_ip_address"] = LOOPBACK
        if address is None:
            env["PYTHONPATH"] = local_pythonpath()
            for name in ("WBMP_CACHE_DIR", "WBMP_COMPILE", "WBMP_COMPILE_BACKGROUND", DEATH_VARIABLE):
                if name in os.environ:
                    env[name] = os.environ[name]
            options["num_cpus"] = self.workers
        else:
            options["address"] = address
        on_term = signal.getsignal(signal.SIGTERM)
        try:
            ray.init(runtime_env={"env_vars": env}, **options)
        except (Exception, SystemExit) as e:  # Ray's connection errors, and its sys.exit
            if isinstance(e, SystemExit) and e.code == signal.SIGTERM:  # Ray's handler met a SIGTERM
                from wbmp.errors import Terminated

                raise Terminated() from None
            if address is None:
                raise
            raise CliError(f"--ray {address!r}: cannot join the cluster: {one_line(str(e) or type(e).__name__, 300)}",
                           ExitCode.USAGE) from None
        finally:  # ray.init makes SIGTERM a sys.exit(15): the CLI's handler (exit 143, clean-up) is put back
            if on_term is not None and threading.current_thread() is threading.main_thread():
                signal.signal(signal.SIGTERM, on_term)
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
