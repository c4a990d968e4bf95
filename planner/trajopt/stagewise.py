"""A stage-wise transcription of the kinematic formulation, solvable by fatrop or IPOPT.

The current transcription (:mod:`planner.trajopt.transcription`) has one block of variables per
knot, the chart displacements ``dq_k``, and its smoothness cost couples three knots (second
differences). This one writes the same problem as an optimal control problem with the structure
fatrop needs (issue 30):

* one *stage* per knot ``k = 1..N-1`` (knot 0 is at rest, knot N repeats knot N-1);
* *states* ``x_k = (dq_k, v_k)``: the chart displacement (nv) and the chart velocity
  ``v_k = (dq_k - dq_{k-1}) / dt`` (nv) [m/s, rad/s];
* *controls* ``u_k = a_k`` (nv), the chart acceleration [m/s^2, rad/s^2], for ``k = 1..N-2``;
* *gap rows* (the dynamics) ``dq_{k+1} = dq_k + dt v_k + dt^2 a_k``, ``v_{k+1} = v_k + dt a_k``,
  touching stages ``k`` and ``k+1`` only;
* *path rows* of one stage only: ``dq_1 = 0``, ``v_1 = 0`` (start at rest) at the first stage, the
  layout's terms of knot ``k`` (contacts, clearance, support polygon, targets, collision rows) at
  stage ``k``;
* joint position limits (on ``dq_k``) and joint velocity limits (on ``v_k``, ``k >= 2``) as bounds;
* a cost that is a sum of per-stage costs: ``w_s dt |a_k|^2`` (the current transcription's
  ``w_s |dq_{k+1} - 2 dq_k + dq_{k-1}|^2 / dt^3``, since that second difference is ``dt^2 a_k``),
  the posture cost on ``dq_k``, the soft terms of knot ``k``; at the last stage ``w_s |v|^2 / dt``
  (the second difference at knot N-1 with ``dq_N = dq_{N-1}``) and the posture cost twice (knot N).

It is the same problem under a change of variables: the same optimum as the current transcription
(tests/planner/trajopt/test_stagewise.py compares the two). Its Lagrangian Hessian is block
diagonal per stage and its constraint Jacobian has the banded form ``[A_k B_k -I]`` plus per-stage
rows, which fatrop's Riccati recursion factorizes in ``O(N (nx + nu)^3)``; IPOPT with MUMPS solves
it too.

Variables, in stage order: ``[dq_1, v_1, a_1, dq_2, v_2, a_2, ..., dq_{N-1}, v_{N-1}]``; rows, in
stage order: the gap rows of stage ``k`` (to ``k+1``), then its path rows. Only the kinematic
formulation (``lay.extra_sizes() == (0, 0)``) is written this way; a dynamic layout's forces,
lifted CoM and momentum rows are not (:class:`StagewiseUnsupported`).
"""

from __future__ import annotations

import time
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

from planner.exceptions import PlannerError, StagewiseUnsupported
from planner.results import SolverStats, SolveStatus
from planner.trajopt.ipopt import _STATUS, ipopt_options
from planner.trajopt.layout import Layout
from planner.trajopt.settings import PlannerSettings
from planner.trajopt.solver_output import SolverOutput
from planner.trajopt.symbolic import model_hash
from planner.trajopt.terms import stage_groups
from planner.trajopt.transcription import (
    _sparse,
    chart_position_limits,
    make_nlp_layout,
    parameter_values,
    stage,
    velocity_joints,
)

SOLVERS = ("ipopt", "fatrop")
METIS = 5  # IPOPT's mumps_pivot_order for METIS


