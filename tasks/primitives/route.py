"""Footpaths around scene objects: where ``walk_to`` walks when the straight line is blocked.

The robot's body, seen from above, is a disc centred between its feet: for an object spanning the
heights ``[z_lo, z_hi]``, its radius is the largest horizontal distance from that centre of the
body's collision geometry at those heights, widened by the margin (:func:`body_radius`, from
:func:`tasks.primitives.bodymap.body_map` at the standing posture; Talos's hanging arms make its
disc 0.59 m wide at hand height, its feet 0.25 m) plus :data:`ROUTE_MARGIN`. The disc does not
change when the robot turns in place, so a path of its centre that keeps every object's footprint
(its outline seen from above, :func:`footprint_distance`) at least that radius away is a path the
body can walk, turning at the corners.

:func:`plan_route` searches that path on a grid of :data:`CELL` over the floor around the start
and the objects (Dijkstra, 8-connected), from the start's cell to the cheapest cell near the target (the path
there plus the distance on to the target) that the caller accepts (``walk_to``: the straight
approach from there ends within reach), then shortens the cell path to straight segments wherever the segment
between two of its points keeps every clearance (the segment sampled every :data:`SAMPLE` and
measured exactly). When no cell next to the target (or to what it stands on) is reachable, the target is enclosed:
:class:`~tasks.exceptions.SceneConflict` names the objects around it (exit 4).

A robot that starts closer to an object than its radius (after walking to the table) may leave
that place: cells within the disc's radius of the start are free when they are no closer to the
object than the start is. Mesh objects are not obstacles here (their geometry is not read in
``tasks/``; the planner still keeps the robot clear of them).
"""

from __future__ import annotations

import heapq
import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from robots import Robot
from tasks.exceptions import SceneConflict
from tasks.primitives.bodymap import body_map
from tasks.scene import SceneObject, extent, on_top, rotation

ROUTE_MARGIN = 0.1  # [m] body disc to object footprints along the route (the body sways while it walks)
CELL = 0.05  # [m] grid resolution
SAMPLE = 0.02  # [m] spacing of the exact clearance samples along a straight segment
BORDER = 1.0  # [m] free floor around the start, the objects and their discs
GOAL_REACH = 1.0  # [m] goals are sought this far beyond the largest radius from the target's footprint
MAX_CANDIDATES = 4000
SUPPORT_TOLERANCE = 0.03  # [m] an object whose bottom is this close to another's top stands on it  # goals tried at most
MAX_CELLS = 250_000  # grid size limit (25 m x 25 m at 5 cm)
_STEPS = [(dx, dy, math.hypot(dx, dy)) for dx in (-1, 0, 1) for dy in (-1, 0, 1) if dx or dy]


def body_radius(robot: Robot, z_range: tuple[float, float]) -> float:
    """Radius [m] of the standing body's collision geometry between heights ``z_range``, seen from
    above, about the point between the feet (the whole body's when no geometry is at those heights;
    boxes of the geometry, so the meshes are inside)."""
    boxes = body_map(robot).boxes
    level = [b for b in boxes if b.lo[2] <= z_range[1] and b.hi[2] >= z_range[0]] or boxes
    return max(float(math.hypot(max(abs(b.lo[0]), abs(b.hi[0])), max(abs(b.lo[1]), abs(b.hi[1])))) for b in level)


def clearance_radius(robot: Robot, obj: SceneObject) -> float:
    """How far [m] the point between the feet keeps from ``obj``'s footprint along a route: the body's
    radius at the object's heights (widened by :data:`ROUTE_MARGIN` up and down: a part above a low
    box passes over it at least that high) plus :data:`ROUTE_MARGIN`."""
    lo, hi = extent(obj)
    return body_radius(robot, (lo[2] - ROUTE_MARGIN, hi[2] + ROUTE_MARGIN)) + ROUTE_MARGIN


def _upright(obj: SceneObject) -> bool:
    return rotation(obj.rpy)[2][2] > 1.0 - 1e-9


def footprint_distance(obj: SceneObject, xy: np.ndarray) -> np.ndarray:
    """Horizontal distance [m] from points ``xy`` (n, 2) to the object's outline seen from above
    (negative inside): exact for upright boxes and cylinders (any yaw) and spheres; a tilted box or
    cylinder counts as its world bounding box; a mesh is infinitely far (not an obstacle here)."""
    xy = np.atleast_2d(np.asarray(xy, dtype=float))
    if obj.shape == "mesh":
        return np.full(len(xy), np.inf)
    d = xy - np.asarray(obj.position[:2])
    if obj.shape == "sphere" or (obj.shape == "cylinder" and _upright(obj)):
        return np.linalg.norm(d, axis=1) - obj.size[0]
    if obj.shape == "box" and _upright(obj):
        yaw = math.atan2(rotation(obj.rpy)[1][0], rotation(obj.rpy)[0][0])
        c, s = math.cos(yaw), math.sin(yaw)
        local = np.stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]], axis=1)
        half = np.array(obj.size[:2]) / 2
    else:
        lo, hi = extent(obj)
        local = xy - (np.array(lo[:2]) + np.array(hi[:2])) / 2
        half = (np.array(hi[:2]) - np.array(lo[:2])) / 2
    q = np.abs(local) - half
    return np.linalg.norm(np.maximum(q, 0.0), axis=1) + np.minimum(q.max(axis=1), 0.0)


