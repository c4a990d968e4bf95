"""The transcription of a layout into a CasADi NLP: variables, parameters, bounds, and the
stage-wise assembly of its derivatives (:func:`build_nlp`). A formulation (the layout, see
:mod:`planner.trajopt.formulation`) extends the kinematic NLP with its own variables and rows."""

from __future__ import annotations

import functools
import hashlib
from collections import OrderedDict
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from planner.exceptions import PlannerError
from planner.trajopt.layout import Layout
from planner.trajopt.layout_data import LayoutData
from planner.trajopt.symbolic import model_hash
from planner.trajopt.terms import stage_function, stage_groups

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


def velocity_joints(lay: LayoutData) -> np.ndarray:
    """Tangent indices of actuated joints with a finite, positive velocity limit."""
    vmax = np.asarray(lay.robot.model.velocityLimit, dtype=float)
    idx = [i for i in range(6, lay.robot.nv) if 0.0 < vmax[i] < LIMIT_CLAMP]
    return np.array(idx, dtype=int)


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
    n_u, n_gd = lay.extra_sizes()
    return NlpLayout(n_x=n_x + n_u, n_g=n_g + n_gd, row_order=row_order, groups=groups,
                     velocity_joints=vj, n_x_kin=n_x, n_g_kin=n_g)


def _selection(lay: Layout, knots: list[int]) -> ca.DM:
    """Sparse (nv * len(knots), n_x) matrix picking the variables of ``knots`` from ``x``."""
    nv, n_x = lay.robot.nv, lay.robot.nv * (lay.N - 2)
    rows = np.arange(nv * len(knots))
    cols = np.concatenate([np.arange(nv) + nv * (k - 2) for k in knots])
    return _sparse(rows, cols, np.ones(len(rows)), (nv * len(knots), n_x))


