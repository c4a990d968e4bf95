r"""Whole-body angular momentum: Pinocchio's centroidal momentum matrix, linearized per knot interval.

The centroidal momentum of the whole body about its CoM is :math:`h = A_g(q)\,v`
(``pin.computeCentroidalMap``; linear part :math:`m \dot c`, angular part :math:`h_\omega`).
Newton-Euler for the whole body, with point contact forces :math:`f_i` at :math:`p_i`:

.. math::

    m(\ddot c - g) = \sum_i f_i, \qquad \dot h_\omega = \sum_i (p_i - c) \times f_i .

The linear part is the lifted CoM's dynamics. The angular part is written on the knot grid as

.. math::

    \frac{h_{k+1/2} - h_{k-1/2}}{\Delta t} = \sum_i (p_{k,i} - c_k) \times f_{k,i},
    \qquad h_{j+1/2} = A_{g,\omega}(q_{j+1/2})\, \frac{q_{j+1} \ominus q_j}{\Delta t}

(:math:`q_{j+1/2}` the midpoint configuration). The chart NLP has no symbolic
:math:`A_g` (no ``pinocchio.casadi`` on this wheel, and an exact :math:`A_g(q)` coupling two
knots would break the per-knot Hessian blocks of the stage-wise NLP), so :math:`h_{j+1/2}` enters
*linearized* about an iterate :math:`\bar{dq}` of the chart displacements:

.. math::

    h_{j+1/2} \approx b_j + P_j\, dq_j + Q_j\, dq_{j+1},

with :math:`A_{g,\omega}` frozen at the iterate's midpoint and the exact Jacobians of the
finite-difference velocity w.r.t. the chart (``pin.dDifference`` and the chart's own
derivative), and :math:`b_j` chosen so that the linearization is exact at the iterate
(:func:`interval_linearization`). The rates are then affine in the chart variables,
:math:`r + J x`, with dense 3 x nv blocks of :math:`J` between each dynamics knot and the
knots before, at and after it: the NLP's parameters are :math:`r` and the nonzeros of
:math:`J` (:func:`momentum_parameters`, :func:`momentum_jacobian_pattern`), so the rows are
one sparse product and their Jacobian is the parameters themselves. (Before, the parameters
were :math:`b, P, Q` and CasADi differentiated the interval momenta at every evaluation: 5 ms
more per evaluation of the rows and of their Jacobian on the Talos 4 steps, ~10 % of an
iteration.)

:func:`planner.trajopt.api.plan` re-linearizes at a solution whose Euler residual with the
exact :math:`A_g` (:func:`euler_residual`) exceeds :attr:`CentroidalSettings.momentum_tolerance`
and re-solves, at most :attr:`CentroidalSettings.momentum_iterations` times; the rows are exact
at a fixed point of that loop, and the error that is left is :math:`(A_g(q) - A_g(\bar q))\,v`,
which the plan's report measures (the full-dynamics ZMP, :mod:`planner.trajopt.centroidal.zmp`).
The re-solve starts from the solution *and its multipliers* (IPOPT's ``warm_start_init_point``,
set in :attr:`CentroidalSettings.ipopt_options`): 7 iterations instead of 12-18, the same
optimum. The tolerance is the CoP margin (5 mm): the residual is a CoP shift, and the planned
CoP keeps that far inside the soles. Where the time went (2026-11-24, Talos 4 steps, ~20
iterations, CPU): IPOPT's linear solves (MUMPS) ~58 ms per iteration (~38 ms without these
rows: their dense blocks add ~30 k Jacobian nonzeros and their fill), the Lagrangian Hessian ~22 ms, the linearization in Python
(:func:`momentum_parameters`, a loop over knots with Pinocchio calls) 5 ms per solve: not
worth vectorizing.

Values are divided by the body weight :math:`m|g|` like the force variables (units m s).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from planner.trajopt.centroidal.data import DynamicData
from planner.trajopt.centroidal.zmp import cross3


def momentum_sizes(nv: int, N: int) -> int:
    """Number of parameters of the momentum rows: the rates' constant part (3 per dynamics knot
    ``k = 1..N-1``), then the nonzeros of their Jacobian (:func:`momentum_jacobian_pattern`)."""
    return 3 * (N - 1) + len(momentum_jacobian_pattern(nv, N)[0])


def _rate_blocks(N: int) -> list[tuple[int, int]]:
    """(dynamics knot ``k``, variable knot index ``i = knot - 2``) of the Jacobian's 3 x nv blocks:
    the knots ``k - 1``, ``k``, ``k + 1`` that are variables (knot N is knot N-1), column-major."""
    out = {(k, min(j, N - 1) - 2) for k in range(1, N) for j in (k - 1, k, k + 1) if min(j, N - 1) >= 2}
    return sorted(out, key=lambda b: (b[1], b[0]))


def momentum_jacobian_pattern(nv: int, N: int) -> tuple[np.ndarray, np.ndarray]:
    """(rows, columns) of the nonzeros of the momentum rates' Jacobian w.r.t. the chart variables
    (3 (N-1) x nv (N-2)), in CasADi's column-major order: dense 3 x nv blocks between the
    dynamics knot ``k`` and the variable knots ``k-1..k+1``."""
    blocks = _rate_blocks(N)
    by_col: dict[int, list[int]] = {}
    for k, i in blocks:
        by_col.setdefault(i, []).append(k)
    rows, cols = [], []
    for i in sorted(by_col):
        ks = sorted(by_col[i])
        for c in range(nv):
            for k in ks:
                rows += [3 * (k - 1) + r for r in range(3)]
                cols += [nv * i + c] * 3
    return np.array(rows, dtype=int), np.array(cols, dtype=int)


def interval_linearization(lay: DynamicData, dq: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The interval momenta linearized about chart displacements ``dq`` (N+1, nv).

    Returns:
        ``(b, P, Q)`` of shapes (N, 3), (N, 3, nv), (N, 3, nv), divided by the body weight, such
        that ``b_j + P_j dq_j + Q_j dq_{j+1}`` is :math:`h_{j+1/2} / (m|g|)` to first order in
        ``dq`` (with :math:`A_g` frozen at the iterate's midpoint), exact at the iterate.
    """
    from planner.trajopt.symbolic import chart_to_configuration

    robot = lay.robot
    model, data = robot.model, robot.data()
    nv, N, dt = robot.nv, lay.N, float(lay.dt)
    weight = robot.mass * 9.81
    q = [chart_to_configuration(model, lay.q_ref, dq[k]) for k in range(N + 1)]
    T = [_chart_tangent(lay.q_ref, dq[k], nv) for k in range(N + 1)]
    b, P, Q = np.zeros((N, 3)), np.zeros((N, 3, nv)), np.zeros((N, 3, nv))
    for j in range(N):
        v = pin.difference(model, q[j], q[j + 1]) / dt
        qm = pin.integrate(model, q[j], 0.5 * dt * v)
        A = pin.computeCentroidalMap(model, data, qm)[3:] / weight
        P[j] = A @ pin.dDifference(model, q[j], q[j + 1], pin.ArgumentPosition.ARG0) @ T[j] / dt
        Q[j] = A @ pin.dDifference(model, q[j], q[j + 1], pin.ArgumentPosition.ARG1) @ T[j + 1] / dt
        b[j] = A @ v - P[j] @ dq[j] - Q[j] @ dq[j + 1]
    return b, P, Q


