r"""A planned motion's full-dynamics ZMP and contact wrench, recomputed with Pinocchio (RNEA).

At each knot :math:`k`, inverse dynamics on the planned :math:`q_k` with central finite
differences on the manifold,

.. math::

    v_k = \tfrac12 (v_{k-1/2} + v_{k+1/2}), \qquad a_k = (v_{k+1/2} - v_{k-1/2}) / \Delta t, \qquad
    v_{j+1/2} = (q_{j+1} \ominus q_j) / \Delta t

(the grid of the plan's CoM dynamics; zero at the first and last knot, where the plan is at rest),
gives the free-flyer part of ``pin.rnea``: the total wrench the contacts must exert on the robot.
Expressed in the world about the origin (force :math:`F`, moment :math:`N`), its ZMP on flat
ground (z = 0) is :math:`(-N_y / F_z,\ N_x / F_z)`. It includes the whole body's rate of angular
momentum, unlike the CoM-only formula. The simulation's diagnosis of a plan (``sim/zmp.py``) and
the dynamic plan's own report (:func:`zmp_checks`) both use these functions.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from planner.trajopt.centroidal.data import DynamicData
from robots import halfplanes, sole_corners_in_world, support_polygon

if TYPE_CHECKING:
    from planner.results import Check
    from robots.model import Robot


def central_velocities(model: pin.Model, q: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Central finite-difference velocities and accelerations (T, nv) on the manifold (0 at both ends)."""
    T = len(q)
    half = np.array([pin.difference(model, q[j], q[j + 1]) / dt for j in range(T - 1)])
    v = np.zeros((T, model.nv))
    a = np.zeros((T, model.nv))
    v[1:-1] = 0.5 * (half[:-1] + half[1:])
    a[1:-1] = (half[1:] - half[:-1]) / dt
    return v, a


def full_dynamics_wrench(robot: Robot, q: np.ndarray, dt: float) -> np.ndarray:
    """Total contact wrench (T, 6) the motion ``q`` needs (world frame, about the origin:
    force [N], then moment [N m]), from ``pin.rnea`` with :func:`central_velocities`."""
    model = robot.model
    data = model.createData()
    v, a = central_velocities(model, q, dt)
    out = np.zeros((len(q), 6))
    for k in range(len(q)):
        tau = pin.rnea(model, data, q[k], v[k], a[k])
        pin.forwardKinematics(model, data, q[k])  # rnea leaves data.oMi untouched
        w = data.oMi[1].act(pin.Force(tau[:6]))
        out[k] = np.concatenate([w.linear, w.angular])
    return out


def zmp_of_wrenches(wrench: np.ndarray, heights: np.ndarray | None = None) -> np.ndarray:
    """ZMP (T, 2) of world wrenches (T, 6) [m] on the horizontal plane z = ``heights`` (T,) (default
    the ground z = 0): :math:`p_x = (h F_x - N_y) / F_z`, :math:`p_y = (h F_y + N_x) / F_z` (the
    moment about :math:`(p_x, p_y, h)` has no horizontal part); NaN where :math:`F_z \\le 0`.
    On a tread 0.3 m up, the ground's ZMP of a robot pushing forward with 10 % of its weight is
    3 cm behind the one on the tread."""
    out = np.full((len(wrench), 2), np.nan)
    fz = wrench[:, 2]
    h = np.zeros(len(wrench)) if heights is None else np.asarray(heights, dtype=float)
    ok = fz > 1e-6
    out[ok, 0] = (h[ok] * wrench[ok, 0] - wrench[ok, 4]) / fz[ok]
    out[ok, 1] = (h[ok] * wrench[ok, 1] + wrench[ok, 3]) / fz[ok]
    return out


def support_heights(placements: Sequence[Sequence[float]]) -> float:
    """The height of the plane a knot's ZMP is taken on: the mean height of its contacts'
    placements [m] (0 without one). Contacts at different heights (one foot on the next tread)
    have no common plane; their mean is where the polygon check is made, and the contact moment
    check (:func:`zmp_checks`) compares the whole wrench."""
    return float(np.mean([p[2] for p in placements])) if len(placements) else 0.0


