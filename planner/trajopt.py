"""Whole-body trajectory optimization of a TaskSpec: CasADi NLP, solved with IPOPT.

:func:`plan` is the entry point. It lays the spec out on a knot grid
(:mod:`planner.formulation`), fetches or builds the solver for that layout's *structure*
(:mod:`planner.cache`: in memory, or compiled C code on disk), feeds it the layout's *values*
as parameters and bounds, solves, and reports the result checked with Pinocchio numerics
(:mod:`planner.diagnose`).

The NLP (DESIGN.md section 3), for knots ``k = 0..N`` on a uniform grid:

* variables ``dq_k`` (nv) for ``k = 2..N-1``, tangent displacements around ``q_ref`` (the
  standing posture); ``dq_0 = dq_1 = 0`` (start at rest) and ``dq_N = dq_{N-1}`` (end at rest);
* joint position limits as variable bounds, joint velocity limits as finite-difference rows;
* the layout's terms: stance soles in 6D, swing clearance, CoM support polygon and box,
  frame/CoM targets (hard: constraint, soft: cost), joint targets (cost);
* cost ``w_s sum |dq_{k+1} - 2 dq_k + dq_{k-1}|^2 / dt^3 + w_p dt sum |dq_k[joints]|^2`` plus
  the soft terms.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from planner.exceptions import PlannerError, PlanningFailed
from planner.formulation import Layout, Term, make_layout
from planner.plan import Plan, SolverStats, SolveStatus
from planner.settings import PlannerSettings
from planner.symbolic import SymbolicKinematics, chart_to_configuration, rotation_error
from robots.model import Robot
from tasks.specs import TaskSpec

LIMIT_CLAMP = 1e10  # limits beyond this magnitude are treated as absent


@dataclass(eq=False)
class NlpLayout:
    """Index bookkeeping of a built NLP (shared by every solve with the same structure).

    Attributes:
        n_x: Number of variables.
        n_g: Number of constraint rows.
        term_rows: Start row of each term's constraint rows (-1 for a cost term).
        velocity_rows: Start row of the velocity-limit rows.
        velocity_joints: Tangent indices of the joints with a velocity limit.
    """

    n_x: int
    n_g: int
    term_rows: list[int]
    velocity_rows: int
    velocity_joints: np.ndarray


@dataclass(eq=False)
class Solver:
    """A reusable solver for one problem structure."""

    function: ca.Function
    nlp_layout: NlpLayout
    origin: str = "built"  # "built", "disk"
    build_time: float = 0.0
    extras: dict = field(default_factory=dict)


def velocity_joints(lay: Layout) -> np.ndarray:
    """Tangent indices of actuated joints with a finite, positive velocity limit."""
    vmax = np.asarray(lay.robot.model.velocityLimit, dtype=float)
    idx = [i for i in range(6, lay.robot.nv) if 0.0 < vmax[i] < LIMIT_CLAMP]
    return np.array(idx, dtype=int)


def build_nlp(lay: Layout) -> tuple[dict, NlpLayout]:
    """The CasADi SX NLP ``{x, p, f, g}`` of a layout's structure (values come as parameters)."""
    robot = lay.robot
    nq, nv, N = robot.nq, robot.nv, lay.N
    kin = SymbolicKinematics(robot.model)
    X = ca.SX.sym("dq", nv, N - 2)
    q_ref = ca.SX.sym("q_ref", nq)
    w_smooth = ca.SX.sym("w_smooth")
    w_posture = ca.SX.sym("w_posture")
    dt = ca.SX.sym("dt")
    zero = ca.SX.zeros(nv)

    def dq_at(k: int):
        if k < 2:
            return zero
        return X[:, min(k, N - 1) - 2]

    fk = kin.function(lay.frame_ids)
    kin_at: dict[int, dict] = {}

    def kinematics(k: int) -> dict:
        if k not in kin_at:
            outs = fk(q_ref, dq_at(k))
            frames = {fid: (outs[1 + 2 * i], outs[2 + 2 * i]) for i, fid in enumerate(lay.frame_ids)}
            kin_at[k] = {"com": outs[0], "frames": frames, "dq": dq_at(k)}
        return kin_at[k]

    params = [q_ref, w_smooth, w_posture, dt]
    g: list = []
    cost = 0
    term_rows: list[int] = []
    n_rows = 0
    for term in lay.terms:
        p = ca.SX.sym(f"p_{term.kind}_{term.knot}", len(term.params))
        params.append(p)
        rows, c = term_expression(term, p, kinematics(term.knot), q_ref, robot)
        cost = cost + c
        if rows is not None:
            term_rows.append(n_rows)
            g.append(rows)
            n_rows += rows.numel()
        else:
            term_rows.append(-1)
    # velocity limits: finite differences between consecutive knots with a variable
    vj = velocity_joints(lay)
    velocity_rows = n_rows
    for k in range(1, N - 1):
        g.append((dq_at(k + 1) - dq_at(k))[vj.tolist()])
        n_rows += len(vj)
    # smoothness + posture
    for k in range(1, N):
        acc = dq_at(k + 1) - 2 * dq_at(k) + dq_at(k - 1)
        cost = cost + w_smooth * ca.sumsqr(acc) / dt**3
    for k in range(2, N + 1):
        cost = cost + w_posture * dt * ca.sumsqr(dq_at(k)[6:])
    nlp = {"x": ca.vec(X), "p": ca.vertcat(*params), "f": cost, "g": ca.vertcat(*g)}
    return nlp, NlpLayout(n_x=nv * (N - 2), n_g=n_rows, term_rows=term_rows,
                          velocity_rows=velocity_rows, velocity_joints=vj)