@dataclass(frozen=True, eq=False)
class StageLayout:
    """Index bookkeeping of a stage-wise NLP.

    Attributes:
        nv: Chart size.
        N: Intervals of the layout (knots 0..N); the OCP has stages for knots 1..N-1.
        nx, nu, ng: States, controls and path rows per stage (fatrop's ``nx``, ``nu``, ``ng``).
        x_offset: Offset of each stage's variables in ``x`` (stage s is knot s + 1).
        row_terms: Per stage, the indices of the layout's terms whose rows it holds, in order.
        row_stage: The stage of every row of ``g``.
        gap_rows: True for the rows of ``g`` that are gap rows (the dynamics).
        n_x, n_g: Variables and rows.
    """

    nv: int
    N: int
    nx: tuple[int, ...]
    nu: tuple[int, ...]
    ng: tuple[int, ...]
    x_offset: np.ndarray
    row_terms: tuple[tuple[int, ...], ...]
    row_stage: np.ndarray
    gap_rows: np.ndarray
    n_x: int
    n_g: int

    @property
    def stages(self) -> int:
        """Number of stages (knots 1..N-1)."""
        return self.N - 1

    def knot_of_stage(self, s: int) -> int:
        """The knot of stage ``s``."""
        return s + 1

    def stage_columns(self, s: int) -> range:
        """Columns of ``x`` that belong to stage ``s`` (its states, then its controls)."""
        start = int(self.x_offset[s])
        return range(start, start + self.nx[s] + self.nu[s])


def stage_layout(lay: Layout) -> StageLayout:
    """The stage-wise bookkeeping of a kinematic layout (pure Python, no CasADi).

    Raises:
        StagewiseUnsupported: the layout's formulation adds variables or rows (a dynamic spec).
    """
    if lay.extra_sizes() != (0, 0):
        raise StagewiseUnsupported(
            "the stage-wise transcription writes kinematic plans only (this spec is dynamic: contact "
            "forces and CoM dynamics); use the default transcription for it")
    nv, N = lay.robot.nv, lay.N
    K = N - 1
    per_knot: dict[int, list[int]] = {k: [] for k in range(1, N)}
    for i, term in enumerate(lay.terms):
        if not term.is_cost:
            per_knot[term.knot].append(i)
    nx = tuple([2 * nv] * K)
    nu = tuple([nv] * (K - 1) + [0])
    ng = tuple((2 * nv if s == 0 else 0) + sum(lay.terms[i].n_rows for i in per_knot[s + 1]) for s in range(K))
    x_offset = np.concatenate([[0], np.cumsum(np.add(nx, nu))[:-1]]).astype(int)
    row_stage, gap = [], []
    for s in range(K):
        if s < K - 1:
            row_stage += [s] * nx[s + 1]
            gap += [True] * nx[s + 1]
        row_stage += [s] * ng[s]
        gap += [False] * ng[s]
    return StageLayout(nv=nv, N=N, nx=nx, nu=nu, ng=ng, x_offset=x_offset,
                       row_terms=tuple(tuple(per_knot[s + 1]) for s in range(K)),
                       row_stage=np.array(row_stage, dtype=int), gap_rows=np.array(gap, dtype=bool),
                       n_x=int(sum(nx) + sum(nu)), n_g=len(row_stage))


def _columns(sl: StageLayout, part: int, knots: list[int]) -> np.ndarray:
    """Columns of ``x`` of ``dq`` (part 0), ``v`` (1) or ``a`` (2) at ``knots``, knot by knot."""
    return np.concatenate([sl.x_offset[k - 1] + part * sl.nv + np.arange(sl.nv) for k in knots])


def _picker(sl: StageLayout, cols: np.ndarray) -> ca.DM:
    """Sparse (len(cols), n_x) matrix picking the columns ``cols`` of ``x``."""
    return _sparse(np.arange(len(cols)), cols, np.ones(len(cols)), (len(cols), sl.n_x))


