"""The NLP extension: forces, lifted CoM, CoM dynamics and sole-corner rows added to the stage-wise
kinematic NLP of :mod:`planner.trajopt.transcription` (variables, derivatives, bounds, parameters)."""

from __future__ import annotations

import hashlib
from collections import OrderedDict
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import casadi as ca
import numpy as np

from planner.trajopt.centroidal.data import DynamicData
from planner.trajopt.centroidal.pattern import CentroidalFunction
from robots import Robot, sole_corners


def sole_corner_heights(kin: Any, oMi: Any, robot: Robot) -> Any:
    """Heights (8,) of the left then right sole corners from symbolic joint placements [m].

    Args:
        kin: A :class:`planner.trajopt.symbolic.SymbolicKinematics`.
        oMi: Its joint placements at one knot.
        robot: The robot (foot frames, sole rectangle).

    Returns:
        CasADi column: left corners 0..3, right corners 0..3 (profile order).
    """
    out = []
    for side in ("left", "right"):
        R, p = kin.frame_placement(oMi, robot.frame_id(f"{side}_foot"))
        for corner in sole_corners(robot.profile.sole, side):
            out.append((p + ca.mtimes(R, ca.DM(corner)))[2])
    return ca.vertcat(*out)


@dataclass(frozen=True, slots=True, kw_only=True)
class DynamicBlocks:
    """The dynamic part of a stage-wise NLP with its hand-assembled derivatives (MX).

    The NLP's variables are ``[x_kin; u; c; l]``: the chart displacements of the variable knots,
    the force variables, the CoM of each variable knot (3 per knot, *lifted*: tied to the
    configuration by equality rows), then, with :attr:`CentroidalSettings.lifts_moment`, the
    moment of the contact forces about the CoM at each dynamics knot (3 per knot, m x body
    weights; :func:`moment_rows`). Lifting the CoM keeps the CoM Jacobian (dense over the
    joints) out of the dynamics rows and the angular-momentum cost: those couple the forces
    with 3 CoM variables per knot instead of every joint, which makes the KKT system much
    sparser. Lifting the moment does the same for its cost ``|Ldot_k|^2``: without it, the cost's
    Hessian is a dense rank-3 block over each knot's edge weights (32 x 32 in double support) and
    its CoM; with it, a diagonal. Rows: the centroidal rows (dynamics; friction rows without
    friction edges; the moment rows ``l_k - Ldot_k(c, u) = 0``), the CoM rows ``c_k - com(q_k) =
    0``, the sole-corner heights of swinging feet, then the whole body's momentum rows ``rate_k(x)
    - l_k = 0`` (lifted; otherwise the rate is added to the moment rows: ``rate_k(x) - Ldot_k = 0``).

    Attributes:
        f: Cost added to the objective (from functions that compute values only).
        g: Constraint rows (column; values only).
        f_d, g_d: The same values, from the functions that also give the derivatives (for the
            NLP's gradient and Jacobian functions, which output both).
        lbg, ubg: Their bounds.
        grad_u, grad_c, grad_l: Gradient of ``f`` (it does not depend on ``x_kin``) [MX columns].
        jac_x, jac_u, jac_c, jac_l: Jacobian of ``g`` w.r.t. ``x_kin``, ``u``, ``c`` and ``l``.
        hess_xx, hess_uu, hess_uc, hess_cc, hess_ll: Hessian blocks of ``lam_f f + lam . g`` (the
            ``x``-``u``, ``x``-``c`` and every ``l``-other block are zero; ``hess_ll`` is diagonal;
            ``hess_xx`` is None when not asked for).
        nu, eta: Multipliers (3, N-2) and (8, N-2) whose products with each variable knot's
            CoM and sole-corner heights give the curvature in ``hess_xx``.
    """

    f: Any
    g: Any
    f_d: Any
    g_d: Any
    lbg: np.ndarray
    ubg: np.ndarray
    grad_u: Any
    grad_c: Any
    grad_l: Any
    jac_x: Any
    jac_u: Any
    jac_c: Any
    jac_l: Any
    hess_xx: Any
    nu: Any
    eta: Any
    hess_uu: Any
    hess_uc: Any
    hess_cc: Any
    hess_ll: Any


