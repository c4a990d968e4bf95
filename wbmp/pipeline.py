"""The end-to-end job: sentence or spec -> actions -> TaskSpec -> Plan -> Execution -> files.

Only this package wires the layers together. :func:`solve` runs each step once, in this order,
each a function of this module with typed inputs and outputs (docs/architecture.md):

====  ==================  ==============================================  ===========================
step  function            from -> to                                      layer
====  ==================  ==============================================  ===========================
0     read_sim_inputs     SolveRequest -> SimInputs (push, faults)        sim
1     parse_instruction   sentence -> language.ActionPlan                 language
2     compile_spec        ActionPlan x Robot x Scene -> tasks.TaskSpec    tasks (fit, ground, compile)
3     check_spec          TaskSpec x Robot -> bound TaskSpec              tasks (bind: roles -> frames)
4     plan_spec           TaskSpec x Robot -> planner.Plan                planner
5-6   simulate_plan       Plan x Robot -> sim.Execution + certificate     sim
7     write_outputs       SolveResult -> files                            wbmp.outputs
====  ==================  ==============================================  ===========================

The motion cache sits around steps 4-6 (:class:`_CacheEntry`): a request answered before, in any
phrasing, is read back as the same typed :class:`SolveResult`. Every step reports progress through
a small callback so the CLI can show it (or stay quiet).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from wbmp.errors import CliError, ExitCode

if TYPE_CHECKING:
    from language import ActionPlan
    from planner import Plan
    from robots import Robot, RobotProfile
    from sim import Execution, Faults, Push, StopRequest
    from tasks import Scene, StartState, TaskSpec
    from wbmp.motioncache import Hit, MotionCache

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


# ---------------------------------------------------------------------------------------------
# The steps, in the order solve() runs them; each takes and returns typed values.
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class SimInputs:
    """What a request asks of the simulation, read and checked before any work.

    Attributes:
        push: The parsed ``--push``, or None.
        faults: The read ``--faults`` file, or None.
    """

    push: Push | None = None
    faults: Faults | None = None


def read_sim_inputs(request: SolveRequest) -> SimInputs:
    """Step 0: the simulation's inputs, before any work: a push typo fails at once (exit 2), a bad
    faults file too (exit 3)."""
    if not request.simulate:
        return SimInputs()
    from sim import load_faults, parse_push

    push = None if request.push is None else parse_push(request.push)
    faults = None if request.faults_path is None else load_faults(request.faults_path)
    return SimInputs(push=push, faults=faults)


def parse_instruction(request: SolveRequest) -> ActionPlan:
    """Step 1, parse: sentence -> ActionPlan with the requested backend."""
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


def compile_spec(request: SolveRequest, actions: ActionPlan, robot: Robot,
                 scene: Scene | None) -> tuple[ActionPlan, TaskSpec]:
    """Step 2, ground and compile: the actions' unstated sizes fitted to the robot (once: the
    printed defaults are the ones compiled), their object words grounded in the scene, and the
    TaskSpec compiled from the request's start (or standing at the origin)."""
    import dataclasses

    from tasks import compile_actions, fit_actions

    actions = dataclasses.replace(actions, actions=tuple(fit_actions(actions.actions, robot)))
    if scene is None:
        _require_scene(actions.actions)
    spec = compile_actions(actions.actions, robot, scene=scene, description=request.instruction or "", fitted=True,
                           start=request.start)
    return actions, spec


def _read_spec(request: SolveRequest, scene: Scene | None) -> tuple[Robot, TaskSpec]:
    """Step 1-2 for ``--spec FILE``: the spec read, on the requested robot and scene."""
    import dataclasses

    from robots import load_robot
    from tasks import load_spec

    assert request.spec_path is not None
    spec = load_spec(request.spec_path)
    robot = load_robot(request.robot or spec.robot)
    if request.robot:
        spec = dataclasses.replace(spec, robot=robot.name)
    if scene is not None:
        spec = dataclasses.replace(spec, scene=scene)
    return robot, spec


def check_spec(spec: TaskSpec, robot: Robot) -> TaskSpec:
    """Step 3, check and bind (:func:`tasks.bind`): unknown frames or joints, contacts off the
    ground (exit 3), a hand target or a footstep inside a scene object (exit 4) are refused before
    planning, in task terms; the spec comes back naming only the robot's frames (roles resolved)."""
    from tasks import bind

    return bind(spec, robot)


