"""Whole-body trajectory optimization of a TaskSpec: CasADi NLP, solved with IPOPT.

:func:`plan` is the entry point. It lays the spec out on a knot grid
(:mod:`planner.trajopt.layout`), fetches or builds the solver for that layout's *structure*
(:mod:`planner.trajopt.cache`: in memory, or compiled C code on disk), feeds it the layout's *values*
as parameters and bounds, solves, and reports the result checked with Pinocchio numerics
(:mod:`planner.trajopt.checks`, :mod:`planner.trajopt.diagnose`).

The NLP (docs/planner.md), for knots ``k = 0..N`` on a uniform grid:

* variables ``dq_k`` (nv) for ``k = 2..N-1``, tangent displacements around ``q_ref`` (the
  standing posture); ``dq_0 = dq_1 = 0`` (start at rest) and ``dq_N = dq_{N-1}`` (end at rest);
* joint position limits as variable bounds, joint velocity limits as finite-difference rows;
* the layout's terms: stance soles in 6D, swing clearance, CoM support polygon and box,
  frame/CoM targets (hard: constraint, soft: cost), joint targets (cost);
* cost ``w_s sum |dq_{k+1} - 2 dq_k + dq_{k-1}|^2 / dt^3 + w_p dt sum |dq_k[joints]|^2`` plus
  the soft terms.
* when ``spec.dynamic``: contact forces at the sole corners as extra variables, CoM dynamics
  ``m (c'' - g) = sum f``, friction pyramids, sole corners of swinging feet above the ground,
  an angular-momentum-rate cost (:mod:`planner.trajopt.centroidal`, ``docs/dynamic.md``).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from typing import Generic, TypeVar

import numpy as np

from planner.exceptions import PlanningFailed
from planner.results import Plan, SolverStats, SolveStatus
from planner.trajopt.cache import get_solver, solver_key
from planner.trajopt.centroidal.layout import DynamicLayout, to_dynamic_layout
from planner.trajopt.checks import precheck
from planner.trajopt.collision import (
    Rows,
    SphereSets,
    collision_diagnosis,
    collision_rows_of,
    exempt_distances,
    idle_pairs,
    missing_rows,
    select,
    sphere_pair_distances,
    sphere_sets,
    with_collision_terms,
)
from planner.trajopt.diagnose import diagnose_failure
from planner.trajopt.layout import Layout, make_layout
from planner.trajopt.library import (
    EscalationRows,
    find_escalation,
    find_seed,
    has_seeds,
    store_escalation,
    store_seed,
)
from planner.trajopt.payload import payload_checks
from planner.trajopt.report import configurations, make_plan
from planner.trajopt.scene_collision import (
    SceneRows,
    add_screened_scene_terms,
    missing_scene_rows,
    obstacles,
    scene_diagnosis,
    scene_rows_of,
    scene_sets,
    with_scene_terms,
)
from planner.trajopt.settings import PlannerSettings
from planner.trajopt.solve import solve_layout
from planner.trajopt.solver_output import SolverOutput, carried_multipliers
from planner.trajopt.transcription import NlpLayout, bounds, make_nlp_layout, parameter_values
from robots import Robot
from tasks import TaskSpec

L = TypeVar("L", bound=Layout)  # a layout, kinematic or dynamic: the functions hand back the same class


@dataclasses.dataclass(frozen=True, eq=False)
class Problem:
    """One spec on one robot, built and ready to solve (:func:`formulate`); frozen: a changed problem
    is a new one (:meth:`with_layout`), and solving it changes nothing in it.

    Attributes:
        layout: The terms on the knot grid (:class:`Layout`, or the dynamic
            ``planner.trajopt.centroidal.layout.DynamicLayout``), with the self-collision and scene
            rows its own guess asks for.
        settings: The settings its solves use (a dynamic problem's add the centroidal IPOPT
            options and its cache switches to the caller's).
        guess: The solver's start from the task alone (all variables, read-only): the nominal
            motion (kinematic, with ``warm_start="nominal"``) or the heading guess (dynamic).
        deferred: The self-collision rows screening left out for idle pairs (added when a solve
            fails; an idle pair a solution brings within the margin gets its rows in the round;
            planner/trajopt/collision.py; a frozen record).
    """

    layout: Layout
    settings: PlannerSettings
    guess: np.ndarray
    deferred: Rows

    def with_layout(self, layout: Layout) -> Problem:
        """This problem with ``layout`` instead of its own (a collision round's rows, a
        re-linearization, the rows earlier plans needed); this one is not changed."""
        return dataclasses.replace(self, layout=layout)


@dataclasses.dataclass(frozen=True, eq=False)
class WarmStart:
    """Where a solve starts instead of its problem's own guess (an explicit argument of :func:`solve`).

    Attributes:
        x: All variables, of the problem's sizes.
        dq: Chart displacements (N+1, nv) of that solution: a dynamic problem's whole-body momentum
            rows are linearized about them (None: about the problem's own guess).
        multipliers: ``(lam_x, lam_g)`` of the same structure's solve (None: IPOPT's own).
        origin: What it is, for :attr:`SolverStats.seed` (``"library (distance 0.0123)"``).
        what: What it is, in a sentence (``"stored solution"``).
    """

    x: np.ndarray
    dq: np.ndarray | None = None
    multipliers: tuple[np.ndarray, np.ndarray] | None = None
    origin: str = "previous solution"
    what: str = "previous solution"


@dataclasses.dataclass(frozen=True, eq=False)
class Solution:
    """A solve's outcome (:func:`solve`): the plan and what a diagnosis of a failure needs.

    Attributes:
        problem: The problem as last solved: with the rows its collision rounds added and its
            momentum rows re-linearized (the one given to :func:`solve` is not changed).
        dq: Chart displacements (N+1, nv).
        stats: The solver's record, adding up every solve (rounds, a failed warm start).
        output: What the last solve returned beside the motion (:class:`SolverOutput`: variables,
            multipliers, rows and bounds).
        forces: The contact-force variables (None: the kinematic formulation has none).
        plan: The plan, checked (not yet with the held objects' torques).
    """

    problem: Problem
    dq: np.ndarray
    stats: SolverStats
    output: SolverOutput
    forces: np.ndarray | None
    plan: Plan

    def warm_start(self) -> WarmStart:
        """This solution as the warm start of another solve of a problem of the same variables (its
        rows may differ: the multipliers are left out)."""
        return WarmStart(x=np.array(self.output.x), dq=np.array(self.dq))


def plan(spec: TaskSpec, robot: Robot, *, settings: PlannerSettings | None = None, throw: bool = True,
         progress: Callable[[str], None] | None = None, warm_start: WarmStart | None = None,
         collision_rows: EscalationRows | None = None) -> Plan:
    """Plan a whole-body motion for ``spec`` on ``robot``, starting and ending at rest.

    Reads no solution library, whatever ``settings.cache.solution_library`` says: the same arguments
    give the same plan whatever is on disk (:func:`plan_with_library` recalls the library's seed
    and rows and passes them here as ``warm_start`` and ``collision_rows``).

    The motion starts at ``spec.start`` (else ``robot.q_standing``). Frames in the spec are role names
    (``right_hand``) or Pinocchio frame names.

    Args:
        spec: What to do.
        robot: Which robot does it.
        settings: Solver and cache settings (default :class:`PlannerSettings`).
        throw: Raise :class:`PlanningFailed` when the solve fails or a constraint group is
            violated; with False, return the (failed) plan with its ``diagnosis``.
        progress: Called with short messages ("building solver", "solving").
        warm_start: Where the solve starts (a previous solution, :meth:`Solution.warm_start`, or
            the library's seed; None: the task's own guess).
        collision_rows: Collision rows to add before the first solve (:func:`recorded_rows`), per
            link pair named ``"link_a/link_b"``: ``(sphere pairs, knots)``, per scene object piece
            ``"scene:<key>"``: ``(robot spheres, knots)`` (the library's record of the rows earlier
            plans of the structure came to need; not used when a name or index does not fit this
            problem, or names rows its settings switch off).

    Returns:
        The plan, on the uniform knot grid, with solver stats and the constraint report.

    Raises:
        robots.FrameNotFound: the spec names a frame the robot does not have.
        UnsupportedModel: the robot has joints the planner cannot model.
        PlanningFailed: the problem is infeasible or the solver failed (with ``throw``; it carries
            the problem last solved and the solver's record).
    """
    problem = formulate(spec, robot, settings or PlannerSettings())  # 1. build the problem
    return _plan_problem(problem, spec, robot, throw, progress, warm_start, collision_rows)


def plan_with_library(spec: TaskSpec, robot: Robot, *, settings: PlannerSettings | None = None, throw: bool = True,
                      progress: Callable[[str], None] | None = None) -> Plan:
    """:func:`plan` with the solution library in ``settings.cache`` (``solution_library``: ``on``,
    ``read``; ``off``: :func:`plan` itself; :mod:`planner.trajopt.library`): a dynamic problem gets
    the self-collision rows earlier plans of its structure came to need and starts from the
    nearest stored solution when that starts nearer to feasibility; with ``on`` a plan that
    succeeded is stored. The one planner entry that reads the library."""
    problem = formulate(spec, robot, settings or PlannerSettings())
    return _plan_problem(problem, spec, robot, throw, progress, None, None, library=True)


def _plan_problem(problem: Problem, spec: TaskSpec, robot: Robot, throw: bool, progress: Callable[[str], None] | None,
                  warm_start: WarmStart | None, collision_rows: EscalationRows | None, library: bool = False) -> Plan:
    """Steps 2-5 of :func:`plan` on a formulated ``problem`` (``library``: with the solution library)."""
    refusal = precheck(problem.layout)  # 2. refuse what needs no solve to see (a target out of every reach, ...)
    if refusal:
        stats = SolverStats(status=SolveStatus.NOT_RUN)
        dq = np.zeros((problem.layout.N + 1, robot.nv))
        return _failed(problem, make_plan(problem.layout, dq, stats, problem.settings, diagnosis=refusal), throw)
    if library:  # 3. solve (with what earlier plans stored)
        solved = _solve_with_library(problem, progress)
    else:
        solved = solve(_with_recorded_rows(problem, collision_rows, progress)[0], warm_start, progress)
    result, too_heavy = _with_payload(solved.plan, robot, spec)  # 4. the held objects' torques, on the plan
    if too_heavy:  # an object too heavy for an arm: the cause, no other diagnosis
        return _failed(solved.problem, result, throw)
    if result.ok:
        return result
    return _failed(solved.problem, _diagnosed(solved, result, spec, progress), throw)  # 5. say why, in task terms


def formulate(spec: TaskSpec, robot: Robot, settings: PlannerSettings) -> Problem:
    """Build the problem of ``spec`` on ``robot``: its layout (kinematic, or dynamic: CoM dynamics
    with contact forces, docs/dynamic.md) with the collision rows its own guess asks for, the
    settings its solves use, and that guess. Reads nothing on disk.

    Raises:
        robots.FrameNotFound: the spec names a frame the robot does not have.
        SpecNotForRobot: the spec names a joint the robot does not have, or its start state does not fit.
    """
    lay, settings = _formulation(spec, robot, settings)
    lay, guess, deferred = _screened_guess(lay, settings)
    guess.setflags(write=False)  # the problem's, shared by every solve of it
    return Problem(lay, settings, guess, deferred)


def solve(problem: Problem, warm_start: WarmStart | None = None,
          progress: Callable[[str], None] | None = None) -> Solution:
    """Solve ``problem`` from ``warm_start`` (None: from its own guess), with its collision rounds
    and re-linearizations (each a new problem, :func:`collision_round`); a solve from a warm start
    that fails is done again from the problem's own guess (a warm start never costs a plan). Reads
    and writes nothing on disk but the solver cache; ``problem`` is not changed."""
    x0, lam0, lay = problem.guess, None, problem.layout
    if warm_start is not None:
        x0, lam0 = warm_start.x, warm_start.multipliers
        if warm_start.dq is not None and isinstance(lay, DynamicLayout):
            lay = lay.with_momentum_point(warm_start.dq)
    lay, dq, stats, output = _solve_with_collisions(lay, problem.settings, progress, x0, problem.deferred, lam0)
    if warm_start is not None:
        stats = dataclasses.replace(stats, seed=warm_start.origin)
    solution = _solution(problem.with_layout(lay), dq, stats, output)
    if warm_start is None or solution.plan.ok:
        return solution
    if progress:
        progress(f"the solve from the {warm_start.what} failed: solving from the task's own guess")
    again = solve(problem, progress=progress)
    tried = solution.stats
    stats = dataclasses.replace(
        again.stats, iterations=tried.iterations + again.stats.iterations,
        build_time=tried.build_time + again.stats.build_time, solve_time=tried.solve_time + again.stats.solve_time,
        seed=f"{tried.seed} failed: solved again from the task's own guess")
    return _solution(again.problem, again.dq, stats, again.output)


def _solution(problem: Problem, dq: np.ndarray, stats: SolverStats, output: SolverOutput) -> Solution:
    """A solve's outcome with its plan."""
    forces = problem.layout.forces_of(output.x)
    result = make_plan(problem.layout, dq, stats, problem.settings, forces=forces)
    return Solution(problem, dq, stats, output, forces, result)


def _failed(problem: Problem, result: Plan, throw: bool) -> Plan:
    """A failed plan, raised as :class:`PlanningFailed` (with ``throw``: carrying ``problem`` and the
    solver's record, ``result.stats``) or returned."""
    if throw:
        raise PlanningFailed(result.diagnosis, result, problem=problem)
    return result


def _solve_with_library(problem: Problem, progress: Callable[[str], None] | None) -> Solution:
    """Step 3 of :func:`plan_with_library`: the solve, with what the solution library holds for the
    problem's structure (:mod:`planner.trajopt.library`, a dynamic problem when the settings use
    it): the self-collision rows earlier plans of the structure came to need and its nearest stored
    solution as the warm start; a plan that succeeded goes into the library."""
    recalled, key0, escalation = _escalate(problem, progress)
    warm_start, loaded = _library_seed(recalled, progress)
    solved = solve(recalled, warm_start, progress)
    if loaded is not None:
        stats = dataclasses.replace(solved.stats, build_time=solved.stats.build_time + loaded[0], cache=loaded[1])
        solved = dataclasses.replace(solved, stats=stats, plan=dataclasses.replace(solved.plan, stats=stats))
    if solved.plan.ok:
        _library_store(solved, problem.guess, key0, escalation)
    return solved


def _with_payload(result: Plan, robot: Robot, spec: TaskSpec) -> tuple[Plan, bool]:
    """Step 4: the held objects' joint torques (payload checks) added to the plan's checks, and
    whether an object is too heavy for an arm (its check's message is then the diagnosis)."""
    payload = payload_checks(robot, spec, result.t, result.q)
    if not payload:
        return result, False
    result = dataclasses.replace(result, checks=result.checks + tuple(payload))
    heavy = next((c for c in payload if not c.ok), None)
    if heavy is None:
        return result, False
    return dataclasses.replace(result, diagnosis=heavy.message), True


def _diagnosed(solved: Solution, result: Plan, spec: TaskSpec, progress: Callable[[str], None] | None) -> Plan:
    """Step 5: why a solve failed, in task terms: a target out of reach first (its relaxed solve
    converges), then the scene's and the body's collision rows, then the layout's own reading of
    the violated rows."""
    if progress:
        progress("the solve failed: diagnosing")
    lay, settings = solved.problem.layout, solved.problem.settings
    diagnosis = ""
    collision = settings.collision
    asked = settings.diagnose and not spec.dynamic and (collision.scene_collision or collision.self_collision)
    if asked:
        # A target out of reach is the cause whatever the collision rows say, and the relaxed solve
        # that finds it converges: asked first, it spares the collision-free re-solve, which runs to
        # the iteration limit when the target is out of reach anyway.
        diagnosis = diagnose_failure(lay, result, settings, targets_only=True)
    if not diagnosis and settings.collision.scene_collision and settings.diagnose:
        diagnosis = scene_diagnosis(lay, settings, lambda free: _solve_uncompiled(free, settings))
    if not diagnosis and settings.collision.self_collision and settings.diagnose:
        diagnosis = collision_diagnosis(lay, settings, lambda free: _solve_uncompiled(free, settings))
    if not diagnosis:
        diagnosis = lay.diagnose(result, lambda: diagnose_failure(lay, result, settings, relax=not asked))
    return make_plan(lay, solved.dq, solved.stats, settings, diagnosis=diagnosis, checks=result.checks,
                     forces=solved.forces)


def _solve_uncompiled(lay: Layout, settings: PlannerSettings) -> tuple:
    """A layout solved from its initial guess without a compile (a diagnosis's collision-free solve)."""
    in_memory = dataclasses.replace(settings, cache=dataclasses.replace(settings.cache, compile=False))
    return solve_layout(lay, in_memory, x0=lay.initial_guess(settings))


def _screened_guess(lay: L, settings: PlannerSettings) -> tuple[L, np.ndarray, Rows]:
    """The layout with the rows its initial guess asks for (:func:`add_screened_terms`), the guess
    (kinematic: the nominal motion; dynamic: the heading guess) and the self-collision rows
    screening left out for idle pairs."""
    x0 = lay.initial_guess(settings)
    screened, deferred = add_screened_terms(lay, settings, x0)
    return screened, x0, deferred


def _guess_configurations(lay: Layout, x0: np.ndarray) -> np.ndarray:
    """Configurations (N+1, nq) of an initial guess ``x0`` (its chart part)."""
    robot = lay.robot
    n_kin = robot.nv * (lay.N - 2)
    dq0 = np.zeros((lay.N + 1, robot.nv))
    dq0[2:lay.N] = x0[:n_kin].reshape(lay.N - 2, robot.nv)
    dq0[lay.N] = dq0[lay.N - 1]
    return configurations(lay, dq0)


def add_screened_terms(lay: L, settings: PlannerSettings, x0: np.ndarray) -> tuple[L, Rows]:
    """The layout with the self-collision and scene rows that the initial guess ``x0`` asks for (with
    the settings that switch them on; a copy: ``lay`` is not changed), and the self-collision rows
    left out for idle pairs (:func:`add_screened_collision_terms`)."""
    if not (settings.collision.self_collision or settings.collision.scene_collision):
        return lay, Rows()
    q0 = _guess_configurations(lay, x0)
    deferred = Rows()
    if settings.collision.self_collision:
        lay, deferred = add_screened_collision_terms(lay, settings, x0, q0)
    if settings.collision.scene_collision:
        lay, _ = add_screened_scene_terms(lay, settings, q0)
    return lay, deferred


def add_screened_collision_terms(lay: L, settings: PlannerSettings, x0: np.ndarray,
                                 q0: np.ndarray | None = None) -> tuple[L, Rows]:
    """The layout with the self-collision rows of the link pairs that the initial guess ``x0`` brings
    within ``settings.collision.screening`` (a copy: ``lay`` is not changed), but for idle pairs (no
    closer than at rest anywhere on the guess, :func:`planner.trajopt.collision.idle_pairs`), which
    are left to the check after the solve; and the rows left out (planner/trajopt/collision.py)."""
    robot = lay.robot
    sets = sphere_sets(robot)
    q0 = _guess_configurations(lay, x0) if q0 is None else q0
    distances = exempt_distances(lay, sets, sphere_pair_distances(robot, sets, q0, within=settings.collision.screening))
    rows = select(lay, sets, distances, settings.collision.screening)
    idle = idle_pairs(lay, sets, distances, settings.collision.margin)
    rows, deferred = rows.split(pi for pi in rows.spheres if idle[pi])
    return with_collision_terms(lay, sets, rows, sorted(rows.spheres), settings.collision.margin), deferred


def planned_layout(spec: TaskSpec, robot: Robot, settings: PlannerSettings | None = None) -> Layout:
    """The layout :func:`plan` solves first (kinematic or dynamic, with the screened collision rows;
    without the rows the solution library may remember for its structure): what keys its solver
    in the cache."""
    return formulate(spec, robot, settings or PlannerSettings()).layout


def _formulation(spec: TaskSpec, robot: Robot, settings: PlannerSettings) -> tuple[Layout, PlannerSettings]:
    """The layout of ``spec`` (kinematic, or dynamic: CoM dynamics with contact forces,
    planner/trajopt/centroidal/, docs/dynamic.md) and the settings its solves use."""
    lay = make_layout(spec, robot)
    if spec.dynamic:
        lay = to_dynamic_layout(lay, settings.centroidal)
        solver, cache = settings.solver, settings.cache
        settings = dataclasses.replace(
            settings,
            solver=dataclasses.replace(solver,
                                       ipopt_extra=(*settings.centroidal.ipopt_options, *solver.ipopt_extra)),
            cache=dataclasses.replace(cache, compile=cache.compile and cache.compile_dynamic,
                                      serialize=cache.serialize or (cache.compile and not cache.compile_dynamic)))
    return lay, settings


def _library_seed(problem: Problem, progress: Callable[[str], None] | None,
                  ) -> tuple[WarmStart | None, tuple[float, str] | None]:
    """The warm start from the nearest stored solution of a dynamic problem's structure
    (:mod:`planner.trajopt.library`), when the settings use the library, it holds one that fits, and
    its start (:meth:`Seed.start`) violates the constraints less (summed) than the problem's own
    guess; and, when it fetched the solver for that, the seconds and origin of the fetch (for the
    stats)."""
    lay, settings, guess = problem.layout, problem.settings, problem.guess
    if not (isinstance(lay, DynamicLayout) and settings.cache.use_cache and settings.cache.solution_library != "off"):
        return None, None
    key = solver_key(lay, settings)
    if not has_seeds(key, settings.cache.cache_dir):
        return None, None
    t0 = time.perf_counter()
    solver = get_solver(lay, settings, progress)  # the structure's sizes (the solve reuses the solver)
    loaded = (time.perf_counter() - t0, solver.origin)
    nl = solver.nlp_layout
    seed = find_seed(lay, key, nl.n_x, nl.n_g, settings.cache.cache_dir)
    if seed is None:
        return None, loaded
    # Used only when it starts nearer to feasibility than the task's own guess: Talos four steps of
    # 0.10 m backward from a 0.15 m forward walk's solution started at a summed violation of 18.2
    # against the guess's 13.2 and took 23 iterations instead of 16 (docs/performance.md).
    _, _, lbg, ubg = bounds(lay, nl)
    p = parameter_values(lay, nl)
    g_of = solver.function.get_function("nlp_g")

    def violation(x: np.ndarray) -> float:
        g = np.asarray(g_of(x=x, p=p)["g"], dtype=float).ravel()
        return float(np.sum(np.maximum(lbg - g, 0.0) + np.maximum(g - ubg, 0.0)))

    if not violation(seed.start(guess)) < violation(guess):
        return None, loaded
    if progress:
        progress(f"starting from a stored solution of this task structure (distance {seed.distance:.3g})")
    return WarmStart(x=seed.start(guess), dq=seed.dq, multipliers=(seed.lam_x, seed.lam_g),
                     origin=f"library (distance {seed.distance:.4f})", what="stored solution"), loaded


def _library_store(solved: Solution, guess: np.ndarray, key0: str | None, escalation: EscalationRows | None) -> None:
    """Keep a successful dynamic plan's solution (and its problem's own guess ``guess``) as a
    seed of its structure (``solution_library="on"``); when collision rounds changed the structure
    the plan started with (``key0``, before any ``escalation`` record was applied), remember the
    self-collision rows it ended with for the next plan of ``key0``."""
    lay, settings, dq = solved.problem.layout, solved.problem.settings, solved.dq
    if not (isinstance(lay, DynamicLayout) and settings.cache.use_cache and settings.cache.solution_library == "on"):
        return
    key = solver_key(lay, settings)
    store_seed(lay, key, guess, solved.output, dq, settings.cache.cache_dir)
    if key0 is None or key == key0:
        return
    named = recorded_rows(lay, settings)
    if named and named != escalation:
        store_escalation(key0, named, settings.cache.cache_dir)


SCENE_ROWS = "scene:"  # a record's name of a scene object's rows: "scene:" + the piece's key ("table#3")


def recorded_rows(lay: Layout, settings: PlannerSettings) -> EscalationRows:
    """The collision rows ``lay`` has, as a record of the solution library (and ``plan``'s
    ``collision_rows``): per link pair ``"link_a/link_b"`` its sphere pairs and knots (with
    ``settings.collision.self_collision``), per scene object piece ``"scene:<key>"`` its robot
    spheres and knots (with ``scene_collision``)."""
    named: EscalationRows = {}
    if settings.collision.self_collision:
        sets = sphere_sets(lay.robot)
        rows = collision_rows_of(lay, sets)
        named.update({"/".join(sets.pair_names[pi]): (set(rows.spheres[pi]), set(rows.knots[pi]))
                      for pi in rows.spheres})
    if settings.collision.scene_collision:
        obs = obstacles(lay.spec.scene)
        scene = scene_rows_of(lay)
        named.update({SCENE_ROWS + obs[oi].key: (set(scene.spheres[oi]), set(scene.knots[oi])) for oi in scene.spheres})
    return named


def _escalate(problem: Problem, progress: Callable[[str], None] | None,
              ) -> tuple[Problem, str | None, EscalationRows | None]:
    """Give a dynamic problem the collision rows (link pairs and scene objects) that earlier plans of
    its structure came to need (:func:`planner.trajopt.library.find_escalation`) before its first
    solve: it then has their final structure, and their seeds, instead of a collision round that
    builds another solver and solves again. A record that names a pair, object, sphere or knot this
    layout does not have is not used. Returns the problem with those rows (a new one: ``problem`` is not changed; the rows
    added leave its ``deferred``), the structure's key before (None: the library is not used) and the
    record."""
    lay, settings = problem.layout, problem.settings
    cache = settings.cache
    if not (isinstance(lay, DynamicLayout) and cache.use_cache and cache.solution_library != "off"
            and (settings.collision.self_collision or settings.collision.scene_collision)):
        return problem, None, None
    key0 = solver_key(lay, settings)
    record = find_escalation(key0, settings.cache.cache_dir)
    if record is None:
        return problem, key0, None
    recalled, fits = _with_recorded_rows(problem, record, progress)
    return recalled, key0, record if fits else None


def _with_recorded_rows(problem: Problem, record: EscalationRows | None, progress: Callable[[str], None] | None,
                        ) -> tuple[Problem, bool]:
    """``problem`` with the collision rows of ``record`` (:func:`recorded_rows`: ``"link_a/link_b"``
    -> (sphere pairs, knots), ``"scene:<key>"`` -> (robot spheres, knots); a new problem: ``problem``
    is not changed; the self-collision rows added leave its ``deferred``), and whether the record
    fits it (a record that names a pair, object, sphere or knot the problem does not have, or rows
    its settings switch off, is not used). The pairs and objects are added in index order, as a
    collision round adds them, so that a record of one round gives that round's structure."""
    lay, settings = problem.layout, problem.settings
    if record is None:
        return problem, True
    self_part = {name: rows for name, rows in record.items() if not name.startswith(SCENE_ROWS)}
    scene_part = {name[len(SCENE_ROWS):]: rows for name, rows in record.items() if name.startswith(SCENE_ROWS)}
    if (self_part and not settings.collision.self_collision) or (scene_part and not settings.collision.scene_collision):
        return problem, False
    extra = _recorded_pair_rows(lay, self_part)
    scene_extra = _recorded_scene_rows(lay, scene_part)
    if extra is None or scene_extra is None:
        return problem, False
    deferred, layout = problem.deferred, lay
    changed: list[int] = []
    objects: list[int] = []
    if extra.spheres:
        sets = sphere_sets(lay.robot)
        rows, changed = collision_rows_of(lay, sets).merged(extra)
        if changed:
            deferred, _ = deferred.split(changed)
            layout = with_collision_terms(layout, sets, rows, sorted(changed), settings.collision.margin)
    if scene_extra.spheres:
        scene, objects = scene_rows_of(lay).merged(scene_extra)
        if objects:
            layout = with_scene_terms(layout, scene_sets(lay.robot), obstacles(lay.spec.scene), scene, sorted(objects),
                                      settings.collision.margin)
    if not (changed or objects):
        return problem, True
    if progress:
        what = " and ".join(f"{n} {unit}" for n, unit in ((len(changed), "link pair(s)"), (len(objects), "object(s)")) if n)
        progress(f"adding the collision rows of {what} that earlier plans of this task structure needed")
    return dataclasses.replace(problem, layout=layout, deferred=deferred), True


def _recorded_pair_rows(lay: Layout, record: EscalationRows) -> Rows | None:
    """A record's self-collision rows by pair index, or None when one does not fit ``lay``."""
    if not record:
        return Rows()
    sets = sphere_sets(lay.robot)
    index = {"/".join(name): pi for pi, name in enumerate(sets.pair_names)}
    ends = np.append(sets.starts[1:], len(sets.sa))
    spheres: dict[int, set[int]] = {}
    knots: dict[int, set[int]] = {}
    for name, (sp, ks) in record.items():
        pi = index.get(name)
        if pi is None or max(sp) >= ends[pi] - sets.starts[pi] or min(ks) < 2 or max(ks) > lay.N - 1:
            return None
        spheres[pi], knots[pi] = set(sp), set(ks)
    return Rows(spheres, knots)


def _recorded_scene_rows(lay: Layout, record: EscalationRows) -> SceneRows | None:
    """A record's scene rows by object piece index, or None when one does not fit ``lay``."""
    if not record:
        return SceneRows()
    index = {ob.key: oi for oi, ob in enumerate(obstacles(lay.spec.scene))}
    n_spheres = len(scene_sets(lay.robot).sphere_radius)
    spheres: dict[int, set[int]] = {}
    knots: dict[int, set[int]] = {}
    for key, (sp, ks) in record.items():
        oi = index.get(key)
        if oi is None or max(sp) >= n_spheres or min(ks) < 2 or max(ks) > lay.N - 1:
            return None
        spheres[oi], knots[oi] = set(sp), set(ks)
    return SceneRows(spheres, knots)


@dataclasses.dataclass(frozen=True, eq=False)
class CollisionRound(Generic[L]):
    """One collision round's outcome (:func:`collision_round`): new records, the ones it was given
    unchanged.

    Attributes:
        layout: The layout to solve next (the round's input itself when no rows changed).
        rows: The self-collision rows it has (None: no self-collision rows).
        scene_rows: The scene rows it has (None: no scene rows).
        deferred: The idle pairs' rows still left out (None: added, or none).
        changed: The link pairs whose rows changed.
        objects: The scene objects whose rows changed.
    """

    layout: L
    rows: Rows | None
    scene_rows: SceneRows | None
    deferred: Rows | None
    changed: tuple[int, ...]
    objects: tuple[int, ...]


def collision_round(lay: L, settings: PlannerSettings, dq: np.ndarray, sets: SphereSets | None, rows: Rows | None,
                    scene_rows: SceneRows | None, deferred: Rows | None) -> CollisionRound[L]:
    """One collision round after a solve ``dq`` (N+1, nv): the link pairs (``sets``, ``rows``; None:
    no self-collision rows) and the (sphere, object) pairs (``scene_rows``; None: no scene rows) that
    the solution brings within the margin without rows get them; the idle pairs' rows (``deferred``)
    stay left out unless the solution brings one of them within the margin (before session 18 a
    round added them all whenever any pair came close: the kitchen pick-up's round 2,135 rows
    instead of 506, 1,629 of them idle leg pairs at every knot that no solve needed).

    Returns the round's :class:`CollisionRound`: the layout to solve next (a new one with the rows;
    ``lay`` itself when none changed) and the records of the rows it has, as new records; ``lay``,
    ``rows``, ``scene_rows`` and ``deferred`` are not changed."""
    q = configurations(lay, dq)
    changed: list[int] = []
    if sets is not None and rows is not None:
        distances = sphere_pair_distances(lay.robot, sets, q, within=settings.collision.screening)
        more = missing_rows(lay, sets, rows, distances, settings.collision.margin, settings.collision.screening)
        rows, changed = rows.merged(more)  # an idle pair only when it came close itself: it stays deferred
        if changed:
            lay = with_collision_terms(lay, sets, rows, changed, settings.collision.margin)
    objects: list[int] = []
    if scene_rows is not None:
        lay, scene_rows, objects = missing_scene_rows(lay, scene_rows, q, settings)
    return CollisionRound(lay, rows, scene_rows, deferred, tuple(changed), tuple(objects))


def _round_multipliers(solved: Layout, out: SolverOutput, lay: Layout) -> tuple[np.ndarray, np.ndarray] | None:
    """The round's solve starts from the solution and its multipliers: the rows ``solved`` (the layout
    of ``out``) and the round's ``lay`` share keep theirs, the round's new rows start at zero
    (:func:`carried_multipliers`; the kitchen sentence's round: 40 -> 31 iterations)."""
    if not isinstance(out.nlp_layout, NlpLayout):  # the stage-wise transcription: nothing to carry
        return None
    return carried_multipliers(solved.terms, out, lay.terms, make_nlp_layout(lay))


def _solve_with_collisions(lay: L, settings: PlannerSettings, progress: Callable[[str], None] | None,
                           x0: np.ndarray, deferred: Rows | None = None,
                           lam0: tuple[np.ndarray, np.ndarray] | None = None,
                           ) -> tuple[L, np.ndarray, SolverStats, SolverOutput]:
    """Solve, then again from the solution while the solution asks for it: a link pair, or a robot
    sphere and a scene object, within the collision margin without rows gets them (at most
    ``settings.collision.rounds`` times, planner/trajopt/collision.py, scene_collision.py), and a
    layout whose linearized rows are off at the solution re-linearizes them (the whole-body momentum rows, planner/trajopt/centroidal/momentum.py).
    ``deferred``: the rows screening left out for idle pairs; they are added when a solve fails
    (and the problem is solved again from ``x0``, as it would have been with them from the start);
    a round gives an idle pair rows only when the solution brings that pair within the margin.
    ``lam0``: the first solve's initial multipliers (a seed's, :mod:`planner.trajopt.library`).
    Returns the layout last solved (each round's rows make a new one, :func:`collision_round`;
    ``lay`` is not changed by them), the solution and stats (adding up the iterations and times of
    every solve) and the last solve's :class:`SolverOutput`."""
    guess = x0
    sets = sphere_sets(lay.robot) if settings.collision.self_collision else None
    rows = collision_rows_of(lay, sets) if sets is not None else None
    scene_rows = scene_rows_of(lay) if settings.collision.scene_collision else None
    total: SolverStats | None = None
    rounds = relinearized = 0
    while True:
        dq, stats, out = solve_layout(lay, settings, progress, x0=x0, lam0=lam0)
        total = stats if total is None else dataclasses.replace(
            stats, iterations=total.iterations + stats.iterations, build_time=total.build_time + stats.build_time,
            cache=total.cache, solve_time=total.solve_time + stats.solve_time)
        if not stats.status.ok:
            if (sets is None or rows is None or deferred is None or not deferred.spheres
                    or stats.status not in (SolveStatus.MAX_ITERATIONS, SolveStatus.NUMERICAL_ERROR)):
                return lay, dq, total, out
            rows, idle = rows.merged(deferred)
            lay = with_collision_terms(lay, sets, rows, idle, settings.collision.margin)
            deferred = None
            if progress:
                progress("the solve failed: solving again with the idle pairs' rows")
            x0, lam0 = guess, None
            continue
        reason = ""
        solved_lay = lay
        if rounds < settings.collision.rounds and (sets is not None or scene_rows is not None):
            round_ = collision_round(lay, settings, dq, sets, rows, scene_rows, deferred)
            lay, rows, scene_rows, deferred = round_.layout, round_.rows, round_.scene_rows, round_.deferred
            if round_.changed or round_.objects:
                rounds += 1
                reason = (f"{len(round_.changed)} more link pair(s) and {len(round_.objects)} object(s) came "
                          "within the collision margin")
        lam0 = None
        # A round's new layout is re-linearized about this solution too (not counted against
        # momentum_iterations): its solution is near this one, so its momentum rows are then near
        # exact and the solve a re-linearization would add after it is not needed (the kitchen
        # sentence: one solve fewer); when they are not, that solve still comes.
        relinearized_lay = lay.relinearized(dq, out.x, relinearized)
        if relinearized_lay is not None:
            same_rows = len(relinearized_lay.terms) == len(lay.terms)  # the torque margin's rows may come
            lay = relinearized_lay
            if not reason:
                relinearized += 1
                reason = "re-linearized about the solution"
                if same_rows:
                    lam0 = (out.lam_x, out.lam_g)  # same structure: the multipliers warm-start it too
        if not reason:
            return lay, dq, total, out
        if lam0 is None:  # a round: the rows both layouts have keep their multipliers, new rows start at 0
            lam0 = _round_multipliers(solved_lay, out, lay)
        if progress:
            progress(f"{reason}: solving again")
        x0 = out.x
