"""The certificate's self-collision line on the robot's own meshes (coal), every link pair.

The self-collision line of :mod:`sim.certify` sees the pairs of the planner's collision model
(MuJoCo's contacts between their convex hulls, confirmed by coal). A pair the model skips
("touching at rest", the SRDF's) is not seen there: G1's torso and upper arm could pass into each
other by a millimetre and the line pass. This line checks **every** pair of links on the URDF
collision meshes with coal, at a sample of the recorded configurations, except

* links on the same joint or on a joint and its parent joint (they share an axis: their meshes
  meet by construction),
* the pairs of the planner's collision model (``RunRecord.collision_pairs``: MuJoCo sees them at
  every tick and the self-collision line confirms them with coal), and
* pairs whose meshes are closer than :data:`REST_GAP` in the run's first configuration (the
  robot is built that way: such a pair cannot be kept apart from the first instant).

A pair whose meshes intersect at a sample fails the line, with the two body parts in words.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from planner.results import Check, CheckKind
from robots.collision import body_part
from robots.model import Robot
from sim.recording import RunRecord

#: [m] pairs whose meshes are closer than this in the run's first configuration are not checked.
REST_GAP = 0.002
#: [s] the configurations checked are this far apart (and the last one).
SAMPLE_PERIOD = 0.04


#: The pairs kept by robot, first configuration and known pairs (a run usually starts standing).
_REST: dict[tuple, list[tuple[int, int]]] = {}


def _adjacent(model: pin.Model, ja: int, jb: int) -> bool:
    return ja == jb or model.parents[ja] == jb or model.parents[jb] == ja


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
        self.links = links

    @property
    def n_pairs(self) -> int:
        """Geometry pairs checked."""
        return len(self.gmodel.collisionPairs)

    def colliding(self, q: np.ndarray) -> list[tuple[str, str]]:
        """The link pairs whose meshes intersect at ``q`` (nq,)."""
        pin.computeCollisions(self.robot.model, self.data, self.gmodel, self.gdata, q, False)
        out = []
        for k, cp in enumerate(self.gmodel.collisionPairs):
            if self.gdata.collisionResults[k].isCollision():
                out.append((self.links[cp.first], self.links[cp.second]))
        return list(dict.fromkeys(out))


def mesh_self_collision_check(run: RunRecord, period: float = SAMPLE_PERIOD) -> Check:
    """No two links' URDF meshes intersect at any sampled configuration of the run (coal), for the
    pairs the collision model does not check (see the module docstring)."""
    ts = run.t
    name = "self-collision on the meshes"
    if not len(ts) or not len(run.robot.collision_model.geometryObjects):
        return Check(name=f"{name}: no meshes", kind=CheckKind.SELF_COLLISION_MESH, value=0.0, limit=0.0,
                     unit="count", ok=True, time=0.0)
    pairs = MeshPairs(run.robot, run.q[0], run.collision_pairs)
    step = max(1, int(round(period / max(float(np.median(np.diff(ts))) if len(ts) > 1 else period, 1e-9))))
    ticks = list(range(0, len(ts), step))
    if ticks[-1] != len(ts) - 1:
        ticks.append(len(ts) - 1)
    hits: list[tuple[int, tuple[str, str]]] = []
    for n in ticks:
        hits += [(n, p) for p in pairs.colliding(run.q[n])]
    if not hits:
        return Check(name=f"{name}: {pairs.n_pairs} more pairs apart", kind=CheckKind.SELF_COLLISION_MESH, value=0.0,
                     limit=0.0, unit="count", ok=True, time=0.0)
    n, (a, b) = hits[0]
    parts = sorted({p for _, p in hits})
    samples = len({k for k, _ in hits})
    pa, pb = body_part(run.robot, a), body_part(run.robot, b)
    more = f" and {len(parts) - 1} other pair(s)" if len(parts) > 1 else ""
    return Check(
        name=f"{name}: {pa} / {pb}", kind=CheckKind.SELF_COLLISION_MESH, subject=f"{pa} / {pb}",
        value=float(samples), limit=0.0, unit="count", ok=False, time=float(ts[n]),
        message=f"the {pa} passed into the {pb} at t = {ts[n]:.2f} s on the robot's meshes ({a} / {b}, coal; "
        f"{samples} of {len(ticks)} sampled configurations{more}): the robot collides with itself",
    )
