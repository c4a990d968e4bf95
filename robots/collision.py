"""The robot's collision model: one capsule per link, fitted to the URDF collision geometry.

Each link's collision geometry (meshes and primitives of ``robot.collision_model``) is gathered
in its parent joint's frame and enclosed by a capsule (or two, cut across a principal axis, when
that saves a quarter of the volume, or, for a wide link, makes the capsules much thinner:
:func:`fit_link`): the axis is the principal direction of
the vertices, the axis line passes through the centre of the smallest circle (approximately)
enclosing their projection on the perpendicular plane, the radius is the largest distance of a
vertex to that line, and the segment is the shortest one whose capsule still holds every vertex.
The capsule therefore *encloses* the geometry (``tests/robots/test_collision.py`` checks every
vertex): distances between capsules never exceed the distances between the meshes.

The pairs to check are every pair of links minus

* ``"srdf"``: the SRDF's ``<disable_collisions>`` pairs (example-robot-data ships an SRDF for
  talos, romeo and icub);
* ``"adjacent"``: links on the same joint, or on a joint and its parent joint;
* ``"touching at rest"``: pairs whose meshes (coal distances) are closer than :data:`REST_MARGIN`,
  or whose capsules' sphere sets are closer than :data:`REST_SPHERE_MARGIN`, in the standing
  posture (a motion starts there: such a pair could not be kept a margin apart, or, the capsules
  being larger than the meshes, not moved at all);
* ``"profile"``: the profile's ``[collisions] remove`` list;

plus the profile's ``[collisions] add`` list. The fit is cached on disk (JSON, keyed by the URDF,
SRDF and profile content and :data:`FIT_VERSION`) under ``$WBMP_CACHE_DIR`` (else
``~/.cache/wbmp``) in ``collision/``; a damaged cache file is rebuilt. See ``docs/collisions.md``.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import itertools
import json
import math
import os
import tempfile
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from robots.safeio import read_json

if TYPE_CHECKING:
    from robots.model import Robot

FIT_VERSION = 8  # bump when the fitting or the pair selection changes: the cache is keyed by it
REST_MARGIN = 0.01  # [m] pairs whose meshes are closer than this in the standing posture are skipped ...
REST_SPHERE_MARGIN = 0.01  # [m] ... and pairs whose (conservative) sphere sets are closer than this
COVER_RANGE = 0.05  # [m] pairs whose own capsules' sphere sets are closer than this at rest may use other covers ...
COVER_GAIN = 0.005  # [m] ... when those are at least this much farther apart there
CYLINDER_SAMPLES = 48  # points around a cylinder/capsule circle (the radius is inflated to cover the chords)
SPHERE_SPACING = 0.75  # sphere-set spacing along a capsule axis, as a fraction of its radius ...
MIN_SPHERE_SPACING = 0.03  # [m] ... but at least this (thin links get a few slightly larger spheres)

SPLIT_GAIN = 0.75  # a link gets two capsules when their volume is below this fraction of one capsule's
RADIUS_GAIN = 0.7  # ... or, for a link whose one capsule is WIDE_RADIUS or wider, when the wider of
WIDE_RADIUS = 0.15  # [m] ... the two is below RADIUS_GAIN of its radius (Talos's torso: 0.27 -> 0.18 m)
SKIP_REASONS = ("srdf", "adjacent", "touching at rest", "profile")


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


# -- pairs -------------------------------------------------------------------------------------


def srdf_path(robot: Robot) -> str | None:
    """The SRDF of a robot: example-robot-data's for a loader robot, else the profile's."""
    profile = robot.profile
    if profile.loader is not None:
        from robots.model import _loader_paths

        try:
            return _loader_paths(profile.where, profile.loader)[1]
        except Exception:  # noqa: BLE001 - no SRDF: nothing to skip
            return None
    return profile.srdf


def srdf_disabled_pairs(path: str | None) -> set[tuple[str, str]]:
    """The ``<disable_collisions link1 link2>`` pairs of an SRDF (sorted pairs; empty if unreadable)."""
    if not path:
        return set()
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError, ValueError):
        return set()
    out = set()
    for el in root.iter("disable_collisions"):
        a, b = el.get("link1"), el.get("link2")
        if a and b and a != b:
            out.add(_pair(a, b))
    return out


def _pair(a: str, b: str) -> tuple[str, str]:
    return (a, b) if a <= b else (b, a)


def _adjacent(model: pin.Model, ja: int, jb: int) -> bool:
    return ja == jb or model.parents[ja] == jb or model.parents[jb] == ja


def _check_table(robot: Robot, links: list[str]) -> None:
    """Every link the profile's ``[collisions]`` table names has collision geometry."""
    from robots.exceptions import ProfileError
    from robots.profile import _suggest

    table = robot.profile.collisions
    named = [(f"collisions.{key}[{i}]", link) for key in ("add", "remove")
             for i, pair in enumerate(getattr(table, key)) for link in pair]
    named += [(f"collisions.body_parts.{link}", link) for link, _ in table.body_parts]
    for key, link in named:
        if link not in links:
            raise ProfileError(f"{robot.profile.where}: {key}: the robot has no link {link!r} with collision "
                               f"geometry{_suggest(link, links)}")


