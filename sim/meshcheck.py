"""The certificate's self-collision line on the robot's own meshes (coal), every link pair.

The self-collision line of :mod:`sim.certify` sees the pairs of the planner's collision model
(MuJoCo's contacts between their convex hulls, confirmed by coal). A pair the model skips
("touching at rest", the SRDF's) is not seen there: G1's torso and upper arm could pass into each
other by a millimetre and the line pass. This line checks **every** pair of links on the URDF
collision meshes with coal, at a sample of the recorded configurations, except

* links on the same joint or at most two joints apart along the chain (they share an axis, or a
  wrist folds one into the other: their meshes meet by construction),
* the pairs of the planner's collision model (``RunRecord.collision_pairs``: MuJoCo sees them at
  every tick and the self-collision line confirms them with coal), and
* pairs whose meshes are closer than :data:`REST_GAP` in the run's first configuration (the
  robot is built that way: such a pair cannot be kept apart from the first instant).

A pair whose meshes intersect (coal on the triangles) while their convex hulls overlap deeper than
the run's ``self_penetration_limit`` (5 mm by default: the self-collision line's own rule, MuJoCo's
hull depth confirmed by coal on the meshes) fails the line, with the two
body parts in words; a shallower intersection is the line's value (G1's torso and upper arm
during a walk or hop), so it shows without failing. Set the limit to 0 for "no pair touches".
"""

from __future__ import annotations

import coal  # type: ignore[import-untyped]
import numpy as np
import pinocchio as pin

from planner import Check, CheckKind
from robots import Robot, body_part
from sim.recording import RunRecord

#: [m] pairs whose meshes are closer than this in the run's first configuration are not checked.
REST_GAP = 0.002
#: [s] the configurations checked are this far apart (and the last one).
SAMPLE_PERIOD = 0.04


#: The pairs kept by robot, first configuration and known pairs (a run usually starts standing).
_REST: dict[tuple, list[tuple[int, int]]] = {}


def _adjacent(model: pin.Model, ja: int, jb: int) -> bool:
    """Links on the same joint or at most two joints apart along the chain (a wrist's two joints
    fold the hand's meshes into the forearm's by construction: talos's forearm and wrist
    sensor overlap 7 mm at most wrist angles, as the SRDFs' disabled pairs say)."""
    if ja == jb or model.parents[ja] == jb or model.parents[jb] == ja:
        return True
    return model.parents[model.parents[ja]] == jb or model.parents[model.parents[jb]] == ja


def _all_pairs(robot: Robot) -> tuple[pin.GeometryModel, tuple[tuple[int, int], ...]]:
    """The collision meshes and every pair of geometries on links that are not adjacent."""
    gmodel = robot.collision_model.copy()
    gmodel.removeAllCollisionPairs()
    objs = gmodel.geometryObjects
    pairs = tuple((i, j) for i in range(len(objs)) for j in range(i + 1, len(objs))
                  if not _adjacent(robot.model, int(objs[i].parentJoint), int(objs[j].parentJoint)))
    return gmodel, pairs