@dataclass(frozen=True, slots=True, kw_only=True)
class Route:
    """A footpath of the point between the feet.

    Attributes:
        waypoints: (x, y) [m] from the start to the end, joined by straight segments.
        length: Sum of the segments [m].
    """

    waypoints: tuple[tuple[float, float], ...]
    length: float


def _clear(objects: Sequence[SceneObject], radii: np.ndarray, xy: np.ndarray, start: np.ndarray,
           start_gap: np.ndarray) -> np.ndarray:
    """(n,) bool: each point keeps every object's clearance (with the start's allowance)."""
    ok = np.ones(len(xy), dtype=bool)
    near_start = np.linalg.norm(xy - start, axis=1) <= radii.max() if len(radii) else ok
    for i, obj in enumerate(objects):
        d = footprint_distance(obj, xy)
        ok &= (d >= radii[i]) | (near_start & (d >= start_gap[i] - 1e-9))
    return ok


def segment_clear(a: np.ndarray, b: np.ndarray, objects: Sequence[SceneObject], radii: Sequence[float]) -> bool:
    """Whether every point of the segment ``a`` to ``b`` (x, y) [m] (sampled every :data:`SAMPLE`)
    keeps at least ``radii[i]`` from ``objects[i]``'s footprint."""
    r = np.asarray(radii, dtype=float)
    return _segment_clear(np.asarray(a, dtype=float), np.asarray(b, dtype=float),
                          lambda xy: _clear(objects, r, xy, np.asarray(a, dtype=float), np.full(len(r), np.inf)))


def _segment_clear(a: np.ndarray, b: np.ndarray, clear: Callable[[np.ndarray], np.ndarray]) -> bool:
    n = max(2, math.ceil(float(np.linalg.norm(b - a)) / SAMPLE) + 1)
    s = np.linspace(0.0, 1.0, n)[:, None]
    return bool(clear(a + s * (b - a)).all())


