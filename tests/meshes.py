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


def placed_sole_corners(robot, contact) -> np.ndarray:
    """The four corners (4, 3) [m] of the profile's sole rectangle of ``contact``'s foot, at the
    contact's placement (its position and roll, pitch, yaw), by hand from the profile."""
    sole = robot.profile.sole
    side = robot.foot_side(robot.model.frames[robot.frame_id(contact.frame)].name)
    ys = (sole.y_min, sole.y_max) if side == "left" else (-sole.y_max, -sole.y_min)
    local = np.array([[x, y, 0.0] for x in (sole.x_min, sole.x_max) for y in ys])
    R = pin.rpy.rpyToMatrix(*contact.placement.rpy)
    return np.asarray(contact.placement.position) + local @ R.T


def region_phase(spec) -> tuple[float, object]:
    """(start time [s], phase) of the spec's first phase with a region contact (a knee, a hand, a thigh)."""
    i, phase = next((i, ph) for i, ph in enumerate(spec.phases) if any(c.region for c in ph.contacts))
    return sum(ph.duration for ph in spec.phases[:i]), phase