def _kinematic_functions(lay: DynamicData) -> tuple[ca.Function, ca.Function, ca.Function]:
    """SX functions of one knot: (dq, q_ref) -> (c, Jc, z, Jz), (dq, q_ref, nu, eta) ->
    hess(nu.c + eta.z), and (dq, q_ref) -> (c, z) (the values alone: what the rows need)."""
    from planner.trajopt.symbolic import SymbolicKinematics

    robot = lay.robot
    kin = SymbolicKinematics(robot.model)
    dq = ca.SX.sym("dq", robot.nv)
    q_ref = ca.SX.sym("q_ref", robot.nq)
    oMi = kin.joint_placements(q_ref, dq)
    c = kin.com(oMi)
    z = sole_corner_heights(kin, oMi, robot)
    nu = ca.SX.sym("nu", 3)
    eta = ca.SX.sym("eta", 8)
    first = ca.Function("dyn_kin", [dq, q_ref], [c, ca.jacobian(c, dq), z, ca.jacobian(z, dq)])
    second = ca.Function("dyn_kin_hess", [dq, q_ref, nu, eta], [ca.hessian(ca.dot(nu, c) + ca.dot(eta, z), dq)[0]])
    values = ca.Function("dyn_kin_values", [dq, q_ref], [c, z])
    return first, second, values


def com_rows(lay: DynamicData) -> int:
    """Number of lifted CoM variables (and of the rows tying them to the configuration)."""
    return 3 * (lay.N - 2)


def moment_rows(lay: DynamicData) -> int:
    """Number of lifted moment variables ``l`` (3 per dynamics knot ``1..N-1``, 0 when
    :attr:`CentroidalSettings.lifts_moment` is off), and of the momentum rows ``rate_k - l_k``."""
    return 3 * (lay.N - 1) if lay.centroidal_settings.lifts_moment else 0


def momentum_rates(lay: DynamicData, x_kin: Any, pm: Any, row_index: np.ndarray | None = None,
                   n_rows: int | None = None) -> tuple[Any, Any]:
    """Whole-body angular-momentum rates of the dynamics knots 1..N-1 and their Jacobian w.r.t. ``x_kin``.

    The rates are affine in the chart variables, ``r + J x`` (``r`` and the nonzeros of ``J`` are
    the parameters ``pm``, :func:`planner.trajopt.centroidal.momentum.momentum_parameters`): the
    Jacobian is the parameters cast to :func:`~planner.trajopt.centroidal.momentum.momentum_jacobian_pattern`,
    and the rows one sparse product (no Hessian). Before, the rows were built from the interval
    momenta ``b + P dq_j + Q dq_{j+1}`` and differentiated by CasADi: the same values, 5 ms more
    per evaluation of the rows and of their Jacobian on the Talos 4 steps.

    Args:
        lay: The dynamic layout.
        x_kin: Chart variables (MX, nv (N-2)).
        pm: The parameters (MX).
        row_index: Where the rates go among ``n_rows`` rows (increasing; default: rows 0..3(N-1)-1
            of their own): the Jacobian is made in place (a selection product would copy it).
        n_rows: Number of those rows.

    Returns:
        (rates (MX column, knot order, placed by ``row_index``), Jacobian (rows, nv (N-2))).
    """
    from planner.trajopt.centroidal.momentum import momentum_jacobian_pattern

    nv, N = lay.robot.nv, lay.N
    rows, cols = momentum_jacobian_pattern(nv, N)
    n_r = 3 * (N - 1)
    r = pm[:n_r]
    if row_index is not None:
        row_index = np.asarray(row_index, dtype=int)
        if len(row_index) != n_r or np.any(np.diff(row_index) <= 0):
            raise ValueError("momentum_rates: row_index must hold 3 (N-1) increasing rows")
        rows = row_index[rows]
        S = ca.DM(ca.Sparsity.triplet(n_rows, n_r, row_index.tolist(), list(range(n_r))), 1.0)
        r = ca.mtimes(S, r)
    sp = ca.Sparsity.triplet(n_r if row_index is None else n_rows, nv * (N - 2), rows.tolist(), cols.tolist())
    J = ca.MX(sp, pm[n_r:])
    return r + ca.mtimes(J, x_kin), J


def _lifted_com_selection(N: int) -> ca.DM:
    """The selection ``vec(C) (3 (N + 1)) <- c (3 (N - 2))`` of the lifted CoM: knots 2..N-1 are
    variables, knot N copies knot N-1 (knots 0 and 1, at the standing CoM, select nothing)."""
    n = N - 2
    rows, cols = [], []
    for k in range(2, N + 1):
        j = min(k, N - 1) - 2
        rows += [3 * k + i for i in range(3)]
        cols += [3 * j + i for i in range(3)]
    return ca.DM(ca.Sparsity.triplet(3 * (N + 1), 3 * n, rows, cols), 1.0)