def build_stagewise_nlp(lay: Layout, symmetric_hessian: bool,
                        objective_scale: float = 1.0) -> tuple[dict, dict, StageLayout]:
    """The stage-wise CasADi NLP of a layout's structure (values as parameters, the same parameter
    vector as :func:`planner.trajopt.transcription.parameter_values`) and its derivatives.

    The term rows and costs come from the same per-knot SX stage functions as the current
    transcription (:func:`planner.trajopt.transcription.stage`, mapped over the knots of a group);
    the gap rows, the quadratic costs and their derivatives are assembled from constant sparse
    operators scaled by ``dt`` and the weights.

    Args:
        lay: A kinematic layout.
        symmetric_hessian: Give the whole Lagrangian Hessian (fatrop needs it) instead of its
            upper triangle (IPOPT's).
        objective_scale: A factor on the cost (fatrop has no ``obj_scaling_factor``: the
            settings' ``objective_scaling`` is applied here for it).

    Returns:
        (nlp dict {x, p, f, g}, nlpsol options {grad_f, jac_g, hess_lag}, bookkeeping).
    """
    sl = stage_layout(lay)
    robot = lay.robot
    nq, nv, N, K = robot.nq, robot.nv, lay.N, sl.stages
    groups = stage_groups(lay)  # the parameter vector's order: stagewise_parameters gives it
    stages = [stage(lay, term_lists[0]) for _s, _k, term_lists in groups]
    n_p = nq + 3 + sum(st.fn.size1_in(2) * len(knots) for st, (_s, knots, _t) in zip(stages, groups, strict=True))
    x = ca.MX.sym("x", sl.n_x)
    p = ca.MX.sym("p", n_p)
    lam_f = ca.MX.sym("lam_f")
    lam_g = ca.MX.sym("lam_g", sl.n_g)
    q_ref = p[0:nq]
    w_smooth, w_posture, dt = p[nq], p[nq + 1], p[nq + 2]
    c_posture = w_posture * dt

    # Quadratic costs: f = sum_j W_j x_j^2 with W = B @ [c_posture, w_s dt, w_s / dt] (B constant).
    B = _cost_selector(sl, N, nv)
    W = ca.mtimes(B, ca.vertcat(c_posture, w_smooth * dt, w_smooth / dt))
    f = ca.dot(W, x * x)
    grad = 2 * W * x

    # Gap rows, stage by stage: dq_{k+1} - dq_k - dt v_k - dt^2 a_k and v_{k+1} - v_k - dt a_k.
    gap_dq, gap_v, jac_gap_dq, jac_gap_v = _gap_rows(sl, N, x, dt)

    # Start at rest: dq_1 = 0, v_1 = 0.
    start = _picker(sl, np.concatenate([_columns(sl, 0, [1]), _columns(sl, 1, [1])]))

    # The layout's terms, per stage group (knots with the same terms share one SX function).
    term_g, term_jac, hessian_blocks = [], [], []
    g_rows_of_term: dict[int, tuple[int, int]] = {}  # term index -> (offset in the term block, rows)
    p_offset, t_offset = nq + 3, 0
    for st, (_sig, gknots, term_lists) in zip(stages, groups, strict=True):
        n = len(gknots)
        n_ps = st.fn.size1_in(2)
        S = _picker(sl, _columns(sl, 0, gknots))
        Xg = ca.reshape(ca.mtimes(S, x), nv, n)
        Qr = ca.repmat(q_ref, 1, n)
        Pg = ca.reshape(p[p_offset: p_offset + n_ps * n], n_ps, n)
        p_offset += n_ps * n
        G, C = st.fn.map(n)(Xg, Qr, Pg)
        f = f + ca.sum2(C)
        if not st.cost_is_zero:
            grad = grad + ca.mtimes(S.T, ca.vec(st.grad.map(n)(Xg, Qr, Pg)))
        hessian_blocks.append((st, n, Xg, Qr, Pg, S, t_offset))
        if st.rows:
            for j, idx in enumerate(term_lists):
                r = t_offset + j * st.rows
                for i in idx:
                    if not lay.terms[i].is_cost:
                        g_rows_of_term[i] = (r, lay.terms[i].n_rows)
                        r += lay.terms[i].n_rows
            term_g.append(ca.vec(G))
            JG = st.jac.map(n)(Xg, Qr, Pg)
            term_jac.append(ca.mtimes(ca.diagcat(*ca.horzsplit(JG, nv)), S))
        t_offset += st.rows * n
    n_term_rows = t_offset

    # Every row in one natural order, then permuted into stage order.
    g_nat = ca.vertcat(gap_dq, gap_v, ca.mtimes(start, x), *term_g)
    jac_nat = ca.vertcat(jac_gap_dq, jac_gap_v, ca.MX(start), *term_jac)
    n_gap = nv * (K - 1)
    perm = _stage_order(sl, nv, g_rows_of_term)
    if len(perm) != sl.n_g or g_nat.numel() != 2 * n_gap + 2 * nv + n_term_rows:
        raise PlannerError(f"internal: {g_nat.numel()} stage-wise rows built, {sl.n_g} expected")
    g_all = g_nat[perm]
    jac_all = jac_nat[perm, :]
    if objective_scale != 1.0:
        f, grad, W = objective_scale * f, objective_scale * grad, objective_scale * W
    nlp = {"x": x, "p": p, "f": f, "g": g_all}

    # Lagrangian Hessian: the quadratic costs' diagonal and each knot's term block (dq_k, dq_k).
    lam_terms = _natural_order(lam_g, perm)[2 * n_gap + 2 * nv:]
    hess = lam_f * ca.diag(2 * W)
    for st, n, Xg, Qr, Pg, S, offset in hessian_blocks:
        L = ca.reshape(lam_terms[offset: offset + st.rows * n], st.rows, n)
        HS = st.hess.map(n)(Xg, Qr, Pg, ca.repmat(objective_scale * lam_f, 1, n), L)
        hess = hess + ca.mtimes(S.T, ca.mtimes(ca.diagcat(*ca.horzsplit(HS, nv)), S))
    derivatives = _derivatives(x, p, lam_f, lam_g, f, grad, g_all, jac_all, hess, symmetric_hessian)
    return nlp, derivatives, sl


