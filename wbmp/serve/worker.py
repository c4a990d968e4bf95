"""The planning process of ``wbmp serve``: one child process that plans one job at a time.

The server never plans in its own process: the child keeps the robot, the solvers and the
motion cache warm between jobs, and the stop button sends it SIGINT, which stops the plan the
way Ctrl-C stops ``wbmp solve`` (:func:`wbmp.errors.check_signals`: also when CasADi turned the
interrupt into an IPOPT failure), after which the child waits for the next job.

Messages on the pipes (:class:`Channel`), child to server: ``("ready",)``, ``("progress", text)``, ``("done",
summary)``, ``("error", one_line_message, exit_code)``, ``("cancelled",)``. Server to child: a
job dictionary (:func:`run_job`), or None to end.
"""

from __future__ import annotations

import os
import signal
import time
from pathlib import Path
from typing import Any

_busy = False
_interrupted = False


def _on_sigint(signum, frame) -> None:  # noqa: ARG001 - the signal-handler signature
    global _interrupted
    from wbmp.errors import note_signal

    if not _busy or _interrupted:
        return  # a stop between jobs, or a second one: nothing more to stop
    _interrupted = True
    note_signal(signum)
    raise KeyboardInterrupt()


_stop: Any = None  # the running job's sim.estop.StopRequest (the page's stop during the simulation)


def _on_sigusr1(signum, frame) -> None:  # noqa: ARG001 - the signal-handler signature
    """The stop button while the job simulates: the simulation's E-stop (the robot comes to rest,
    the motion and its certificate say when and how), not a cancelled job."""
    if _stop is not None:
        _stop.request("the page's stop button")


class Channel:
    """Pickled messages over two pipes (``multiprocessing.connection`` framing): ``send``,
    ``recv``, ``poll``, ``close``, as a duplex ``multiprocessing.Pipe`` end."""

    def __init__(self, read_fd: int, write_fd: int) -> None:
        from multiprocessing.connection import Connection

        self._in = Connection(read_fd, writable=False)
        self._out = Connection(write_fd, readable=False)

    def send(self, obj: Any) -> None:
        """Send one message."""
        self._out.send(obj)

    def recv(self) -> Any:
        """The next message (EOFError when the other side is gone)."""
        return self._in.recv()

    def poll(self, timeout: float = 0.0) -> bool:
        """Whether a message arrives within ``timeout`` seconds."""
        return self._in.poll(timeout)

    def close(self) -> None:
        """Close both pipes."""
        self._in.close()
        self._out.close()


def child(read_fd: int, write_fd: int) -> None:
    """Entry point of the planning process (``python -c``; see ``Session._start_worker``)."""
    main(Channel(read_fd, write_fd))


def main(conn: Any) -> None:
    """The child's loop: jobs from ``conn``, messages back on it."""
    global _busy, _interrupted
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    signal.signal(signal.SIGINT, _on_sigint)
    signal.signal(signal.SIGUSR1, _on_sigusr1)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    from wbmp.errors import classify, clear_signals, one_line

    conn.send(("ready",))
    while True:
        try:
            job = conn.recv()
        except (EOFError, OSError, KeyboardInterrupt):
            if _busy:
                continue
            return
        if job is None:
            return
        clear_signals()
        _interrupted = False
        _busy = True
        try:
            report = lambda text: conn.send(("progress", str(text)))  # noqa: E731
            summary = run_plots(job, report) if "plots" in job else run_job(job, report)
            _busy = False
            conn.send(("done", summary))
        except KeyboardInterrupt:
            _busy = False
            conn.send(("cancelled",))
        except Exception as exc:  # noqa: BLE001 - the job's boundary, as the CLI's
            _busy = False
            from wbmp.errors import check_signals

            try:
                check_signals()
            except KeyboardInterrupt:
                conn.send(("cancelled",))
                continue
            code = classify(exc)
            if code is None:
                import traceback

                traceback.print_exc()
                conn.send(("error", f"internal error ({type(exc).__name__}): {one_line(str(exc))}", 1))
            else:
                conn.send(("error", one_line(str(exc)), int(code)))
        finally:
            _busy = False
            clear_signals()


