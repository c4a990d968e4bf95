"""Capsules: the shapes of the robot's collision model, their fit to a link's geometry, distances.

The data (:class:`Capsule`, :class:`CollisionModel`), the gathering of each link's URDF collision
geometry as points, the capsule fit (:func:`fit_link`, :func:`axis_capsules`) and the distances
(segments, capsules, sphere sets, coal on the meshes). Which pairs are checked, the disk cache and
the links' human names are in :mod:`robots.collision`, which re-exports these names.
"""

from __future__ import annotations

import contextlib
import itertools
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

if TYPE_CHECKING:
    from robots.model import Robot

CYLINDER_SAMPLES = 48  # points around a cylinder/capsule circle (the radius is inflated to cover the chords)
SPHERE_SPACING = 0.75  # sphere-set spacing along a capsule axis, as a fraction of its radius ...
MIN_SPHERE_SPACING = 0.03  # [m] ... but at least this (thin links get a few slightly larger spheres)

SPLIT_GAIN = 0.75  # a link gets two capsules when their volume is below this fraction of one capsule's
RADIUS_GAIN = 0.7  # ... or, for a link whose one capsule is WIDE_RADIUS or wider, when the wider of
WIDE_RADIUS = 0.15  # [m] ... the two is below RADIUS_GAIN of its radius (Talos's torso: 0.27 -> 0.18 m)


@dataclass(frozen=True)
class Capsule:
    """A capsule attached to a joint.

    Attributes:
        link: Link (body frame) name whose geometry it encloses.
        joint: Pinocchio id of the joint the link moves with.
        placement: Capsule frame in the joint frame; its axis is the local z, centred on the origin.
        length: Length of the axis segment [m] (0: a sphere).
        radius: Radius [m].
        cover: 0 for the link's own capsules (:attr:`CollisionModel.capsules`), k >= 1 for its
            k-th alternative cover (:attr:`CollisionModel.alternatives`).
    """

    link: str
    joint: int
    placement: pin.SE3
    length: float
    radius: float
    cover: int = 0

    def endpoints(self) -> tuple[np.ndarray, np.ndarray]:
        """The axis segment's ends in the joint frame (2 x (3,)) [m]."""
        axis = self.placement.rotation[:, 2]
        c = self.placement.translation
        return c - 0.5 * self.length * axis, c + 0.5 * self.length * axis

    def spheres(self) -> tuple[np.ndarray, float]:
        """A sphere set covering the capsule: centres (n, 3) in the joint frame and their radius [m].

        The centres are evenly spaced on the axis segment, ends included, at most
        ``max(SPHERE_SPACING * radius, MIN_SPHERE_SPACING)`` apart; the common radius ``sqrt(r^2 + (s/2)^2)`` covers the
        cylinder between two centres, so the union of the spheres contains the capsule and sticks
        out of it by at most ``sqrt(r^2 + (s/2)^2) - r`` (7 % of the radius).
        """
        a, b = self.endpoints()
        spacing = max(SPHERE_SPACING * self.radius, MIN_SPHERE_SPACING)
        n = max(1, int(math.ceil(self.length / spacing))) + 1 if self.length > 1e-9 else 1
        if n == 1:
            return self.placement.translation.reshape(1, 3).copy(), self.radius
        s = self.length / (n - 1)
        centres = a + np.outer(np.linspace(0.0, 1.0, n), b - a)
        return centres, math.sqrt(self.radius**2 + (0.5 * s) ** 2)