def _cost_selector(sl: StageLayout, N: int, nv: int) -> Any:
    """The constant (n_x, 3) operator B of the quadratic costs' weights ``W = B @ [c_posture, w_s dt,
    w_s / dt]``: posture on the joints of knots 2..N-1 (knot N repeats N-1), smoothness on each
    stage's acceleration, and the last stage's velocity."""
    rows: list[int] = []
    cols: list[int] = []
    vals: list[float] = []
    K = sl.stages
    for s in range(K):
        k = s + 1
        base = int(sl.x_offset[s])
        if k >= 2:
            joints = base + np.arange(6, nv)
            rows += list(joints)
            cols += [0] * len(joints)
            vals += [2.0 if k == N - 1 else 1.0] * len(joints)
        part, col = (2, 1) if s < K - 1 else (1, 2)
        block = base + part * nv + np.arange(nv)
        rows += list(block)
        cols += [col] * nv
        vals += [1.0] * nv
    return _sparse(rows, cols, vals, (sl.n_x, 3))


def _gap_rows(sl: StageLayout, N: int, x: Any, dt: Any) -> tuple[Any, Any, Any, Any]:
    """The gap rows ``dq_{k+1} - dq_k - dt v_k - dt^2 a_k`` and ``v_{k+1} - v_k - dt a_k`` of knots
    1..N-2, and their (linear) Jacobians."""
    knots = list(range(1, N - 1))
    nxt = list(range(2, N))
    DQ0, V0, A0 = (_picker(sl, _columns(sl, part, knots)) for part in (0, 1, 2))
    DQ1, V1 = (_picker(sl, _columns(sl, part, nxt)) for part in (0, 1))
    J_dq = DQ1 - DQ0  # constant parts; dt-scaled parts below
    J_v = V1 - V0
    gap_dq = ca.mtimes(J_dq, x) - dt * ca.mtimes(V0, x) - dt**2 * ca.mtimes(A0, x)
    gap_v = ca.mtimes(J_v, x) - dt * ca.mtimes(A0, x)
    jac_gap_dq = ca.MX(J_dq) - dt * ca.MX(V0) - dt**2 * ca.MX(A0)
    jac_gap_v = ca.MX(J_v) - dt * ca.MX(A0)
    return gap_dq, gap_v, jac_gap_dq, jac_gap_v


def _stage_order(sl: StageLayout, nv: int, g_rows_of_term: dict[int, tuple[int, int]]) -> list[int]:
    """The permutation from the natural row order (gaps of dq, gaps of v, the start rows, the
    terms' rows) to stage order: each stage's gap rows, then its own rows."""
    K = sl.stages
    n_gap = nv * (K - 1)
    perm: list[int] = []
    for s in range(K):
        if s < K - 1:
            perm += [s * nv + j for j in range(nv)] + [n_gap + s * nv + j for j in range(nv)]
        if s == 0:
            perm += [2 * n_gap + j for j in range(2 * nv)]
        for i in sl.row_terms[s]:
            r, n_rows = g_rows_of_term[i]
            perm += [2 * n_gap + 2 * nv + r + j for j in range(n_rows)]
    return perm


