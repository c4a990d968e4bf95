"""A ``wbmp serve`` session: the motions made so far, the job queue and the planning process.

One plan at a time: a job waits in a bounded queue (:data:`MAX_WAITING`; beyond it the page is
told to wait, HTTP 429) and one dispatcher thread hands jobs to the planning process
(:mod:`wbmp.serve.worker`) in order. What a job is follows from its words, read when its turn
comes (so "slower" after "squat" acts on the squat even when typed while the squat plans):

- a correction (:mod:`wbmp.serve.corrections`): the last motion's actions, changed;
- "then <sentence>": the sentence's actions, planned from where the last motion ended (its last
  knot, at rest: :mod:`wbmp.continuation`); when the robot ends holding or having moved an
  object, the last motion's actions and the sentence's are planned together from where the last
  one started; when it does not end standing on both feet, the continuation is refused in words;
- "undo": the motion the last correction started from becomes the last motion (no plan);
- anything else: a new sentence.

Every motion's files are in its own folder under the session's folder, named by an opaque id
that the page uses to ask for them; no path from the page reaches the file system.
"""

from __future__ import annotations

import collections
import contextlib
import os
import secrets
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from wbmp.errors import Busy, CorrectionError, Unavailable
from wbmp.serve import corrections

MAX_WAITING = 2  # jobs waiting behind the running one; more is refused (429)
MAX_JOBS_KEPT = 100  # finished jobs remembered for the page
MAX_MOTIONS = 200  # motions of one session (their files stay until the server stops)
MAX_PROGRESS = 40  # progress lines kept per job
WORKER_START_TIMEOUT = 600.0  # seconds for the planning process to import its libraries


def new_id() -> str:
    """An opaque id: 12 hexadecimal digits."""
    return secrets.token_hex(6)


@dataclass
class Motion:
    """One planned motion of the session."""

    id: str
    text: str  # what it is: the sentence, "squat (slower)", "squat, then wave"
    kind: str  # sentence, correction, continuation, again
    folder: Path
    summary: dict[str, Any]
    parent: str | None = None
    changes: list[dict[str, Any]] = field(default_factory=list)
    said: str = ""  # what was typed
    created: float = field(default_factory=time.time)

    def brief(self) -> dict[str, Any]:
        """The history entry of the page."""
        cert = self.summary.get("certificate")
        return {"id": self.id, "text": self.text, "said": self.said or self.text, "kind": self.kind,
                "parent": self.parent,
                "changes": self.changes, "certified": None if cert is None else bool(cert["ok"]),
                "cached": self.summary.get("cached"), "seconds": self.summary.get("total_seconds"),
                "duration": self.summary.get("duration")}

    def full(self) -> dict[str, Any]:
        """Everything the page shows of it."""
        return {**self.brief(), **self.summary}