def _centroidal_functions(cf: CentroidalFunction, N: int) -> tuple[ca.Function, ca.Function, ca.Function,
                                                                    ca.Function, int]:
    """The centroidal rows ``g`` and cost ``f`` as SX functions of ``(C, u, p, dt)``: their values,
    their first derivatives w.r.t. ``(vec C, u)`` and the Hessian of ``sigma f + lam . g``; and the
    number of rows."""
    Cs = ca.SX.sym("C", 3, N + 1)
    Us = ca.SX.sym("u", cf.terms.n_variables)
    Ps = ca.SX.sym("p", cf.terms.parameter_values.size)
    dts = ca.SX.sym("dt")
    gs, fs = cf.function(Cs, Us, Ps, dts)
    n_c = gs.numel()
    ls = ca.SX.sym("lam", n_c)
    sig = ca.SX.sym("sigma")
    w = ca.vertcat(ca.vec(Cs), Us)
    lag = sig * fs + ca.dot(ls, gs)
    g0 = ca.Function("dyn_centroidal_g", [Cs, Us, Ps, dts], [gs])
    f0 = ca.Function("dyn_centroidal_f", [Cs, Us, Ps, dts], [fs])
    d1 = ca.Function("dyn_centroidal_d1", [Cs, Us, Ps, dts], [gs, fs, ca.jacobian(gs, w), ca.gradient(fs, w)])
    d2 = ca.Function("dyn_centroidal_d2", [Cs, Us, Ps, dts, sig, ls], [ca.hessian(lag, w)[0]])
    return g0, f0, d1, d2, n_c


def _swing_corner_selection(robot: Any, cf: CentroidalFunction, n: int) -> ca.DM:
    """The rows of the swinging soles' corner heights, picked from ``vec(Z)`` (8 corners a knot)."""
    feet = [robot.frame_id(f"{s}_foot") for s in ("left", "right")]
    zr = [(k - 2) * 8 + feet.index(fid) * 4 + i for k, fid, i in cf.corner_rows]
    return ca.DM(ca.Sparsity.triplet(len(zr), 8 * n, list(range(len(zr))), zr), 1.0)


class _MomentumBlocks(NamedTuple):
    n_l: int  # lifted moment variables (0: not lifted)
    add_c: Any  # added to the centroidal rows: + l_k (lifted), + dh/dt of the body, or None
    f_l: Any
    grad_l: Any
    hess_ll: Any
    g_r: Any  # the rows rate_k(x) - l_k (lifted only)
    jac_rx: Any
    jac_l: Any
    jac_cx: Any  # d(centroidal rows)/dx (the body's dh/dt, not lifted)


def _momentum_blocks(lay: DynamicData, cf: CentroidalFunction, x_kin: Any, dt: Any, lam_f: Any, pm: Any,
                     moment: Any, n_c: int, n_rest: int) -> _MomentumBlocks:
    """Euler for the whole body: the rows ``-Ldot_k`` of the centroidal function get ``+ l_k`` (the
    lifted moments, with their own rows ``rate_k(x) = l_k`` and cost) or ``+ dh/dt`` of the body
    (linearized about ``pm``); nothing without whole-body momentum rows."""
    from planner.trajopt.centroidal.pattern import momentum_row_index

    nv, n = lay.robot.nv, lay.N - 2
    idx = momentum_row_index(cf.terms.constraints)
    n_l = moment_rows(lay)
    out = _MomentumBlocks(n_l, None, ca.MX(0), ca.MX(0, 1), ca.MX(0, 0), ca.MX(0, 1), ca.MX(0, nv * n),
                          ca.MX(n_c + n_rest, 0), ca.MX(n_c, nv * n))
    if not len(idx):
        return out
    if pm is None:
        raise ValueError("dynamic_blocks: whole-body momentum rows need their linearization parameters pm")
    if n_l == 0:
        rates, jac_cx = momentum_rates(lay, x_kin, pm, idx, n_c)
        return out._replace(add_c=rates, jac_cx=jac_cx)
    if moment is None or moment.numel() != n_l or len(idx) != n_l:
        raise ValueError("dynamic_blocks: the lifted moment needs 3 variables per dynamics knot")
    S = ca.DM(ca.Sparsity.triplet(n_c, n_l, idx.tolist(), list(range(n_l))), 1.0)
    rates, jac_rx = momentum_rates(lay, x_kin, pm)
    w_l = 2 * lay.centroidal_settings.angular_momentum_weight * dt
    return out._replace(add_c=ca.mtimes(S, moment), f_l=0.5 * w_l * ca.sumsqr(moment), grad_l=w_l * moment,
                        hess_ll=ca.MX(ca.Sparsity.diag(n_l), ca.repmat(lam_f * w_l, n_l, 1)),
                        g_r=rates - moment, jac_rx=jac_rx, jac_l=ca.vertcat(ca.MX(S), ca.MX(n_rest, n_l)))