def choose_covers(capsules: dict[str, list[Capsule]], alternatives: dict[str, list[Capsule]],
                  pairs: list[tuple[str, str]], data: pin.Data,
                  unchecked: set[tuple[str, str]]) -> dict[tuple[str, str], tuple[int, int]]:
    """Per pair whose own capsules' sphere sets are closer than :data:`COVER_RANGE` at the joint
    placements ``data.oMi`` (the standing posture), the covers of its two links (0: their own
    capsules; k: alternative k) whose sphere sets are farthest apart there, kept only when that is
    at least :data:`COVER_GAIN` farther than with the own capsules. Any cover encloses its link,
    so the pair's sphere-set distance still never exceeds the meshes' at any posture; choosing at
    rest gives the cover tight on the side where the other link is (Talos's hanging forearm beside
    the pelvis: 13 mm -> 75 mm; the meshes are 93 mm apart). Pairs farther apart keep the own
    capsules, the tightest overall (the arms crossing in front of the torso).

    A link keeps its own capsules in a pair when a link on its joint and the pair's other link are
    ``unchecked`` (touching at rest): its own capsules are then what keeps the other link off
    that neighbour's mesh (G1's chest logo, on the torso, keeps the shoulders off the torso)."""
    out: dict[tuple[str, str], tuple[int, int]] = {}
    joint_of = {link: caps[0].joint for link, caps in capsules.items()}
    on_joint: dict[int, list[str]] = {}
    for link, j in joint_of.items():
        on_joint.setdefault(j, []).append(link)

    def free(link: str, other: str) -> bool:  # may ``link`` take another cover against ``other``?
        return not any(_pair(t, other) in unchecked for t in on_joint[joint_of[link]] if t != other)

    for a, b in pairs:
        own = min(sphere_distance(c1, c2, data) for c1 in capsules[a] for c2 in capsules[b])
        if own >= COVER_RANGE:
            continue
        options_a = [(0, capsules[a])] + [(c.cover, [c]) for c in alternatives.get(a, []) if free(a, b)]
        options_b = [(0, capsules[b])] + [(c.cover, [c]) for c in alternatives.get(b, []) if free(b, a)]
        best = (own, (0, 0))
        for (ka, ca), (kb, cb) in itertools.product(options_a, options_b):
            d = min(sphere_distance(c1, c2, data) for c1 in ca for c2 in cb)
            if d > best[0]:
                best = (d, (ka, kb))
        if best[0] >= own + COVER_GAIN:
            out[(a, b)] = best[1]
    return out


