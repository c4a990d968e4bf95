"""The plan's own dynamic feasibility: its ZMP from the full dynamics against its support polygon."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from planner import Plan
from robots.contact import halfplanes, sole_corners_in_world, support_polygon
from robots.model import Robot


def plan_zmp(robot: Robot, plan: Plan) -> np.ndarray:
    r"""ZMP of the plan at its knots from the full rigid-body dynamics (flat ground at z = 0).

    At each knot, inverse dynamics (``pin.rnea`` on the plan's own ``q``, ``v``, ``a``) gives the
    wrench the contacts must exert on the floating base; its moment about the ground point
    :math:`p` has no horizontal part when :math:`p_x = -N_y / F_z`, :math:`p_y = N_x / F_z` (world
    frame, moments about the origin). This includes the rate of angular momentum, unlike the
    CoM-only formula, and uses no interpolation.

    Returns:
        (T, 2) ZMP per knot [m] (NaN where the contacts would have to pull, :math:`F_z \le 0`).
    """
    model = robot.model
    data = model.createData()
    out = np.full((len(plan.t), 2), np.nan)
    for k in range(len(plan.t)):
        tau = pin.rnea(model, data, plan.q[k], plan.v[k], plan.a[k])
        pin.forwardKinematics(model, data, plan.q[k])  # rnea leaves data.oMi untouched
        wrench = data.oMi[1].act(pin.Force(tau[:6]))
        fz = wrench.linear[2]
        if fz > 1e-6:
            out[k] = (-wrench.angular[1] / fz, wrench.angular[0] / fz)
    return out


def plan_zmp_excursion(
    robot: Robot, plan: Plan, *, tolerance: float = 0.005
) -> tuple[float, float] | None:
    """Largest distance of the plan's ZMP outside its support polygon, with its time.

    The ZMP is :func:`plan_zmp` at the plan's knots (full dynamics); the support polygon is the
    convex hull (:func:`robots.contact.support_polygon`) of the sole corners of the contacts active at the knot, placed by the knot's
    configuration. A knot whose contacts would have to pull counts as outside by the
    distance from the polygon's centre to its farthest corner.

    Returns:
        ``(distance [m], time [s])`` when the ZMP leaves the polygon by more than ``tolerance``,
        else None.
    """
    model = robot.model
    data = model.createData()
    zmp = plan_zmp(robot, plan)
    worst, worst_t = 0.0, 0.0
    spec = plan.spec
    for k in range(len(plan.t)):
        phase = spec.phases[spec.phase_at(float(plan.t[k]))]
        pin.framesForwardKinematics(model, data, plan.q[k])
        pts = []
        for contact in phase.contacts:
            fid = robot.frame_id(contact.frame)
            side = robot.foot_side(model.frames[fid].name) or "left"
            pts.append(sole_corners_in_world(robot.profile.sole, side, data.oMf[fid]))
        hull = support_polygon(pts)
        if len(hull) < 3:  # no contact, or a degenerate polygon (a line): skip the knot
            continue
        if np.isnan(zmp[k]).any():
            pts2 = np.vstack(pts)[:, :2]
            dist = float(np.max(np.linalg.norm(pts2 - pts2.mean(axis=0), axis=1)))
        else:
            A, b = halfplanes(hull)
            dist = float(np.max(A @ zmp[k] - b))
        if dist > worst:
            worst, worst_t = dist, float(plan.t[k] - plan.t[0])
    return (worst, worst_t) if worst > tolerance else None