def dynamic_blocks(lay: DynamicData, cf: CentroidalFunction, x_kin: Any, u: Any, c: Any, q_ref: Any, p: Any, dt: Any,
                   lam_f: Any, lam: Any, *, kinematic_hessian: bool = True, pm: Any = None,
                   moment: Any = None) -> DynamicBlocks:
    """Assemble the dynamic terms of a stage-wise NLP with exact derivatives.

    The centroidal function (dynamics, friction, cost) is evaluated on the lifted CoM variables
    ``c`` (knots 0 and 1 at the standing CoM, knot N repeating N-1) with its derivatives w.r.t.
    ``(C, u)`` from SX; the configuration enters only through the rows ``c_k - com(q_k)`` and
    the sole-corner heights, whose values and Jacobians come from one mapped SX function and
    whose curvature from a second one (the Hessian of ``-mu_k . com_k + eta_k . z_k`` with the
    multipliers of those rows).

    Args:
        lay: The layout.
        cf: The centroidal function of the layout.
        x_kin: Chart displacements of knots 2..N-1 (MX, nv (N-2)).
        u: Force variables (MX, ``cf.terms.n_variables``).
        c: Lifted CoM of knots 2..N-1 (MX, 3 (N-2)) [m].
        q_ref: Reference configuration (MX, nq).
        p: Contact parameters (MX, ``cf.terms.parameter_values.size``).
        dt: Knot spacing (MX scalar) [s].
        lam_f: Objective multiplier (MX scalar).
        lam: Multipliers of this block's rows (MX, len(lbg)).
        kinematic_hessian: Build :attr:`DynamicBlocks.hess_xx` (off: the caller adds the
            curvature of the CoM and sole-corner rows itself, from ``nu`` and ``eta``).
        pm: Linearization parameters of the whole-body angular momentum (MX,
            :func:`planner.trajopt.centroidal.momentum.momentum_sizes`; with
            ``CentroidalSettings.whole_body_momentum``).
        moment: The lifted moments ``l`` (MX, :func:`moment_rows`; with
            ``CentroidalSettings.lifts_moment``).

    Returns:
        The blocks.
    """
    robot, N = lay.robot, lay.N
    nv, n = robot.nv, lay.N - 2
    # built once per layout and shared by its copies (a collision round's layout builds its NLP again)
    first, second, values = lay.memo("kinematic_functions", lambda: _kinematic_functions(lay))
    X = ca.reshape(x_kin, nv, n)
    Qr = ca.repmat(q_ref, 1, n)
    # values and derivatives from separate functions: a call computes all its outputs, and the
    # NLP's f and g (IPOPT evaluates them at every line-search trial) need no derivative
    Ck_d, JC, Z_d, JZ = first.map(n)(X, Qr)
    Ck, Z = values.map(n)(X, Qr)
    c0 = values(ca.MX.zeros(nv), q_ref)[0]
    Cv = ca.reshape(c, 3, n)
    C = ca.horzcat(c0, c0, Cv, Cv[:, n - 1])
    E = _lifted_com_selection(N)
    g0, f0, d1, d2, n_c = (lay.memo("centroidal_functions", lambda: _centroidal_functions(cf, N))
                           if cf is lay.centroidal() else _centroidal_functions(cf, N))
    n_m = 3 * n
    lam_c, lam_m = lam[:n_c], lam[n_c:n_c + n_m]
    g_c, f_c = g0(C, u, p, dt), f0(C, u, p, dt)
    g_cd, f_cd, J_w, G_w = d1(C, u, p, dt)
    H_w = d2(C, u, p, dt, lam_f, lam_c)
    m = 3 * (N + 1)
    J_C, J_U = J_w[:, :m], J_w[:, m:]
    G_C, G_U = G_w[:m], G_w[m:]
    H_CC, H_CU, H_UU = H_w[:m, :m], H_w[:m, m:], H_w[m:, m:]
    Sz = _swing_corner_selection(robot, cf, n)
    n_z = Sz.size1()
    lam_z = lam[n_c + n_m:n_c + n_m + n_z]
    g_z = ca.mtimes(Sz, ca.vec(Z))
    g_zd = ca.mtimes(Sz, ca.vec(Z_d))
    jac_z = ca.mtimes(Sz, ca.diagcat(*ca.horzsplit(JZ, nv)))
    eta = ca.reshape(ca.mtimes(Sz.T, lam_z), 8, n) if n_z else ca.MX.zeros(8, n)
    nu = -ca.reshape(lam_m, 3, n)
    HK = second.map(n)(X, Qr, nu, eta) if kinematic_hessian else None
    n_u = cf.terms.n_variables
    mb = _momentum_blocks(lay, cf, x_kin, dt, lam_f, pm, moment, n_c, n_m + n_z)
    n_l, f_l, grad_l, hess_ll = mb.n_l, mb.f_l, mb.grad_l, mb.hess_ll
    g_r, g_rd, jac_rx, jac_l, jac_cx = mb.g_r, mb.g_r, mb.jac_rx, mb.jac_l, mb.jac_cx
    if mb.add_c is not None:
        g_c, g_cd = g_c + mb.add_c, g_cd + mb.add_c
    return DynamicBlocks(
        f=f_c + f_l,
        g=ca.vertcat(g_c, c - ca.vec(Ck), g_z, g_r),
        f_d=f_cd + f_l,
        g_d=ca.vertcat(g_cd, c - ca.vec(Ck_d), g_zd, g_rd),
        lbg=np.concatenate([cf.lbg, np.zeros(n_m), np.zeros(n_z), np.zeros(n_l)]),
        ubg=np.concatenate([cf.ubg, np.zeros(n_m), np.full(n_z, np.inf), np.zeros(n_l)]),
        grad_u=G_U,
        grad_c=ca.mtimes(E.T, G_C),
        grad_l=grad_l,
        jac_x=ca.vertcat(jac_cx, -ca.diagcat(*ca.horzsplit(JC, nv)), jac_z, jac_rx),
        jac_u=ca.vertcat(J_U, ca.MX(n_m + n_z + n_l, n_u)),
        jac_c=ca.vertcat(ca.mtimes(J_C, E), ca.MX(ca.DM.eye(n_m)), ca.MX(n_z + n_l, n_m)),
        jac_l=ca.vertcat(jac_l, -ca.MX(ca.DM.eye(n_l))),
        hess_xx=ca.diagcat(*ca.horzsplit(HK, nv)) if kinematic_hessian else None,
        nu=nu,
        eta=eta,
        hess_uu=H_UU,
        hess_uc=ca.mtimes(H_CU.T, E),
        hess_cc=ca.mtimes(E.T, ca.mtimes(H_CC, E)),
        hess_ll=hess_ll,
    )


