"""One job of a batch, in a worker process: exactly what ``wbmp solve --out FILE`` does.

:func:`run_job` never raises for a failed item: the exception is classified with
:func:`wbmp.errors.classify` (the code ``wbmp solve`` would exit with) and returned in the
record with its one-line message; an exception that has no exit code (a bug) is recorded as
exit 1 with its type and message. Only Ctrl-C and SIGTERM propagate, after the motion file's
temporary file was removed (the write goes through :class:`viz.files.Staging`).

With ``cache`` (the default of ``wbmp batch``; off with ``--no-cache``) a job is answered from
the motion cache (:mod:`wbmp.motioncache`, ``$WBMP_CACHE_DIR/motions``) when it holds this
request, and a fresh result is stored there, exactly as ``wbmp solve`` does: a library built
again (another folder, or after ``--force``) costs a read and a write per item.

Test-only hook: :data:`DEATH_VARIABLE` (``WBMP_TEST_WORKER_DEATH=HOW:ID``, HOW one of ``exit``,
``kill``, ``segv``) makes the worker that plans the item with id ID die when it commits that
item's motion file — after the temporary file was written, before it is renamed into place —
by ``os._exit(70)``, SIGKILL, or a real segmentation fault. It exists to test the worker-death
path with real processes; nothing in a batch file or on the command line can trigger it, and it
is not a user setting.

This module imports nothing heavy at the top: a worker process sets its thread limits in
:func:`init_worker` before numpy, CasADi or MuJoCo load their BLAS.
"""

from __future__ import annotations

import contextlib
import json
import os
import socket
import tempfile
import time
from pathlib import Path
from typing import Any

from robots import file_sha256

#: BLAS/OpenMP thread variables set to 1 in every worker (as ``wbmp.cli.run`` does for one solve):
#: the workers are the parallelism, and a second thread per worker only competes for the cores.
THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
#: Test-only: ``HOW:ID`` kills the worker planning item ID at its motion file's commit (module docstring).
DEATH_VARIABLE = "WBMP_TEST_WORKER_DEATH"
_DEATHS = ("exit", "kill", "segv")


def worker_env() -> dict[str, str]:
    """Environment variables every worker gets: one BLAS thread unless the user chose."""
    return {name: os.environ.get(name, "1") for name in THREAD_VARIABLES}


def init_worker() -> None:
    """Set up a local-pool worker: one BLAS thread; SIGTERM unwinds (no temporary file left),
    SIGINT too (Ctrl-C reaches the whole process group)."""
    import signal

    for name, value in worker_env().items():
        os.environ.setdefault(name, value)

    def _on_signal(signum, frame) -> None:  # noqa: ARG001 - the signal-handler signature
        from wbmp.errors import Terminated, note_signal

        note_signal(signum)
        if signum == signal.SIGTERM:
            signal.signal(signal.SIGTERM, signal.SIG_IGN)
            raise Terminated()
        raise KeyboardInterrupt()

    signal.signal(signal.SIGTERM, _on_signal)
    signal.signal(signal.SIGINT, _on_signal)


def _where() -> str:
    return f"{socket.gethostname()}:{os.getpid()}"


def failure_record(job: Any, code: int, message: str, *, elapsed: float = 0.0) -> dict[str, Any]:
    """The record of a job that failed outside the solver (a crashed worker, a lost task)."""
    return {
        "id": job.item.id, "robot": job.robot_label, "line": job.item.line, **job.item.source(),
        "status": "failed", "exit_code": int(code), "certificate": None, "message": message,
        "timings": {"total": round(elapsed, 4)}, "cached": False, "motion": None, "sha256": None,
        "input_sha256": job.input_sha256, "worker": None,
    }


def _die(how: str) -> None:
    """End this process the hard way (test-only, :data:`DEATH_VARIABLE`)."""
    import signal
    import sys

    sys.stdout.flush()
    sys.stderr.flush()
    if how == "kill":
        os.kill(os.getpid(), signal.SIGKILL)
    elif how == "segv":
        import ctypes

        ctypes.string_at(0)  # a read of address 0: SIGSEGV in native code
    os._exit(70)