@dataclass
class Job:
    """One request of the page."""

    id: str
    text: str
    state: str = "queued"  # queued, running, done, error, cancelled
    kind: str = ""
    progress: collections.deque = field(default_factory=lambda: collections.deque(maxlen=MAX_PROGRESS))
    error: str = ""
    exit_code: int = 0
    motion: str | None = None
    changes: list[dict[str, Any]] = field(default_factory=list)
    plots_of: str | None = None  # a job that draws this motion's plots
    stopping: bool = False  # stop was pressed while it ran
    submitted: float = field(default_factory=time.monotonic)
    started: float | None = None
    finished: float | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON form for the page."""
        end = self.finished if self.finished is not None else time.monotonic()
        return {"id": self.id, "text": self.text, "state": self.state, "kind": self.kind,
                "progress": list(self.progress), "error": self.error, "exit_code": self.exit_code,
                "motion": self.motion, "changes": self.changes,
                "seconds": None if self.started is None else end - self.started}


class Session:
    """The server's state; thread-safe (one lock), with one dispatcher thread and one child
    process that plans.

    Args:
        robot: Robot name or profile file (None: talos).
        scene: Scene file (None: no scene).
        library: A motion library folder (``--motions``: BVH clips with a ``clips.csv``) a
            sentence that names no known action is looked up in, or None.
        folder: Where the motions' folders go; None = a new temporary folder, removed by
            :meth:`close`.
    """

    def __init__(self, *, robot: str | None = None, scene: str | None = None, folder: str | Path | None = None,
                 start_worker: bool = True, library: str | None = None) -> None:
        self.robot = robot
        self.scene = scene
        self.library = library
        self._own_folder = folder is None
        self.folder = Path(tempfile.mkdtemp(prefix="wbmp-serve-")) if folder is None else Path(folder)
        self._lock = threading.Lock()
        self._wake = threading.Condition(self._lock)
        self._queue: collections.deque[Job] = collections.deque()
        self.jobs: collections.OrderedDict[str, Job] = collections.OrderedDict()
        self.motions: dict[str, Motion] = {}
        self.history: list[str] = []
        self.last: str | None = None  # the motion corrections act on
        self._running: Job | None = None
        self._closed = False
        self._started = False
        self._worker: Any = None
        self._conn: Any = None
        self.worker_state = "starting"
        self._thread = threading.Thread(target=self._dispatch, name="wbmp-serve-dispatch", daemon=True)
        if start_worker:
            self.start()

    def start(self) -> None:
        """Start the dispatcher and the planning process (once)."""
        with self._lock:
            if self._started or self._closed:
                return
            self._started = True
        self._thread.start()

    # ---- the page's requests -------------------------------------------------------------
    def submit(self, text: str, *, plots_of: str | None = None) -> Job:
        """Queue a job for ``text`` (Busy when the queue is full, Unavailable when closed)."""
        with self._lock:
            if self._closed or self.worker_state == "failed":
                raise Unavailable("the planning process is not running: restart wbmp serve")
            if len(self._queue) >= MAX_WAITING + (0 if self._running is not None else 1):
                raise Busy(f"{len(self._queue) + (self._running is not None)} plans are already waiting or running; "
                           "wait for them, or press stop")
            job = Job(id=new_id(), text=text, plots_of=plots_of, kind="plots" if plots_of else "")
            self.jobs[job.id] = job
            while len(self.jobs) > MAX_JOBS_KEPT:
                oldest = next(iter(self.jobs))
                if self.jobs[oldest].state in ("queued", "running"):
                    break
                self.jobs.pop(oldest)
            self._queue.append(job)
            self._wake.notify_all()
            return job

    def submit_plots(self, motion_id: str) -> Job:
        """Queue the drawing of a motion's plots (KeyError: no such motion; Busy, Unavailable)."""
        motion = self.motion(motion_id)
        if motion is None:
            raise KeyError(motion_id)
        job = self.submit(f"plots of {motion.text}", plots_of=motion_id)
        return job

    def stop(self) -> int:
        """Cancel the running plan and the waiting ones; returns how many were cancelled."""
        with self._lock:
            n = 0
            while self._queue:
                job = self._queue.popleft()
                job.state, job.finished = "cancelled", time.monotonic()
                n += 1
            running = self._running
            if running is not None and running.state == "running" and self._worker is not None:
                simulating = any(line.startswith("simulating") for line in running.progress)
                running.progress.append("E-stop: bringing the robot to rest" if simulating else "stopping")
                running.stopping = not simulating
                self._interrupt(estop=simulating)
                n += 1
            return n

    def _interrupt(self, *, estop: bool = False) -> None:
        """SIGINT to the planning process: it stops its job as Ctrl-C stops ``wbmp solve``; with
        ``estop`` (the job is simulating) SIGUSR1: the simulation's E-stop, as ``kill -USR1`` to
        ``wbmp solve`` (the robot stands or damps; the motion shows the stop)."""
        with contextlib.suppress(ProcessLookupError, OSError):
            os.kill(self._worker.pid, signal.SIGUSR1 if estop else signal.SIGINT)

    def state(self) -> dict[str, Any]:
        """What the page polls."""
        with self._lock:
            return {
                "robot": self.robot or "talos", "scene": Path(self.scene).name if self.scene else None,
                "motions": Path(self.library).name if self.library else None,
                "worker": self.worker_state,
                "running": None if self._running is None else self._running.to_dict(),
                "waiting": [j.to_dict() for j in self._queue],
                "jobs": [j.to_dict() for j in list(self.jobs.values())[-10:]],
                "history": [self.motions[i].brief() for i in self.history],
                "last": self.last,
            }

    def job(self, job_id: str) -> dict[str, Any] | None:
        """One job's state, or None."""
        with self._lock:
            job = self.jobs.get(job_id)
            return None if job is None else job.to_dict()

    def motion(self, motion_id: str) -> Motion | None:
        """A motion of this session by its id, or None."""
        with self._lock:
            return self.motions.get(motion_id)

    # ---- the dispatcher ------------------------------------------------------------------
    def _start_worker(self) -> None:
        """The planning process: ``python -c`` of :func:`wbmp.serve.worker.child` with two pipes
        (not multiprocessing's spawn, which runs the parent's ``__main__`` again in the child:
        ``python -m wbmp serve`` would start a second server)."""
        from wbmp.serve.worker import Channel

        to_child_r, to_child_w = os.pipe()
        from_child_r, from_child_w = os.pipe()
        root = str(Path(__file__).resolve().parents[2])  # the wbmp the server runs, first on the path
        env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in (root, os.environ.get("PYTHONPATH")) if p)}
        try:
            process = subprocess.Popen(
                [sys.executable, "-c", "import sys; from wbmp.serve.worker import child; "
                 "child(int(sys.argv[1]), int(sys.argv[2]))", str(to_child_r), str(from_child_w)],
                pass_fds=(to_child_r, from_child_w), env=env, stdin=subprocess.DEVNULL)
        finally:
            os.close(to_child_r)
            os.close(from_child_w)
        conn = Channel(from_child_r, to_child_w)
        if not conn.poll(WORKER_START_TIMEOUT) or conn.recv() != ("ready",):
            process.kill()
            process.wait()
            conn.close()
            raise RuntimeError("the planning process did not start")
        with self._lock:
            self._worker, self._conn = process, conn
            self.worker_state = "ready"

    def _dispatch(self) -> None:
        try:
            self._start_worker()
        except Exception:  # noqa: BLE001 - shown on the page, the server keeps serving the files
            with self._lock:
                self.worker_state = "failed"
            return
        while True:
            with self._lock:
                while not self._queue and not self._closed:
                    self._wake.wait()
                if self._closed:
                    return
                job = self._queue.popleft()
                job.state, job.started = "running", time.monotonic()
                self._running = job
            try:
                self._run(job)
            except Exception as exc:  # noqa: BLE001 - a job's failure must not end the dispatcher
                from wbmp.errors import one_line

                self._finish(job, "error", error=one_line(f"{type(exc).__name__}: {exc}"), exit_code=1)
            finally:
                with self._lock:
                    self._running = None

    def _finish(self, job: Job, state: str, *, error: str = "", exit_code: int = 0) -> None:
        with self._lock:
            job.state, job.error, job.exit_code, job.finished = state, error, exit_code, time.monotonic()

    def _run(self, job: Job) -> None:
        from wbmp.errors import ExitCode

        if job.plots_of is not None:
            self._run_plots(job)
            return
        try:
            plan = self._interpret(job)
        except CorrectionError as e:
            self._finish(job, "error", error=str(e), exit_code=int(ExitCode.USAGE))
            return
        except Exception as e:  # a continuation's sentence that does not parse: the CLI's line and code
            from wbmp.errors import classify, one_line

            code = classify(e)
            if code is None:
                raise
            self._finish(job, "error", error=one_line(str(e)), exit_code=int(code))
            return
        if plan is None:  # undo: done already
            return
        request, parent = plan
        folder = self.folder / new_id()
        folder.mkdir(mode=0o700)
        request["folder"] = str(folder)
        request["robot"], request["scene"] = self.robot, self.scene
        if self.library is not None:
            request["motions"] = self.library
        message = self._exchange(job, request)
        if message is None:
            shutil.rmtree(folder, ignore_errors=True)
            return
        if message[0] == "done":
            motion = Motion(id=folder.name, text=request["text"], said=job.text, kind=job.kind, folder=folder,
                            summary=message[1], parent=parent, changes=job.changes)
            with self._lock:
                self.motions[motion.id] = motion
                self.history.append(motion.id)
                self.last = motion.id
                job.motion = motion.id
                while len(self.history) > MAX_MOTIONS:
                    old = self.motions.pop(self.history.pop(0))
                    shutil.rmtree(old.folder, ignore_errors=True)
            self._finish(job, "done", exit_code=int(message[1]["exit_code"]))
            return
        shutil.rmtree(folder, ignore_errors=True)
        if message[0] == "cancelled":
            self._finish(job, "cancelled", error="stopped")
        else:
            self._finish(job, "error", error=message[1], exit_code=message[2])

    def _exchange(self, job: Job, request: dict[str, Any]) -> tuple | None:
        """Send ``request`` to the planning process, note its progress on ``job``; its last
        message, or None when the process died (the job failed, the process is started again)."""
        self._conn.send(request)
        while True:
            try:
                message = self._conn.recv()
            except (EOFError, OSError):
                self._finish(job, "error", error="the planning process ended unexpectedly; it is started again",
                             exit_code=1)
                self._restart_worker()
                return None
            if message[0] != "progress":
                return message
            with self._lock:
                job.progress.append(message[1])
                if job.stopping:  # a stop that came before the job began in the planning process
                    self._interrupt()

    def _run_plots(self, job: Job) -> None:
        motion = self.motion(job.plots_of or "")
        if motion is None:
            self._finish(job, "error", error="no such motion in this session", exit_code=2)
            return
        message = self._exchange(job, {"plots": str(motion.folder)})
        if message is None:
            return
        if message[0] == "done":
            with self._lock:
                motion.summary["plots"] = message[1]["plots"]
                job.motion = motion.id
            self._finish(job, "done")
        elif message[0] == "cancelled":
            self._finish(job, "cancelled", error="stopped")
        else:
            self._finish(job, "error", error=message[1], exit_code=message[2])

    def _restart_worker(self) -> None:
        with self._lock:
            self.worker_state = "starting"
        try:
            self._start_worker()
        except Exception:  # noqa: BLE001
            with self._lock:
                self.worker_state = "failed"

    def _interpret(self, job: Job) -> tuple[dict[str, Any], str | None] | None:
        """The worker's request for ``job`` and the motion it starts from (None for undo)."""
        from tasks import Action

        with self._lock:
            last = self.motions.get(self.last) if self.last else None
        kinds = corrections.parse_correction(job.text)
        rest = corrections.continuation(job.text)
        if kinds is not None:
            if last is None:
                raise CorrectionError(f"'{job.text.strip()}' corrects the last motion, and there is none "
                                      "yet: say a sentence first, e.g. squat twice")
            if kinds == ("undo",):
                job.kind = "undo"
                if last.parent is None or last.parent not in self.motions:
                    raise CorrectionError("nothing to undo: the last motion is not a correction")
                with self._lock:
                    self.last = last.parent
                    job.motion = last.parent
                self._finish(job, "done")
                return None
            current = corrections.Actions(
                actions=tuple(Action(name=a["name"], params=a["params"], overlay=a["overlay"])
                              for a in last.summary["actions"]),
                given=tuple(frozenset(a["given"]) for a in last.summary["actions"]),
                step_duration=last.summary.get("step_duration"))
            if not current.actions:
                raise CorrectionError("the last motion has no actions to correct (it came from a spec "
                                      "or is a clip of the motion library): say a new sentence")
            new, changes = corrections.apply(kinds, current)
            job.kind = "again" if set(kinds) <= {"again", "undo"} else "correction"
            job.changes = [c.to_dict() for c in changes]
            with self._lock:
                job.progress.append("; ".join(c.describe() for c in changes) or "the same actions again")
            name = _name(last.text, job.text)
            return {"text": name, "actions": _wire(new), "step_duration": new.step_duration,
                    "start": last.summary.get("start")}, last.id
        if rest is not None and last is not None:
            return self._continue(job, last, rest)
        job.kind = "sentence"
        return {"text": job.text, "actions": None}, None

    def _continue(self, job: Job, last: Motion, rest: str) -> tuple[dict[str, Any], str]:
        """The worker's request for "then <rest>" after ``last`` (its end: :mod:`wbmp.continuation`)."""
        end = last.summary.get("end") or {"kind": "together", "reason": "the last motion does not say where it ended"}
        job.kind = "continuation"
        if end["kind"] == "refused":
            raise CorrectionError(
                f"'then' starts where the last motion ended, and no motion can start there: {end['reason']}; "
                "correct the last motion, or say a new sentence (it starts standing at the origin)")
        if end["kind"] == "start":
            with self._lock:
                job.progress.append(f"starting where {_brief(last.text)} ended")
            return {"text": rest, "actions": None, "start": end["q"],
                    "step_duration": last.summary.get("step_duration")}, last.id
        if not last.summary.get("actions"):
            raise CorrectionError(
                f"'then' starts where the last motion ended, and no motion can start there: {end['reason']}, and "
                "the last motion has no actions to plan again with this one: say a new sentence")
        with self._lock:
            job.progress.append(f"{end['reason']}: planning it again together with {rest!r}, from where it started")
        from language import parse
        from tasks import MAX_ACTIONS, Action

        added = parse(rest)
        mine = corrections.Actions(
            actions=tuple(Action(name=a["name"], params=a["params"], overlay=a["overlay"])
                          for a in last.summary["actions"]),
            given=tuple(frozenset(a["given"]) for a in last.summary["actions"]))
        both = corrections.Actions(actions=mine.actions + tuple(added.actions),
                                   given=mine.given + tuple(added.given))
        if len(both.actions) > MAX_ACTIONS:
            raise CorrectionError(f"the continuation makes {len(both.actions)} actions; wbmp plans at "
                                              f"most {MAX_ACTIONS} at a time: start a new sentence")
        return ({"text": f"{last.text}, then {rest}", "actions": _wire(both),
                 "step_duration": last.summary.get("step_duration"), "start": last.summary.get("start")}, last.id)

    def close(self) -> None:
        """Stop the dispatcher and the planning process, and remove a temporary folder."""
        with self._lock:
            self._closed = True
            self._wake.notify_all()
            worker, conn = self._worker, self._conn
        if worker is not None:
            with contextlib.suppress(OSError, ValueError, BrokenPipeError):
                conn.send(None)
            try:
                worker.wait(10)
            except subprocess.TimeoutExpired:
                worker.kill()
                worker.wait()
            conn.close()
        if self._own_folder:
            shutil.rmtree(self.folder, ignore_errors=True)


def _brief(text: str) -> str:
    """A motion's name for a progress line, bounded: ``'squat'``."""
    return repr(text if len(text) <= 80 else text[:77] + "...")


def _name(last_text: str, correction: str) -> str:
    """The corrected motion's name: ``squat (slower)``, bounded."""
    from tasks import MAX_TEXT_LENGTH

    base = last_text if len(last_text) < 200 else last_text[:197] + "..."
    return f"{base} ({correction.strip()})"[:MAX_TEXT_LENGTH]


def _wire(actions: corrections.Actions) -> list[dict[str, Any]]:
    """Actions as the worker's job carries them (plain values: the pipe pickles them)."""
    return [{"name": a.name, "overlay": bool(a.overlay), "given": sorted(g),
             "params": {k: v for k, v in a.to_dict()["params"].items() if k in g}}
            for a, g in zip(actions.actions, actions.given, strict=True)]