def _sparse(rows, cols, values, shape) -> ca.DM:
    """Sparse DM from triplets (duplicates summed, explicit zeros kept).

    Built with numpy and CasADi's compressed-column sparsity: ``scipy.sparse`` costs ~0.45 s of
    CPU to import (its array-API shim imports ``numpy.f2py``), a third of a first-ever kinematic
    build, and nothing else on the planning path needs it."""
    n_rows, n_cols = int(shape[0]), int(shape[1])
    rows = np.asarray(rows, dtype=np.int64).ravel()
    cols = np.asarray(cols, dtype=np.int64).ravel()
    values = np.asarray(values, dtype=float).ravel()
    linear, where = np.unique(cols * n_rows + rows, return_inverse=True)  # column-major: CasADi's order
    summed = np.bincount(where.ravel(), weights=values, minlength=len(linear))
    colind = np.searchsorted(linear // n_rows if n_rows else linear, np.arange(n_cols + 1), side="left")
    pattern = ca.Sparsity(n_rows, n_cols, colind.tolist(), (linear % n_rows if n_rows else linear).tolist())
    return ca.DM(pattern, summed.tolist())


def _quadratic_operators(lay: LayoutData) -> tuple[ca.DM, ca.DM, ca.DM]:
    """Constant operators of the quadratic costs and of the velocity rows.

    They depend on ``nv``, ``N`` and the velocity-limited joints only; kept per process (a dynamic
    build asks twice: here and in its chart Hessian).

    Returns:
        ``A`` (second differences of dq over knots 1..N-1), ``P`` (joint part of dq at knots
        2..N), ``D`` (velocity-limited joints of dq_{k+1} - dq_k for k = 1..N-2).
    """
    return _operators(lay.robot.nv, lay.N, tuple(int(j) for j in velocity_joints(lay)))


@functools.lru_cache(maxsize=16)
def _operators(nv: int, N: int, vj: tuple[int, ...]) -> tuple[ca.DM, ca.DM, ca.DM]:
    """:func:`_quadratic_operators` of a chart size, knot count and velocity-limited joints."""
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
        assert b is not None  # knots from 2 on are variables
        rows += list(range(r, r + nv - 6))
        cols += list(range(b + 6, b + nv))
        vals += [1.0] * (nv - 6)
        r += nv - 6
    P = _sparse(rows, cols, vals, (r, n_x))
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


@dataclass(eq=False)
class Stage:
    """The SX functions of one knot structure: ``(dq, q_ref, p) ->`` rows and cost, their Jacobian,
    the cost's gradient and (:attr:`hess`, built on first use) the Lagrangian's Hessian
    ``(dq, q_ref, p, sigma, lam)``."""

    fn: ca.Function
    jac: ca.Function
    grad: ca.Function
    rows: int
    cost_is_zero: bool
    name: str = ""
    _hess: ca.Function | None = None

    @property
    def hess(self) -> ca.Function:
        """The Lagrangian's Hessian w.r.t. ``dq`` (SX AD, ~0.04 s of CPU per Talos stage): built
        only when asked, because a dynamic layout assembles its own chart Hessian
        (:func:`planner.trajopt.centroidal.nlp.stage_hessians`) and never calls this one."""
        if self._hess is None:
            nv, nq = self.fn.size1_in(0), self.fn.size1_in(1)
            dq, qr, ps = ca.SX.sym("dq", nv), ca.SX.sym("q_ref", nq), ca.SX.sym("p", self.fn.size1_in(2))
            sigma = ca.SX.sym("sigma")
            gk, ck = self.fn(dq, qr, ps)
            lam = ca.SX.sym("lam", gk.numel())
            self._hess = ca.Function("hess_" + self.name, [dq, qr, ps, sigma, lam],
                                     [ca.hessian(sigma * ck + ca.dot(lam, gk), dq)[0]])
        return self._hess


STAGE_CACHE_SIZE = 256
_STAGES: OrderedDict[tuple, Stage] = OrderedDict()


def stage(lay: Layout, term_ids: list[int]) -> Stage:
    """The :class:`Stage` of the terms ``term_ids`` at one knot, from a per-process cache keyed by
    the robot model and the terms' structure: a collision round, the re-solve of a wider screening,
    or another plan of the same robot rebuilds only the knot structures it has not seen (the
    symbolic Hessians are most of a solver's build time). The functions are named after the key,
    so generated C never holds two different functions of one name."""
    terms = [lay.terms[i] for i in term_ids]
    key = (model_hash(lay.robot.model), tuple((t.kind, t.structure, len(t.params), t.n_rows) for t in terms))
    hit = _STAGES.get(key)
    if hit is not None:
        _STAGES.move_to_end(key)
        return hit
    name = "stage_" + hashlib.sha256(repr(key).encode()).hexdigest()[:16]
    fn = stage_function(lay, term_ids, name)
    nv, nq = lay.robot.nv, lay.robot.nq
    dq, qr, ps = ca.SX.sym("dq", nv), ca.SX.sym("q_ref", nq), ca.SX.sym("p", fn.size1_in(2))
    gk, ck = fn(dq, qr, ps)
    out = Stage(
        fn=fn,
        jac=ca.Function("jac_" + name, [dq, qr, ps], [ca.jacobian(gk, dq)]),
        grad=ca.Function("grad_" + name, [dq, qr, ps], [ca.gradient(ck, dq)]),
        rows=int(gk.numel()), cost_is_zero=bool(ck.is_zero()), name=name,
    )
    _STAGES[key] = out
    while len(_STAGES) > STAGE_CACHE_SIZE:
        _STAGES.popitem(last=False)
    return out


def build_nlp(lay: Layout) -> tuple[dict, dict, NlpLayout]:
    """The CasADi NLP of a layout's structure (values come as parameters) and its derivatives.

    Knots with the same term structure share one SX stage function (with its Jacobian and
    Hessian) evaluated with ``map``; the NLP's gradient, constraint Jacobian and Lagrangian
    Hessian are assembled from those blocks and from constant sparse operators of the
    quadratic terms. The derivative code (and the generated C) therefore grows with the number
    of distinct stages, not with the number of knots.

    The layout's ``extend_nlp`` gets ``grad_f`` and ``jac_g``; the kinematic ``hess_lag`` is built
    afterwards, only when it returns none of its own. A dynamic layout
    (:mod:`planner.trajopt.centroidal`) assembles the whole Hessian itself, so the kinematic stage
    Hessians are never built for it (~0.5-0.8 s of CPU of a first-ever Talos walk).

    Returns:
        (nlp dict {x, p, f, g}, nlpsol options {grad_f, jac_g, hess_lag}, index bookkeeping).
    """
    robot = lay.robot
    nq, nv, N = robot.nq, robot.nv, lay.N
    nl = make_nlp_layout(lay)
    x = ca.MX.sym("x", nl.n_x_kin)
    X = ca.reshape(x, nv, N - 2)
    groups = stage_groups(lay)
    stages = [stage(lay, term_lists[0]) for _s, _k, term_lists in groups]
    n_p = nq + 3 + sum(st.fn.size1_in(2) * len(knots) for st, (_s, knots, _t) in zip(stages, groups, strict=True))
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
    g, jac = [], []
    hessian_blocks = []  # per stage group: what its Lagrangian Hessian is made from
    p_offset, g_offset = nq + 3, 0
    for st, (_sig, knots, _terms) in zip(stages, groups, strict=True):
        n = len(knots)
        n_ps = st.fn.size1_in(2)
        Xg = X[:, [k - 2 for k in knots]]
        Qr = ca.repmat(q_ref, 1, n)
        Pg = ca.reshape(p[p_offset: p_offset + n_ps * n], n_ps, n)
        p_offset += n_ps * n
        G, C = st.fn.map(n)(Xg, Qr, Pg)
        JG = st.jac.map(n)(Xg, Qr, Pg)
        GC = st.grad.map(n)(Xg, Qr, Pg)
        rows = st.rows
        L = ca.reshape(lam_g[g_offset: g_offset + rows * n], rows, n)
        g_offset += rows * n
        S = _selection(lay, knots)
        f = f + ca.sum2(C)
        if st.cost_is_zero:
            GC = ca.MX.zeros(nv, n)
        grad = grad + ca.mtimes(S.T, ca.vec(GC))
        hessian_blocks.append((st, n, Xg, Qr, Pg, L, S))
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
    }
    nlp, derivatives = lay.extend_nlp(nlp, derivatives)  # a dynamic layout: forces, CoM dynamics, sole corners
    if "hess_lag" not in derivatives:  # the kinematic NLP's own (a dynamic layout makes the whole one)
        hess = lam_f * (2 * c_smooth * AtA + 2 * c_posture * PtP)
        for st, n, Xg, Qr, Pg, L, S in hessian_blocks:
            HS = st.hess.map(n)(Xg, Qr, Pg, ca.repmat(lam_f, 1, n), L)
            hess = hess + ca.mtimes(S.T, ca.mtimes(ca.diagcat(*ca.horzsplit(HS, nv)), S))
        derivatives = {**derivatives, "hess_lag": ca.Function(
            "nlp_hess_l", [x, p, lam_f, lam_g], [ca.triu(hess)], ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"])}
    return nlp, derivatives, nl


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
    return lay.extend_parameters(p)


def chart_position_limits(lay: Layout) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) of one knot's chart displacement ``dq`` (nv): the joints' position limits about the
    reference ``q_ref`` (never excluding it; an unbounded joint, |limit| >= ``LIMIT_CLAMP``, stays
    free), the floating base free."""
    robot, nv = lay.robot, lay.robot.nv
    lo = np.full(nv, -np.inf)
    hi = np.full(nv, np.inf)
    lower = np.asarray(robot.model.lowerPositionLimit, dtype=float)[7:]
    upper = np.asarray(robot.model.upperPositionLimit, dtype=float)[7:]
    ref = lay.q_ref[7:]
    lo[6:] = np.where(np.abs(lower) < LIMIT_CLAMP, np.minimum(lower - ref, 0.0), -np.inf)
    hi[6:] = np.where(np.abs(upper) < LIMIT_CLAMP, np.maximum(upper - ref, 0.0), np.inf)
    return lo, hi


def bounds(lay: Layout, nl: NlpLayout) -> tuple[np.ndarray, ...]:
    """(lbx, ubx, lbg, ubg) of a layout."""
    robot, N = lay.robot, lay.N
    lo, hi = chart_position_limits(lay)
    lbx = np.tile(lo, N - 2)
    ubx = np.tile(hi, N - 2)
    lbg = [lay.terms[i].lower for i in nl.row_order]
    ubg = [lay.terms[i].upper for i in nl.row_order]
    vmax = np.asarray(robot.model.velocityLimit, dtype=float)[nl.velocity_joints] * lay.dt
    lbg += [-vmax] * (N - 2)
    ubg += [vmax] * (N - 2)
    return lay.extend_bounds(lbx, ubx, np.concatenate(lbg), np.concatenate(ubg))