@dataclass(frozen=True)
class CollisionModel:
    """The collision model of a robot.

    Attributes:
        robot: Profile name.
        capsules: One capsule (two for links whose shape one capsule fits badly) per link with
            collision geometry, in the collision model's order.
        pairs: Link pairs to keep apart (each pair sorted, the list sorted).
        skipped: Pair -> why it is not checked (``"srdf"``, ``"adjacent"``, ``"touching at rest"``,
            ``"profile"``).
        alternatives: Alternative covers of the links, each one capsule enclosing the whole link
            (:func:`axis_capsules`; ``cover`` 1, 2, 3), used only by the pairs of ``covers``.
        covers: Checked pair -> (cover of its first link, cover of its second), for the pairs that
            are not checked with the links' own capsules (0, 0): each cover encloses its link's
            geometry, so any choice is conservative; the choice is the one whose sphere sets are
            farthest apart in the standing posture (see :func:`choose_covers`).
    """

    robot: str
    capsules: tuple[Capsule, ...]
    pairs: tuple[tuple[str, str], ...]
    skipped: dict[tuple[str, str], str] = field(default_factory=dict)
    alternatives: tuple[Capsule, ...] = ()
    covers: dict[tuple[str, str], tuple[int, int]] = field(default_factory=dict)

    def capsules_of(self, link: str, cover: int = 0) -> tuple[Capsule, ...]:
        """The capsules of ``link`` (one or two; empty if it has no collision geometry), or of its
        alternative ``cover`` (one)."""
        if cover == 0:
            return tuple(c for c in self.capsules if c.link == link)
        return tuple(c for c in self.alternatives if c.link == link and c.cover == cover)

    def pair_capsules(self, a: str, b: str) -> tuple[tuple[Capsule, ...], tuple[Capsule, ...]]:
        """The capsules pair (a, b) is checked with: ``a``'s and ``b``'s (their covers of :attr:`covers`)."""
        pair = _pair(a, b)
        ka, kb = self.covers.get(pair, (0, 0))
        if pair[0] != a:
            ka, kb = kb, ka
        return self.capsules_of(a, ka), self.capsules_of(b, kb)

    @property
    def links(self) -> tuple[str, ...]:
        """Links with capsules, in the collision model's order."""
        return tuple(dict.fromkeys(c.link for c in self.capsules))



def _pair(a: str, b: str) -> tuple[str, str]:
    return (a, b) if a <= b else (b, a)


# -- geometry gathering ------------------------------------------------------------------------


def _circle_points(radius: float, z: float, n: int = CYLINDER_SAMPLES) -> np.ndarray:
    # Points on a polygon circumscribing the circle: the polygon's vertices lie at radius / cos(pi/n)
    # so the polygon (and any capsule around it) contains the true circle.
    r = radius / math.cos(math.pi / n)
    a = np.linspace(0.0, 2 * math.pi, n, endpoint=False)
    return np.column_stack([r * np.cos(a), r * np.sin(a), np.full(n, z)])


def _sphere_points(radius: float, n: int = 12) -> np.ndarray:
    pts = [np.array([[0.0, 0.0, radius], [0.0, 0.0, -radius]]) / math.cos(math.pi / n)]
    for el in np.linspace(-math.pi / 2, math.pi / 2, n + 1)[1:-1]:
        pts.append(_circle_points(radius * math.cos(el), radius * math.sin(el), 2 * n) / math.cos(math.pi / n))
    return np.vstack(pts)


def geometry_points(geom) -> np.ndarray | None:
    """Points (n, 3) whose convex hull contains a coal geometry, in its own frame; None if unknown."""
    kind = type(geom).__name__
    if hasattr(geom, "vertices") and hasattr(geom, "num_vertices"):
        v = np.asarray(geom.vertices(), dtype=float).reshape(-1, 3)
        return v if len(v) else None
    if kind == "Box":
        h = np.asarray(geom.halfSide, dtype=float)
        return np.array(list(itertools.product(*[(-x, x) for x in h])))
    if kind == "Cylinder":
        return np.vstack([_circle_points(geom.radius, geom.halfLength), _circle_points(geom.radius, -geom.halfLength)])
    if kind == "Capsule":
        cap = _sphere_points(geom.radius)
        shift = np.array([0.0, 0.0, geom.halfLength])
        return np.vstack([cap + shift, cap - shift])
    if kind == "Sphere":
        return _sphere_points(geom.radius)
    if kind == "Ellipsoid":
        return _sphere_points(1.0) * np.asarray(geom.radii, dtype=float)
    if kind == "Cone":
        return np.vstack([_circle_points(geom.radius, -geom.halfLength), [[0.0, 0.0, geom.halfLength]]])
    if kind == "Convex" or hasattr(geom, "points"):
        with contextlib.suppress(Exception):
            return np.asarray(geom.points(), dtype=float).reshape(-1, 3)
    return None