def support_excursion(robot: Robot, q: np.ndarray, zmp: np.ndarray, frames: Sequence[Sequence[int]]) -> np.ndarray:
    """Distance of each knot's ZMP outside the support polygon of its contact frames [m].

    The polygon is the convex hull of the sole corners of the frames (ids) held at the knot,
    placed by the knot's configuration. 0 inside; NaN where there is no polygon (flight, or a
    line); where the contacts would have to pull (ZMP NaN), the distance from the polygon's
    centre to its farthest corner.
    """
    model = robot.model
    data = model.createData()
    out = np.full(len(q), np.nan)
    for k, ids in enumerate(frames):
        if not ids:
            continue
        pin.forwardKinematics(model, data, q[k])  # then the held frames only (not every frame)
        pts = []
        for fid in ids:
            side = robot.foot_side(model.frames[fid].name) or "left"
            pts.append(sole_corners_in_world(robot.profile.sole, side, pin.updateFramePlacement(model, data, fid)))
        hull = support_polygon(pts)
        if len(hull) < 3:
            continue
        if np.isnan(zmp[k]).any():
            pts2 = np.vstack(pts)[:, :2]
            out[k] = float(np.max(np.linalg.norm(pts2 - pts2.mean(axis=0), axis=1)))
        else:
            A, b = halfplanes(hull)
            out[k] = max(0.0, float(np.max(A @ zmp[k] - b)))
    return out


def planned_wrench(lay: DynamicData, corner_forces: dict[str, np.ndarray]) -> np.ndarray:
    """World wrench (T, 6) about the origin of a plan's corner forces (``Plan.extras["corner_forces"]``)."""
    contacts = lay.pattern().contacts  # bound once per layout, with its CoP margin
    out = np.zeros((lay.N + 1, 6))
    for k, active in enumerate(contacts):
        for c in active:
            f = corner_forces[c.frame][k]  # (n_points, 3)
            out[k, :3] += f.sum(axis=0)
            out[k, 3:] += cross3(c.points_in_world, f).sum(axis=0)
    return out


def cross3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross products of (n, 3) arrays: the same operations as ``np.cross`` (equal bit
    for bit) without its general-axis overhead, which dominates at n = 4."""
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1]
    out[..., 1] = a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2]
    out[..., 2] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return out


def zmp_checks(lay: DynamicData, q: np.ndarray, corner_forces: dict[str, np.ndarray] | None,
               tolerance: float) -> list[Check]:
    """The plan's full-dynamics checks: its ZMP (RNEA) inside the support polygon of the contacts
    it holds at each knot, and the contact moment its forces give against the one RNEA needs.

    Args:
        lay: The dynamic layout.
        q: Planned configurations (N+1, nq).
        corner_forces: The plan's corner forces (None: only the ZMP check).
        tolerance: Accepted ZMP excursion, and moment difference divided by the body weight [m].
    """
    from planner.results import Check, CheckKind

    robot = lay.robot
    t = np.asarray(lay.t, dtype=float)
    wrench = full_dynamics_wrench(robot, q, float(lay.dt))
    zmp = zmp_of_wrenches(wrench, np.array([support_heights([M.translation for _f, M in active.values()])
                                            for active in lay.contacts_at]))
    held = [sorted(active) for active in lay.contacts_at]
    exc = support_excursion(robot, q, zmp, held)
    exc = np.where(np.isnan(exc), 0.0, exc)
    i = int(np.argmax(exc))
    out = [Check.constraint(name="full-dynamics ZMP (RNEA) in the support polygon", kind=CheckKind.FULL_DYNAMICS_ZMP,
                            violation=float(exc[i]), tolerance=tolerance, unit="m", time=float(t[i]))]
    if corner_forces is not None:
        weight = robot.mass * 9.81
        planned = planned_wrench(lay, corner_forces)
        # interior knots only: the first and last knot carry no forces (at rest by construction)
        err = np.linalg.norm((wrench - planned)[1:-1, 3:5], axis=1) / weight
        j = int(np.argmax(err)) if len(err) else 0
        out.append(Check.constraint(
            name="contact moment vs full dynamics (RNEA) / mg", kind=CheckKind.FULL_DYNAMICS_WRENCH,
            violation=float(err[j]) if len(err) else 0.0, tolerance=tolerance, unit="m", time=float(t[j + 1])))
    return out
