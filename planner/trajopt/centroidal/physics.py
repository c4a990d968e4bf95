"""Centroidal physics as CasADi expressions (numpy inputs work too where noted): CoM
acceleration, the dynamics residual, friction pyramids and their edges, the angular-momentum rate."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import casadi as ca
import numpy as np

from robots import pyramid_coefficient, pyramid_edges_in_contact

GRAVITY = np.array([0.0, 0.0, -9.81])  # [m/s^2], world frame (z up)


# ---------------------------------------------------------------------------------------------
# Per-knot expressions (CasADi; numpy inputs work too where noted)
# ---------------------------------------------------------------------------------------------


def com_acceleration(c_prev: Any, c: Any, c_next: Any, dt: float) -> Any:
    """Central finite-difference CoM acceleration :math:`(c_{k+1} - 2c_k + c_{k-1})/\\Delta t^2`.

    Args:
        c_prev, c, c_next: CoM at knots k-1, k, k+1 (3,) [m] (CasADi or numpy).
        dt: Knot spacing [s].

    Returns:
        The acceleration (3,) [m/s^2], same type as the inputs.
    """
    return (c_next - 2 * c + c_prev) / (dt * dt)


def com_dynamics_residual(mass: float, com_acc: Any, total_force: Any, gravity: np.ndarray = GRAVITY) -> Any:
    """Newton's law for the centre of mass: :math:`m(\\ddot c - g) - \\sum f` (zero when met) [N].

    Args:
        mass: Total mass [kg].
        com_acc: CoM acceleration (3,) [m/s^2].
        total_force: Sum of the contact forces (3,) in the world [N].
        gravity: Gravity (3,) [m/s^2].

    Returns:
        The residual (3,) [N].
    """
    return mass * (com_acc - gravity) - total_force


def _casadi(x: Any) -> Any:
    return x if isinstance(x, (ca.SX, ca.MX, ca.DM)) else ca.DM(np.asarray(x, dtype=float))


def friction_pyramid(force: Any, rotation: Any, mu: Any, *, inner: bool = True) -> Any:
    """Friction-pyramid rows of one force; every entry must be >= 0 [N].

    Rows: :math:`n^\\top f`, :math:`\\mu' n^\\top f - t_1^\\top f`, :math:`\\mu' n^\\top f + t_1^\\top f`,
    :math:`\\mu' n^\\top f - t_2^\\top f`, :math:`\\mu' n^\\top f + t_2^\\top f`, with
    :math:`\\mu' = \\mu/\\sqrt 2` for the inner pyramid (inside the Coulomb cone) and :math:`\\mu`
    for the outer one.

    Args:
        force: Force (3,) in the world [N] (CasADi or numpy).
        rotation: Contact frame in the world (3, 3), columns t1, t2, n (numpy or CasADi).
        mu: Friction coefficient [-] (number or CasADi).
        inner: The contact model's pyramid (:mod:`robots.contact`); False: the outer one.

    Returns:
        The 5 rows (CasADi column).
    """
    mu_p = pyramid_coefficient(mu) if inner else mu
    local = ca.mtimes(_casadi(rotation).T, _casadi(force))
    fn = local[2]
    return ca.vertcat(fn, mu_p * fn - local[0], mu_p * fn + local[0], mu_p * fn - local[1], mu_p * fn + local[1])


def pyramid_edges(rotation: Any, mu: Any, *, inner: bool = True) -> Any:
    """The 4 edges of a friction pyramid in the world, as the columns of a (3, 4) matrix.

    In the contact frame the edges are :math:`(\\pm\\mu', \\pm\\mu', 1)` (the corners of the square
    :math:`|f_x|, |f_y| \\le \\mu' f_z` at unit normal force), so the non-negative combinations
    :math:`f = E \\lambda, \\lambda \\ge 0` are exactly the pyramid of :func:`friction_pyramid`.
    With :math:`\\mu' = \\mu/\\sqrt 2` (inner) every edge lies on the Coulomb cone.

    Args:
        rotation: Contact frame in the world (3, 3), columns t1, t2, n (numpy or CasADi).
        mu: Friction coefficient [-] (number or CasADi).
        inner: The contact model's pyramid (:mod:`robots.contact`); False: the outer one.

    Returns:
        The edges (3, 4): numpy when ``rotation`` and ``mu`` are numbers, else CasADi.
    """
    mu_p = pyramid_coefficient(mu) if inner else mu
    if isinstance(rotation, (ca.SX, ca.MX)) or isinstance(mu, (ca.SX, ca.MX)):
        local = ca.vertcat(ca.horzcat(mu_p, -mu_p, -mu_p, mu_p), ca.horzcat(mu_p, mu_p, -mu_p, -mu_p),
                           ca.DM.ones(1, 4))
        return ca.mtimes(_casadi(rotation), local)
    local = pyramid_edges_in_contact(float(mu))
    if not inner:  # the outer pyramid (an experiment, not the contact model): edges (+-mu, +-mu, 1)
        local[:2] = np.sign(local[:2]) * float(mu)
    return np.asarray(rotation, dtype=float) @ local


def angular_momentum_rate(com: Any, points: np.ndarray | Sequence[Any], forces: Sequence[Any]) -> Any:
    """Rate of angular momentum about the CoM implied by point forces, :math:`\\sum (p_i - c) \\times f_i`.

    Args:
        com: CoM (3,) [m] (CasADi).
        points: n application points (3,) in the world [m] (numpy rows or CasADi).
        forces: n forces (3,) in the world [N] (CasADi).

    Returns:
        :math:`\\dot L` (3,) [N m].
    """
    total = ca.DM.zeros(3)
    for p, f in zip(points, forces, strict=True):
        total = total + ca.cross(_casadi(p) - com, f)
    return total