@contextlib.contextmanager
def _death_hook(item_id: str) -> Any:
    """Test-only (:data:`DEATH_VARIABLE`): while active, committing this item's motion file kills
    the process after the temporary file was written."""
    value = os.environ.get(DEATH_VARIABLE, "")
    how, _, target = value.partition(":")
    if how not in _DEATHS or target != item_id:
        yield
        return
    from viz import Staging

    original = Staging.commit

    def commit(self: Any, *args: Any, **kwargs: Any) -> Any:
        _die(how)
        return original(self, *args, **kwargs)  # pragma: no cover - _die does not return

    Staging.commit = commit  # type: ignore[method-assign]
    try:
        yield
    finally:
        Staging.commit = original  # type: ignore[method-assign]


def _retarget(item: Any, robot: str, simulate: bool, cache: bool) -> Any:
    """A clip of a folder of clips, retargeted as ``wbmp retarget`` does (through the motion cache
    with ``cache``)."""
    from wbmp.retarget import RetargetRequest, retarget

    return retarget(RetargetRequest(clip=item.clip_path, robot=robot, simulate=simulate, start=item.start,
                                    end=item.end), cache=cache)


def run_job(job: Any, out_dir: str, simulate: bool, cache: bool = True) -> dict[str, Any]:
    """Plan (and simulate) one job, write its motion file, return its index record; with
    ``cache``, answered from (and stored into) the motion cache as ``wbmp solve`` does."""
    from wbmp.errors import ExitCode, check_signals, classify, clear_signals, one_line
    from wbmp.outputs import write_outputs
    from wbmp.pipeline import SolveRequest, solve

    clear_signals()
    t_start = time.perf_counter()
    item = job.item
    record: dict[str, Any] = {
        "id": item.id, "robot": job.robot_label, "line": item.line, **item.source(),
        "status": "failed", "exit_code": int(ExitCode.INTERNAL), "certificate": None, "message": "",
        "timings": {}, "cached": False, "motion": None, "sha256": None, "input_sha256": job.input_sha256,
        "worker": _where(),
    }
    target = Path(out_dir) / job.motion_name
    with contextlib.ExitStack() as stack:
        spec_path = item.spec_path
        if item.spec_object is not None:  # a spec object of a JSONL line: the solver reads a file
            folder = stack.enter_context(tempfile.TemporaryDirectory(prefix="wbmp-batch-spec-"))
            spec_path = str(Path(folder) / "spec.json")
            Path(spec_path).write_text(json.dumps(item.spec_object, ensure_ascii=False), encoding="utf-8")
        request = SolveRequest(instruction=item.instruction, spec_path=spec_path, scene_path=item.scene_path,
                               robot=job.robot, simulate=simulate)
        try:
            result = solve(request, cache=cache) if item.clip_path is None else _retarget(item, job.robot, simulate, cache)
            code = int(result.exit_code)
            t0 = time.perf_counter()
            with _death_hook(item.id):
                write_outputs(result, out=str(target))
            check_signals()
            record["timings"] = {k: round(v, 4) for k, v in result.timings.items()}
            record["timings"]["write"] = round(time.perf_counter() - t0, 4)
            record["exit_code"] = code
            record["cached"] = result.cached is not None
            record["status"] = "ok" if code == 0 else "failed"
            if result.execution is not None and result.execution.certificate is not None:
                cert = result.execution.certificate
                record["certificate"] = "pass" if cert.ok else "fail"
                if getattr(cert, "figures", None):  # the evaluation figures (docs/safety.md)
                    record["figures"] = {k: round(float(v), 6) for k, v in cert.figures.items()}
                if not cert.ok:
                    record["message"] = one_line(f"simulation check failed: {cert.reason}")
            figures = getattr(result, "figures", None)  # a clip's (wbmp.retarget.RetargetResult)
            if figures is not None:
                exec_figures = getattr(result, "exec_figures", None)
                record["retarget"] = {"plan": figures.to_dict(),
                                      "execution": None if exec_figures is None else exec_figures.to_dict()}
            record["motion"] = job.motion_name
            record["sha256"] = file_sha256(target)
        except Exception as exc:  # noqa: BLE001 - every failure of one item is recorded, the batch goes on
            check_signals()  # an interrupt a library turned into its own error stops the batch
            mapped = classify(exc)
            if mapped is None:
                record["exit_code"] = int(ExitCode.INTERNAL)
                record["message"] = one_line(f"internal error: {type(exc).__name__}: {exc}")
            else:
                record["exit_code"] = int(mapped)
                record["message"] = one_line(str(exc))
            with contextlib.suppress(OSError):  # a motion of an earlier run is not this item's result
                target.unlink()
    record["timings"]["total"] = round(time.perf_counter() - t_start, 4)
    return record