def _build(robot: Robot) -> CollisionModel:
    model = robot.model
    capsules = []
    alternatives = []
    for link, (joint, pts) in link_points(robot).items():
        own = fit_link(pts)
        for placement, length, radius in own:
            capsules.append(Capsule(link=link, joint=joint, placement=placement, length=length, radius=radius))
        for k, (placement, length, radius) in enumerate(axis_capsules(pts), start=1):
            if len(own) == 1 and abs(length - own[0][1]) < 1e-12 and abs(radius - own[0][2]) < 1e-12:
                continue  # the link's own capsule
            alternatives.append(Capsule(link=link, joint=joint, placement=placement, length=length, radius=radius,
                                        cover=k))
    caps: dict[str, list[Capsule]] = {}
    for c in capsules:
        caps.setdefault(c.link, []).append(c)
    links = list(caps)
    table = robot.profile.collisions
    _check_table(robot, links)
    srdf = srdf_disabled_pairs(srdf_path(robot))
    removed = {_pair(a, b) for a, b in table.remove}
    added = {_pair(a, b) for a, b in table.add}
    skipped: dict[tuple[str, str], str] = {}
    candidates = []
    for a, b in itertools.combinations(sorted(links), 2):
        pair = _pair(a, b)
        if pair in added:
            continue
        if pair in removed:
            skipped[pair] = "profile"
        elif pair in srdf:
            skipped[pair] = "srdf"
        elif _adjacent(model, caps[a][0].joint, caps[b][0].joint):
            skipped[pair] = "adjacent"
        else:
            candidates.append(pair)
    rest_mesh = mesh_distances(robot, robot.q_standing, candidates)
    data = model.createData()
    pin.forwardKinematics(model, data, robot.q_standing)
    pairs = set(added)
    for pair in candidates:
        d_caps = min(sphere_distance(c1, c2, data) for c1 in caps[pair[0]] for c2 in caps[pair[1]])
        if rest_mesh.get(pair, math.inf) < REST_MARGIN or d_caps < REST_SPHERE_MARGIN:
            skipped[pair] = "touching at rest"
        else:
            pairs.add(pair)
    alt: dict[str, list[Capsule]] = {}
    for c in alternatives:
        alt.setdefault(c.link, []).append(c)
    covers = choose_covers(caps, alt, sorted(pairs), data,
                           unchecked={p for p, why in skipped.items() if why == "touching at rest"})
    used = {(link, k) for pair, ks in covers.items() for link, k in zip(pair, ks, strict=True) if k}
    return CollisionModel(robot=robot.name, capsules=tuple(capsules), pairs=tuple(sorted(pairs)),
                          skipped=dict(sorted(skipped.items())),
                          alternatives=tuple(c for c in alternatives if (c.link, c.cover) in used), covers=covers)


# -- the disk cache ----------------------------------------------------------------------------


def cache_dir() -> Path:
    """``$WBMP_CACHE_DIR/collision`` (else ``~/.cache/wbmp/collision``): the root the solver cache uses."""
    from robots.cache import cache_folder

    folder = cache_folder("collision")
    assert folder is not None  # no switch: never off
    return folder


def cache_key(robot: Robot) -> str:
    """Hash of what the model depends on: URDF and SRDF content, the profile's collision table, the
    standing posture and :data:`FIT_VERSION`."""
    h = hashlib.sha256()
    h.update(f"fit-v{FIT_VERSION}|{REST_MARGIN}|{REST_SPHERE_MARGIN}|{COVER_RANGE}|{COVER_GAIN}|{robot.name}".encode())
    for path in (robot.urdf_path, srdf_path(robot)):
        if path:
            try:
                h.update(Path(path).read_bytes())
            except OSError:
                h.update(path.encode())
    h.update(repr(robot.profile.collisions).encode())
    h.update(np.asarray(robot.q_standing, dtype=float).tobytes())
    return h.hexdigest()[:20]


def _to_json(cm: CollisionModel) -> dict:
    return {
        "fit_version": FIT_VERSION,
        "robot": cm.robot,
        "capsules": [_capsule_json(c) for c in cm.capsules],
        "alternatives": [_capsule_json(c) for c in cm.alternatives],
        "pairs": [list(p) for p in cm.pairs],
        "skipped": [[a, b, why] for (a, b), why in cm.skipped.items()],
        "covers": [[a, b, ka, kb] for (a, b), (ka, kb) in cm.covers.items()],
    }