STAGE_HESSIAN_CACHE_SIZE = 256
_STAGE_HESSIANS: OrderedDict[tuple, tuple[ca.Function, int, int]] = OrderedDict()


def _stage_hessian(robot: Robot, terms: list) -> tuple[ca.Function, int, int]:
    """The SX function of one stage type's part of the chart Hessian (:func:`stage_hessians`), its
    parameter count and its row count, from a per-process cache keyed by the robot and the terms'
    structure (as the kinematic stages, :func:`planner.trajopt.transcription.stage`): a collision
    round's NLP builds only the stage types it changed. Named after the key (generated C never holds
    two functions of one name).

    ``fn(dq, q_ref, p, sigma, lam) -> (H, nu_cost)``: ``H`` the Hessian of ``sigma cost + lam . g``
    of the terms (with the Gauss-Newton part of the soft CoM targets), ``nu_cost`` (3,) what the soft
    CoM targets add to the CoM multiplier (per unit ``sigma``). The CoM and sole-corner part, the
    same at every knot, is :func:`_robot_hessian`'s: differentiated once per robot, not per stage
    type, and no substitution of the CoM multiplier into each stage's Hessian (that took ~40 % of
    a stairs climb's stage Hessians)."""
    from planner.trajopt.kinds import ClosedChainTerm, CoMPositionTerm
    from planner.trajopt.symbolic import SymbolicKinematics, model_hash
    from planner.trajopt.term import StageKinematics

    key = (robot.name, model_hash(robot.model),
           tuple((type(t).__name__, t.kind, t.structure, len(t.params), t.n_rows, getattr(t, "hard", None))
                 for t in terms))
    hit = _STAGE_HESSIANS.get(key)
    if hit is not None:
        _STAGE_HESSIANS.move_to_end(key)
        return hit
    name = "dyn_stage_hess_" + hashlib.sha256(repr(key).encode()).hexdigest()[:16]
    nq, nv = robot.nq, robot.nv
    kin = SymbolicKinematics(robot.model)
    dq = ca.SX.sym("dq", nv)
    qr = ca.SX.sym("q_ref", nq)
    oMi = kin.joint_placements(qr, dq)
    # a closed chain's frames come from the joint placements its term builds (as before the kinds were classes)
    frame_ids = sorted({f for t in terms if not isinstance(t, ClosedChainTerm) for f in t.frames()})
    com = kin.com(oMi)
    stage = StageKinematics(robot, qr, dq, com, {f: kin.frame_placement(oMi, f)[::-1] for f in frame_ids})
    ps = ca.SX.sym("p", sum(len(t.params) for t in terms))
    sigma = ca.SX.sym("sigma")
    rows, cost, offset = [], 0, 0
    # soft CoM targets w |S (c - c*)|^2: Hessian 2 w (J^T S^T S J + sum_i e_i hess c_i), the
    # second part folded into the CoM multiplier (AD of the square costs ~5x more)
    nu_cost = ca.SX.zeros(3)
    gauss_newton = ca.SX.zeros(nv, nv)
    for t in terms:
        pt = ps[offset: offset + len(t.params)]
        offset += len(t.params)
        if isinstance(t, CoMPositionTerm) and not t.hard:
            sel = [i for i, a in enumerate(t.axes) if a]
            e = (com - pt[0:3])[sel]
            J = ca.jacobian(com[sel], dq)
            gauss_newton = gauss_newton + 2 * pt[3] * ca.mtimes(J.T, J)
            nu_cost[sel] = nu_cost[sel] + 2 * pt[3] * e
            continue
        r, cst = t.expression(pt, stage)
        cost = cost + cst
        if r is not None:
            rows.append(r)
    g = ca.vertcat(*rows) if rows else ca.SX.zeros(0)
    lam = ca.SX.sym("lam", g.numel())
    hess = ca.hessian(sigma * cost + ca.dot(lam, g), dq)[0] + sigma * gauss_newton
    fn = ca.Function(name, [dq, qr, ps, sigma, lam], [hess, nu_cost])
    out = (fn, int(ps.numel()), int(g.numel()))
    _STAGE_HESSIANS[key] = out
    while len(_STAGE_HESSIANS) > STAGE_HESSIAN_CACHE_SIZE:
        _STAGE_HESSIANS.popitem(last=False)
    return out