def link_points(robot: Robot) -> dict[str, tuple[int, np.ndarray]]:
    """Per link with collision geometry: (parent joint id, points (n, 3) in the joint frame) [m]."""
    out: dict[str, tuple[int, list[np.ndarray]]] = {}
    model = robot.model
    for obj in robot.collision_model.geometryObjects:
        pts = geometry_points(obj.geometry)
        if pts is None or not np.all(np.isfinite(pts)):
            continue
        link = model.frames[obj.parentFrame].name if obj.parentFrame < len(model.frames) else obj.name
        world = pts @ obj.placement.rotation.T + obj.placement.translation
        out.setdefault(link, (int(obj.parentJoint), []))[1].append(world)
    return {k: (j, np.vstack(c)) for k, (j, c) in out.items()}


# -- fitting -----------------------------------------------------------------------------------


def _enclosing_circle(p: np.ndarray, iterations: int = 40) -> np.ndarray:
    """Centre of an approximately smallest circle enclosing 2-D points (Badoiu-Clarkson on the
    points' convex hull)."""
    if len(p) > 8:
        from scipy.spatial import ConvexHull, QhullError

        with contextlib.suppress(QhullError, ValueError):
            p = p[ConvexHull(p).vertices]
    c = 0.5 * (p.min(axis=0) + p.max(axis=0))
    for i in range(1, iterations + 1):
        far = p[np.argmax(np.sum((p - c) ** 2, axis=1))]
        c = c + (far - c) / (i + 1)
    return c


def _segment_for(t: np.ndarray, d: np.ndarray, r: float) -> tuple[float, float]:
    """Shortest segment [lo, hi] on the axis whose capsule of radius r holds points at axial t, radial d."""
    reach = np.sqrt(np.maximum(r * r - d * d, 0.0))
    hi = float(np.max(t - reach))
    lo = float(np.min(t + reach))
    if lo > hi:  # a sphere is enough
        mid = 0.5 * (lo + hi)
        return mid, mid
    return lo, hi


def _volume(length: float, radius: float) -> float:
    return math.pi * radius * radius * length + 4.0 / 3.0 * math.pi * radius**3


def fit_link(points: np.ndarray) -> list[tuple[pin.SE3, float, float]]:
    """One or two capsules enclosing ``points``: two when cutting the points' convex hull across a
    principal axis (at 30, 50 or 70 % of its extent) saves more than ``1 - SPLIT_GAIN`` of the
    volume (an L-shaped thigh with its hip motor, a hand with its fingers), or, for a link whose
    one capsule is at least ``WIDE_RADIUS`` wide, when the wider of the two capsules of some cut
    (any principal axis) is below ``RADIUS_GAIN`` of its radius: a boxy link (Talos's torso, one
    capsule of 0.27 m standing 15 cm in front of the chest mesh) gets two of 0.17-0.18 m."""
    from scipy.spatial import ConvexHull, QhullError

    points = np.asarray(points, dtype=float)
    try:
        hull = ConvexHull(points)
    except (QhullError, ValueError):
        return [fit_capsule(points)]
    vertices = points[hull.vertices]
    edges = np.unique(np.sort(np.vstack([hull.simplices[:, [0, 1]], hull.simplices[:, [1, 2]],
                                         hull.simplices[:, [0, 2]]]), axis=1), axis=0)
    one = fit_capsule(vertices)
    best = ([one], _volume(one[1], one[2]))
    narrowest: tuple[list, float] = ([one], one[2] * RADIUS_GAIN)  # (capsules, largest radius)
    mean = vertices.mean(axis=0)
    _, _, vt = np.linalg.svd(vertices - mean, full_matrices=False)
    for k, axis in enumerate(vt):
        t_all = (points - mean) @ axis
        lo, hi = float(t_all.min()), float(t_all.max())
        for f in (0.3, 0.5, 0.7):
            cut = lo + f * (hi - lo)
            ta, tb = t_all[edges[:, 0]], t_all[edges[:, 1]]
            crossing = (ta - cut) * (tb - cut) < 0
            w = ((cut - ta[crossing]) / (tb[crossing] - ta[crossing]))[:, None]
            section = points[edges[crossing, 0]] * (1 - w) + points[edges[crossing, 1]] * w
            t_v = (vertices - mean) @ axis
            parts = [np.vstack([vertices[t_v <= cut], section]), np.vstack([vertices[t_v >= cut], section])]
            if min(len(p) for p in parts) < 4:
                continue
            fits = [fit_capsule(p) for p in parts]
            volume = sum(_volume(c[1], c[2]) for c in fits)
            if k < 2 and volume < best[1] * (SPLIT_GAIN if len(best[0]) == 1 else 1.0):
                best = (fits, volume)
            widest = max(c[2] for c in fits)
            if widest < narrowest[1]:
                narrowest = (fits, widest)
    if len(best[0]) == 1 and len(narrowest[0]) == 2 and one[2] >= WIDE_RADIUS:
        return narrowest[0]  # a boxy link (Talos's torso): two capsules, each much thinner
    return best[0]