def _chart_tangent(q_ref: np.ndarray, dq: np.ndarray, nv: int) -> np.ndarray:
    """Derivative (nv, nv) of ``chart_to_configuration(q_ref, dq)`` w.r.t. ``dq``, in Pinocchio's
    tangent space at that configuration (local frame of the base)."""
    R_ref = pin.Quaternion(q_ref[3:7]).matrix()
    R = R_ref @ pin.exp3(np.asarray(dq[3:6], dtype=float))
    D = np.eye(nv)
    D[0:3, 0:3] = R.T @ R_ref
    D[3:6, 3:6] = pin.Jexp3(np.asarray(dq[3:6], dtype=float))
    return D


def interval_momentum(robot, q: np.ndarray, dt: float) -> np.ndarray:
    """Angular centroidal momentum ``A_g,w(q_{j+1/2}) (q_{j+1} - q_j) / dt`` of each interval (T-1, 3) [N m s]."""
    model, data = robot.model, robot.data()
    out = np.zeros((len(q) - 1, 3))
    for j in range(len(q) - 1):
        v = pin.difference(model, q[j], q[j + 1]) / dt
        qm = pin.integrate(model, q[j], 0.5 * dt * v)
        out[j] = pin.computeCentroidalMap(model, data, qm)[3:] @ v
    return out