_ROBOT_HESSIANS: dict[tuple, ca.Function] = {}


def _robot_hessian(robot: Robot) -> ca.Function:
    """The SX function of the chart Hessian of ``nu . com + eta . z`` (the CoM rows' and the
    sole-corner rows' part of every knot's Lagrangian Hessian): ``fn(dq, q_ref, nu, eta)``; one per
    robot and process."""
    from planner.trajopt.symbolic import SymbolicKinematics, model_hash

    key = (robot.name, model_hash(robot.model))
    hit = _ROBOT_HESSIANS.get(key)
    if hit is not None:
        return hit
    kin = SymbolicKinematics(robot.model)
    dq = ca.SX.sym("dq", robot.nv)
    qr = ca.SX.sym("q_ref", robot.nq)
    oMi = kin.joint_placements(qr, dq)
    nu = ca.SX.sym("nu", 3)
    eta = ca.SX.sym("eta", 8)
    lag = ca.dot(nu, kin.com(oMi)) + ca.dot(eta, sole_corner_heights(kin, oMi, robot))
    name = "dyn_robot_hess_" + hashlib.sha256(repr(key).encode()).hexdigest()[:16]
    fn = ca.Function(name, [dq, qr, nu, eta], [ca.hessian(lag, dq)[0]])
    _ROBOT_HESSIANS[key] = fn
    return fn


def stage_hessians(lay: DynamicData, x_kin: Any, q_ref: Any, p_kin: Any, lam_f: Any, lam_kin: Any, nu: Any,
                   eta: Any) -> Any:
    """Block-diagonal chart Hessian of a dynamic NLP's Lagrangian, one SX function per stage type.

    For the knots of each stage group of :func:`planner.trajopt.stage_groups`, one mapped SX
    function gives the Hessian of ``lam_f cost_k + lam_k . g_k`` w.r.t. ``dq_k``; one SX function
    of the robot (:func:`_robot_hessian`), mapped over every knot, adds that of ``nu_k . com_k +
    eta_k . z_k`` (the CoM and sole-corner rows of the dynamics, and the soft CoM targets'
    second-order part on the CoM multiplier); the blocks are laid out in knot order with one
    ``diagcat`` each (no sparse products with selection matrices). Parameters and multipliers are read in the
    order :func:`planner.trajopt.transcription.build_nlp` gives them.

    Args:
        lay: The dynamic layout.
        x_kin: Chart displacements of knots 2..N-1 (MX, nv (N-2)).
        q_ref: Reference configuration (MX, nq).
        p_kin: Parameters of the kinematic NLP (MX).
        lam_f: Objective multiplier (MX scalar).
        lam_kin: Multipliers of the kinematic rows (MX).
        nu, eta: Multipliers on each variable knot's CoM (3, N-2) and sole-corner heights (8, N-2).

    Returns:
        The (nv (N-2), nv (N-2)) block-diagonal Hessian (MX, both triangles), without the
        constant quadratic costs.
    """
    from planner.trajopt.terms import stage_groups

    robot = lay.robot
    nq, nv, n = robot.nq, robot.nv, lay.N - 2
    X = ca.reshape(x_kin, nv, n)
    blocks: dict[int, Any] = {}
    nu_costs: dict[int, Any] = {}
    p_offset, g_offset = nq + 3, 0
    for _sig, knots, term_lists in stage_groups(lay):
        fn, n_p, n_g = _stage_hessian(robot, [lay.terms[i] for i in term_lists[0]])
        m = len(knots)
        cols = [kk - 2 for kk in knots]
        Pg = ca.reshape(p_kin[p_offset: p_offset + n_p * m], n_p, m)
        p_offset += n_p * m
        L = ca.reshape(lam_kin[g_offset: g_offset + n_g * m], n_g, m)
        g_offset += n_g * m
        HS, NC = fn.map(m)(X[:, cols], ca.repmat(q_ref, 1, m), Pg, ca.repmat(lam_f, 1, m), L)
        for kk, block, nc in zip(knots, ca.horzsplit(HS, nv), ca.horzsplit(NC, 1), strict=True):
            blocks[kk], nu_costs[kk] = block, nc
    # the CoM and sole-corner rows' part, one function mapped over every knot; the soft CoM
    # targets' second-order part rides on the CoM multiplier
    nu_all = nu + lam_f * ca.horzcat(*[nu_costs[kk] for kk in range(2, lay.N)])
    HR = _robot_hessian(robot).map(n)(X, ca.repmat(q_ref, 1, n), nu_all, eta)
    return ca.diagcat(*[blocks[kk] for kk in range(2, lay.N)]) + ca.diagcat(*ca.horzsplit(HR, nv))


