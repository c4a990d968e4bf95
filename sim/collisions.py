"""Distances between the robot's URDF collision meshes (coal), independent of MuJoCo and of the
planner's collision model: the reference the certificate's self-collision line confirms against.

MuJoCo collides meshes as their convex hulls, which are larger than the meshes; coal
(``hpp-fcl``, through Pinocchio's geometry functions) works on the triangles themselves. Coal gives the distance between two meshes that
do not touch, and whether they intersect, but no penetration depth between two non-convex
meshes: the depth comes from MuJoCo's contacts, the confirmation from coal.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from robots import Robot


class MeshDistance:
    """Coal distances between the collision meshes of two links of ``robot``.

    Args:
        robot: The robot; its ``collision_model`` holds the URDF collision geometry.
    """

    def __init__(self, robot: Robot) -> None:
        self.robot = robot
        self._gmodel = robot.collision_model.copy()
        n = len(self._gmodel.geometryObjects)
        for i in range(n):  # every pair, also of geometries on the same joint
            for j in range(i + 1, n):
                self._gmodel.addCollisionPair(pin.CollisionPair(i, j))
        self._gdata = self._gmodel.createData()
        self._data = robot.model.createData()
        self._by_link: dict[str, list[int]] = {}
        frames = robot.model.frames
        for i, obj in enumerate(self._gmodel.geometryObjects):
            self._by_link.setdefault(frames[obj.parentFrame].name, []).append(i)
        self._q: np.ndarray | None = None

    def links(self) -> list[str]:
        """Links with collision geometry."""
        return sorted(self._by_link)

    def _place(self, q: np.ndarray) -> None:
        if self._q is None or not np.array_equal(self._q, q):
            pin.updateGeometryPlacements(self.robot.model, self._data, self._gmodel, self._gdata, q)
            self._q = np.array(q)

    def between(self, q: np.ndarray, a: str, b: str) -> float:
        """Smallest distance [m] between the meshes of links ``a`` and ``b`` at ``q`` (nq,); 0
        when they intersect; inf when a link has no collision geometry."""
        self._place(q)
        best = np.inf
        for i in self._by_link.get(a, ()):
            for j in self._by_link.get(b, ()):
                k = self._gmodel.findCollisionPair(pin.CollisionPair(min(i, j), max(i, j)))
                if pin.computeCollision(self._gmodel, self._gdata, k):
                    return 0.0
                dist = pin.computeDistance(self._gmodel, self._gdata, k).min_distance
                best = min(best, max(float(dist), 0.0))
        return best

    def to_shape(self, q: np.ndarray, links, shape, placement: pin.SE3) -> float:
        """Smallest distance [m] from the meshes of ``links`` at ``q`` to a coal ``shape`` (a scene
        object's box, cylinder or sphere) at world ``placement``; 0 when they intersect."""
        import coal  # type: ignore[import-untyped]

        self._place(q)
        at = coal.Transform3s(placement.rotation, placement.translation)
        best = np.inf
        for link in links:
            for i in self._by_link.get(link, ()):
                M = self._gdata.oMg[i]
                dist = coal.distance(self._gmodel.geometryObjects[i].geometry, coal.Transform3s(M.rotation, M.translation),
                                     shape, at, coal.DistanceRequest(), coal.DistanceResult())
                best = min(best, max(float(dist), 0.0))
        return best


def object_shape(shape: str, size) -> object:
    """The coal shape of a scene object (box: sides; cylinder: radius, length along its z; sphere:
    radius), None for a mesh."""
    import coal

    size = [float(v) for v in size]
    return {"box": lambda: coal.Box(*size), "cylinder": lambda: coal.Cylinder(*size),
            "sphere": lambda: coal.Sphere(*size)}.get(shape, lambda: None)()