def _hull_vertices(points: np.ndarray) -> np.ndarray:
    """The vertices of the convex hull of ``points`` (all of them when the hull is degenerate): a
    capsule is convex, so it holds the points iff it holds these."""
    if len(points) < 16:
        return points
    from scipy.spatial import ConvexHull, QhullError

    try:
        return points[ConvexHull(points).vertices]
    except (QhullError, ValueError):
        return points


def _fit_along(pts: np.ndarray, mean: np.ndarray, axis: np.ndarray) -> tuple:
    """(volume, centre, axis, e1, e2, length, radius) of the smallest capsule along ``axis``
    holding the hull vertices ``pts`` (radius among a few values >= the largest radial distance)."""
    axis = axis / np.linalg.norm(axis)
    helper = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(axis, helper)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(axis, e1)
    rel = pts - mean
    uv = np.column_stack([rel @ e1, rel @ e2])
    c2 = _enclosing_circle(uv)
    origin = mean + c2[0] * e1 + c2[1] * e2
    t = (pts - origin) @ axis
    d = np.linalg.norm(uv - c2, axis=1)
    r0 = float(d.max()) * (1 + 1e-9) + 1e-6
    best = None
    for scale in (1.0, 1.05, 1.1, 1.2, 1.35, 1.5, 1.75, 2.0):
        r = r0 * scale
        lo, hi = _segment_for(t, d, r)
        volume = math.pi * r * r * (hi - lo) + 4.0 / 3.0 * math.pi * r**3
        if best is None or volume < best[0]:
            best = (volume, origin + 0.5 * (lo + hi) * axis, axis, e1, e2, hi - lo, r)
    assert best is not None
    return best


def _as_capsule(fit: tuple) -> tuple[pin.SE3, float, float]:
    _, centre, axis, e1, e2, length, radius = fit
    R = np.column_stack([e1, e2, axis])
    if np.linalg.det(R) < 0:
        R[:, 0] = -R[:, 0]
    return pin.SE3(R, centre), float(length), float(radius)


def _axis_fits(points: np.ndarray) -> list[tuple]:
    pts = _hull_vertices(np.asarray(points, dtype=float))
    mean = pts.mean(axis=0)
    _, _, vt = np.linalg.svd(pts - mean, full_matrices=False)
    return [_fit_along(pts, mean, axis) for axis in vt]


def fit_capsule(points: np.ndarray) -> tuple[pin.SE3, float, float]:
    """(placement, length, radius) of a small capsule enclosing ``points`` (n, 3) [m].

    Axis: the principal direction of the points; axis line: through the centre of the enclosing
    circle of their projection; radius: chosen among a few values >= the largest radial distance
    to minimize the capsule's volume; segment: the shortest one holding every point.
    """
    fits = _axis_fits(points)  # each principal direction: keep the smallest capsule
    return _as_capsule(min(fits, key=lambda f: f[0]))


def axis_capsules(points: np.ndarray) -> list[tuple[pin.SE3, float, float]]:
    """One capsule enclosing ``points`` along each of their three principal directions (the
    smallest along that direction): the alternative covers of a link (:data:`CollisionModel.alternatives`).
    A flat link's capsule along its longest direction bulges out of its wide faces' sides (Talos's
    pelvis: 7 cm beyond its flanks, where the forearms hang); the one along its second direction
    hugs those flanks (8 mm) and bulges elsewhere."""
    return [_as_capsule(f) for f in _axis_fits(points)]


# -- distances ---------------------------------------------------------------------------------