def build_spec(request: SolveRequest, progress: Progress = _silent) -> tuple[Robot, TaskSpec, ActionPlan | None]:
    """Steps 1-3: (robot, spec, actions) for a sentence or a spec file (with the scene file, when
    given); actions is None for a spec file.

    The scene is loaded first (a bad scene file: exit 3 before anything else); a hand target or
    a footstep inside one of its objects is refused before planning (exit 4, naming the object).
    """
    from robots import load_robot

    scene = None
    if request.scene_path is not None:
        from tasks import load_scene

        scene = load_scene(request.scene_path)
    actions: ActionPlan | None = None
    if request.spec_path is not None:
        robot, spec = _read_spec(request, scene)
    else:
        if not request.instruction or not request.instruction.strip():
            raise CliError("give an instruction in quotes, or --spec FILE", ExitCode.USAGE)
        progress("parsing the instruction")
        parsed = parse_instruction(request) if request.actions is None else request.actions
        robot = load_robot(request.profile if request.profile is not None else request.robot or "talos")
        actions, spec = compile_spec(request, parsed, robot, scene)
    spec = check_spec(spec, robot)
    return robot, spec, actions


def check_sim_times(request: SolveRequest, inputs: SimInputs, horizon: float) -> None:
    """Step 3 for the simulation: a push, a stop or a faults push after the motion would never act
    (``--push`` and ``--estop-at`` exit 2, a faults file's push exit 3)."""
    if inputs.push is not None:
        from sim import check_push_time

        check_push_time(inputs.push, horizon)
    if request.estop_at is not None and not 0.0 <= request.estop_at < horizon:
        raise CliError(f"--estop-at {request.estop_at:g}: the motion lasts {horizon:.3g} s; give a time from 0 to "
                       f"below {horizon:.3g} s", ExitCode.USAGE)
    if inputs.faults is not None:
        from sim import FaultsError

        for i, p in enumerate(inputs.faults.pushes):
            if not p.t < horizon:
                raise FaultsError(f"faults file {request.faults_path!r}: pushes[{i}].t = {p.t:g} s is after the "
                                  f"motion, which lasts {horizon:.3g} s; give a time below {horizon:.3g} s")


def plan_spec(spec: TaskSpec, robot: Robot, progress: Progress, *, library: bool) -> Plan:
    """Step 4, plan: the trajectory optimization, with the user's ``WBMP_*`` switches (compile,
    background, solution library, build memory). Without the motion cache (``library`` False,
    ``--no-cache``) there is no solution library either: the result of the request alone, whatever
    was planned before (planner/trajopt/library.py)."""
    from planner import plan, plan_with_library
    from wbmp.environment import planner_settings

    progress(f"planning {spec.horizon:.1f} s of motion for {robot.name}")
    if library:  # the one planner call that reads the solution library (plan() reads nothing on disk)
        return plan_with_library(spec, robot, progress=progress, settings=planner_settings())
    return plan(spec, robot, progress=progress, settings=planner_settings(cache={"solution_library": "off"}))


def simulate_plan(plan: Plan, robot: Robot, request: SolveRequest, inputs: SimInputs, progress: Progress) -> Execution:
    """Steps 5-6, simulate and certify: the whole-body controller tracks the plan in MuJoCo (with
    the push, faults and E-stop asked for: its stop time, flag file and signal); the execution
    carries its certificate."""
    from sim import EStopSettings, simulate

    progress("simulating in MuJoCo with the whole-body controller")
    estop = EStopSettings(at=request.estop_at, flag_file=request.estop_flag, request=request.stop_request)
    return simulate(plan, robot, push=inputs.push, progress=progress, estop=estop, faults=inputs.faults)


# ---------------------------------------------------------------------------------------------
# The job: the steps above, with the motion cache around them.
# ---------------------------------------------------------------------------------------------


