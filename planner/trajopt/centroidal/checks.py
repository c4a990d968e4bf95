"""Numeric checks of a finished dynamic plan (numpy): friction, centre of pressure, CoM dynamics."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from planner.results import Check, CheckKind
from planner.trajopt.centroidal.contacts import contact_geometry_points
from planner.trajopt.centroidal.data import DynamicData
from planner.trajopt.centroidal.pattern import CentroidalPattern, CentroidalTerms
from planner.trajopt.centroidal.physics import GRAVITY, com_dynamics_residual
from robots import center_of_pressure, friction_violation, sole_corners

if TYPE_CHECKING:
    from planner.trajopt.settings import PlannerSettings


def rest_polygon_checks(lay: DynamicData, com: np.ndarray, tolerance: float) -> list[Check]:
    """Support-polygon CoM bounds of a dynamic plan, where they apply: at the last knot (at rest).

    Args:
        lay: The layout.
        com: CoM per knot (N+1, 3) [m].
        tolerance: Accepted excursion [m].

    Returns:
        One check per support-polygon bound of the spec.
    """
    from planner.trajopt.layout import halfplanes, support_polygon

    out = []
    k = lay.N
    hull = support_polygon(lay, k)
    for bounds in lay.spec.com_bounds:
        if not bounds.support_polygon or len(hull) < 3:
            continue
        A, b = halfplanes(hull)
        viol = max(0.0, float(np.max(A @ com[k, :2] - (b - bounds.margin))))
        out.append(Check.constraint(name=f"CoM bound {bounds.name!r} support polygon at rest",
                                    kind=CheckKind.COM_SUPPORT_POLYGON_AT_REST, violation=viol, tolerance=tolerance,
                                    unit="m", time=float(lay.t[k]), subject=bounds.name))
    return out


def cop_violation(cop: np.ndarray, x_range: tuple[float, float], y_range: tuple[float, float]) -> np.ndarray:
    """Distance of each CoP (T, 2) outside the rectangle ``x_range`` x ``y_range`` [m] (0 inside, NaN ignored)."""
    cop = np.asarray(cop, dtype=float)
    dx = np.maximum(0.0, np.maximum(x_range[0] - cop[:, 0], cop[:, 0] - x_range[1]))
    dy = np.maximum(0.0, np.maximum(y_range[0] - cop[:, 1], cop[:, 1] - y_range[1]))
    out = np.hypot(dx, dy)
    return np.where(np.isnan(out), 0.0, out)


def dynamic_checks(
    lay: DynamicData,
    q: np.ndarray,
    com: np.ndarray,
    terms: CentroidalTerms | CentroidalPattern,
    corner_rows: Sequence[tuple[int, int, int]],
    force_values: np.ndarray,
    *,
    force_tolerance: float = 1e-3,
    position_tolerance: float = 1e-5,
    ankle_torque_margin: float | None = None,
) -> list[Check]:
    """Report of a dynamic plan, recomputed with Pinocchio and numpy from the solution.

    Groups: Newton's law for the CoM (with the Pinocchio CoM of the returned configurations),
    the friction cone (the true Coulomb cone, not the pyramid) and the centre of pressure inside
    each sole rectangle per contact frame (where the sole carries more than the force tolerance:
    the CoP of a nearly unloaded sole, e.g. at take-off, is not defined), no force at a knot
    without contact, and every sole corner of a swinging foot above the ground.

    Args:
        lay: The layout.
        q: Configurations (N+1, nq).
        com: CoM per knot (N+1, 3) [m].
        terms: The centroidal terms of the NLP.
        corner_rows: (knot, foot frame id, corner) rows of swinging sole corners.
        force_values: Solution values of ``terms.variables``.
        force_tolerance: Accepted force-law violation, as a fraction of the body weight [-].
        position_tolerance: Accepted CoP excursion and corner depth [m].
        ankle_torque_margin: Check the moment of each sole's forces about its ankle joints
            against this fraction of their effort limits (``CentroidalSettings``; None: no check).

    Returns:
        One :class:`~planner.results.Check` per group.
    """
    cen = terms
    t = np.asarray(lay.t, dtype=float)
    dt = float(t[1] - t[0])
    tol_n = force_tolerance * cen.weight
    corners = cen.corner_forces(force_values)
    checks: list[Check] = []

    def worst(name: str, kind: CheckKind, values: list[tuple[float, float]], tol: float, unit: str,
              subject: str = "") -> None:
        if not values:
            return
        v, tt = max(values, key=lambda x: x[0])
        checks.append(Check.constraint(name=name, kind=kind, violation=max(0.0, float(v)), tolerance=tol, unit=unit,
                                       time=float(tt), subject=subject))

    newton = []
    mass = cen.weight / float(np.linalg.norm(GRAVITY))
    for k in cen.dynamics_knots:
        acc = (com[k + 1] - 2 * com[k] + com[k - 1]) / dt**2
        total = sum((corners[f][k].sum(axis=0) for f in corners), np.zeros(3))
        newton.append((float(np.linalg.norm(com_dynamics_residual(mass, acc, total))), t[k]))
    worst("CoM dynamics m(c'' - g) = sum f", CheckKind.COM_DYNAMICS, newton, tol_n, "N")
    friction: dict[str, list] = {}
    cop: dict[str, list] = {}
    ankle: dict[str, list] = {}
    margin = ankle_torque_margin
    idle = []
    soles: dict[str, tuple | None] = {}  # frame -> the full sole's x and y ranges (None: a point contact)
    for k, active in enumerate(cen.contacts):
        held = {c.frame for c in active} if k in cen.dynamics_knots else set()
        for frame, f in corners.items():
            if frame not in held:
                idle.append((float(np.abs(f[k]).max()), t[k]))
        if k not in cen.dynamics_knots:
            continue
        for c in active:
            fk = corners[c.frame][k]
            friction.setdefault(c.frame, []).append((float(friction_violation(fk, c.rotation, c.friction_coefficient).max()), t[k]))
            if c.frame not in soles:
                full = contact_geometry_points(lay.robot, c.frame)
                soles[c.frame] = None if full is None else ((full[:, 0].min(), full[:, 0].max()),
                                                            (full[:, 1].min(), full[:, 1].max()))
            ranges = soles[c.frame]
            if ranges is not None:
                p = center_of_pressure(c.points_in_frame, fk[None], c.rotation, min_normal=tol_n)
                viol = cop_violation(p, *ranges)
                cop.setdefault(c.frame, []).append((float(viol[0]), t[k]))
            if margin is not None:
                for a, moment in zip(c.ankle, c.ankle_torques(fk), strict=True):
                    ankle.setdefault(a.joint, []).append((abs(float(moment)) / a.effort, t[k], a.effort))
    for frame, rows in friction.items():
        worst(f"{frame} friction cone", CheckKind.FRICTION_CONE, rows, tol_n, "N", frame)
    for frame, rows in cop.items():
        worst(f"{frame} centre of pressure in the sole", CheckKind.CENTRE_OF_PRESSURE, rows, position_tolerance, "m",
              frame)
    for joint, rows in ankle.items():  # the planned forces' moment about the ankle axis, in % of its limit
        peak, tt, effort = max(rows, key=lambda x: x[0])
        limit = float(ankle_torque_margin or 0.0)
        checks.append(Check(name=f"{joint} torque of the contact forces", kind=CheckKind.ANKLE_TORQUE,
                            value=100.0 * peak, limit=100.0 * limit, unit="%", time=float(tt),
                            ok=bool(peak * effort <= limit * effort + 0.1 * tol_n), subject=joint))  # tol: 10 cm lever
    worst("no contact force without contact", CheckKind.FORCE_WITHOUT_CONTACT, idle, 0.0, "N")
    depth = _swing_corner_depths(lay, q, corner_rows, t)
    worst("swing sole corners above the ground", CheckKind.SWING_SOLE_CORNERS, depth, position_tolerance, "m")
    return checks


def _swing_corner_depths(lay: DynamicData, q: np.ndarray, corner_rows: Sequence[tuple[int, int, int]],
                         t: np.ndarray) -> list[tuple[float, float]]:
    """(depth below the ground [m], time [s]) of each swinging sole corner row, with Pinocchio."""
    model, data = lay.robot.model, lay.robot.data()
    depth: list[tuple[float, float]] = []
    sole = lay.robot.profile.sole
    corners = {side: sole_corners(sole, side) for side in ("left", "right")}
    by_knot: dict[int, list[tuple[int, int]]] = {}
    for k, fid, i in corner_rows:
        by_knot.setdefault(k, []).append((fid, i))
    for k, rows in by_knot.items():
        pin.framesForwardKinematics(model, data, q[k])
        for fid, i in rows:
            side = lay.robot.foot_side(model.frames[fid].name)
            assert side is not None  # corner rows belong to the soles
            z = float(data.oMf[fid].act(corners[side][i])[2])
            depth.append((-z, t[k]))
    return depth


def dynamic_plan_checks(lay: DynamicData, q: np.ndarray, com: np.ndarray, forces: np.ndarray | None,
                        checks: Sequence[Check], settings: PlannerSettings) -> list[Check]:
    """The report of a dynamic plan: the kinematic checks with the support polygon taken at rest
    (the last knot), plus the dynamic checks (:func:`dynamic_checks`) and the plan's full
    dynamics recomputed with RNEA (:func:`planner.trajopt.centroidal.zmp.zmp_checks`: ZMP in
    the support polygon, contact moment; ``CentroidalSettings.zmp_tolerance``).

    Args:
        lay: The dynamic layout.
        q: Configurations (N+1, nq).
        com: CoM per knot (N+1, 3) [m].
        forces: Solution values of the force variables (None: none available).
        checks: The kinematic report (``planner.trajopt.checks.check_plan``).
        settings: ``PlannerSettings`` (``tolerances.polygon`` [m]).

    Returns:
        The checks.
    """
    out = [c for c in checks if c.kind is not CheckKind.COM_SUPPORT_POLYGON]
    out += rest_polygon_checks(lay, com, settings.tolerances.polygon)
    if forces is not None:
        out += dynamic_checks(lay, q, com, lay.pattern(), lay.corner_rows(), forces,
                              force_tolerance=lay.centroidal_settings.force_tolerance,
                              position_tolerance=settings.tolerances.polygon,
                              ankle_torque_margin=lay.centroidal_settings.ankle_torque_margin)
    from planner.trajopt.centroidal.zmp import zmp_checks

    corner = lay.pattern().corner_forces(forces) if forces is not None else None
    out += zmp_checks(lay, q, corner, lay.centroidal_settings.zmp_tolerance)
    return out