def _natural_order(lam_g: Any, perm: list[int]) -> Any:
    """The multipliers of the stage-ordered rows back in the natural row order."""
    inverse = np.empty(len(perm), dtype=int)
    inverse[np.asarray(perm)] = np.arange(len(perm))
    return lam_g[inverse.tolist()]


def _derivatives(x: Any, p: Any, lam_f: Any, lam_g: Any, f: Any, grad: Any, g: Any, jac: Any, hess: Any,
                 symmetric_hessian: bool) -> dict[str, Any]:
    """The derivative options of nlpsol: the cost's gradient, the rows' Jacobian and the Lagrangian's
    Hessian (whole for fatrop, its upper triangle for IPOPT)."""
    name = "hess_gamma_x_x" if symmetric_hessian else "triu_hess_gamma_x_x"
    return {
        "grad_f": ca.Function("sw_grad_f", [x, p], [f, ca.densify(grad)], ["x", "p"], ["f", "grad_f_x"]),
        "jac_g": ca.Function("sw_jac_g", [x, p], [g, jac], ["x", "p"], ["g", "jac_g_x"]),
        "hess_lag": ca.Function("sw_hess_l", [x, p, lam_f, lam_g], [hess if symmetric_hessian else ca.triu(hess)],
                                ["x", "p", "lam_f", "lam_g"], [name]),
    }


def stagewise_parameters(lay: Layout) -> np.ndarray:
    """The parameter vector of a layout (the same as the current transcription's)."""
    return parameter_values(lay, make_nlp_layout(lay))


def stagewise_bounds(lay: Layout, sl: StageLayout) -> tuple[np.ndarray, ...]:
    """(lbx, ubx, lbg, ubg): joint position limits on ``dq_k``, velocity limits on ``v_k`` (k >= 2),
    gap and start rows equal to 0, the terms' bounds."""
    robot, nv = lay.robot, sl.nv
    lo, hi = chart_position_limits(lay)
    vj = velocity_joints(lay)
    vmax = np.asarray(robot.model.velocityLimit, dtype=float)[vj]
    lbx = np.full(sl.n_x, -np.inf)
    ubx = np.full(sl.n_x, np.inf)
    for s in range(sl.stages):
        base = int(sl.x_offset[s])
        lbx[base: base + nv], ubx[base: base + nv] = lo, hi
        if s >= 1:
            lbx[base + nv + vj], ubx[base + nv + vj] = -vmax, vmax
    lbg, ubg = [], []
    for s in range(sl.stages):
        zeros = np.zeros((sl.nx[s + 1] if s < sl.stages - 1 else 0) + (2 * nv if s == 0 else 0))
        lbg.append(zeros)
        ubg.append(zeros)
        for i in sl.row_terms[s]:
            lbg.append(lay.terms[i].lower)
            ubg.append(lay.terms[i].upper)
    return lbx, ubx, np.concatenate(lbg), np.concatenate(ubg)


def to_stagewise(lay: Layout, sl: StageLayout, dq: np.ndarray) -> np.ndarray:
    """The stage-wise variables of chart displacements ``dq`` (N+1, nv): velocities and
    accelerations by finite differences (``dq_0 = dq_1 = 0`` is the start at rest)."""
    N, dt = lay.N, lay.dt
    d = np.array(dq, dtype=float)
    d[0:2] = 0.0
    v = np.zeros_like(d)
    v[1:] = (d[1:] - d[:-1]) / dt
    a = np.zeros_like(d)
    a[1:N - 1] = (v[2:N] - v[1:N - 1]) / dt
    x = np.zeros(sl.n_x)
    for s in range(sl.stages):
        k, base = s + 1, int(sl.x_offset[s])
        x[base: base + sl.nv] = d[k]
        x[base + sl.nv: base + 2 * sl.nv] = v[k]
        if s < sl.stages - 1:
            x[base + 2 * sl.nv: base + 3 * sl.nv] = a[k]
    return x