def solve(request: SolveRequest, progress: Progress = _silent, *, cache: bool = False,
          cache_dir: str | Path | None = None, cache_read: bool = True) -> SolveResult:
    """Run the whole job; raises the layers' exceptions (mapped to exit codes by the CLI).

    Ctrl-C or SIGTERM stops it at the next progress message or step, also when a library
    swallowed the interrupt (CasADi turns it into an IPOPT failure): see
    :func:`wbmp.errors.check_signals`. Writing the files is :func:`wbmp.outputs.write_outputs`.

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


def _checked(progress: Progress) -> Progress:
    """``progress`` that first stops on a pending Ctrl-C or SIGTERM."""
    from wbmp.errors import check_signals

    def checked_progress(message: str) -> None:
        check_signals()
        progress(message)

    return checked_progress


def _solve(request: SolveRequest, progress: Progress, *, motions: MotionCache | None = None,
           rkey: str | None = None, read: bool = True) -> SolveResult:
    """Steps 0-6 of a fresh request, answered from the motion cache when another phrasing (or
    request) of the same spec is there, and stored there when it succeeds."""
    from wbmp.errors import check_signals

    progress = _checked(progress)
    timings: dict[str, float] = {}
    inputs = read_sim_inputs(request)
    t0 = time.perf_counter()
    robot, spec, actions = build_spec(request, progress)
    timings["spec"] = time.perf_counter() - t0
    check_sim_times(request, inputs, spec.horizon)
    library = motions is not None  # the solution library goes with the motion cache, hashable robot files or not
    entry = None if motions is None else _CacheEntry.of(motions, robot, spec, request, inputs, rkey)
    if entry is not None and read and not request.safety:
        hit = entry.motions.load(entry.key)
        if hit is not None:  # the same motion from another phrasing (or request)
            entry.remember_request(actions)
            progress("answering from the motion cache")
            return _from_cache(request, hit, robot, timings["spec"], actions=actions, spec=spec)
    t0 = time.perf_counter()
    plan = plan_spec(spec, robot, progress, library=library)
    check_signals()
    timings["plan"] = time.perf_counter() - t0
    execution = None
    if request.simulate:
        t0 = time.perf_counter()
        execution = simulate_plan(plan, robot, request, inputs, progress)
        check_signals()
        timings["simulate"] = time.perf_counter() - t0
    result = SolveResult(robot=robot, spec=spec, plan=plan, actions=actions, execution=execution, timings=timings)
    # only results that succeeded are stored: a failure is cheap to repeat and worth re-checking
    if entry is not None and plan.ok and (execution is None or execution.ok) and not request.safety:
        entry.store(result)
    return result


@dataclass(frozen=True)
class _CacheEntry:
    """Where a request's motion lives in the motion cache: its key (spec, robot files, simulation
    and push) and the request record that points to it."""

    motions: MotionCache
    key: str
    files: dict[str, str]  # {path: sha256} of the robot's files (wbmp.motioncache.robot_files)
    digest: str
    rkey: str | None

    @classmethod
    def of(cls, motions: MotionCache, robot: Robot, spec: TaskSpec, request: SolveRequest, inputs: SimInputs,
           rkey: str | None) -> _CacheEntry | None:
        """The entry, or None when a robot file cannot be hashed (solved, not cached)."""
        from wbmp.motioncache import motion_key, robot_files, robot_hash

        try:
            files = robot_files(robot)
        except OSError:
            return None
        digest = robot_hash(robot, files)
        key = motion_key(spec, digest, simulate=request.simulate, push=inputs.push)
        return cls(motions, key, files, digest, rkey)

    def remember_request(self, actions: ActionPlan | None) -> None:
        """Point the request's record (its sentence, robot and options) at this motion."""
        if self.rkey is not None:
            self.motions.store_request(self.rkey, self.key, self.files, self.digest, _actions_record(actions))

    def store(self, result: SolveResult) -> None:
        """Store a fresh result, compressed once (``--out`` writes the same bytes)."""
        from wbmp.motionfile import npz_bytes
        result.motion_file = npz_bytes(result_arrays(result))
        self.motions.store_file(self.key, result.motion_file, result.spec)
        self.remember_request(result.actions)
        result.cache_key = self.key


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


def _actions_record(actions: ActionPlan | None) -> dict[str, Any] | None:
    return None if actions is None else actions.to_record()


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
    from wbmp.motionfile import json_default, plan_report

    arrays = dict(result.cached.arrays)
    full_report = {**result.cached.motion.report, **result.report(), **plan_report(result.plan)}
    arrays["spec_json"] = np.array(spec_to_json(result.plan.spec, indent=None))
    arrays["actions_json"] = np.array(json.dumps(actions))
    arrays["report_json"] = np.array(json.dumps(full_report, default=json_default))
    return arrays