def dynamic_sizes(lay: DynamicData) -> tuple[int, int]:
    """(force + lifted CoM + lifted moment variables, dynamic constraint rows) of a dynamic layout."""
    pat = lay.pattern()
    n_l = moment_rows(lay)
    return pat.n_variables + com_rows(lay) + n_l, len(pat.lbg) + com_rows(lay) + len(lay.corner_rows()) + n_l


def extend_nlp(lay: DynamicData, nlp: dict, derivatives: dict) -> tuple[dict, dict]:
    """Add the forces, lifted CoM, CoM dynamics and sole-corner rows to a stage-wise kinematic NLP.

    Args:
        lay: The dynamic layout.
        nlp: ``{x, p, f, g}`` of the kinematic NLP (MX).
        derivatives: Its ``grad_f``, ``jac_g``, ``hess_lag`` functions (nlpsol options).

    Returns:
        The extended ``(nlp, derivatives)``: variables ``[x; u; c; l]``, parameters ``[p; contact
        geometry; momentum linearization]``, rows ``[g; dynamic rows]``.
    """
    cf = lay.centroidal()
    robot = lay.robot
    n_x, n_p, n_g = nlp["x"].numel(), nlp["p"].numel(), nlp["g"].numel()
    n_u = cf.terms.n_variables
    n_m = com_rows(lay)
    n_l = moment_rows(lay)
    _, n_gd = dynamic_sizes(lay)
    n_pd = cf.terms.parameter_values.size
    n_pm = momentum_parameter_count(lay)
    x = ca.MX.sym("x", n_x + n_u + n_m + n_l)
    p = ca.MX.sym("p", n_p + n_pd + n_pm)
    lam_f = ca.MX.sym("lam_f")
    lam_g = ca.MX.sym("lam_g", n_g + n_gd)
    xk, u, c, lm = x[:n_x], x[n_x:n_x + n_u], x[n_x + n_u:n_x + n_u + n_m], x[n_x + n_u + n_m:]
    pk, pd, pm = p[:n_p], p[n_p:n_p + n_pd], p[n_p + n_pd:]
    nq = robot.nq
    b = dynamic_blocks(lay, cf, xk, u, c, pk[:nq], pd, pk[nq + 2], lam_f, lam_g[n_g:], kinematic_hessian=False,
                       pm=pm, moment=lm)
    f_kd, grad_k = derivatives["grad_f"](xk, pk)
    g_kd, jac_k = derivatives["jac_g"](xk, pk)
    # the kinematic NLP's own f and g: its derivative functions would compute the derivatives too
    f_k = ca.Function("kin_f", [nlp["x"], nlp["p"]], [nlp["f"]])(xk, pk)
    g_k = ca.Function("kin_g", [nlp["x"], nlp["p"]], [nlp["g"]])(xk, pk)
    # chart Hessian: the constant quadratic costs + per-knot blocks (kinematic terms and the
    # CoM / sole-corner rows together), instead of the kinematic hess_lag plus a second pass
    from planner.trajopt.transcription import _quadratic_operators

    A, P, _ = _quadratic_operators(lay)
    w_smooth, w_posture, dt = pk[nq], pk[nq + 1], pk[nq + 2]
    quad = lam_f * (2 * w_smooth / dt**3 * ca.mtimes(A.T, A) + 2 * w_posture * dt * ca.mtimes(P.T, P))
    h_k = ca.triu(quad + stage_hessians(lay, xk, pk[:nq], pk, lam_f, lam_g[:n_g], b.nu, b.eta))
    f = f_k + b.f
    g = ca.vertcat(g_k, b.g)
    grad = ca.vertcat(grad_k, b.grad_u, b.grad_c, b.grad_l)
    jac = ca.vertcat(ca.horzcat(jac_k, ca.MX(n_g, n_u + n_m + n_l)), ca.horzcat(b.jac_x, b.jac_u, b.jac_c, b.jac_l))
    hess = ca.blockcat([
        [h_k, ca.MX(n_x, n_u), ca.MX(n_x, n_m), ca.MX(n_x, n_l)],
        [ca.MX(n_u, n_x), ca.triu(b.hess_uu), b.hess_uc, ca.MX(n_u, n_l)],
        [ca.MX(n_m, n_x), ca.MX(n_m, n_u), ca.triu(b.hess_cc), ca.MX(n_m, n_l)],
        [ca.MX(n_l, n_x), ca.MX(n_l, n_u), ca.MX(n_l, n_m), b.hess_ll],
    ])
    out = {
        "grad_f": ca.Function("nlp_grad_f", [x, p], [f_kd + b.f_d, grad], ["x", "p"], ["f", "grad_f_x"]),
        "jac_g": ca.Function("nlp_jac_g", [x, p], [ca.vertcat(g_kd, b.g_d), jac], ["x", "p"], ["g", "jac_g_x"]),
        "hess_lag": ca.Function("nlp_hess_l", [x, p, lam_f, lam_g], [hess], ["x", "p", "lam_f", "lam_g"],
                                ["triu_hess_gamma_x_x"]),
    }
    return {"x": x, "p": p, "f": f, "g": g}, out


