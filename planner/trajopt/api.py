"""Whole-body trajectory optimization of a TaskSpec: CasADi NLP, solved with IPOPT.

:func:`plan` is the entry point. It lays the spec out on a knot grid
(:mod:`planner.trajopt.layout`), fetches or builds the solver for that layout's *structure*
(:mod:`planner.trajopt.cache`: in memory, or compiled C code on disk), feeds it the layout's *values*
as parameters and bounds, solves, and reports the result checked with Pinocchio numerics
(:mod:`planner.trajopt.checks`, :mod:`planner.trajopt.diagnose`).

The NLP (DESIGN.md section 3), for knots ``k = 0..N`` on a uniform grid:

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

from collections.abc import Callable

import numpy as np

from planner.exceptions import PlanningFailed
from planner.results import Plan, SolverStats, SolveStatus
from planner.trajopt.centroidal.layout import to_dynamic_layout
from planner.trajopt.checks import precheck
from planner.trajopt.collision import (
    collision_diagnosis,
    missing_rows,
    select,
    set_collision_terms,
    sphere_pair_distances,
    sphere_sets,
)
from planner.trajopt.diagnose import diagnose_failure
from planner.trajopt.layout import Layout, make_layout
from planner.trajopt.report import configurations, make_plan
from planner.trajopt.settings import PlannerSettings
from planner.trajopt.solve import solve_layout
from robots.model import Robot
from tasks.specs import TaskSpec


def plan(spec: TaskSpec, robot: Robot, *, settings: PlannerSettings | None = None, throw: bool = True,
         progress: Callable[[str], None] | None = None) -> Plan:
    """Plan a whole-body motion for ``spec`` on ``robot``, starting and ending at rest.

    The motion starts at ``robot.q_standing``. Frames in the spec are role names
    (``right_hand``) or Pinocchio frame names.

    Args:
        spec: What to do.
        robot: Which robot does it.
        settings: Solver and cache settings (default :class:`PlannerSettings`).
        throw: Raise :class:`PlanningFailed` when the solve fails or a constraint group is
            violated; with False, return the (failed) plan with its ``diagnosis``.
        progress: Called with short messages ("building solver", "solving").

    Returns:
        The plan, on the uniform knot grid, with solver stats and the constraint report.

    Raises:
        robots.FrameNotFound: the spec names a frame the robot does not have.
        UnsupportedModel: the robot has joints the planner cannot model.
        PlanningFailed: the problem is infeasible or the solver failed (with ``throw``).
    """
    settings = settings or PlannerSettings()
    lay = make_layout(spec, robot)
    if spec.dynamic:  # CoM dynamics with contact forces (planner/trajopt/centroidal/, docs/dynamic.md)
        lay = to_dynamic_layout(lay, settings.centroidal)
        import dataclasses

        settings = dataclasses.replace(
            settings, ipopt_extra=(*settings.centroidal.ipopt_options, *settings.ipopt_extra),
            compile=settings.compile and settings.compile_dynamic)
    problem = precheck(lay)
    if problem:
        stats = SolverStats(status=SolveStatus.NOT_RUN)
        failed = make_plan(lay, np.zeros((lay.N + 1, robot.nv)), stats, settings, diagnosis=problem)
        if throw:
            raise PlanningFailed(problem, failed)
        return failed
    x0 = lay.initial_guess(settings)  # kinematic: the nominal motion; dynamic: the heading guess
    dq, stats, raw = _solve_with_collisions(lay, settings, progress, x0)
    forces = lay.forces_of(raw["x"])
    result = make_plan(lay, dq, stats, settings, forces=forces)
    if result.ok:
        return result
    if progress:
        progress("the solve failed: diagnosing")
    diagnosis = ""
    if settings.self_collision and settings.diagnose:
        diagnosis = collision_diagnosis(lay, settings)
    if not diagnosis:
        diagnosis = lay.diagnose(result, lambda: diagnose_failure(lay, result, settings, raw))
    result = make_plan(lay, dq, stats, settings, diagnosis=diagnosis, checks=result.checks, forces=forces)
    if throw:
        raise PlanningFailed(diagnosis, result)
    return result


def _solve_with_collisions(lay: Layout, settings: PlannerSettings, progress: Callable[[str], None] | None,
                           x0: np.ndarray) -> tuple[np.ndarray, SolverStats, dict]:
    """Solve with self-collision rows (planner/trajopt/collision.py): rows for the pairs the initial
    guess brings within the screening distance; then every pair is checked on the solution and a
    pair within the margin without rows is added and the NLP solved again from that solution."""
    if not settings.self_collision:
        return solve_layout(lay, settings, progress, x0=x0)
    robot = lay.robot
    sets = sphere_sets(robot)
    margin, screening = settings.collision_margin, settings.collision_screening
    n_kin = robot.nv * (lay.N - 2)
    dq0 = np.zeros((lay.N + 1, robot.nv))
    dq0[2:lay.N] = x0[:n_kin].reshape(lay.N - 2, robot.nv)
    dq0[lay.N] = dq0[lay.N - 1]
    rows = select(lay, sets, sphere_pair_distances(robot, sets, configurations(lay, dq0)), screening)
    set_collision_terms(lay, sets, rows, sorted(rows.spheres), margin)
    for round_ in range(settings.collision_rounds + 1):
        dq, stats, raw = solve_layout(lay, settings, progress, x0=x0)
        if not stats.status.ok or round_ == settings.collision_rounds:
            return dq, stats, raw
        more = missing_rows(lay, sets, rows, sphere_pair_distances(robot, sets, configurations(lay, dq)),
                            margin, screening)
        changed = rows.merge(more)
        if not changed:
            return dq, stats, raw
        if progress:
            progress(f"{len(changed)} more link pair(s) came within the collision margin: solving again")
        set_collision_terms(lay, sets, rows, changed, margin)
        x0 = raw["x"]
    return dq, stats, raw