class MeshPairs:
    """The pairs of ``robot``'s meshes to check from configuration ``q0``, and their collisions.

    Args:
        robot: The robot (its ``collision_model``: the URDF collision geometry).
        q0: The first configuration (nq,): pairs closer than :data:`REST_GAP` there are left out.
        known: Link pairs checked elsewhere (left out).
    """

    def __init__(self, robot: Robot, q0: np.ndarray, known: tuple[tuple[str, str], ...] = ()) -> None:
        self.robot = robot
        base, candidates = _all_pairs(robot)
        self.gmodel = base.copy()
        frames = robot.model.frames
        links = [frames[o.parentFrame].name for o in self.gmodel.geometryObjects]
        skip = {tuple(sorted(p)) for p in known}
        for i, j in candidates:
            if tuple(sorted((links[i], links[j]))) not in skip:
                self.gmodel.addCollisionPair(pin.CollisionPair(i, j))
        self.data = robot.model.createData()
        self.gdata = self.gmodel.createData()
        key = (robot.name, len(links), np.asarray(q0, dtype=float).tobytes(), frozenset(skip))
        keep = _REST.get(key)
        if keep is None:
            pin.updateGeometryPlacements(robot.model, self.data, self.gmodel, self.gdata, q0)
            keep = []
            for k, cp in enumerate(self.gmodel.collisionPairs):
                if pin.computeCollision(self.gmodel, self.gdata, k):
                    continue
                if pin.computeDistance(self.gmodel, self.gdata, k).min_distance < REST_GAP:
                    continue
                keep.append((cp.first, cp.second))
            if len(_REST) > 16:
                _REST.clear()
            _REST[key] = keep
        self.gmodel.removeAllCollisionPairs()
        for i, j in keep:
            self.gmodel.addCollisionPair(pin.CollisionPair(i, j))
        self.gdata = self.gmodel.createData()
        self._hulls: dict[int, object] = {}
        self.links = links

    @property
    def n_pairs(self) -> int:
        """Geometry pairs checked."""
        return len(self.gmodel.collisionPairs)

    def _hull(self, i: int):
        """The convex hull of geometry ``i`` (a primitive is its own)."""
        hull = self._hulls.get(i)
        if hull is None:
            geom = self.gmodel.geometryObjects[i].geometry
            if hasattr(geom, "buildConvexRepresentation"):
                geom.buildConvexRepresentation(False)
                hull = geom.convex
            else:
                hull = geom
            self._hulls[i] = hull
        return hull

    def _hull_depth(self, i: int, j: int) -> float:
        """Penetration depth [m] of the convex hulls of geometries ``i`` and ``j`` as placed now
        (coal's GJK/EPA: exact for convex shapes; the measure MuJoCo's contacts give the
        self-collision line)."""
        a, b = self.gdata.oMg[i], self.gdata.oMg[j]
        request, result = coal.CollisionRequest(), coal.CollisionResult()
        request.enable_contact = True
        if not coal.collide(self._hull(i), coal.Transform3s(a.rotation, a.translation), self._hull(j),
                            coal.Transform3s(b.rotation, b.translation), request, result):
            return 0.0
        return abs(float(result.getContact(0).penetration_depth))

    def colliding(self, q: np.ndarray) -> dict[tuple[str, str], float]:
        """The link pairs whose meshes intersect at ``q`` (nq,), with the depth of their convex
        hulls there [m] (the meshes themselves have no penetration depth in coal)."""
        pin.computeCollisions(self.robot.model, self.data, self.gmodel, self.gdata, q, False)
        out: dict[tuple[str, str], float] = {}
        for k, cp in enumerate(self.gmodel.collisionPairs):
            if self.gdata.collisionResults[k].isCollision():
                pair = (self.links[cp.first], self.links[cp.second])
                out[pair] = max(out.get(pair, 0.0), self._hull_depth(cp.first, cp.second))
        return out


def mesh_self_collision_check(run: RunRecord, period: float = SAMPLE_PERIOD) -> Check:
    """No two links' URDF meshes pass into each other deeper than the run's
    ``self_penetration_limit`` (the limit of the self-collision line) at any sampled configuration
    (coal), for the pairs the collision model does not check (see the module docstring). The value
    is the deepest intersection [mm] (negative), or 0 when no pair intersects."""
    ts = run.t
    name = "self-collision on the meshes"
    limit = run.settings.self_penetration_limit
    if not len(ts) or not len(run.robot.collision_model.geometryObjects):
        return Check(name=f"{name}: no meshes", kind=CheckKind.SELF_COLLISION_MESH, value=0.0, limit=-1000 * limit,
                     unit="mm", ok=True, time=0.0, upper=False)
    pairs = MeshPairs(run.robot, run.q[0], run.collision_pairs)
    step = max(1, int(round(period / max(float(np.median(np.diff(ts))) if len(ts) > 1 else period, 1e-9))))
    ticks = list(range(0, len(ts), step))
    if ticks[-1] != len(ts) - 1:
        ticks.append(len(ts) - 1)
    hits: list[tuple[int, tuple[str, str], float]] = []  # tick, link pair, depth [m]
    for n in ticks:
        hits += [(n, pair, depth) for pair, depth in pairs.colliding(run.q[n]).items()]
    if not hits:
        return Check(name=f"{name}: {pairs.n_pairs} more pairs apart", kind=CheckKind.SELF_COLLISION_MESH, value=0.0,
                     limit=-1000 * limit, unit="mm", ok=True, time=0.0, upper=False)
    deep = [h for h in hits if h[2] > limit]
    n, (a, b), depth = deep[0] if deep else max(hits, key=lambda h: h[2])
    depth = max(h[2] for h in hits if h[1] == (a, b))
    samples = len({k for k, p, _ in hits if p == (a, b)})
    others = len({p for _, p, _ in (deep or hits)}) - 1
    pa, pb = body_part(run.robot, a), body_part(run.robot, b)
    more = f"; {others} other pair(s)" if others else ""
    return Check(
        name=f"{name}: {pa} / {pb}", kind=CheckKind.SELF_COLLISION_MESH, subject=f"{pa} / {pb}",
        value=-1000 * depth, limit=-1000 * limit, unit="mm", ok=not deep, time=float(ts[n]), upper=False,
        message=f"the {pa} passed into the {pb} at t = {ts[n]:.2f} s on the robot's meshes, {1000 * depth:.1f} mm "
        f"deep (> {1000 * limit:.0f} mm; {a} / {b}, coal; {samples} of {len(ticks)} sampled configurations{more}): "
        "the robot collides with itself" if deep else "",
    )