def momentum_parameters(lay: DynamicData, dq: np.ndarray) -> np.ndarray:
    """Parameters of the angular-momentum rows linearized about chart displacements ``dq`` (N+1, nv).

    The rate of dynamics knot ``k`` is ``(h_{k+1/2} - h_{k-1/2}) / dt``, with the interval momenta
    of :func:`interval_linearization` and ``dq_0 = dq_1 = 0``, ``dq_N = dq_{N-1}``: affine in the
    chart variables, ``r + J x``.

    Returns:
        ``r`` (3 per dynamics knot ``k = 1..N-1``), then the nonzeros of ``J`` in the order of
        :func:`momentum_jacobian_pattern`, all divided by the body weight.
    """
    N, dt = lay.N, float(lay.dt)
    b, P, Q = interval_linearization(lay, dq)
    # the blocks of knot k's rate: -P_{k-1} on dq_{k-1}, P_k - Q_{k-1} on dq_k, Q_k on dq_{k+1}
    block: dict[tuple[int, int], np.ndarray] = {}
    rate = (b[1:] - b[:-1]) / dt
    for k in range(1, N):
        for j, B in ((k - 1, -P[k - 1]), (k, P[k] - Q[k - 1]), (k + 1, Q[k])):
            j = min(j, N - 1)
            if j >= 2:
                block[k, j - 2] = block.get((k, j - 2), 0.0) + B / dt
    values = []
    by_col: dict[int, list[int]] = {}
    for k, i in _rate_blocks(N):
        by_col.setdefault(i, []).append(k)
    for i in sorted(by_col):
        ks = sorted(by_col[i])
        # column-major: for each joint column, the 3 rows of each dynamics knot in order
        values.append(np.stack([block[k, i] for k in ks], axis=0).transpose(2, 0, 1).ravel())
    return np.concatenate([rate.ravel(), *values])


def euler_residual(lay: DynamicData, dq: np.ndarray, forces: np.ndarray) -> float:
    """Largest violation of the whole body's Euler law at a solution, divided by the body weight [m].

    The exact rows of :mod:`this module <planner.trajopt.centroidal.momentum>` (Pinocchio's
    :math:`A_g` at each interval's midpoint, not the linearization) against the moment of the
    solution's corner forces about the configuration's CoM, at the dynamics knots.

    Args:
        lay: The dynamic layout.
        dq: Chart displacements of the solution (N+1, nv).
        forces: Its force variables.
    """
    from planner.trajopt.symbolic import chart_to_configuration

    robot = lay.robot
    model, data = robot.model, robot.data()
    q = np.array([chart_to_configuration(model, lay.q_ref, d) for d in dq])
    pat = lay.pattern()
    h = interval_momentum(robot, q, float(lay.dt)) / pat.weight
    com = np.array([pin.centerOfMass(model, data, qk) for qk in q])
    moments = force_moments(pat, com, forces)
    worst = 0.0
    for j, k in enumerate(pat.dynamics_knots):
        worst = max(worst, float(np.linalg.norm((h[k] - h[k - 1]) / lay.dt - moments[j])))
    return worst


def force_moments(pat, com: np.ndarray, forces: np.ndarray) -> np.ndarray:
    """Moment of the corner forces about the CoM at each dynamics knot, divided by the body weight.

    Args:
        pat: The :class:`~planner.trajopt.centroidal.pattern.CentroidalPattern`.
        com: CoM per knot (T, 3) [m].
        forces: The force variables.

    Returns:
        (len(pat.dynamics_knots), 3) [m], in the order of the dynamics knots.
    """
    corners = pat.corner_forces(forces)
    out = np.zeros((len(pat.dynamics_knots), 3))
    for j, k in enumerate(pat.dynamics_knots):
        for contact in pat.contacts[k]:
            out[j] += cross3(contact.points_in_world - com[k], corners[contact.frame][k]).sum(axis=0)
    return out / pat.weight
