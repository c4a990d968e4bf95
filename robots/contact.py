r"""Contact facts shared by every layer: sole corners, support polygon, centre of pressure, friction.

The planner, the controller, the simulation and the viewers all read these functions; none of them
writes out a sole corner, a convex hull or a friction bound of its own.

Sole geometry. A sole is the profile's :class:`~robots.profile.SoleRectangle` in the foot frame
(z = sole normal, origin on the sole surface; the right foot mirrors the left, ``y -> -y``). Its
four corners are counter-clockwise seen from above. A margin moves every side inward.

The friction model (one model, stated once). For a contact with Coulomb coefficient :math:`\mu`
(the spec contact's own, else the robot profile's ``friction_coefficient``) and force
:math:`f = (f_x, f_y, f_z)` in the contact (sole) frame:

* **the cone** (physics, the report's check and MuJoCo):
  :math:`\sqrt{f_x^2 + f_y^2} \le \mu f_z`;
* **the pyramid** (what the planner and the controller enforce): the 4-edge pyramid *inscribed*
  in that cone, its faces along the sole's x and y axes,

  .. math:: |f_x| \le \mu' f_z, \quad |f_y| \le \mu' f_z, \qquad \mu' = \mu / \sqrt 2,

  with edges :math:`(\pm\mu', \pm\mu', 1)` lying on the cone. No further safety factor (1.0):
  the inscription is the margin. On a 45° diagonal the pyramid reaches the cone exactly
  (:math:`|f_t| \le \mu f_z`); along the sole axes it keeps :math:`1 - 1/\sqrt 2 \approx 29\,\%`
  of :math:`\mu f_z` in reserve. Every force the planner or the controller accepts is inside the
  cone, so the report's cone check and MuJoCo accept it too.
* **MuJoCo** is told the cone itself: an elliptic cone (``cone="elliptic"``), ``condim=3``
  (sliding friction only) and friction :math:`\mu` on the floor and the soles. MuJoCo's default
  pyramidal cone would be the diamond :math:`|f_1| + |f_2| \le \mu f_n` in a tangent frame of
  MuJoCo's choosing, which allows only :math:`\mu/\sqrt 2` on its diagonals, less than the
  planner's pyramid plans with.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np
import pinocchio as pin

from robots.profile import SoleRectangle

# --------------------------------------------------------------------------------------------------
# Sole corners
# --------------------------------------------------------------------------------------------------


def sole_corners(sole: SoleRectangle, side: str, *, margin: float = 0.0) -> np.ndarray:
    """Corners (4, 3) of a sole in its foot frame, counter-clockwise, z = 0 [m].

    Args:
        sole: The profile's sole rectangle (of the left foot).
        side: ``"left"`` or ``"right"`` (mirrored, ``y -> -y``).
        margin: Every side moves this far inward [m]; a side shorter than twice the margin
            collapses to its midline (callers that need area check first).

    Returns:
        The corners, rows ``(x, y, 0)``, in the order of :meth:`SoleRectangle.corners`.
    """
    xy = np.array(sole.corners(side), dtype=float)
    if margin:
        centre = xy.mean(axis=0)
        sides = np.array([sole.x_max - sole.x_min, sole.y_max - sole.y_min])
        xy = centre + (xy - centre) * np.clip(1.0 - 2.0 * margin / sides, 0.0, 1.0)
    return np.column_stack([xy, np.zeros(4)])


def points_in_world(points_in_frame: np.ndarray, placement: pin.SE3) -> np.ndarray:
    """Points (n, 3) given in a frame, placed in the world by ``placement`` [m]."""
    return np.asarray(points_in_frame, dtype=float) @ placement.rotation.T + placement.translation


def sole_corners_in_world(sole: SoleRectangle, side: str, placement: pin.SE3, *, margin: float = 0.0) -> np.ndarray:
    """Corners (4, 3) of a sole whose foot frame is at ``placement`` in the world [m].

    Args:
        sole: The profile's sole rectangle.
        side: ``"left"`` or ``"right"``.
        placement: The foot frame in the world (``oMf``, or a contact's planned placement).
        margin: Inward margin of every side [m] (see :func:`sole_corners`).
    """
    return points_in_world(sole_corners(sole, side, margin=margin), placement)


# --------------------------------------------------------------------------------------------------
# Support polygon
# --------------------------------------------------------------------------------------------------


COLLINEAR = 1e-12  # [m^2] twice the area of a triangle of hull points taken as collinear


def convex_hull(points: np.ndarray) -> np.ndarray:
    """Counter-clockwise convex hull (H, 2) of points in the ground plane [m].

    Andrew's monotone chain. ``points`` is (n, 2) or (n, 3) (the third column is ignored);
    points closer than 1e-12 m are merged and collinear points are dropped (also those that
    round-off leaves a hair off the line, |cross| <= :data:`COLLINEAR` m^2: the hull of two soles
    side by side is the same whichever way the robot faces). Fewer than three distinct points are
    returned as they are (sorted).
    """
    pts = sorted({(round(float(x), 12), round(float(y), 12)) for x, y in np.asarray(points, dtype=float)[:, :2]})
    if len(pts) <= 2:
        return np.array(pts, dtype=float).reshape(-1, 2)

    def cross(o, a, b) -> float:
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower: list = []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    upper: list = []
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    hull = lower[:-1] + upper[:-1]
    # a corner that round-off left a hair off the line through its neighbours is dropped after
    # the chain is built (dropping it while building could keep the wrong one of two points whose
    # x differ by round-off)
    i = 0
    while len(hull) > 3 and i < len(hull):
        if cross(hull[i - 1], hull[i], hull[(i + 1) % len(hull)]) <= COLLINEAR:
            hull.pop(i)
            i = max(i - 1, 0)
        else:
            i += 1
    return np.array(hull, dtype=float)


def support_polygon(corner_sets: Iterable[np.ndarray]) -> np.ndarray:
    """Support polygon (H, 2): the counter-clockwise convex hull of the given soles' corners [m].

    Args:
        corner_sets: World corners (n, 3) or (n, 2) of each sole (or contact surface) in contact.

    Returns:
        The hull; (0, 2) when nothing touches the ground, fewer than 3 rows when degenerate.
    """
    pts = [np.asarray(c, dtype=float)[:, :2] for c in corner_sets]
    if not pts:
        return np.zeros((0, 2))
    return convex_hull(np.vstack(pts))


def halfplanes(polygon: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(A, b) with ``A x <= b`` for a counter-clockwise convex polygon; rows have unit norm."""
    A, b = [], []
    for i in range(len(polygon)):
        p0, p1 = polygon[i], polygon[(i + 1) % len(polygon)]
        e = p1 - p0
        n = np.array([e[1], -e[0]]) / np.linalg.norm(e)  # outward normal of a CCW polygon
        A.append(n)
        b.append(float(n @ p0))
    return np.array(A), np.array(b)


def polygon_margin(polygon: np.ndarray, point: np.ndarray) -> float:
    """Signed distance [m] of a 2D point inside a counter-clockwise convex polygon (> 0 inside).

    It is the smallest distance to an edge's line, negative when the point is outside that edge:
    ``min(b - A p)`` with :func:`halfplanes`. A polygon with fewer than 3 vertices gives -inf.
    """
    if len(polygon) < 3:
        return -math.inf
    A, b = halfplanes(polygon)
    return float(np.min(b - A @ np.asarray(point, dtype=float)[:2]))


# --------------------------------------------------------------------------------------------------
# Centre of pressure
# --------------------------------------------------------------------------------------------------


def center_of_pressure(points_in_frame: np.ndarray, forces: np.ndarray, rotation: np.ndarray, *,
                       min_normal: float = 1e-6) -> np.ndarray:
    """Centre of pressure of corner forces in the contact frame (x, y) [m]; NaN when unloaded.

    :math:`p = \\sum_i f_{z,i} p_i / \\sum_i f_{z,i}` over the corner points :math:`p_i`.

    Args:
        points_in_frame: Corner points (n, 3) in the contact frame [m].
        forces: (T, n, 3) world forces [N].
        rotation: Contact frame in the world (3, 3).
        min_normal: Total normal force below which the CoP is undefined [N].

    Returns:
        (T, 2) CoP in the contact frame.
    """
    fn = np.asarray(forces, dtype=float) @ np.asarray(rotation)[:, 2]  # (T, n)
    total = fn.sum(axis=1)
    cop = np.full((fn.shape[0], 2), np.nan)
    ok = total > min_normal
    cop[ok] = (fn[ok] @ points_in_frame[:, :2]) / total[ok, None]
    return cop


# --------------------------------------------------------------------------------------------------
# The friction model
# --------------------------------------------------------------------------------------------------

PYRAMID_EDGES = 4  # edges of the linearized cone (the inscribed pyramid)
PYRAMID_FACTOR = 1.0 / math.sqrt(2.0)  # mu' / mu: per-axis bound of the inscribed 4-edge pyramid
#: The pyramid's facets as signs ``(s_x, s_y)`` of the rows ``s_x f_x + s_y f_y - mu' f_z <= 0``.
PYRAMID_FACETS = ((1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0))
#: The pyramid's edges as signs ``(s_x, s_y)`` of ``(s_x mu', s_y mu', 1)`` (counter-clockwise).
PYRAMID_EDGE_SIGNS = ((1.0, 1.0), (-1.0, 1.0), (-1.0, -1.0), (1.0, -1.0))
MUJOCO_CONE = "elliptic"  # MuJoCo's cone type: the Coulomb cone itself
MUJOCO_CONDIM = 3  # MuJoCo's contact dimension: normal + 2 sliding directions
MUJOCO_TORSIONAL = 0.005  # [m] MuJoCo's torsional friction (used only with condim >= 4)
MUJOCO_ROLLING = 0.0001  # [m] MuJoCo's rolling friction (used only with condim 6)


def pyramid_coefficient(mu):
    """Per-axis bound :math:`\\mu' = \\mu/\\sqrt 2` of the inscribed pyramid [-] (numbers or CasADi)."""
    return mu / math.sqrt(2.0)


def pyramid_edges_in_contact(mu: float) -> np.ndarray:
    """The planner's rows: the pyramid's 4 edges (3, 4) in the contact frame, columns
    :math:`(\\pm\\mu', \\pm\\mu', 1)` in the order of :data:`PYRAMID_EDGE_SIGNS`.

    Non-negative combinations :math:`f = E \\lambda, \\lambda \\ge 0` are exactly the pyramid.
    """
    mu_p = float(pyramid_coefficient(mu))
    return np.array([[sx * mu_p for sx, _ in PYRAMID_EDGE_SIGNS],
                     [sy * mu_p for _, sy in PYRAMID_EDGE_SIGNS],
                     [1.0] * PYRAMID_EDGES])


def pyramid_facets(mu: float) -> np.ndarray:
    """The controller's rows: (4, 3) ``C`` with ``C f <= 0`` for a force ``f`` in the contact frame.

    Rows :math:`\\pm f_x - \\mu' f_z \\le 0` and :math:`\\pm f_y - \\mu' f_z \\le 0` (together they
    imply :math:`f_z \\ge 0`).
    """
    mu_p = float(pyramid_coefficient(mu))
    return np.array([[sx, sy, -mu_p] for sx, sy in PYRAMID_FACETS])


def forces_in_contact(forces: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """World forces (..., 3) expressed in a contact frame whose world orientation is ``rotation``."""
    return np.asarray(forces, dtype=float) @ np.asarray(rotation)


def friction_violation(forces: np.ndarray, rotation: np.ndarray, mu: float) -> np.ndarray:
    """The report's check: how far each force is outside the Coulomb cone and the unilateral half-space [N].

    Args:
        forces: (..., 3) world forces [N].
        rotation: Contact frame in the world (3, 3).
        mu: Friction coefficient [-].

    Returns:
        (...,) violation >= 0: ``max(0, |f_t| - mu f_n, -f_n)``.
    """
    local = forces_in_contact(forces, rotation)
    fn = local[..., 2]
    ft = np.linalg.norm(local[..., :2], axis=-1)
    return np.maximum(0.0, np.maximum(ft - mu * fn, -fn))


def friction_ratio(forces: np.ndarray, rotation: np.ndarray, mu: float) -> np.ndarray:
    """Share of the Coulomb cone each force uses, :math:`|f_t| / (\\mu f_n)` [-] (inf when ``f_n <= 0``).

    A force is inside the cone when the ratio is at most 1.
    """
    local = forces_in_contact(forces, rotation)
    fn = local[..., 2]
    ft = np.linalg.norm(local[..., :2], axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(fn > 0.0, ft / (mu * np.where(fn > 0.0, fn, 1.0)), np.inf)


def mujoco_friction(mu: float) -> tuple[float, float, float]:
    """MuJoCo's ``friction`` attribute of a geom: sliding :math:`\\mu`, torsional, rolling."""
    return (float(mu), MUJOCO_TORSIONAL, MUJOCO_ROLLING)
