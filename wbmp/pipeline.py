"""The end-to-end job: sentence or spec -> actions -> TaskSpec -> Plan -> Execution -> files.

Only this package wires the layers together; each step is a function call into its layer, and
every step reports progress through a small callback so the CLI can show it (or stay quiet).
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from wbmp.errors import CliError, ExitCode

if TYPE_CHECKING:
    from language import ActionPlan
    from planner import Plan
    from robots import Robot, RobotProfile
    from sim import Execution, StopRequest
    from tasks import StartState, TaskSpec
    from wbmp.motioncache import Hit

Progress = Callable[[str], None]


def _silent(_: str) -> None:
    pass


@dataclass(kw_only=True)
class SolveRequest:
    """What ``wbmp solve`` was asked to do.

    Attributes:
        instruction: A sentence (English or Chinese), or None when ``spec_path`` is given.
        spec_path: A TaskSpec JSON file, or None.
        scene_path: A scene JSON file (docs/scenes.md), or None; it replaces the spec's own scene.
        robot: Robot name or profile file; None = the spec's robot (or talos for a sentence).
        parser: ``rules`` or ``llm``.
        llm_options: Options of the LLM backend (url, model, api_key, timeout).
        simulate: Run the controller in MuJoCo and certify the motion.
        push: ``"N@t"`` push on the base during simulation, or None: above 0 N, at most
            ``sim.MAX_PUSH_FORCE``, and a time within the motion (0 <= t < horizon).
        actions: A ``language.ActionPlan`` to plan instead of parsing ``instruction`` (which
            then only names the motion): ``wbmp serve``'s corrections change the actions'
            parameters. Such a request is looked up in the motion cache by its spec only.
        profile: A ``robots.RobotProfile`` to plan a sentence or actions with instead of
            ``robot`` (``wbmp serve``'s "slower" on a walk changes its ``step_duration``).
        estop_at: Stop request at this time of the simulation [s] (``--estop-at``), or None.
        estop_flag: Stop when this file appears during the simulation (``--estop-flag``), or None.
        faults_path: A faults JSON file (``--faults``, docs/safety.md), or None.
        stop_request: A ``sim.estop.StopRequest`` set from outside (SIGUSR1), or None.
        start: A ``tasks.specs.StartState``: the sentence's or actions' motion starts there, at rest
            (``wbmp serve``'s "then <sentence>" from where the last motion ended), or None
            (standing at the origin). Such a request is looked up in the motion cache by its spec only.

    :meth:`check` (called by :func:`solve` first) refuses, with :class:`CliError` exit 2, what
    needs no work to see: an empty ``robot`` or ``scene_path``, an instruction longer than
    ``tasks.limits.MAX_TEXT_LENGTH`` characters, a push without the simulation.
    """

    instruction: str | None = None
    spec_path: str | None = None
    scene_path: str | None = None
    robot: str | None = None
    parser: str = "rules"
    llm_options: dict[str, Any] = field(default_factory=dict)
    simulate: bool = True
    push: str | None = None
    actions: ActionPlan | None = None
    profile: RobotProfile | None = None
    estop_at: float | None = None
    estop_flag: str | None = None
    faults_path: str | None = None
    stop_request: StopRequest | None = None
    start: StartState | None = None

    @property
    def safety(self) -> bool:
        """A stop or faults were asked for: the result is neither read from nor stored in the motion cache."""
        return self.estop_at is not None or self.estop_flag is not None or self.faults_path is not None

    def check(self) -> None:
        """Refuse contradictory or empty options before any work (:class:`CliError`, exit 2)."""
        from wbmp.errors import ROBOT_HINT, require_instruction, require_text

        require_text(self.robot, "--robot", ROBOT_HINT)
        require_text(self.scene_path, "--scene", "give a scene JSON file (docs/scenes.md)")
        require_instruction(self.instruction)
        if self.push is not None and not self.simulate:
            raise CliError("--push needs the simulation: drop --no-sim", ExitCode.USAGE)
        require_text(self.estop_flag, "--estop-flag", "give the path of a file whose appearance stops the motion")
        for value, option in ((self.estop_at, "--estop-at"), (self.estop_flag, "--estop-flag"),
                              (self.faults_path, "--faults")):
            if value is not None and not self.simulate:
                raise CliError(f"{option} needs the simulation: drop --no-sim", ExitCode.USAGE)


@dataclass(kw_only=True)
class SolveResult:
    """Everything the job produced: one typed record whatever its source (a fresh solve or the
    motion cache).

    Attributes:
        spec: The compiled (or read) task spec, with this request's description.
        plan: The plan (a cached one's stats say ``cache="cached"``).
        robot: The robot's model, or None for a cached result until :meth:`model` loads it (a hit
            that writes no page, plot or viewer never loads Pinocchio).
        robot_name: The robot's name (default: ``robot.name``).
        robot_source: What :meth:`model` loads (a name, a profile file or a
            :class:`robots.RobotProfile`; default: ``robot_name``).
        actions: The parsed actions of a sentence, or None for a spec file.
        execution: The simulated execution (a cached one read back from the motion file, with its
            certificate and events), or None without the simulation.
        timings: Wall time of each step [s].
        cached: The :class:`wbmp.motioncache.Hit` the result was read from, or None.
        cache_key: Its motion cache key (also set after a fresh solve that was stored).
        motion_file: The motion file (``.npz`` bytes) of a fresh result stored in the motion cache:
            ``--out`` writes these bytes, compressed once.
    """

    spec: TaskSpec
    plan: Plan
    robot: Robot | None = None
    robot_name: str = ""
    robot_source: str | RobotProfile | None = None
    actions: ActionPlan | None = None
    execution: Execution | None = None
    timings: dict[str, float] = field(default_factory=dict)
    cached: Hit | None = None
    cache_key: str | None = None
    motion_file: bytes | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        if self.robot is not None and not self.robot_name:
            self.robot_name = self.robot.name
        if not self.robot_name:
            raise ValueError("SolveResult needs the robot or its name")

    def model(self) -> Robot:
        """The robot's model (a cached result loads it here, once)."""
        if self.robot is None:
            from robots import load_robot

            self.robot = load_robot(self.robot_source if self.robot_source is not None else self.robot_name)
        return self.robot

    @property
    def exit_code(self) -> ExitCode:
        """0 when planned (and certified when simulated), 5 when the simulation check failed."""
        if self.execution is not None and not self.execution.ok:
            return ExitCode.SIM_FAILED
        return ExitCode.OK

    def report(self) -> dict[str, Any]:
        """The JSON report stored in the motion file and printed by ``--json``."""
        s = self.plan.stats
        out: dict[str, Any] = {
            "robot": self.robot_name,
            "cached": self.cached is not None,
            "instruction": self.spec.description,
            "solver": {
                "status": s.status.name.lower(),
                "iterations": s.iterations,
                "build_time": s.build_time,
                "solve_time": s.solve_time,
                "cache": s.cache,
                "seed": s.seed,
                "n_variables": s.n_variables,
                "n_constraints": s.n_constraints,
            },
            "constraints": [
                {"name": c.name, "violation": c.violation, "tolerance": c.tolerance, "unit": c.unit,
                 "time": c.time, "ok": c.ok}
                for c in self.plan.checks
            ],
            "timings": self.timings,
        }
        if self.actions is not None:
            out["actions"] = self.actions.to_dict()["actions"]
        if self.execution is not None:
            from wbmp.motionfile import execution_report

            out.update(execution_report(self.execution))  # its certificate and events (pushes, falls, E-stops)
        return out


def parse_instruction(request: SolveRequest):
    """Sentence -> ActionPlan with the requested backend."""
    from language import parse

    assert request.instruction is not None  # build_spec parses only a request with a sentence
    options = request.llm_options if request.parser == "llm" else {}
    return parse(request.instruction, backend=request.parser, **options)


def _require_scene(actions) -> None:
    """A sentence that names an object needs ``--scene`` (a usage error, exit 2)."""
    for a in actions:
        ref = a.params.get("object")
        if ref is not None:
            raise CliError(f'{a.name} "{ref}" refers to an object, but there is no scene: give one with --scene FILE '
                           "(docs/scenes.md), e.g. --scene examples/scenes/kitchen.json", ExitCode.USAGE)


def build_spec(request: SolveRequest, progress: Progress = _silent):
    """(robot, spec, actions) for a sentence or a spec file (with the scene file, when given).

    The scene is loaded first (a bad scene file: exit 3 before anything else); a hand target or
    a footstep inside one of its objects is refused before planning (exit 4, naming the object).
    """
    import dataclasses

    from robots import load_robot
    from tasks import check_spec_for_robot, check_spec_in_scene_for_robot, load_spec

    scene = None
    if request.scene_path is not None:
        from tasks import load_scene

        scene = load_scene(request.scene_path)
    if request.spec_path is not None:
        spec = load_spec(request.spec_path)
        robot = load_robot(request.robot or spec.robot)
        if request.robot:
            spec = dataclasses.replace(spec, robot=robot.name)
        if scene is not None:
            spec = dataclasses.replace(spec, scene=scene)
        check_spec_for_robot(spec, robot)  # unknown joints, contacts off the ground: exit 3, before planning
        check_spec_in_scene_for_robot(spec, robot)  # a target inside an object: exit 4, before planning
        return robot, spec, None
    if not request.instruction or not request.instruction.strip():
        raise CliError("give an instruction in quotes, or --spec FILE", ExitCode.USAGE)
    progress("parsing the instruction")
    actions = parse_instruction(request) if request.actions is None else request.actions
    robot = load_robot(request.profile if request.profile is not None else request.robot or "talos")
    from tasks import compile_actions, fit_actions

    # unstated sizes chosen within the robot's limits, once: the printed defaults are the ones compiled
    actions = dataclasses.replace(actions, actions=tuple(fit_actions(actions.actions, robot)))
    if scene is None:
        _require_scene(actions.actions)
    spec = compile_actions(actions.actions, robot, scene=scene, description=request.instruction or "", fitted=True,
                           start=request.start)
    check_spec_for_robot(spec, robot)
    check_spec_in_scene_for_robot(spec, robot)
    return robot, spec, actions


def solve(request: SolveRequest, progress: Progress = _silent, *, cache: bool = False,
          cache_dir: str | Path | None = None, cache_read: bool = True) -> SolveResult:
    """Run the whole job; raises the layers' exceptions (mapped to exit codes by the CLI).

    Ctrl-C or SIGTERM stops it at the next progress message or step, also when a library
    swallowed the interrupt (CasADi turns it into an IPOPT failure): see
    :func:`wbmp.errors.check_signals`.

    Args:
        request: What to do.
        progress: Called with a message at each step.
        cache: Answer from the motion cache when it holds this result, and store a fresh one
            there (:mod:`wbmp.motioncache`; ``wbmp solve`` does unless ``--no-cache``). A
            result read from it has ``cached`` set and a lazily loaded ``robot``.
        cache_dir: The motion cache folder (default ``$WBMP_CACHE_DIR/motions``, else
            ``~/.cache/wbmp/motions``).
        cache_read: With ``cache``, False solves afresh and only stores the result (``wbmp
            solve --plots``: the contact-force plot needs the simulation's contact forces, which
            a motion file does not keep).
    """
    from wbmp.errors import check_signals

    request.check()
    if not cache:
        return _solve(request, progress)
    if request.safety:  # a stop or faults: planned with the solution library, simulated afresh, not stored
        cache_read = False
    from wbmp.motioncache import MotionCache, request_key

    motions = MotionCache(cache_dir)
    t0 = time.perf_counter()
    # given actions or a start state: keyed by the spec
    rkey = request_key(request) if request.actions is None and request.start is None else None
    if rkey is not None and cache_read:
        found = motions.lookup_request(rkey)
        if found is not None:
            hit = motions.load(found.motion)
            if hit is not None:
                check_signals()
                progress("answering from the motion cache")
                return _from_cache(request, hit, None, time.perf_counter() - t0, actions=_stored_actions(found.actions))
    return _solve(request, progress, motions=motions, rkey=rkey, read=cache_read)


def _stored_actions(record: dict[str, Any] | None) -> ActionPlan | None:
    """The parsed actions a request record keeps, or None (a record without them, or damaged:
    the sentence is parsed again)."""
    if record is None:
        return None
    from language import ActionPlan, LanguageError

    try:
        return ActionPlan.from_record(record)
    except LanguageError:
        return None


def _from_cache(request: SolveRequest, hit: Hit, robot: Robot | None, elapsed: float,
                actions: ActionPlan | None = None, spec: TaskSpec | None = None) -> SolveResult:
    """A SolveResult from a verified motion cache entry, with this request's sentence and actions."""
    import dataclasses

    motion = hit.motion
    plan = motion.plan
    if spec is None:
        spec = plan.spec if request.instruction is None else dataclasses.replace(plan.spec,
                                                                                 description=request.instruction)
    if actions is None and request.actions is not None:
        actions = request.actions
    if actions is None and request.instruction is not None:
        actions = parse_instruction(request)  # a request record without its actions (or damaged ones)
    plan = dataclasses.replace(plan, spec=spec, stats=dataclasses.replace(plan.stats, cache="cached"))
    execution = motion.execution
    if execution is not None and execution.certificate is None:
        execution = None  # only certified results are stored: an entry without its certificate is not one
    source = request.profile if request.profile is not None else request.robot or motion.robot_name
    return SolveResult(robot=robot, robot_name=motion.robot_name, robot_source=source, spec=spec, plan=plan,
                       actions=actions, execution=execution, timings={"cache": elapsed}, cached=hit,
                       cache_key=hit.key)


def _solve(request: SolveRequest, progress: Progress, *, motions: Any = None, rkey: str | None = None,
           read: bool = True) -> SolveResult:
    from wbmp.errors import check_signals

    report = progress

    def checked_progress(message: str) -> None:
        check_signals()
        report(message)

    progress = checked_progress

    timings: dict[str, float] = {}
    push = None
    if request.simulate and request.push is not None:
        from sim import parse_push

        push = parse_push(request.push)  # before any work: a typo fails at once (exit 2)
    faults = None
    if request.simulate and request.faults_path is not None:
        from sim import load_faults

        faults = load_faults(request.faults_path)  # before any work: a bad file fails at once (exit 3)
    t0 = time.perf_counter()
    robot, spec, actions = build_spec(request, progress)
    timings["spec"] = time.perf_counter() - t0
    if push is not None:
        from sim import check_push_time

        check_push_time(push, spec.horizon)  # a push after the motion would never act (exit 2)
    if request.simulate:
        _check_safety_times(request, faults, spec.horizon)
    key = digest = files = None
    library = motions is not None  # the solution library goes with the motion cache, hashable robot files or not
    if motions is not None:
        from wbmp.motioncache import motion_key, robot_files, robot_hash

        try:
            files = robot_files(robot)
        except OSError:  # a robot file that cannot be hashed: solved, not cached
            files, motions = None, None
    if motions is not None and files is not None:
        digest = robot_hash(robot, files)
        key = motion_key(spec, digest, simulate=request.simulate, push=push)
        hit = motions.load(key) if read and not request.safety else None
        if hit is not None:  # the same motion from another phrasing (or request)
            if rkey is not None:
                motions.store_request(rkey, key, files, digest, _actions_record(actions))
            progress("answering from the motion cache")
            return _from_cache(request, hit, robot, timings["spec"], actions=actions, spec=spec)
    from planner import plan as plan_motion
    from wbmp.environment import planner_settings

    progress(f"planning {spec.horizon:.1f} s of motion for {robot.name}")
    t0 = time.perf_counter()
    # the user's WBMP_* switches (compile, background, solution library, build memory); without the
    # motion cache (--no-cache), no solution library either: the result of the request alone,
    # whatever was planned before (planner/trajopt/library.py)
    settings = planner_settings() if library else planner_settings(solution_library="off")
    plan = plan_motion(spec, robot, progress=progress, settings=settings)
    check_signals()
    timings["plan"] = time.perf_counter() - t0
    execution = None
    if request.simulate:
        from sim import simulate

        progress("simulating in MuJoCo with the whole-body controller")
        t0 = time.perf_counter()
        execution = simulate(plan, robot, push=push, progress=progress, estop=_estop_settings(request),
                             faults=faults)
        check_signals()
        timings["simulate"] = time.perf_counter() - t0
    result = SolveResult(robot=robot, spec=spec, plan=plan, actions=actions, execution=execution, timings=timings)
    if motions is not None and key is not None and files is not None and digest is not None \
            and plan.ok and (execution is None or execution.ok) and not request.safety:
        # only results that succeeded are stored: a failure is cheap to repeat and worth re-checking
        from wbmp.motionfile import npz_bytes

        result.motion_file = npz_bytes(result_arrays(result))  # compressed once: the cache and --out
        motions.store_file(key, result.motion_file, spec)
        if rkey is not None:
            motions.store_request(rkey, key, files, digest, _actions_record(actions))
        result.cache_key = key
    return result


def _actions_record(actions: ActionPlan | None) -> dict[str, Any] | None:
    return None if actions is None else actions.to_record()


def _estop_settings(request: SolveRequest) -> Any:
    """The simulation's E-stop settings for a request (its stop time, flag file and signal)."""
    from sim import EStopSettings

    return EStopSettings(at=request.estop_at, flag_file=request.estop_flag, request=request.stop_request)


def _check_safety_times(request: SolveRequest, faults: Any, horizon: float) -> None:
    """A stop or a faults push after the motion would never act: ``--estop-at`` exit 2, a push exit 3."""
    if request.estop_at is not None and not 0.0 <= request.estop_at < horizon:
        raise CliError(f"--estop-at {request.estop_at:g}: the motion lasts {horizon:.3g} s; give a time from 0 to "
                       f"below {horizon:.3g} s", ExitCode.USAGE)
    if faults is not None:
        from sim import FaultsError

        for i, p in enumerate(faults.pushes):
            if not p.t < horizon:
                raise FaultsError(f"faults file {request.faults_path!r}: pushes[{i}].t = {p.t:g} s is after the "
                                  f"motion, which lasts {horizon:.3g} s; give a time below {horizon:.3g} s")


_REQUEST_KEYS = ("spec_json", "actions_json", "report_json")  # what result_arrays() rewrites for a cached result


def result_arrays(result: SolveResult) -> dict[str, Any]:
    """The motion file's arrays of a result (a cached result: the stored arrays, with this
    request's spec description, actions and report)."""
    from wbmp.motionfile import motion_arrays

    actions = result.actions.to_dict()["actions"] if result.actions is not None else None
    if result.cached is None:
        return motion_arrays(result.plan, result.model(), execution=result.execution, actions=actions,
                             report=result.report())
    import json

    import numpy as np

    from tasks import spec_to_json
    from wbmp.motionfile import _json_default, plan_report

    arrays = dict(result.cached.arrays)
    full_report = {**result.cached.motion.report, **result.report(), **plan_report(result.plan)}
    arrays["spec_json"] = np.array(spec_to_json(result.plan.spec, indent=None))
    arrays["actions_json"] = np.array(json.dumps(actions))
    arrays["report_json"] = np.array(json.dumps(full_report, default=_json_default))
    return arrays


@contextlib.contextmanager
def output_errors() -> Iterator[None]:
    """Turn :class:`viz.files.OutputError` (a refused path, a failed write) into exit 2."""
    from viz.files import OutputError

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
    from viz.files import OutputPathError, check_distinct, check_output_dir, check_output_file

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
    from viz.plots import PLOT_FILES

    return PLOT_FILES


def _write_html(path: Path, result: SolveResult, staging: Any, *, cache_dir: str | Path | None) -> None:
    """The HTML replay; its data is reused from (or stored into) the motion cache when the
    result is in it (the page's data does not depend on the title)."""
    from viz.html import page_data, render_page

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
    from viz.files import Staging
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
