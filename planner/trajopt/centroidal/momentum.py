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
derivative), and :math:`b_j` chosen so that the linearization is exact at the iterate.
:func:`planner.trajopt.api.plan` re-linearizes at each solution and re-solves (warm start from
it) :attr:`CentroidalSettings.momentum_iterations` times; the rows are exact at a fixed point of
that loop, and the error that is left is :math:`(A_g(q) - A_g(\bar q))\,v`, which the plan's
report measures (the full-dynamics ZMP, :mod:`planner.trajopt.centroidal.zmp`).

Values are divided by the body weight :math:`m|g|` like the force variables (units m s).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

if TYPE_CHECKING:
    from planner.trajopt.centroidal.layout import DynamicLayout


def momentum_sizes(nv: int, N: int) -> int:
    """Number of linearization parameters: per interval ``j = 0..N-1``: ``b`` (3), ``P``, ``Q`` (3 x nv)."""
    return N * (3 + 6 * nv)


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


def momentum_parameters(lay: DynamicLayout, dq: np.ndarray) -> np.ndarray:
    """Linearization parameters of the angular-momentum rows about chart displacements ``dq`` (N+1, nv).

    Returns:
        Per interval ``j = 0..N-1``: ``b_j`` (3), then ``P_j`` and ``Q_j`` (3 x nv, column-major,
        CasADi's order), all divided by the body weight, so that ``b + P dq_j + Q dq_{j+1}`` is
        :math:`h_{j+1/2} / (m|g|)` to first order in ``dq`` (with :math:`A_g` frozen).
    """
    from planner.trajopt.symbolic import chart_to_configuration

    robot = lay.robot
    model, data = robot.model, robot.data()
    nv, N, dt = robot.nv, lay.N, float(lay.dt)
    weight = robot.mass * 9.81
    q = [chart_to_configuration(model, lay.q_ref, dq[k]) for k in range(N + 1)]
    T = [_chart_tangent(lay.q_ref, dq[k], nv) for k in range(N + 1)]
    out = []
    for j in range(N):
        v = pin.difference(model, q[j], q[j + 1]) / dt
        qm = pin.integrate(model, q[j], 0.5 * dt * v)
        A = pin.computeCentroidalMap(model, data, qm)[3:]
        J0 = pin.dDifference(model, q[j], q[j + 1], pin.ArgumentPosition.ARG0) @ T[j]
        J1 = pin.dDifference(model, q[j], q[j + 1], pin.ArgumentPosition.ARG1) @ T[j + 1]
        P = A @ J0 / dt
        Q = A @ J1 / dt
        b = A @ v - P @ dq[j] - Q @ dq[j + 1]
        out += [b / weight, (P / weight).ravel(order="F"), (Q / weight).ravel(order="F")]
    return np.concatenate(out)


def euler_residual(lay: DynamicLayout, dq: np.ndarray, forces: np.ndarray) -> float:
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
    h = interval_momentum(robot, q, float(lay.dt))
    pat = lay.pattern()
    corners = pat.corner_forces(forces)
    worst = 0.0
    for k in pat.dynamics_knots:
        c = pin.centerOfMass(model, data, q[k])
        moment = np.zeros(3)
        for contact in pat.contacts[k]:
            moment += np.cross(contact.points_in_world - c, corners[contact.frame][k]).sum(axis=0)
        worst = max(worst, float(np.linalg.norm((h[k] - h[k - 1]) / lay.dt - moment)))
    return worst / pat.weight