def extend_bounds(lay: DynamicData, lbx: np.ndarray, ubx: np.ndarray, lbg: np.ndarray,
                  ubg: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Bounds of the extended NLP from the kinematic ones (force boxes, free CoM and moments,
    dynamic rows)."""
    pat = lay.pattern()
    rows = lay.corner_rows()
    n_z = len(rows)
    n_m = com_rows(lay) + moment_rows(lay)
    n_l = moment_rows(lay)
    return (
        np.concatenate([lbx, pat.lower, np.full(n_m, -np.inf)]),
        np.concatenate([ubx, pat.upper, np.full(n_m, np.inf)]),
        np.concatenate([lbg, pat.lbg, np.zeros(com_rows(lay)), swing_corner_floor(lay, rows), np.zeros(n_l)]),
        np.concatenate([ubg, pat.ubg, np.zeros(com_rows(lay)), np.full(n_z, np.inf), np.zeros(n_l)]),
    )


SWING_CLEARANCE = 0.01  # [m] lowest sole corner of a swinging foot, away from lift-off and touch-down


def swing_corner_floor(lay: DynamicData, rows: Sequence[tuple[int, int, int]]) -> np.ndarray:
    """Lower bounds of the swinging sole-corner heights [m].

    0 at the first and last free knot of a swing (the sole may still or already touch there),
    :data:`SWING_CLEARANCE` in between. With 0 everywhere, a Talos 4-step plan put the swinging
    toe on the ground two knots (0.15 s) before its touch-down, and the simulation, tracking it
    within millimetres, touched the floor early: an unplanned contact.
    """
    floor = np.zeros(len(rows))
    n = len(lay.contacts_at)
    for j, (k, fid, _corner) in enumerate(rows):
        before = k - 1 >= 0 and fid in lay.contacts_at[k - 1]
        after = k + 1 >= n or fid in lay.contacts_at[k + 1]
        if not before and not after:
            floor[j] = SWING_CLEARANCE
    return floor


def momentum_parameter_count(lay: DynamicData) -> int:
    """Number of whole-body momentum linearization parameters (0 when the setting is off)."""
    from planner.trajopt.centroidal.momentum import momentum_sizes

    return momentum_sizes(lay.robot.nv, lay.N) if lay.centroidal_settings.whole_body_momentum else 0


def extend_parameters(lay: DynamicData, p: np.ndarray) -> np.ndarray:
    """Parameter values of the extended NLP: the kinematic ones, the contact geometry, then the
    whole-body momentum linearized at :meth:`DynamicData.momentum_point`."""
    parts = [p, lay.pattern().parameter_values]
    if lay.centroidal_settings.whole_body_momentum:
        from planner.trajopt.centroidal.momentum import momentum_parameters

        parts.append(momentum_parameters(lay, lay.momentum_point()))
    return np.concatenate(parts)