def _grid_costs(free: np.ndarray, s: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Dijkstra over the free cells from cell ``s`` (8-connected, no corner cutting): the path
    cost of each cell [m] (inf where unreachable) and its parent cell (-1, -1 at ``s``)."""
    shape = free.shape
    cost = np.full(shape, np.inf)
    parent = np.full((*shape, 2), -1, dtype=int)
    cost[s] = 0.0
    heap: list[tuple[float, tuple[int, int]]] = [(0.0, s)]
    while heap:
        c, (i, j) = heapq.heappop(heap)
        if c > cost[i, j]:
            continue
        for dx, dy, w in _STEPS:
            a, b = i + dx, j + dy
            if 0 <= a < shape[0] and 0 <= b < shape[1] and free[a, b] and c + CELL * w < cost[a, b]:
                if dx and dy and not (free[i + dx, j] and free[i, j + dy]):
                    continue  # no corner cutting
                cost[a, b] = c + CELL * w
                parent[a, b] = (i, j)
                heapq.heappush(heap, (c + CELL * w, (a, b)))
    return cost, parent


def plan_route(start: Sequence[float] | np.ndarray, target: SceneObject, objects: Sequence[SceneObject],
               radii: Sequence[float], accept: Callable[[np.ndarray], str]) -> Route:
    """The shortest grid path from ``start`` (x, y) [m] to a cell near ``target`` that ``accept``
    takes, shortened to straight segments, every point at least ``radii[i]`` from ``objects[i]``.

    Args:
        start: Where the point between the feet starts (x, y) [m].
        target: The object to walk to (one of ``objects``).
        objects: The obstacles (the target among them).
        radii: Per object, the clearance of the point between the feet [m] (:func:`clearance_radius`).
        accept: Why a goal (x, y) does not suit, "" when it does (``walk_to``: the straight approach from
            there ends within reach); called on the reachable cells within the largest radius +
            :data:`GOAL_REACH` of the target, cheapest first (the path there plus the distance from
            there to the target).

    Raises:
        SceneConflict: no cell near the target can be reached (it is enclosed: the message names the
            objects around it), or ``accept`` takes none of them (the message says so).
    """
    objects = list(objects)
    r = np.asarray(radii, dtype=float)
    p0 = np.asarray(start, dtype=float)
    gap0 = np.array([float(footprint_distance(o, p0[None])[0]) for o in objects])
    lo, hi = p0 - BORDER, p0 + BORDER
    for obj, ri in zip(objects, r, strict=True):
        if obj.shape == "mesh":
            continue
        box_lo, box_hi = extent(obj)
        lo = np.minimum(lo, np.array(box_lo[:2]) - ri - BORDER)
        hi = np.maximum(hi, np.array(box_hi[:2]) + ri + BORDER)
    shape = (int(math.ceil((hi[0] - lo[0]) / CELL)) + 1, int(math.ceil((hi[1] - lo[1]) / CELL)) + 1)
    if shape[0] * shape[1] > MAX_CELLS:
        raise SceneConflict(f"walk_to: the scene spans {hi[0] - lo[0]:.0f} x {hi[1] - lo[1]:.0f} m around the robot; "
                            f"routes are planned over at most {math.sqrt(MAX_CELLS) * CELL:.0f} x "
                            f"{math.sqrt(MAX_CELLS) * CELL:.0f} m", target.name)
    gx, gy = np.meshgrid(lo[0] + CELL * np.arange(shape[0]), lo[1] + CELL * np.arange(shape[1]), indexing="ij")
    cells = np.stack([gx.ravel(), gy.ravel()], axis=1)

    def clear(xy: np.ndarray) -> np.ndarray:
        return _clear(objects, r, xy, p0, gap0)

    free = clear(cells).reshape(shape)
    ti = objects.index(target)
    to_target = footprint_distance(target, cells).reshape(shape)
    near = (to_target <= r.max() + GOAL_REACH) & free
    s = (int(round((p0[0] - lo[0]) / CELL)), int(round((p0[1] - lo[1]) / CELL)))
    free[s] = True
    cost, parent = _grid_costs(free, s)
    # the ring around the target (and around what it stands on: a cup on a table is reached from the table)
    ring = to_target <= r[ti] + 2 * CELL
    lo_t, hi_t = extent(target)
    bottom = ((lo_t[0] + hi_t[0]) / 2, (lo_t[1] + hi_t[1]) / 2, lo_t[2])
    for k, obj in enumerate(objects):
        if k != ti and on_top(obj, bottom, tolerance=SUPPORT_TOLERANCE):
            ring |= footprint_distance(obj, cells).reshape(shape) <= r[k] + 2 * CELL
    ring &= np.isfinite(cost)
    reachable = near & np.isfinite(cost)
    if not ring.any():
        raise SceneConflict(_enclosed(target, objects, r, cells), target.name)
    # cheapest first: the route there plus the straight approach (about the distance to the target)
    order = np.argwhere(reachable)
    keys = cost[reachable] + to_target[reachable]
    goal, nearest = None, (math.inf, "")
    for i, j in order[np.argsort(keys, kind="stable")][:MAX_CANDIDATES].tolist():
        error = accept(np.array([gx[i, j], gy[i, j]]))
        if not error:
            goal = (i, j)
            break
        nearest = min(nearest, (float(to_target[i, j]), error))
    if goal is None:
        raise SceneConflict(f"walk_to: no place the robot can walk to has the {target.name} within reach; from the "
                            f"nearest: {nearest[1].removeprefix('walk_to: ')}", target.name)
    path = [goal]
    while path[-1] != s:
        path.append(tuple(parent[path[-1]]))
    points = [p0] + [np.array([gx[c], gy[c]]) for c in reversed(path[:-1])]
    pulled = [points[0]]
    k = 0
    while k < len(points) - 1:
        far = len(points) - 1
        while far > k + 1 and not _segment_clear(points[k], points[far], clear):
            far -= 1
        pulled.append(points[far])
        k = far
    length = float(sum(np.linalg.norm(b - a) for a, b in itertools.pairwise(pulled)))
    return Route(waypoints=tuple((float(p[0]), float(p[1])) for p in pulled), length=length)


def _enclosed(target: SceneObject, objects: list[SceneObject], r: np.ndarray, cells: np.ndarray) -> str:
    """Why nothing near ``target`` is reachable: the objects whose discs close the ring around it."""
    ti = objects.index(target)
    ring = np.abs(footprint_distance(target, cells) - r[ti]) <= 2 * CELL
    around = []
    for i, obj in enumerate(objects):
        if i != ti and (footprint_distance(obj, cells[ring]) < r[i]).any():
            around.append(obj.name)
    width = 2 * float(r.max())
    if not around:
        return (f"walk_to: the {target.name} cannot be reached from where the robot stands: no path keeps the body "
                f"{ROUTE_MARGIN:g} m clear of the objects (it needs a passage {width:.2f} m wide)")
    names = ", ".join(f"the {n}" for n in around[:-1]) + (" and " if len(around) > 1 else "") + f"the {around[-1]}"
    return (f"walk_to: the {target.name} is enclosed by {names}: no passage to it is wide enough for the robot "
            f"({width:.2f} m, its body {ROUTE_MARGIN:g} m clear of them); move one of them in the scene")


__all__ = [
    "CELL",
    "ROUTE_MARGIN",
    "Route",
    "body_radius",
    "clearance_radius",
    "footprint_distance",
    "plan_route",
    "segment_clear",
]
