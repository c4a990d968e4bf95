"""The robot's collision meshes placed at a configuration, for tests that check a posture against
the floor or an object on the URDF's own triangles (Pinocchio forward kinematics, no wbmp code)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin


def collision_meshes(robot, q) -> list[tuple[int, np.ndarray]]:
    """(parent joint, world vertices (n, 3)) of every collision mesh of ``robot`` at ``q``."""
    model, data = robot.model, robot.model.createData()
    cdata = robot.collision_model.createData()
    pin.framesForwardKinematics(model, data, q)
    pin.updateGeometryPlacements(model, data, robot.collision_model, cdata, q)
    return [(g.parentJoint, np.asarray(g.geometry.vertices(), dtype=float).reshape(-1, 3) @ cdata.oMg[i].rotation.T
             + cdata.oMg[i].translation)
            for i, g in enumerate(robot.collision_model.geometryObjects) if hasattr(g.geometry, "num_vertices")]