def chart_of(lay: Layout, sl: StageLayout, x: np.ndarray) -> np.ndarray:
    """Chart displacements (N+1, nv) of stage-wise variables ``x`` (knot 0 at rest, knot N = N-1)."""
    dq = np.zeros((lay.N + 1, sl.nv))
    for s in range(sl.stages):
        base = int(sl.x_offset[s])
        dq[s + 1] = x[base: base + sl.nv]
    dq[lay.N] = dq[lay.N - 1]
    return dq


def fatrop_options(settings: PlannerSettings, sl: StageLayout) -> dict:
    """The ``nlpsol`` options of fatrop with the stage structure given (``structure_detection: manual``)."""
    return {
        "print_time": False,
        "structure_detection": "manual",
        "N": sl.stages - 1,
        "nx": list(sl.nx),
        "nu": list(sl.nu),
        "ng": list(sl.ng),
        "fatrop": {
            "print_level": int(settings.solver.print_level),
            "max_iter": int(settings.solver.max_iterations),
            "tol": float(settings.solver.tolerance),
            "constr_viol_tol": float(settings.solver.constraint_tolerance),
            **dict(settings.solver.fatrop_extra),
        },
    }


@dataclass(eq=False)
class StagewiseSolver:
    """A stage-wise solver of one structure."""

    function: ca.Function
    stage_layout: StageLayout
    backend: str
    build_time: float
    objective_scale: float = 1.0


CACHE_SIZE = 16
_SOLVERS: OrderedDict[tuple, StagewiseSolver] = OrderedDict()


def _options_key(settings: PlannerSettings) -> tuple:
    s = settings.solver
    return (s.max_iterations, s.tolerance, s.constraint_tolerance, s.print_level, s.objective_scaling,
            s.ipopt_extra, s.fatrop_extra)


def get_stagewise_solver(lay: Layout, settings: PlannerSettings, backend: str,
                         progress: Callable[[str], None] | None = None) -> tuple[StagewiseSolver, str]:
    """The stage-wise solver of a layout's structure for ``backend`` (``"ipopt"`` or ``"fatrop"``),
    from this process's cache or built (in memory: no C code, nothing on disk). Returns the solver
    and where it came from (``"memory"`` or ``"built"``)."""
    if backend not in SOLVERS:
        raise PlannerError(f"settings: the stage-wise solver must be one of {', '.join(SOLVERS)}, got {backend!r}")
    key = (model_hash(lay.robot.model), lay.structure(), backend, _options_key(settings))
    hit = _SOLVERS.get(key) if settings.cache.use_cache else None
    if hit is not None:
        _SOLVERS.move_to_end(key)
        return hit, "memory"
    if progress:
        progress(f"building the stage-wise solver ({backend})")
    t0 = time.perf_counter()
    scale = 1.0 if backend == "ipopt" else settings.solver.objective_scaling  # IPOPT scales it itself
    nlp, derivatives, sl = build_stagewise_nlp(lay, symmetric_hessian=backend == "fatrop", objective_scale=scale)
    if backend == "ipopt":
        options = ipopt_options(settings)
        # METIS: MUMPS's automatic ordering fills this banded KKT system in badly (talos squat: 3.7 s
        # of CPU for 11 iterations against 0.8 s with METIS; docs/performance.md).
        options["ipopt"] = {"mumps_pivot_order": METIS, **options["ipopt"]} if not any(
            k == "mumps_pivot_order" for k, _ in settings.solver.ipopt_extra) else options["ipopt"]
        options = {**options, **derivatives}
    else:  # CasADi's fatrop interface takes no derivative functions: it builds them by AD of the NLP
        options = fatrop_options(settings, sl)
    function = ca.nlpsol(f"wbmp_stagewise_{backend}", backend, nlp, options)
    solver = StagewiseSolver(function=function, stage_layout=sl, backend=backend,
                             build_time=time.perf_counter() - t0, objective_scale=scale)
    if settings.cache.use_cache:
        _SOLVERS[key] = solver
        while len(_SOLVERS) > CACHE_SIZE:
            _SOLVERS.popitem(last=False)
    return solver, "built"