def _actions_plan(job: dict[str, Any]):
    """The job's ActionPlan when it gives actions (a correction, a continuation), else None."""
    if job.get("actions") is None:
        return None
    from language import ActionPlan
    from tasks import Action

    actions = tuple(Action(name=a["name"], params=a["params"], overlay=a["overlay"]) for a in job["actions"])
    return ActionPlan(actions=actions, backend="rules", text=job["text"],
                      given=tuple(frozenset(a["given"]) for a in job["actions"]))


def describe_actions(plan) -> list[dict[str, Any]]:
    """Every action with all its parameters, the stated ones and their units (the page's list and
    the corrections' input)."""
    from tasks import REGISTRY

    out = []
    for i, a in enumerate(plan.actions):
        schema = REGISTRY[a.name]
        out.append({
            "name": a.name, "overlay": bool(a.overlay),
            "params": a.to_dict()["params"],
            "given": sorted(plan.given[i]),
            "units": {p.name: p.unit for p in schema.params},
        })
    return out


def run_job(job: dict[str, Any], progress) -> dict[str, Any]:
    """Plan one job and write its files into ``job["folder"]``; returns the page's summary.

    ``job``: ``text`` (the sentence, or the motion's name for given actions), ``actions`` (None,
    or what :func:`describe_actions` gives), ``robot``, ``scene``, ``folder``, ``step_duration``
    (None: the profile's; else the robot's pace for this plan, "slower" on a walk), ``start``
    (None, or the configuration the motion starts from: "then <sentence>"), ``motions`` (None, or
    the clip library a sentence that names no action is looked up in, as ``wbmp solve --motions``).

    The summary's ``end`` (:func:`wbmp.continuation.end_state`) says whether and how a
    continuation can start where this motion ends.
    """
    from language import LanguageError
    from wbmp.outputs import write_outputs
    from wbmp.pipeline import SolveRequest, solve

    t0 = time.perf_counter()
    folder = Path(job["folder"])
    profile = _profile(job.get("robot"))
    step = job.get("step_duration")
    paced = None
    if step is not None and step != profile.step_duration:
        import dataclasses

        paced = profile = dataclasses.replace(profile, step_duration=float(step))
    global _stop
    from sim import StopRequest

    _stop = StopRequest()
    start = None
    if job.get("start") is not None:
        from tasks import StartState

        start = StartState(q=tuple(float(x) for x in job["start"]))
    request = SolveRequest(instruction=job["text"], scene_path=job.get("scene"), robot=job.get("robot"),
                           actions=_actions_plan(job), profile=paced, stop_request=_stop, start=start)
    clip = None
    try:
        try:
            result = solve(request, progress, cache=True)
        except LanguageError:
            if not job.get("motions") or job.get("actions") is not None:
                raise
            result, clip = _from_library(job, progress)
            if result is None:
                raise  # no clip of the library either: refused as without it
    finally:
        _stop = None
    solved = time.perf_counter() - t0
    write_outputs(result, out=str(folder / "motion.npz"), progress=lambda _: progress("writing the motion file"))
    progress("drawing the replay")
    _write_pages(result, folder)
    report = result.report()
    words = []
    if result.actions is not None and result.actions.words:
        words = result.actions.words_dict()
    elif clip is not None:
        from wbmp.motions import clip_words

        words = [w.to_dict() for w in clip_words(job["text"], clip)]
    certificate = None
    if result.execution is not None and result.execution.certificate is not None:
        certificate = {"ok": bool(result.execution.certificate.ok),
                       "summary": result.execution.certificate.summary(),
                       "checks": report.get("certificate", {}).get("checks", [])}
    return {
        "robot": result.robot_name,
        "actions": describe_actions(result.actions) if result.actions is not None else [],
        "describe": result.actions.describe() if result.actions is not None else _clip_line(clip, job),
        "words": words,
        "plan": result.plan.summary(),
        "certificate": certificate,
        "cached": result.cached is not None,
        "duration": float(result.plan.t[-1]),
        "step_duration": float(profile.step_duration),
        "exit_code": int(result.exit_code),
        "seconds": solved,
        "total_seconds": time.perf_counter() - t0,
        "end": _end(result, job).to_dict(),
        "start": None if start is None else list(start.q),
    }