def term_expression(term: Term, p, kin: dict, q_ref, robot: Robot):
    """(constraint rows or None, cost) of one term, given its parameter symbol ``p``."""
    s = term.structure
    kind = term.kind
    if kind == "contact":
        pos, R = kin["frames"][s[1]]
        R_t = ca.reshape(p[3:12], 3, 3)
        return ca.vertcat(pos - p[0:3], rotation_error(R_t, R)), 0
    if kind == "clearance":
        pos, _ = kin["frames"][s[1]]
        return pos[2], 0
    if kind == "polygon":
        A = ca.reshape(p, s[1], 2)
        return ca.mtimes(A, kin["com"][0:2]), 0
    if kind == "com_box":
        return kin["com"][[i for i, a in enumerate(s[1]) if a]], 0
    if kind in ("frame_pos", "com_pos"):
        if kind == "frame_pos":
            pos, _ = kin["frames"][s[1]]
            axes, mode = s[2], s[3]
        else:
            pos = kin["com"]
            axes, mode = s[1], s[2]
        err = (pos - p[0:3])[[i for i, a in enumerate(axes) if a]]
        return _target_rows(err, mode, p[3])
    if kind == "frame_rot":
        _, R = kin["frames"][s[1]]
        err = rotation_error(ca.reshape(p[0:9], 3, 3), R)
        return _target_rows(err, s[2], p[9])
    if kind == "joint":
        iv = s[1]
        value = q_ref[iv + 1] + kin["dq"][iv]  # one-dof joints: idx_q = idx_v + 1
        return None, p[1] * (value - p[0]) ** 2
    raise PlannerError(f"internal: unknown term kind {kind!r}")


def _target_rows(err, mode: str, weight):
    if mode in ("eq", "box"):
        return err, 0
    return None, weight * ca.sumsqr(err)


def ipopt_options(settings: PlannerSettings) -> dict:
    """nlpsol options for IPOPT + MUMPS with the exact Hessian."""
    return {
        "print_time": False,
        "ipopt": {
            "print_level": int(settings.print_level),
            "sb": "yes",
            "max_iter": int(settings.max_iterations),
            "tol": float(settings.tolerance),
            "constr_viol_tol": float(settings.constraint_tolerance),
            "linear_solver": "mumps",
            "mu_strategy": "adaptive",
        },
    }


def parameter_values(lay: Layout) -> np.ndarray:
    """The NLP parameter vector of a layout (same order as :func:`build_nlp`)."""
    spec = lay.spec
    parts = [lay.q_ref, [spec.smoothness_weight, spec.posture_weight, lay.dt]]
    parts += [t.params for t in lay.terms]
    return np.concatenate([np.asarray(x, dtype=float).ravel() for x in parts])


def bounds(lay: Layout, nl: NlpLayout) -> tuple[np.ndarray, ...]:
    """(lbx, ubx, lbg, ubg) of a layout."""
    robot, N, nv = lay.robot, lay.N, lay.robot.nv
    lo = np.full(nv, -np.inf)
    hi = np.full(nv, np.inf)
    lower = np.asarray(robot.model.lowerPositionLimit, dtype=float)[7:]
    upper = np.asarray(robot.model.upperPositionLimit, dtype=float)[7:]
    ref = lay.q_ref[7:]
    lo[6:] = np.where(np.abs(lower) < LIMIT_CLAMP, np.minimum(lower - ref, 0.0), -np.inf)
    hi[6:] = np.where(np.abs(upper) < LIMIT_CLAMP, np.maximum(upper - ref, 0.0), np.inf)
    lbx = np.tile(lo, N - 2)
    ubx = np.tile(hi, N - 2)
    lbg = [t.lower for t in lay.terms if not t.is_cost]
    ubg = [t.upper for t in lay.terms if not t.is_cost]
    vmax = np.asarray(robot.model.velocityLimit, dtype=float)[nl.velocity_joints] * lay.dt
    lbg += [-vmax] * (N - 2)
    ubg += [vmax] * (N - 2)
    lbg_a = np.concatenate(lbg) if lbg else np.zeros(0)
    ubg_a = np.concatenate(ubg) if ubg else np.zeros(0)
    return lbx, ubx, lbg_a, ubg_a


