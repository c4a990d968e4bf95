r"""Compiled inner loop of the whole-body controller tick (numba).

Everything of a tick after the Pinocchio calls happens here, in one compiled function: the task
errors and desired accelerations, the least-squares Hessian and gradient, the contact force map
:math:`S = J_c^\top G` and an exact solve of the QP *without its inequalities*.

Why the equality-only solve is exact when it is feasible: the QP is convex, and its feasible set
is a subset of the equality-constrained one. If the minimizer of the equality-constrained problem
meets every inequality (friction pyramids, torque limits), it is the QP's minimizer too. On a
standing or walking robot that is the common case: the force regularization spreads the load
over the sole corners, far from the pyramid edges, and the torques are far from their limits.
When an inequality is violated the caller solves the full QP with proxsuite.

The equality-only problem is solved in reduced form. With the force cost :math:`\tfrac d2|f|^2`
the stationarity in the forces gives :math:`f = S_6^\top \lambda / d` (:math:`\lambda`: the
multiplier of the six floating-base dynamics rows), which leaves a symmetric indefinite system in
the accelerations and the multipliers only:

.. math::

    \begin{bmatrix} H & M_6^\top & J_c^\top \\ M_6 & -W & 0 \\ J_c & 0 & 0 \end{bmatrix}
    \begin{bmatrix} a \\ \lambda \\ \mu \end{bmatrix} =
    \begin{bmatrix} -g \\ -h_6 \\ b_c \end{bmatrix}, \qquad W = S_6 S_6^\top / d,

of size ``nv + 6 + 6 * n_stance`` (56 on Talos in double support, against 80 for the KKT system
proxsuite factorizes with all the force variables). It is solved by the range-space method:
:math:`H` is positive definite (every acceleration is regularized), so with :math:`H = L L^\top`,
:math:`Y = L^{-1} B^\top` (:math:`B = [M_6; J_c]`) the multipliers solve the small positive
definite system :math:`(Y^\top Y + \mathrm{diag}(W, 0))\, y = -r - Y^\top L^{-1} g`, and
:math:`a = -L^{-\top}(L^{-1} g + Y y)`: two Cholesky factorizations (38 and 18 on Talos)
instead of an LU of the whole system, a third of the flops.

When the equality-only solution violates rows, the same solve runs again with the violated
rows held as equalities (a corner whose normal force is negative lifts off: its force is 0;
a pyramid row or a torque limit is held at its bound), and the row whose multiplier has the
wrong sign is released, at most ``max_active_iters`` times. A solution is returned only when
every KKT condition of the full QP is met: stationarity holds by construction, every row holds
(tolerance ``tol``), active rows sit at their bounds with correctly signed multipliers.
Otherwise (cycling, dependent rows, the iteration cap) the caller solves the full QP.

numba compiles the function on first use and caches the machine code beside this file (or in
the user's cache directory when that is read-only), so later processes load it in well under a
second.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numba import njit

# Let LLVM reorder sums (vectorized dot products) and fuse multiply-adds; no finite-math
# assumptions, so the NaN checks stay.
_FAST = {"reassoc", "contract"}

FAST_SOLVED = 0  # the equality-only solution meets every inequality: it is the QP's solution
FAST_INEQUALITY = 1  # an inequality is violated: solve the full QP
FAST_SINGULAR = 2  # the reduced system could not be solved
ACTIVE_SET_SOLVED = 3  # solved with some friction/torque rows active (KKT conditions verified)

# pyramid rows (+-fx or +-fy) - mu' fz <= 0: robots.contact.PYRAMID_FACETS as a literal numba freezes
# at compile time (tests/robots/test_contact.py checks that the two agree)
_FACETS = ((1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0))


@njit(cache=True, nogil=True, fastmath=_FAST)
def _cholesky(A, n):
    """In-place lower Cholesky factor of the leading n x n block of A; False if not positive definite."""
    for j in range(n):
        acc = A[j, j]
        for k in range(j):
            acc -= A[j, k] * A[j, k]
        if not acc > 0.0:
            return False
        d = np.sqrt(acc)
        A[j, j] = d
        for i in range(j + 1, n):
            acc = A[i, j]
            for k in range(j):
                acc -= A[i, k] * A[j, k]
            A[i, j] = acc / d
    return True


@njit(cache=True, nogil=True, fastmath=_FAST)
def _forward(L, n, b):
    """Solve L x = b in place (L lower triangular, n x n)."""
    for i in range(n):
        acc = b[i]
        for k in range(i):
            acc -= L[i, k] * b[k]
        b[i] = acc / L[i, i]


@njit(cache=True, nogil=True, fastmath=_FAST)
def _backward(L, n, b):
    """Solve L^T x = b in place (L lower triangular, n x n)."""
    for i in range(n - 1, -1, -1):
        acc = b[i]
        for k in range(i + 1, n):
            acc -= L[k, i] * b[k]
        b[i] = acc / L[i, i]


@njit(cache=True, nogil=True, fastmath=_FAST)
def _log3_quat(q, q_ref, out):
    """Rotation vector of R(q)^T R(q_ref), quaternions (x, y, z, w) at q[3:7] (pin.difference's angular part)."""
    x0, y0, z0, w0 = q[3], q[4], q[5], q[6]
    x1, y1, z1, w1 = q_ref[3], q_ref[4], q_ref[5], q_ref[6]
    # conj(q0) * q1
    w = w0 * w1 + x0 * x1 + y0 * y1 + z0 * z1
    x = w0 * x1 - x0 * w1 - y0 * z1 + z0 * y1
    y = w0 * y1 + x0 * z1 - y0 * w1 - z0 * x1
    z = w0 * z1 - x0 * y1 + y0 * x1 - z0 * w1
    if w < 0.0:
        w, x, y, z = -w, -x, -y, -z
    s = np.sqrt(x * x + y * y + z * z)
    k = 2.0 * np.arctan2(s, w) / s if s > 1e-12 else 2.0 / w
    out[0] = k * x
    out[1] = k * y
    out[2] = k * z


@njit(cache=True, nogil=True, fastmath=_FAST)
def tick_kernel(
    M, h, J, drift, v, q, q_ref, dq_post, hom, ref_pos, ref_rot, feedforward, anchor_pos, anchor_rot,
    frame_active, kp_rows, kd_rows, w_rows, post_feedforward, kp_post, kd_post, diag_a, diag_a_total, g0s,
    stance, force_reg, mu, tau_max, tol, try_fast, max_active_iters, pos, rots, Ha, ga, S, a_des, x, tau,
    info
):
    """One tick's assembly and (when feasible) solve; see the module docstring.

    Args:
        M, h: Mass matrix (nv, nv) and nonlinear effects (nv,).
        J, drift: Stacked task Jacobians (nrow, nv) and drifts ``J'v`` (nrow,): CoM rows, then
            6 world-aligned rows per frame (contact frames first), then any rows without a
            position error (the centroidal angular momentum: their ``kp`` is 0).
        v: Generalized velocity (nv,).
        q, q_ref: Configuration and the reference one (nq,), for the posture error.
        dq_post: Posture error ``q_ref - q`` on the manifold (nv,). If ``nq == nv + 1`` (a
            free flyer and 1-dof joints) it is computed here and written into this array;
            otherwise the caller computes it (``pin.difference``).
        hom: Frame placements (nf, 4, 4), homogeneous.
        ref_pos, ref_rot, feedforward: The reference at this tick: CoM and frame positions
            (1 + nf, 3), frame rotations (nf, 3, 3), ``a_ref + Kd v_ref`` per row (nrow,).
        anchor_pos, anchor_rot, frame_active: Where each stance sole is held, and which frames
            are stance soles (nf,).
        kp_rows, kd_rows, w_rows: Per-row gains and square-root weights (nrow,); stance rows
            have weight 0 (they are constraints).
        post_feedforward, kp_post, kd_post: Posture feed-forward ``a_ref + Kd v_ref`` and
            gains (nv,).
        diag_a, diag_a_total: Diagonal posture weights, and the same plus the acceleration
            regularization (nv,).
        g0s: Corner-force to sole-wrench maps in the sole frame, force scale included (nc, 6, 12).
        stance: Indices of the stance contacts (ns,).
        force_reg: Weight ``d`` of the force regularization (scaled forces).
        mu: Per-axis bound mu' of the friction pyramids (robots.contact.pyramid_coefficient) [-].
        tau_max: Torque limits (nv - 6,).
        tol: Feasibility tolerance of the inequality check.
        try_fast: Solve the equality-only QP (otherwise only assemble).
        max_active_iters: Active-set iterations allowed after an infeasible equality-only
            solution (0: go straight to the full QP).
        pos, rots: Outputs: frame positions written to ``pos[1:]`` (``pos[0]`` is the CoM, an
            input) and rotations (nf, 3, 3).
        Ha, ga, S, a_des: Outputs for the full QP: Hessian block (nv, nv), gradient (nv,),
            force map ``J_c^T G`` (nv, 12 nc; zero columns for swing contacts), desired task
            accelerations (nrow,).
        x, tau: Outputs of the fast path: ``(a, f)`` (nv + 12 nc,) and torques (nv - 6,),
            clipped to ``tau_max``.
        info: Output (2,): active-set iterations and active inequality rows.

    Returns:
        ``FAST_SOLVED``, ``ACTIVE_SET_SOLVED``, ``FAST_INEQUALITY`` or ``FAST_SINGULAR``;
        always ``FAST_INEQUALITY`` when ``try_fast`` is false.
    """
    nv = M.shape[0]
    _task_accelerations(J, drift, v, hom, ref_pos, ref_rot, feedforward, anchor_pos, anchor_rot, frame_active,
                        kp_rows, kd_rows, pos, rots, a_des)
    if q.shape[0] == nv + 1:  # posture error on the manifold (free flyer + 1-dof joints)
        for j in range(3):
            dq_post[j] = 0.0  # the base position has no posture weight
        _log3_quat(q, q_ref, dq_post[3:6])
        for j in range(6, nv):
            dq_post[j] = q_ref[j + 1] - q[j + 1]
    _least_squares(J, w_rows, a_des, v, dq_post, post_feedforward, kp_post, kd_post, diag_a, diag_a_total, Ha, ga)
    _force_map(J, rots, g0s, stance, S)
    if not try_fast:
        return FAST_INEQUALITY
    return _solve_tick(M, h, J, a_des, stance, S, Ha, ga, g0s.shape[0], force_reg, mu, tau_max, tol,
                       max_active_iters, x, tau, info)


@njit(cache=True, nogil=True, fastmath=_FAST)
def _task_accelerations(J, drift, v, hom, ref_pos, ref_rot, feedforward, anchor_pos, anchor_rot, frame_active,
                        kp_rows, kd_rows, pos, rots, a_des):
    """The frames' placements (into ``pos[1:]``, ``rots``), the task errors (CoM, positions,
    small-angle orientations, world-aligned; a stance sole's against its anchor) and the desired
    task accelerations ``a_des``."""
    nv = J.shape[1]
    nrow = J.shape[0]
    nf = rots.shape[0]
    err = np.zeros(nrow)  # rows after the frames' (the angular momentum) have no position error
    for j in range(3):
        err[j] = ref_pos[0, j] - pos[0, j]
    rel = np.empty((3, 3))
    for i in range(nf):
        for a in range(3):
            pos[1 + i, a] = hom[i, a, 3]
            for b in range(3):
                rots[i, a, b] = hom[i, a, b]
        r0 = 3 + 6 * i
        if frame_active[i]:
            tp = anchor_pos[i]
            tr = anchor_rot[i]
        else:
            tp = ref_pos[1 + i]
            tr = ref_rot[i]
        for j in range(3):
            err[r0 + j] = tp[j] - pos[1 + i, j]
        R = rots[i]
        for a in range(3):  # R^T R_target
            for b in range(3):
                acc = 0.0
                for c in range(3):
                    acc += R[c, a] * tr[c, b]
                rel[a, b] = acc
        w0 = rel[2, 1] - rel[1, 2]
        w1 = rel[0, 2] - rel[2, 0]
        w2 = rel[1, 0] - rel[0, 1]
        for j in range(3):
            err[r0 + 3 + j] = 0.5 * (R[j, 0] * w0 + R[j, 1] * w1 + R[j, 2] * w2)
    for r in range(nrow):
        jv = 0.0
        for c in range(nv):
            jv += J[r, c] * v[c]
        a_des[r] = feedforward[r] + kp_rows[r] * err[r] - kd_rows[r] * jv - drift[r]


@njit(cache=True, nogil=True, fastmath=_FAST)
def _least_squares(J, w_rows, a_des, v, dq_post, post_feedforward, kp_post, kd_post, diag_a, diag_a_total, Ha, ga):
    """The Hessian block ``Ha`` and gradient ``ga`` of the weighted task rows and the posture
    (stance rows have weight 0 and are skipped)."""
    nv = J.shape[1]
    nrow = J.shape[0]
    m = 0
    for r in range(nrow):
        if w_rows[r] != 0.0:
            m += 1
    T = np.empty((m, nv))
    rw = np.empty(m)
    m = 0
    for r in range(nrow):
        wr = w_rows[r]
        if wr != 0.0:
            for c in range(nv):
                T[m, c] = wr * J[r, c]
            rw[m] = wr * a_des[r]
            m += 1
    Ha[:, :] = T.T @ T
    for c in range(nv):
        acc = 0.0
        for r in range(m):
            acc += T[r, c] * rw[r]
        Ha[c, c] += diag_a_total[c]
        a_post = post_feedforward[c] + kp_post[c] * dq_post[c] - kd_post[c] * v[c]
        ga[c] = -acc - diag_a[c] * a_post


@njit(cache=True, nogil=True, fastmath=_FAST)
def _force_map(J, rots, g0s, stance, S):
    """The contact force map ``S = J_c^T G`` (world-aligned Jacobian, ``G`` rotated from the sole
    frame; zero columns for swing contacts)."""
    S[:, :] = 0.0
    G = np.empty((6, 12))
    for si in range(stance.shape[0]):
        i = stance[si]
        R = rots[i]
        g0 = g0s[i]
        for blk in range(2):
            for a in range(3):
                for c in range(12):
                    acc = 0.0
                    for b in range(3):
                        acc += R[a, b] * g0[3 * blk + b, c]
                    G[3 * blk + a, c] = acc
        Si = J[3 + 6 * i : 9 + 6 * i].T @ G
        S[:, 12 * i : 12 * i + 12] = Si


@njit(cache=True, nogil=True, fastmath=_FAST)
def _solve_tick(M, h, J, a_des, stance, S, Ha, ga, nc, force_reg, mu, tau_max, tol, max_active_iters, x, tau, info):
    """The equality-only QP, then (if rows are violated) the active-set continuation."""
    nv = M.shape[0]
    ns = stance.shape[0]
    L = Ha.copy()
    if not _cholesky(L, nv):
        return FAST_SINGULAR
    zg = ga.copy()
    _forward(L, nv, zg)  # L^-1 g
    inv_d = 1.0 / force_reg
    in_stance = np.zeros(nc, dtype=np.bool_)
    for si in range(ns):
        in_stance[stance[si]] = True
    off = np.zeros(4 * nc, dtype=np.bool_)  # corner lifted off: f = 0 (3 rows)
    facet = np.zeros((4 * nc, 4), dtype=np.bool_)  # one pyramid row held at 0
    t_up = np.zeros(nv - 6, dtype=np.bool_)
    t_lo = np.zeros(nv - 6, dtype=np.bool_)
    a_out = np.empty(nv)
    f = np.empty(12 * nc)
    first = 6 + 6 * ns
    for it in range(max_active_iters + 1):
        Ba, Bf, r, has_a, kind = _rows(M, h, J, a_des, stance, S, mu, tau_max, off, facet, t_up, t_lo)
        y = _solve_rows(Ba, Bf, r, has_a, L, zg, inv_d, a_out, f)
        if y.shape[0] == 0:
            return FAST_SINGULAR if it == 0 else FAST_INEQUALITY
        worst_row = _worst_multiplier(y, kind, first, mu, tol)
        if worst_row >= 0:  # before the additions: row numbers follow this solve's active set
            _release(worst_row, first, off, facet, t_up, t_lo, nc, nv - 6)
        added = _add_violations(a_out, f, M, h, S, in_stance, mu, tau_max, tol, off, facet, t_up, t_lo, tau)
        if not added and worst_row < 0:
            x[:nv] = a_out
            x[nv:] = f
            for j in range(nv - 6):
                tau[j] = min(max(tau[j], -tau_max[j]), tau_max[j])
            info[0] = it
            info[1] = Ba.shape[0] - first
            return FAST_SOLVED if it == 0 else ACTIVE_SET_SOLVED
    return FAST_INEQUALITY

@njit(cache=True, nogil=True, fastmath=_FAST)
def _rows(M, h, J, a_des, stance, S, mu, tau_max, off, facet, t_up, t_lo):
    """Equality rows of the reduced problem: floating-base dynamics (6), stance contacts (6
    each), then the active inequality rows (lifted-off corners, pyramid rows, torque limits).

    Returns ``Ba`` (rows, nv) and ``Bf`` (rows, 12 nc), the rows' acceleration and force parts;
    ``r`` the right-hand sides (``Ba a + Bf f = r``); ``has_a`` whether a row has an acceleration
    part; ``kind``: 0 equality, 1 inequality held at its bound (multiplier >= 0), 2 first of the
    three rows of a lifted-off corner.
    """
    nv = M.shape[0]
    nu = nv - 6
    nc = S.shape[1] // 12
    nfv = 12 * nc
    ns = stance.shape[0]
    n_rows = 6 + 6 * ns
    for c in range(4 * nc):
        if off[c]:
            n_rows += 3
        else:
            for t in range(4):
                if facet[c, t]:
                    n_rows += 1
    for j in range(nu):
        if t_up[j]:
            n_rows += 1
        if t_lo[j]:
            n_rows += 1
    Ba = np.zeros((n_rows, nv))
    Bf = np.zeros((n_rows, nfv))
    r = np.zeros(n_rows)
    has_a = np.zeros(n_rows, dtype=np.bool_)
    kind = np.zeros(n_rows, dtype=np.int64)
    for row in range(6):
        for cc in range(nv):
            Ba[row, cc] = M[row, cc]
        for cc in range(nfv):
            Bf[row, cc] = -S[row, cc]
        r[row] = -h[row]
        has_a[row] = True
    row = 6
    for si in range(ns):
        jr0 = 3 + 6 * stance[si]
        for q in range(6):
            for cc in range(nv):
                Ba[row, cc] = J[jr0 + q, cc]
            r[row] = a_des[jr0 + q]
            has_a[row] = True
            row += 1
    for c in range(4 * nc):
        base = 12 * (c // 4) + 3 * (c % 4)
        if off[c]:
            kind[row] = 2
            for q in range(3):
                Bf[row, base + q] = 1.0
                row += 1
            continue
        for t in range(4):
            if facet[c, t]:
                Bf[row, base] = _FACETS[t][0]
                Bf[row, base + 1] = _FACETS[t][1]
                Bf[row, base + 2] = -mu
                kind[row] = 1
                row += 1
    for j in range(nu):
        for sign in (1.0, -1.0):
            if (sign > 0 and t_up[j]) or (sign < 0 and t_lo[j]):
                for cc in range(nv):
                    Ba[row, cc] = sign * M[6 + j, cc]
                for cc in range(nfv):
                    Bf[row, cc] = -sign * S[6 + j, cc]
                r[row] = tau_max[j] - sign * h[6 + j]
                has_a[row] = True
                kind[row] = 1
                row += 1
    return Ba, Bf, r, has_a, kind


@njit(cache=True, nogil=True, fastmath=_FAST)
def _solve_rows(Ba, Bf, r, has_a, L, zg, inv_d, a, f):
    """Range-space solve of min 1/2 a'Ha + g'a + d/2 |f|^2 s.t. Ba a + Bf f = r.

    With ``H = L L^T``, ``Y = L^-1 Ba^T`` and ``zg = L^-1 g``: the multipliers solve
    ``(Y^T Y + Bf Bf^T / d) y = -r - Y^T zg``; then ``a = -L^-T (zg + Y y)`` and
    ``f = -Bf^T y / d``. Writes ``a`` and ``f``; returns ``y`` (empty if the rows are dependent
    or the result is not finite).
    """
    n_rows, nv = Ba.shape
    Y = np.zeros((n_rows, nv))  # rows: columns of L^-1 Ba^T
    for q in range(n_rows):
        if has_a[q]:
            for cc in range(nv):
                Y[q, cc] = Ba[q, cc]
            _forward(L, nv, Y[q])
    Sch = Y @ Y.T + (Bf @ Bf.T) * inv_d
    y = np.empty(n_rows)
    for q in range(n_rows):
        acc = -r[q]
        for cc in range(nv):
            acc -= Y[q, cc] * zg[cc]
        y[q] = acc
    if not _cholesky(Sch, n_rows):
        return np.empty(0)
    _forward(Sch, n_rows, y)
    _backward(Sch, n_rows, y)
    for cc in range(nv):
        acc = zg[cc]
        for q in range(n_rows):
            acc += Y[q, cc] * y[q]
        a[cc] = -acc
    _backward(L, nv, a)
    for cc in range(f.shape[0]):
        acc = 0.0
        for q in range(n_rows):
            acc -= Bf[q, cc] * y[q]
        f[cc] = acc * inv_d
    for cc in range(nv):
        if not np.isfinite(a[cc]):
            return np.empty(0)
    return y


@njit(cache=True, nogil=True)
def _worst_multiplier(y, kind, first, mu, tol):
    """The active inequality row whose multiplier has the most wrong sign (beyond ``tol``), or -1.

    A held row needs ``y >= 0``; a lifted-off corner's multiplier ``nu`` (of ``f = 0``) must lie
    in the cone of its four pyramid rows: ``nu_z <= 0`` and ``|nu_x| + |nu_y| <= -nu_z / mu``.
    """
    worst, worst_row = tol, -1
    for q in range(first, y.shape[0]):
        if kind[q] == 1:
            bad = -y[q]
        elif kind[q] == 2:
            nz = y[q + 2]
            bad = max(nz, abs(y[q]) + abs(y[q + 1]) + nz / mu)
        else:
            continue
        if bad > worst:
            worst, worst_row = bad, q
    return worst_row


@njit(cache=True, nogil=True)
def _add_violations(a, f, M, h, S, in_stance, mu, tau_max, tol, off, facet, t_up, t_lo, tau):
    """Torques of (a, f) into ``tau``; every violated row joins the active set. True if any did.

    A corner with a violated pyramid row and a negative normal force lifts off (f = 0); three
    or more held rows of one corner pin it to 0 as well.
    """
    nv = M.shape[0]
    nc = in_stance.shape[0]
    nfv = 12 * nc
    added = False
    for i in range(nc):
        if not in_stance[i]:
            continue
        for k in range(4):
            c = 4 * i + k
            if off[c]:
                continue
            fx, fy, fz = f[12 * i + 3 * k], f[12 * i + 3 * k + 1], f[12 * i + 3 * k + 2]
            violated = False
            for t in range(4):
                if not facet[c, t] and _FACETS[t][0] * fx + _FACETS[t][1] * fy - mu * fz > tol:
                    violated = True
            if not violated:
                continue
            added = True
            if fz < 0.0:
                off[c] = True
                facet[c, :] = False
                continue
            n_active = 0
            for t in range(4):
                if _FACETS[t][0] * fx + _FACETS[t][1] * fy - mu * fz > tol:
                    facet[c, t] = True
                if facet[c, t]:
                    n_active += 1
            if n_active >= 3:
                off[c] = True
                facet[c, :] = False
    for j in range(nv - 6):
        tj = h[6 + j]
        for cc in range(nv):
            tj += M[6 + j, cc] * a[cc]
        for cc in range(nfv):
            tj -= S[6 + j, cc] * f[cc]
        tau[j] = tj
        if not t_up[j] and tj > tau_max[j] + tol:
            t_up[j] = True
            added = True
        if not t_lo[j] and -tj > tau_max[j] + tol:
            t_lo[j] = True
            added = True
    return added


@njit(cache=True, nogil=True)
def _release(target, first, off, facet, t_up, t_lo, nc, nu):
    """Drop the active row ``target`` (row order of :func:`_rows`)."""
    row = first
    for c in range(4 * nc):
        if off[c]:
            if row == target:
                off[c] = False
                return
            row += 3
            continue
        for t in range(4):
            if facet[c, t]:
                if row == target:
                    facet[c, t] = False
                    return
                row += 1
    for j in range(nu):
        if t_up[j]:
            if row == target:
                t_up[j] = False
                return
            row += 1
        if t_lo[j]:
            if row == target:
                t_lo[j] = False
                return
            row += 1


def kernel_ready() -> bool:
    """Whether the first tick will start at once: the kernel is compiled in this process, or
    numba's cache beside this file holds it (otherwise the first tick compiles it, ~15 s)."""
    if tick_kernel.signatures:
        return True
    try:  # numba's own cache object knows its folder (NUMBA_CACHE_DIR too) and index file name
        cache = tick_kernel._cache
        return (Path(cache._cache_path) / cache._cache_file._index_name).is_file()
    except AttributeError:  # another numba layout: the default one, <module>.<function>-<line>.<python>.nbi
        folder = Path(__file__).resolve().parent / "__pycache__"
        return any(folder.glob(f"{Path(__file__).stem}.tick_kernel-*.nbi"))