def _status(backend: str, stats: dict) -> tuple[SolveStatus, str]:
    """(mapped status, the backend's own status) of a solve."""
    if backend == "ipopt":
        raw = str(stats.get("return_status", ""))
        return _STATUS.get(raw, SolveStatus.NUMERICAL_ERROR if raw else SolveStatus.NOT_RUN), raw
    unified = str(stats.get("unified_return_status", ""))
    raw = f"fatrop return flag {stats.get('return_status', '?')} ({unified})"
    if stats.get("success"):
        return SolveStatus.SOLVED, raw
    if unified == "SOLVER_RET_LIMITED":
        return SolveStatus.MAX_ITERATIONS, raw
    if unified == "SOLVER_RET_INFEASIBLE":
        return SolveStatus.INFEASIBLE, raw
    return SolveStatus.NUMERICAL_ERROR, raw


def solve_stagewise(lay: Layout, settings: PlannerSettings, progress: Callable[[str], None] | None = None,
                    x0: np.ndarray | None = None, backend: str | None = None) -> tuple[np.ndarray, SolverStats, SolverOutput]:
    """Solve a kinematic layout with the stage-wise transcription: what
    :func:`planner.trajopt.solve.solve_layout` returns, (dq per knot (N+1, nv), stats, output).

    ``x0`` is in the current transcription's variables (``dq_2 .. dq_{N-1}``, as
    :meth:`Layout.initial_guess` gives), and so is the output's ``x`` (a collision round starts the next
    solve from it); its ``x_stagewise`` holds the stage-wise solution, its ``lam_g`` the
    multipliers in stage order.

    Raises:
        StagewiseUnsupported: a dynamic layout.
    """
    backend = backend or settings.solver.stagewise_solver
    t0 = time.perf_counter()
    solver, origin = get_stagewise_solver(lay, settings, backend, progress)
    build_time = time.perf_counter() - t0
    sl = solver.stage_layout
    nv, N = lay.robot.nv, lay.N
    if x0 is None:
        x0 = lay.initial_guess()
    dq0 = np.zeros((N + 1, nv))
    dq0[2:N] = np.asarray(x0, dtype=float)[: nv * (N - 2)].reshape(N - 2, nv)
    dq0[N] = dq0[N - 1]
    lbx, ubx, lbg, ubg = stagewise_bounds(lay, sl)
    p = stagewise_parameters(lay)
    if progress:
        progress(f"solving stage-wise with {backend} ({sl.n_x} variables, {sl.n_g} constraints, "
                 f"{sl.stages} stages)")
    t1 = time.perf_counter()
    start = to_stagewise(lay, sl, dq0)
    try:
        sol = solver.function(x0=start, p=p, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)
    except RuntimeError as exc:  # fatrop raises on some failures instead of returning a status
        # and may be left half set up (a later call ran with its default options): never reuse it
        for key in [k for k, v in _SOLVERS.items() if v is solver]:
            del _SOLVERS[key]
        reason = str(exc).strip().splitlines()[-1] if str(exc).strip() else "no message"
        sol = {"x": start, "f": np.nan, "g": np.zeros(sl.n_g), "lam_x": np.zeros(sl.n_x), "lam_g": np.zeros(sl.n_g)}
        st = {"iter_count": 0}
        status, raw_status = SolveStatus.NUMERICAL_ERROR, f"{backend} raised: {reason}"
    else:
        st = solver.function.stats()
        status, raw_status = _status(backend, st)
    solve_time = time.perf_counter() - t1
    xs = np.asarray(sol["x"], dtype=float).ravel()
    dq = chart_of(lay, sl, xs)
    stats = SolverStats(
        status=status, iterations=int(st.get("iter_count", 0)), build_time=build_time, solve_time=solve_time,
        cache=origin, objective=float(sol["f"]) / solver.objective_scale, n_variables=sl.n_x, n_constraints=sl.n_g,
        backend=f"{backend} (stage-wise)", raw_status=raw_status)
    out = SolverOutput(x=dq[2:N].ravel(), x_stagewise=xs, lam_x=np.asarray(sol["lam_x"]), lam_g=np.asarray(sol["lam_g"]),
                       g=np.asarray(sol["g"]), lbg=lbg, ubg=ubg, nlp_layout=sl)
    return dq, stats, out
