"""The plan's own dynamic feasibility: its ZMP from the full dynamics against its support polygon.

The computation is the planner's (:mod:`planner.trajopt.centroidal.zmp`, which a dynamic plan's
report also runs); here it is applied to any plan, kinematic ones included, with the contacts of
the spec's phase at each knot.
"""

from __future__ import annotations

import numpy as np

from planner import Plan, full_dynamics_wrench, support_excursion, support_heights, zmp_of_wrenches
from robots import Robot


def plan_zmp(robot: Robot, plan: Plan) -> np.ndarray:
    r"""ZMP of the plan at its knots from the full rigid-body dynamics, on the plane of the knot's
    contacts (their mean height: z = 0 on the floor, :func:`planner.trajopt.centroidal.zmp.support_heights`).

    At each knot, inverse dynamics (``pin.rnea`` on the plan's ``q`` with central finite-difference
    velocities and accelerations, :func:`planner.trajopt.centroidal.zmp.full_dynamics_wrench`)
    gives the wrench the contacts must exert; its ZMP is :math:`p_x = -N_y / F_z`,
    :math:`p_y = N_x / F_z` (world frame, moments about the origin). This includes the rate of
    angular momentum, unlike the CoM-only formula, and uses no interpolation.

    Returns:
        (T, 2) ZMP per knot [m] (NaN where the contacts would have to pull, :math:`F_z \le 0`).
    """
    spec = plan.spec
    heights = [support_heights([c.placement.position for c in spec.phases[spec.phase_at(float(t))].contacts])
               for t in plan.t]
    return zmp_of_wrenches(full_dynamics_wrench(robot, plan.q, plan.dt), np.array(heights))


def plan_zmp_excursion(
    robot: Robot, plan: Plan, *, tolerance: float = 0.005
) -> tuple[float, float] | None:
    """Largest distance of the plan's ZMP outside its support polygon, with its time.

    The ZMP is :func:`plan_zmp` at the plan's knots (full dynamics); the support polygon is the
    convex hull (:func:`robots.contact.support_polygon`) of the sole corners of the contacts of
    the spec's phases at the knot (both phases at a boundary), placed by the knot's configuration
    (:func:`planner.trajopt.centroidal.zmp.support_excursion`). A knot whose contacts would have
    to pull counts as outside by the distance from the polygon's centre to its farthest corner.

    Returns:
        ``(distance [m], time [s])`` when the ZMP leaves the polygon by more than ``tolerance``,
        else None.
    """
    spec = plan.spec
    half = 0.5 * plan.dt
    # a contact holds at both ends of its phase (as the planner plans it): at a phase boundary the
    # polygon is that of both phases' contacts (at lift-off the leaving sole still pushes)
    frames = [sorted({robot.frame_id(c.frame) for s in (-half, half)
                      for c in spec.phases[spec.phase_at(max(0.0, float(t) + s))].contacts})
              for t in plan.t]
    dist = support_excursion(robot, plan.q, plan_zmp(robot, plan), frames)
    dist = np.where(np.isnan(dist), 0.0, dist)
    k = int(np.argmax(dist))
    return (float(dist[k]), float(plan.t[k] - plan.t[0])) if dist[k] > tolerance else None