def _capsule_json(c: Capsule) -> dict:
    return {"link": c.link, "joint": c.joint, "rotation": c.placement.rotation.tolist(),
            "translation": c.placement.translation.tolist(), "length": c.length, "radius": c.radius,
            "cover": c.cover}


def _capsule_from_json(c: dict, robot: Robot) -> Capsule:
    R = np.array(c["rotation"], dtype=float)
    p = np.array(c["translation"], dtype=float)
    length, radius, joint, cover = float(c["length"]), float(c["radius"]), int(c["joint"]), int(c["cover"])
    if (R.shape != (3, 3) or p.shape != (3,) or not np.all(np.isfinite(R)) or not np.all(np.isfinite(p))
            or not np.allclose(R.T @ R, np.eye(3), atol=1e-6) or not (length >= 0 and radius > 0)
            or not 0 < joint < robot.model.njoints or not isinstance(c["link"], str) or not 0 <= cover <= 3):
        raise ValueError("bad capsule")
    return Capsule(link=c["link"], joint=joint, placement=pin.SE3(R, p), length=length, radius=radius, cover=cover)


def _from_json(data: dict, robot: Robot) -> CollisionModel:
    """A model from its cache file; ValueError/KeyError/TypeError when anything is off."""
    if data.get("fit_version") != FIT_VERSION or data.get("robot") != robot.name:
        raise ValueError("stale")
    capsules = tuple(_capsule_from_json(c, robot) for c in data["capsules"])
    alternatives = tuple(_capsule_from_json(c, robot) for c in data["alternatives"])
    links = {c.link for c in capsules}
    pairs = tuple(sorted(_pair(str(a), str(b)) for a, b in data["pairs"]))
    skipped = {_pair(str(a), str(b)): str(why) for a, b, why in data["skipped"]}
    covers = {(str(a), str(b)): (int(ka), int(kb)) for a, b, ka, kb in data["covers"]}
    if (not all(a in links and b in links for a, b in pairs) or not set(skipped.values()) <= set(SKIP_REASONS)
            or any(c.cover < 1 for c in alternatives)
            or any(c.cover != 0 for c in capsules)):
        raise ValueError("bad pairs")
    model = CollisionModel(robot=robot.name, capsules=capsules, pairs=pairs, skipped=skipped,
                           alternatives=alternatives, covers=covers)
    for (a, b), (ka, kb) in covers.items():
        if (a, b) not in pairs or any(not model.capsules_of(link, k) for link, k in ((a, ka), (b, kb))):
            raise ValueError("bad covers")
    return model


def _write_atomic(path: Path, text: str) -> None:
    with contextlib.suppress(OSError):
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
        try:
            with os.fdopen(fd, "w", encoding="utf-8") as f:
                f.write(text)
            Path(tmp).replace(path)
        except OSError:
            with contextlib.suppress(OSError):
                Path(tmp).unlink()


_MEMORY: dict[tuple[int, str], CollisionModel] = {}


def collision_model(robot: Robot) -> CollisionModel:
    """The collision model of ``robot``: from memory, the disk cache, or fitted now (~1 s)."""
    from robots.cache import mark_used, trim_cache

    key = cache_key(robot)
    mem = _MEMORY.get((id(robot), key))
    if mem is not None:
        return mem
    path = cache_dir() / f"{robot.name}-{key}.json"
    cm = None
    try:
        if path.is_file():  # a regular file of at most 8 MiB (a FIFO or a device is damaged)
            cm = _from_json(read_json(path, 8 << 20), robot)
            mark_used(path)
    except (OSError, ValueError, KeyError, TypeError, IndexError, AttributeError, RecursionError):
        cm = None  # damaged, stale or removed meanwhile: rebuilt below
    if cm is None:
        cm = _build(robot)
        _write_atomic(path, json.dumps(_to_json(cm)))
        trim_cache(path.parent)
    _MEMORY[(id(robot), key)] = cm
    return cm