def _from_library(job: dict[str, Any], progress):
    """(the retargeted clip of the job's motion library that its sentence names, the clip), or
    (None, None); a continuation is refused: a clip starts from its own first frame."""
    from wbmp.motions import load_library, match, retarget_from_library

    clip = match(job["text"], load_library(job["motions"]))
    if clip is None:
        return None, None
    if job.get("start") is not None:
        from wbmp.errors import CliError, ExitCode

        raise CliError(f"{job['text']!r} is the motion-library clip {clip.path.name} ({clip.label}), which starts "
                       "from its own first frame, not where the robot stands: say it as a new sentence",
                       ExitCode.USAGE)
    result = retarget_from_library(job["text"], job["motions"], robot=job.get("robot"), simulate=True,
                                   progress=progress, cache=True)
    return result, clip


def _clip_line(clip, job: dict[str, Any]) -> str:
    if clip is None:
        return ""
    from wbmp.motions import describe_clip

    return describe_clip(clip, Path(job["motions"]).name)


def _end(result, job: dict[str, Any]):
    """Whether "then <sentence>" can start where ``result`` ends (:mod:`wbmp.continuation`)."""
    from wbmp.continuation import end_state

    profile = _profile(job.get("robot"))
    feet = (profile.frame("left_foot") or "left_foot", profile.frame("right_foot") or "right_foot")
    return end_state(result.spec, result.plan, result.execution, feet, profile.sole)


def run_plots(job: dict[str, Any], progress) -> dict[str, Any]:
    """Draw the PNG plots of the motion in ``job["plots"]`` (its folder) into its ``plots``
    folder, as ``wbmp show --plots`` does; returns ``{"plots": [file names]}``."""
    from viz import write_plots
    from wbmp.commands.show import load

    folder = Path(job["plots"])
    progress("loading the motion")
    robot, plan, execution = load(str(folder / "motion.npz"))
    progress("drawing the plots")
    paths = write_plots(folder / "plots", robot, plan, execution=execution)
    return {"plots": [p.name for p in paths]}


def _profile(robot: str | None):
    """The profile of the session's robot (a built-in one without loading its model)."""
    from robots import builtin_profiles, load_robot

    builtins = builtin_profiles()
    name = robot or "talos"
    return builtins[name] if name in builtins else load_robot(name).profile


def _write_pages(result, folder: Path) -> None:
    """``replay.html`` (standalone, the download) and ``view.html`` (the same page, meshcat's
    bundle from the server's ``/static/meshcat.js``: the in-page viewer, cached by the browser)."""
    from viz import page_data, render_page
    from wbmp.motioncache import MotionCache

    data = None
    motions = MotionCache() if result.cache_key is not None else None
    if motions is not None and result.cache_key is not None:
        data = motions.load_page(result.cache_key)
    if data is None:
        data = page_data(result.model(), result.plan, execution=result.execution)
        if motions is not None and result.cache_key is not None:
            motions.store_page(result.cache_key, data)
    title = result.spec.description or result.spec.name
    for name, src in (("replay.html", None), ("view.html", "/static/meshcat.js")):
        text = render_page(data, result.robot_name, result.plan, execution=result.execution, title=title,
                           meshcat_src=src)
        (folder / name).write_text(text, encoding="utf-8")