def segment_distance(p1: np.ndarray, q1: np.ndarray, p2: np.ndarray, q2: np.ndarray) -> float:
    """Distance between segments [p1, q1] and [p2, q2] (numeric, exact) [m]."""
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a, e, f = float(d1 @ d1), float(d2 @ d2), float(d2 @ r)
    eps = 1e-15
    if a <= eps and e <= eps:
        return float(np.linalg.norm(r))
    if a <= eps:
        s, t = 0.0, min(max(f / e, 0.0), 1.0)
    else:
        c = float(d1 @ r)
        if e <= eps:
            t, s = 0.0, min(max(-c / a, 0.0), 1.0)
        else:
            b = float(d1 @ d2)
            denom = a * e - b * b
            s = min(max((b * f - c * e) / denom, 0.0), 1.0) if denom > eps else 0.0
            t = (b * s + f) / e
            if t < 0.0:
                t, s = 0.0, min(max(-c / a, 0.0), 1.0)
            elif t > 1.0:
                t, s = 1.0, min(max((b - c) / a, 0.0), 1.0)
    return float(np.linalg.norm(p1 + d1 * s - (p2 + d2 * t)))


def capsule_world(c: Capsule, data: pin.Data) -> tuple[np.ndarray, np.ndarray]:
    """World endpoints of a capsule's segment given joint placements in ``data.oMi``."""
    M = data.oMi[c.joint]
    a, b = c.endpoints()
    return M.act(a), M.act(b)


def capsule_distance(c1: Capsule, c2: Capsule, data: pin.Data) -> float:
    """Signed distance between two capsules (negative: penetration depth) [m]."""
    p1, q1 = capsule_world(c1, data)
    p2, q2 = capsule_world(c2, data)
    return segment_distance(p1, q1, p2, q2) - c1.radius - c2.radius


def sphere_distance(c1: Capsule, c2: Capsule, data: pin.Data) -> float:
    """Distance between the sphere sets of two capsules (negative: overlap) [m]."""
    (s1, r1), (s2, r2) = c1.spheres(), c2.spheres()
    w1 = s1 @ data.oMi[c1.joint].rotation.T + data.oMi[c1.joint].translation
    w2 = s2 @ data.oMi[c2.joint].rotation.T + data.oMi[c2.joint].translation
    return float(np.min(np.linalg.norm(w1[:, None, :] - w2[None, :, :], axis=2))) - r1 - r2


def pair_distances(cm: CollisionModel, model: pin.Model, q: np.ndarray,
                   pairs: tuple[tuple[str, str], ...] | None = None) -> dict[tuple[str, str], float]:
    """Capsule distance of every checked pair (or of ``pairs``) at configuration ``q``, with the
    pair's covers (:attr:`CollisionModel.covers`) [m]."""
    data = model.createData()
    pin.forwardKinematics(model, data, q)
    out = {}
    for p in (cm.pairs if pairs is None else pairs):
        ca, cb = cm.pair_capsules(*p)
        out[p] = min(capsule_distance(c1, c2, data) for c1 in ca for c2 in cb)
    return out


def pair_sphere_distance(cm: CollisionModel, a: str, b: str, data: pin.Data) -> float:
    """Sphere-set distance of links ``a`` and ``b`` with the pair's covers, joint placements in
    ``data.oMi`` [m]: what the planner keeps at least the margin."""
    ca, cb = cm.pair_capsules(a, b)
    return min(sphere_distance(c1, c2, data) for c1 in ca for c2 in cb)


def mesh_distances(robot: Robot, q: np.ndarray, pairs: list[tuple[str, str]]) -> dict[tuple[str, str], float]:
    """Distance (coal) between the URDF collision geometries of each link pair at ``q`` [m]
    (negative or 0: touching or interpenetrating)."""
    gmodel = robot.collision_model.copy()
    model = robot.model
    by_link: dict[str, list[int]] = {}
    for i, obj in enumerate(gmodel.geometryObjects):
        by_link.setdefault(model.frames[obj.parentFrame].name, []).append(i)
    index: list[tuple[tuple[str, str], int]] = []
    for a, b in pairs:
        for ia in by_link.get(a, []):
            for ib in by_link.get(b, []):
                gmodel.addCollisionPair(pin.CollisionPair(ia, ib))
                index.append(((a, b), len(gmodel.collisionPairs) - 1))
    gdata = gmodel.createData()
    data = model.createData()
    pin.computeDistances(model, data, gmodel, gdata, q)
    out: dict[tuple[str, str], float] = {}
    for pair, k in index:
        d = float(gdata.distanceResults[k].min_distance)
        out[pair] = min(out.get(pair, math.inf), d)
    return out