# -- names for messages ------------------------------------------------------------------------


def _ancestors(model: pin.Model, joint: int) -> list[int]:
    out = []
    while joint > 0:
        out.append(joint)
        joint = model.parents[joint]
    return out


@functools.lru_cache(maxsize=16)
def _body_parts(robot: Robot) -> dict[str, str]:
    model = robot.model
    data = model.createData()
    pin.framesForwardKinematics(model, data, robot.q_standing)
    cm = collision_model(robot)
    overrides = dict(robot.profile.collisions.body_parts)

    def joint_of(role: str) -> int | None:
        frame = robot.profile.frame(role)
        return int(model.frames[model.getFrameId(frame)].parentJoint) if frame else None

    def origin(role: str) -> np.ndarray:
        return data.oMf[robot.frame_id(role)].translation

    def chain(role: str) -> set[int]:
        j = joint_of(role)
        return set(_ancestors(model, j)) if j is not None else set()

    @functools.cache  # asked for every link: computed once per role
    def below(role: str) -> set[int]:  # the joints of the subtree under a role's joint
        j = joint_of(role)
        return {i for i in range(1, model.njoints) if j is not None and j in _ancestors(model, i)}

    base_j = joint_of("base") or 1
    hands = {s: chain(f"{s}_hand") for s in ("left", "right")}
    feet = {s: chain(f"{s}_foot") for s in ("left", "right")}
    head = chain("head")
    common = (hands["left"] & hands["right"]) | (feet["left"] & feet["right"]) | (hands["left"] & feet["left"])
    out: dict[str, str] = {}
    for link in cm.links:
        c = max(cm.capsules_of(link), key=lambda c: _volume(c.length, c.radius))  # the main part
        if c.link in overrides:
            out[c.link] = overrides[c.link]
            continue
        centre = data.oMi[c.joint].act(c.placement.translation)
        j = c.joint
        name = None
        for side in ("left", "right"):
            if j in below(f"{side}_hand"):
                name = f"{side} hand"
            elif j in hands[side] - common:
                start = (origin(f"{side}_shoulder") if robot.has_role(f"{side}_shoulder")
                         else data.oMi[min(hands[side] - common)].translation)
                end = origin(f"{side}_hand")
                f = float(np.dot(centre - start, end - start) / max(np.dot(end - start, end - start), 1e-9))
                name = f"{side} " + ("shoulder" if f < 0.1 else "upper arm" if f < 0.5 else "forearm" if f < 0.85
                                     else "hand")
            elif j in feet[side] - common or j in below(f"{side}_foot"):
                hip = data.oMi[min(feet[side] - common)] if feet[side] - common else data.oMi[j]
                z0, z1 = hip.translation[2], origin(f"{side}_foot")[2]
                f = float((z0 - centre[2]) / max(z0 - z1, 1e-9))
                name = f"{side} " + ("hip" if f < 0.12 else "thigh" if f < 0.5 else "shin" if f < 0.85 else "foot")
            if name:
                break
        if name is None:
            if j == base_j or (j in feet["left"] & feet["right"]):
                name = "pelvis"
            elif j in head - common:
                name = "head" if robot.has_role("head") and centre[2] >= origin("head")[2] - 0.05 else "neck"
            elif j in common or (robot.has_role("torso") and j in chain("torso")):
                name = "torso"
            else:
                name = c.link.replace("_", " ")
        out[c.link] = name
    return out


def body_part(robot: Robot, link: str) -> str:
    """A human name of a link for messages ("left forearm", "pelvis", "right thigh"): derived from
    the robot's roles and kinematic chains, or the profile's ``[collisions] body_parts``."""
    override = dict(robot.profile.collisions.body_parts).get(link)
    if override:
        return override
    return _body_parts(robot).get(link, link.replace("_", " "))