_STATUS = {
    "Solve_Succeeded": SolveStatus.SOLVED,
    "Solved_To_Acceptable_Level": SolveStatus.SOLVED_INACCURATE,
    "Infeasible_Problem_Detected": SolveStatus.INFEASIBLE,
    "Restoration_Failed": SolveStatus.INFEASIBLE,
    "Maximum_Iterations_Exceeded": SolveStatus.MAX_ITERATIONS,
    "Maximum_CpuTime_Exceeded": SolveStatus.MAX_ITERATIONS,
    "Maximum_WallTime_Exceeded": SolveStatus.MAX_ITERATIONS,
}


def solve_layout(lay: Layout, settings: PlannerSettings, progress: Callable[[str], None] | None = None,
                 x0: np.ndarray | None = None) -> tuple[np.ndarray, SolverStats, dict]:
    """Fetch/build the solver of a layout, solve, return (dq per knot (N+1, nv), stats, raw)."""
    from planner.cache import get_solver

    t0 = time.perf_counter()
    solver = get_solver(lay, settings, progress)
    build_time = time.perf_counter() - t0
    nl = solver.nlp_layout
    lbx, ubx, lbg, ubg = bounds(lay, nl)
    p = parameter_values(lay)
    if x0 is None:
        x0 = np.zeros(nl.n_x)
    if progress:
        progress(f"solving ({nl.n_x} variables, {nl.n_g} constraints)")
    t1 = time.perf_counter()
    sol = solver.function(x0=x0, p=p, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)
    solve_time = time.perf_counter() - t1
    st = solver.function.stats()
    raw = str(st.get("return_status", ""))
    status = _STATUS.get(raw, SolveStatus.NUMERICAL_ERROR if raw else SolveStatus.NOT_RUN)
    x = np.asarray(sol["x"], dtype=float).ravel()
    dq = np.zeros((lay.N + 1, lay.robot.nv))
    dq[2:lay.N] = x.reshape(lay.N - 2, lay.robot.nv)
    dq[lay.N] = dq[lay.N - 1]
    stats = SolverStats(
        status=status, iterations=int(st.get("iter_count", 0)), build_time=build_time,
        solve_time=solve_time, cache=solver.origin, objective=float(sol["f"]),
        n_variables=nl.n_x, n_constraints=nl.n_g, raw_status=raw,
    )
    return dq, stats, {"x": x, "lam_g": np.asarray(sol["lam_g"]).ravel(), "g": np.asarray(sol["g"]).ravel(),
                       "lbg": lbg, "ubg": ubg, "nlp_layout": nl}


def configurations(lay: Layout, dq: np.ndarray) -> np.ndarray:
    """Configurations (N+1, nq) from the chart displacements."""
    model = lay.robot.model
    return np.array([chart_to_configuration(model, lay.q_ref, d) for d in dq])


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
    from planner.diagnose import check_plan, diagnose_failure, precheck

    settings = settings or PlannerSettings()
    if spec.dynamic:
        raise PlannerError(
            f"spec {spec.name or '(unnamed)'!r} asks for CoM dynamics (dynamic=true), which the planner does not "
            "model yet; set dynamic to false for a quasi-static plan"
        )
    lay = make_layout(spec, robot)
    problem = precheck(lay)
    if problem:
        stats = SolverStats(status=SolveStatus.NOT_RUN)
        failed = _make_plan(lay, np.zeros((lay.N + 1, robot.nv)), stats, settings, diagnosis=problem)
        if throw:
            raise PlanningFailed(problem, failed)
        return failed
    dq, stats, raw = solve_layout(lay, settings, progress)
    result = _make_plan(lay, dq, stats, settings)
    if result.ok:
        return result
    if progress:
        progress("the solve failed: diagnosing")
    diagnosis = diagnose_failure(lay, result, settings, raw)
    result = _make_plan(lay, dq, stats, settings, diagnosis=diagnosis, checks=result.checks)
    if throw:
        raise PlanningFailed(diagnosis, result)
    return result


def _make_plan(lay: Layout, dq: np.ndarray, stats: SolverStats, settings: PlannerSettings, *,
               diagnosis: str = "", checks=None) -> Plan:
    from planner.diagnose import check_plan, finite_differences

    q = configurations(lay, dq)
    v, a = finite_differences(lay.robot.model, q, lay.dt)
    com = com_trajectory(lay.robot, q)
    if checks is None:
        checks = check_plan(lay, q, v, com, settings)
    return Plan(robot=lay.robot.name, spec=lay.spec, t=lay.t.copy(), q=q, v=v, a=a, com=com, stats=stats,
                checks=tuple(checks), diagnosis=diagnosis,
                extras={"frame_names": {fid: lay.robot.model.frames[fid].name for fid in lay.frame_ids}})


def com_trajectory(robot: Robot, q: np.ndarray) -> np.ndarray:
    """Centre of mass per configuration (T, 3) [m], Pinocchio numerics."""
    import pinocchio as pin

    data = robot.data()
    return np.array([np.array(pin.centerOfMass(robot.model, data, qk)) for qk in q])
