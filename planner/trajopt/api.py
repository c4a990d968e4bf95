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
* when ``spec.dynamic``: contact forces at the sole corners as extra variables, CoM dynamics
  ``m (c'' - g) = sum f``, friction pyramids, sole corners of swinging feet above the ground,
  an angular-momentum-rate cost (:mod:`planner.centroidal`, ``docs/dynamic.md``).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from planner import centroidal
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
        row_order: Term indices in the order their rows appear in ``g``.
        groups: Knot groups sharing one stage function: (knots, term indices per knot).
        velocity_joints: Tangent indices of the joints with a velocity limit.
        n_x_kin, n_g_kin: Variables and rows of the kinematic part (the chart displacements
            and their rows); a dynamic layout adds its force variables and rows after them.
    """

    n_x: int
    n_g: int
    row_order: list[int]
    groups: list[list[int]]
    velocity_joints: np.ndarray
    n_x_kin: int = -1
    n_g_kin: int = -1


@dataclass(eq=False)
class Solver:
    """A reusable solver for one problem structure."""

    function: ca.Function
    nlp_layout: NlpLayout
    origin: str = "built"  # "built", "disk", "memory"
    build_time: float = 0.0
    extras: dict = field(default_factory=dict)


def velocity_joints(lay: Layout) -> np.ndarray:
    """Tangent indices of actuated joints with a finite, positive velocity limit."""
    vmax = np.asarray(lay.robot.model.velocityLimit, dtype=float)
    idx = [i for i in range(6, lay.robot.nv) if 0.0 < vmax[i] < LIMIT_CLAMP]
    return np.array(idx, dtype=int)


def stage_groups(lay: Layout) -> list[tuple[tuple, list[int], list[list[int]]]]:
    """Variable knots grouped by the structure of their terms: (signature, knots, terms per knot)."""
    per_knot: dict[int, list[int]] = {k: [] for k in lay.variable_knots}
    for i, term in enumerate(lay.terms):
        per_knot[term.knot].append(i)
    groups: dict[tuple, tuple[list[int], list[list[int]]]] = {}
    for k, idx in per_knot.items():
        sig = tuple((lay.terms[i].structure, len(lay.terms[i].params), lay.terms[i].n_rows) for i in idx)
        knots, terms = groups.setdefault(sig, ([], []))
        knots.append(k)
        terms.append(idx)
    return [(sig, knots, terms) for sig, (knots, terms) in groups.items()]


def stage_function(lay: Layout, term_ids: list[int], name: str) -> ca.Function:
    """SX function ``(dq[nv], q_ref[nq], p) -> (g, cost)`` of the terms at one knot."""
    robot = lay.robot
    kin = SymbolicKinematics(robot.model)
    dq = ca.SX.sym("dq", robot.nv)
    q_ref = ca.SX.sym("q_ref", robot.nq)
    terms = [lay.terms[i] for i in term_ids]
    frame_ids = sorted({t.structure[1] for t in terms if t.kind in FRAME_KINDS})
    oMi = kin.joint_placements(q_ref, dq)
    k = {"com": kin.com(oMi), "frames": {f: kin.frame_placement(oMi, f)[::-1] for f in frame_ids}, "dq": dq}
    n_p = sum(len(t.params) for t in terms)
    p = ca.SX.sym("p", n_p)
    rows, cost, offset = [], 0, 0
    for t in terms:
        r, c = term_expression(t, p[offset: offset + len(t.params)], k, q_ref, robot)
        offset += len(t.params)
        cost = cost + c
        if r is not None:
            rows.append(r)
    g = ca.vertcat(*rows) if rows else ca.SX.zeros(0)
    return ca.Function(name, [dq, q_ref, p], [g, cost], ["dq", "q_ref", "p"], ["g", "cost"])


FRAME_KINDS = ("contact", "clearance", "frame_pos", "frame_rot")


def make_nlp_layout(lay: Layout) -> NlpLayout:
    """Variable/row bookkeeping of the NLP of a layout (pure Python, no CasADi)."""
    row_order: list[int] = []
    groups: list[list[int]] = []
    for _sig, knots, term_lists in stage_groups(lay):
        for idx in term_lists:
            row_order += [i for i in idx if not lay.terms[i].is_cost]
        groups.append(knots)
    vj = velocity_joints(lay)
    n_g = sum(lay.terms[i].n_rows for i in row_order) + len(vj) * (lay.N - 2)
    n_x = lay.robot.nv * (lay.N - 2)
    n_u, n_gd = centroidal.dynamic_sizes(lay) if isinstance(lay, centroidal.DynamicLayout) else (0, 0)
    return NlpLayout(n_x=n_x + n_u, n_g=n_g + n_gd, row_order=row_order, groups=groups,
                     velocity_joints=vj, n_x_kin=n_x, n_g_kin=n_g)


def _selection(lay: Layout, knots: list[int]) -> ca.DM:
    """Sparse (nv * len(knots), n_x) matrix picking the variables of ``knots`` from ``x``."""
    nv, n_x = lay.robot.nv, lay.robot.nv * (lay.N - 2)
    rows = np.arange(nv * len(knots))
    cols = np.concatenate([np.arange(nv) + nv * (k - 2) for k in knots])
    return _sparse(rows, cols, np.ones(len(rows)), (nv * len(knots), n_x))


def _sparse(rows, cols, values, shape) -> ca.DM:
    """Sparse DM from triplets (duplicates summed)."""
    from scipy.sparse import coo_matrix

    m = coo_matrix((np.asarray(values, dtype=float), (np.asarray(rows, dtype=int), np.asarray(cols, dtype=int))),
                   shape=shape).tocsc()
    m.sum_duplicates()
    return ca.DM(m)


def _quadratic_operators(lay: Layout) -> tuple[ca.DM, ca.DM, ca.DM]:
    """Constant operators of the quadratic costs and of the velocity rows.

    Returns:
        ``A`` (second differences of dq over knots 1..N-1), ``P`` (joint part of dq at knots
        2..N), ``D`` (velocity-limited joints of dq_{k+1} - dq_k for k = 1..N-2).
    """
    nv, N = lay.robot.nv, lay.N
    n_x = nv * (N - 2)

    def col(k: int) -> int | None:  # variable column block of knot k (None: fixed at 0)
        if k < 2:
            return None
        return nv * (min(k, N - 1) - 2)

    rows, cols, vals = [], [], []
    r = 0
    for k in range(1, N):
        for kk, c in ((k + 1, 1.0), (k, -2.0), (k - 1, 1.0)):
            b = col(kk)
            if b is not None:
                rows += list(range(r, r + nv))
                cols += list(range(b, b + nv))
                vals += [c] * nv
        r += nv
    A = _sparse(rows, cols, vals, (r, n_x))
    rows, cols, vals = [], [], []
    r = 0
    for k in range(2, N + 1):
        b = col(k)
        rows += list(range(r, r + nv - 6))
        cols += list(range(b + 6, b + nv))
        vals += [1.0] * (nv - 6)
        r += nv - 6
    P = _sparse(rows, cols, vals, (r, n_x))
    vj = velocity_joints(lay)
    rows, cols, vals = [], [], []
    r = 0
    for k in range(1, N - 1):
        for j in vj:
            for kk, c in ((k + 1, 1.0), (k, -1.0)):
                b = col(kk)
                if b is not None:
                    rows.append(r)
                    cols.append(b + j)
                    vals.append(c)
            r += 1
    D = _sparse(rows, cols, vals, (r, n_x))
    return A, P, D


def build_nlp(lay: Layout) -> tuple[dict, dict, NlpLayout]:
    """The CasADi NLP of a layout's structure (values come as parameters) and its derivatives.

    Knots with the same term structure share one SX stage function (with its Jacobian and
    Hessian) evaluated with ``map``; the NLP's gradient, constraint Jacobian and Lagrangian
    Hessian are assembled from those blocks and from constant sparse operators of the
    quadratic terms. The derivative code (and the generated C) therefore grows with the number
    of distinct stages, not with the number of knots.

    Returns:
        (nlp dict {x, p, f, g}, nlpsol options {grad_f, jac_g, hess_lag}, index bookkeeping).
    """
    robot = lay.robot
    nq, nv, N = robot.nq, robot.nv, lay.N
    nl = make_nlp_layout(lay)
    x = ca.MX.sym("x", nl.n_x_kin)
    X = ca.reshape(x, nv, N - 2)
    groups = stage_groups(lay)
    fns = [stage_function(lay, term_lists[0], f"stage{gi}") for gi, (_s, _k, term_lists) in enumerate(groups)]
    n_p = nq + 3 + sum(fn.size1_in(2) * len(knots) for fn, (_s, knots, _t) in zip(fns, groups, strict=True))
    p = ca.MX.sym("p", n_p)
    lam_f = ca.MX.sym("lam_f")
    lam_g = ca.MX.sym("lam_g", nl.n_g_kin)
    q_ref = p[0:nq]
    w_smooth, w_posture, dt = p[nq], p[nq + 1], p[nq + 2]
    c_smooth = w_smooth / dt**3
    c_posture = w_posture * dt
    A, P, D = _quadratic_operators(lay)
    AtA, PtP = ca.mtimes(A.T, A), ca.mtimes(P.T, P)
    f = c_smooth * ca.sumsqr(ca.mtimes(A, x)) + c_posture * ca.sumsqr(ca.mtimes(P, x))
    grad = 2 * c_smooth * ca.mtimes(AtA, x) + 2 * c_posture * ca.mtimes(PtP, x)
    hess = lam_f * (2 * c_smooth * AtA + 2 * c_posture * PtP)
    g, jac = [], []
    p_offset, g_offset = nq + 3, 0
    for fn, (_sig, knots, _terms) in zip(fns, groups, strict=True):
        n = len(knots)
        dq, qr, ps = ca.SX.sym("dq", nv), ca.SX.sym("q_ref", nq), ca.SX.sym("p", fn.size1_in(2))
        sigma = ca.SX.sym("sigma")
        gk, ck = fn(dq, qr, ps)
        lam = ca.SX.sym("lam", gk.numel())
        jac_fn = ca.Function("jac_" + fn.name(), [dq, qr, ps], [ca.jacobian(gk, dq)])
        grad_fn = ca.Function("grad_" + fn.name(), [dq, qr, ps], [ca.gradient(ck, dq)])
        hess_fn = ca.Function("hess_" + fn.name(), [dq, qr, ps, sigma, lam],
                              [ca.hessian(sigma * ck + ca.dot(lam, gk), dq)[0]])
        Xg = X[:, [k - 2 for k in knots]]
        Qr = ca.repmat(q_ref, 1, n)
        Pg = ca.reshape(p[p_offset: p_offset + fn.size1_in(2) * n], fn.size1_in(2), n)
        p_offset += fn.size1_in(2) * n
        G, C = fn.map(n)(Xg, Qr, Pg)
        JG = jac_fn.map(n)(Xg, Qr, Pg)
        GC = grad_fn.map(n)(Xg, Qr, Pg)
        rows = gk.numel()
        L = ca.reshape(lam_g[g_offset: g_offset + rows * n], rows, n)
        g_offset += rows * n
        HS = hess_fn.map(n)(Xg, Qr, Pg, ca.repmat(lam_f, 1, n), L)
        S = _selection(lay, knots)
        f = f + ca.sum2(C)
        if ck.is_zero():
            GC = ca.MX.zeros(nv, n)
        grad = grad + ca.mtimes(S.T, ca.vec(GC))
        hess = hess + ca.mtimes(S.T, ca.mtimes(ca.diagcat(*ca.horzsplit(HS, nv)), S))
        if rows:
            g.append(ca.vec(G))
            jac.append(ca.mtimes(ca.diagcat(*ca.horzsplit(JG, nv)), S))
    g.append(ca.mtimes(D, x))
    jac.append(ca.MX(D))
    g_all, jac_all = ca.vertcat(*g), ca.vertcat(*jac)
    if g_all.numel() != nl.n_g_kin:
        raise PlannerError(f"internal: {g_all.numel()} constraint rows built, {nl.n_g_kin} expected")
    nlp = {"x": x, "p": p, "f": f, "g": g_all}
    derivatives = {
        "grad_f": ca.Function("nlp_grad_f", [x, p], [f, grad], ["x", "p"], ["f", "grad_f_x"]),
        "jac_g": ca.Function("nlp_jac_g", [x, p], [g_all, jac_all], ["x", "p"], ["g", "jac_g_x"]),
        "hess_lag": ca.Function("nlp_hess_l", [x, p, lam_f, lam_g], [ca.triu(hess)],
                                ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"]),
    }
    if isinstance(lay, centroidal.DynamicLayout):  # forces, CoM dynamics, sole corners
        nlp, derivatives = centroidal.extend_nlp(lay, nlp, derivatives)
    return nlp, derivatives, nl


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
            "obj_scaling_factor": float(settings.objective_scaling),
            **dict(settings.ipopt_extra),
        },
    }


def parameter_values(lay: Layout, nl: NlpLayout) -> np.ndarray:
    """The NLP parameter vector of a layout (same order as :func:`build_nlp`)."""
    spec = lay.spec
    parts = [lay.q_ref, [spec.smoothness_weight, spec.posture_weight, lay.dt]]
    per_knot: dict[int, list] = {}
    for term in lay.terms:
        per_knot.setdefault(term.knot, []).append(term.params)
    for knots in nl.groups:
        for k in knots:
            parts += per_knot.get(k, [])
    p = np.concatenate([np.asarray(x, dtype=float).ravel() for x in parts])
    if isinstance(lay, centroidal.DynamicLayout):
        p = centroidal.extend_parameters(lay, p)
    return p


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
    lbg = [lay.terms[i].lower for i in nl.row_order]
    ubg = [lay.terms[i].upper for i in nl.row_order]
    vmax = np.asarray(robot.model.velocityLimit, dtype=float)[nl.velocity_joints] * lay.dt
    lbg += [-vmax] * (N - 2)
    ubg += [vmax] * (N - 2)
    if isinstance(lay, centroidal.DynamicLayout):
        return centroidal.extend_bounds(lay, lbx, ubx, np.concatenate(lbg), np.concatenate(ubg))
    return lbx, ubx, np.concatenate(lbg), np.concatenate(ubg)


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
    p = parameter_values(lay, nl)
    if x0 is None:
        x0 = centroidal.initial_guess(lay) if isinstance(lay, centroidal.DynamicLayout) else np.zeros(nl.n_x)
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
    dq[2:lay.N] = x[: lay.robot.nv * (lay.N - 2)].reshape(lay.N - 2, lay.robot.nv)
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
    from planner.diagnose import diagnose_failure, precheck

    settings = settings or PlannerSettings()
    lay = make_layout(spec, robot)
    if spec.dynamic:  # CoM dynamics with contact forces (planner/centroidal.py, docs/dynamic.md)
        lay = centroidal.to_dynamic_layout(lay, settings.centroidal)
        import dataclasses

        settings = dataclasses.replace(
            settings, ipopt_extra=(*settings.centroidal.ipopt_options, *settings.ipopt_extra),
            compile=settings.compile and settings.compile_dynamic)
    problem = precheck(lay)
    if problem:
        stats = SolverStats(status=SolveStatus.NOT_RUN)
        failed = _make_plan(lay, np.zeros((lay.N + 1, robot.nv)), stats, settings, diagnosis=problem)
        if throw:
            raise PlanningFailed(problem, failed)
        return failed
    x0 = None
    if settings.warm_start == "nominal" and not isinstance(lay, centroidal.DynamicLayout):
        from planner.nominal import nominal_motion

        x0 = nominal_motion(lay)[2:lay.N].ravel()
    forces = None
    if isinstance(lay, centroidal.DynamicLayout):  # base along the feet's heading, weight on the corners
        x0 = centroidal.initial_guess(lay)
    dq, stats, raw = solve_layout(lay, settings, progress, x0=x0)
    if isinstance(lay, centroidal.DynamicLayout):
        forces = centroidal.forces_of(lay, raw["x"])
    result = _make_plan(lay, dq, stats, settings, forces=forces)
    if result.ok:
        return result
    if progress:
        progress("the solve failed: diagnosing")
    if isinstance(lay, centroidal.DynamicLayout):
        diagnosis = centroidal.diagnose_dynamic(lay, result)
    else:
        diagnosis = diagnose_failure(lay, result, settings, raw)
    result = _make_plan(lay, dq, stats, settings, diagnosis=diagnosis, checks=result.checks, forces=forces)
    if throw:
        raise PlanningFailed(diagnosis, result)
    return result


def _make_plan(lay: Layout, dq: np.ndarray, stats: SolverStats, settings: PlannerSettings, *,
               diagnosis: str = "", checks=None, forces: np.ndarray | None = None) -> Plan:
    from planner.diagnose import check_plan, finite_differences

    q = configurations(lay, dq)
    v, a = finite_differences(lay.robot.model, q, lay.dt)
    com = com_trajectory(lay.robot, q)
    if checks is None:
        checks = check_plan(lay, q, v, com, settings)
        if isinstance(lay, centroidal.DynamicLayout):
            checks = centroidal.dynamic_plan_checks(lay, q, com, forces, checks, settings)
    extras = {"frame_names": {fid: lay.robot.model.frames[fid].name for fid in lay.frame_ids}}
    plan_forces = {}
    if isinstance(lay, centroidal.DynamicLayout) and forces is not None:
        corner = lay.pattern().corner_forces(forces)
        plan_forces = {frame: f.sum(axis=1) for frame, f in corner.items()}
        extras["corner_forces"] = corner
    return Plan(robot=lay.robot.name, spec=lay.spec, t=lay.t.copy(), q=q, v=v, a=a, com=com, stats=stats,
                checks=tuple(checks), diagnosis=diagnosis, forces=plan_forces, extras=extras)


def com_trajectory(robot: Robot, q: np.ndarray) -> np.ndarray:
    """Centre of mass per configuration (T, 3) [m], Pinocchio numerics."""
    import pinocchio as pin

    data = robot.data()
    return np.array([np.array(pin.centerOfMass(robot.model, data, qk)) for qk in q])
