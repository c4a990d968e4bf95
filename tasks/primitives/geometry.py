"""What the primitives need to know about a robot standing still, computed once with Pinocchio.

Every primitive states its targets relative to the robot at its standing posture
(``robot.q_standing``): the standing centre of mass, the standing placement of the hands,
shoulders, head and torso, the arm length, the support polygon. :func:`standing_geometry`
computes these numbers once per robot (cached) in the *standing world frame*: soles flat on
z = 0, feet centred on x = y = 0. A :class:`Stance` maps that frame to where the robot stands
now (identity until the robot has stepped or turned).

The *heading frame* is the robot's own frame on the ground: origin between the feet, x axis
forward (the soles' mean x axis), y axis to the left, z axis up. Directions such as
``forward`` or ``left`` are taken in it. The *base frame* of ``reach`` targets has the heading
frame's axes and the base link's standing position as origin (some robots, e.g. iCub, have a
base link whose own x axis points backwards; the heading frame does not depend on that).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from robots import Robot, convex_hull, polygon_margin, support_polygon
from tasks.exceptions import TaskDefinitionError
from tasks.specs import Pose

SIDE_SIGN = {"left": 1.0, "right": -1.0}  # y direction of a side in the heading frame
SUPPORT_MARGIN_MAX = 0.02  # [m] default inward margin of the support polygon
SUPPORT_MARGIN_FRACTION = 0.25  # margin at most this fraction of the sole's narrower side


@dataclass(frozen=True, eq=False)
class StandingGeometry:
    """Numbers of a robot at ``q_standing``, in the standing world frame (read-only arrays).

    Attributes:
        robot: Robot name.
        com: Centre of mass (3,) [m].
        placements: Role -> frame placement (pin.SE3) for every role the robot has.
        arm_length: Side -> length of the kinematic chain from the shoulder joint to the hand
            frame [m] (sum of the link lengths: an upper bound of the reach).
        heading: The heading frame (pin.SE3): origin between the soles, yaw of the soles.
        sole_centers: Side -> centre of the sole rectangle in the world (3,) [m].
        support_polygon: Counter-clockwise convex hull of both soles in the world (n, 2) [m].
        support_margin: Inward margin of the support polygon used by the primitives [m].
        neck_joints: Joint ids between the torso (or base) and the head frame; empty when the
            head is rigidly attached (no neck).
    """

    robot: str
    com: np.ndarray
    placements: dict[str, pin.SE3]
    arm_length: dict[str, float]
    heading: pin.SE3
    sole_centers: dict[str, np.ndarray]
    support_polygon: np.ndarray
    support_margin: float
    neck_joints: tuple[int, ...]

    def position(self, role: str) -> np.ndarray:
        """Standing position of a role's frame (3,) [m]."""
        return self.placements[role].translation.copy()

    def rotation(self, role: str) -> np.ndarray:
        """Standing orientation of a role's frame (3, 3)."""
        return self.placements[role].rotation.copy()

    def heading_axis(self, direction: str) -> np.ndarray:
        """Unit vector (3,) in the world of a direction word of the heading frame."""
        local = {
            "forward": (1.0, 0.0, 0.0),
            "backward": (-1.0, 0.0, 0.0),
            "left": (0.0, 1.0, 0.0),
            "right": (0.0, -1.0, 0.0),
            "up": (0.0, 0.0, 1.0),
            "down": (0.0, 0.0, -1.0),
        }[direction]
        return self.heading.rotation @ np.array(local)

    def max_com_shift(self, direction_in_world: np.ndarray) -> float:
        """Largest shift of the standing CoM along a horizontal unit vector that keeps its
        ground projection in the support polygon shrunk by ``support_margin`` [m]."""
        return ray_exit_distance(self.support_polygon, self.com[:2], direction_in_world[:2], self.support_margin)


@dataclass(frozen=True, slots=True, kw_only=True)
class Stance:
    """Where the robot stands: the placements of both soles.

    ``Stance.standing(robot)`` is the standing posture (feet centred on x = y = 0). Targets
    computed in the standing world frame are carried to this stance by
    :meth:`transform_from_standing`, the rigid motion of the heading frame.
    """

    left: Pose
    right: Pose

    @classmethod
    def standing(cls, robot: Robot) -> Stance:
        """The stance of the standing posture."""
        g = standing_geometry(robot)
        return cls(left=_pose(g.placements["left_foot"]), right=_pose(g.placements["right_foot"]))

    @classmethod
    def at(cls, robot: Robot, q) -> Stance:
        """The stance of the configuration ``q`` (nq): where its soles are (a motion's start state)."""
        data = robot.data()
        pin.framesForwardKinematics(robot.model, data, np.asarray(q, dtype=float))
        return cls(left=_pose(data.oMf[robot.frame_id("left_foot")]),
                   right=_pose(data.oMf[robot.frame_id("right_foot")]))

    def sole(self, side: str) -> Pose:
        """Placement of the ``side`` ('left'/'right') sole frame."""
        return self.left if side == "left" else self.right

    def heading(self) -> pin.SE3:
        """The heading frame of this stance."""
        return heading_frame(_se3(self.left), _se3(self.right))

    def transform_from_standing(self, robot: Robot) -> pin.SE3:
        """Rigid motion that carries the standing world frame onto this stance."""
        return self.heading() * standing_geometry(robot).heading.inverse()


def _se3(pose: Pose) -> pin.SE3:
    return pin.SE3(pin.rpy.rpyToMatrix(*pose.rpy), np.array(pose.position))


def _pose(m: pin.SE3) -> Pose:
    return Pose(position=_clean(m.translation), rpy=_clean(pin.rpy.matrixToRpy(m.rotation)))


def _clean(v) -> tuple[float, float, float]:
    """A 3-tuple of Python floats, with round-off below 1e-12 set to zero (readable JSON)."""
    return tuple(0.0 if abs(float(x)) < 1e-12 else float(x) for x in v)  # type: ignore[return-value]


def heading_frame(left: pin.SE3, right: pin.SE3) -> pin.SE3:
    """Frame between two sole placements: mean position on the ground, mean yaw, z up."""
    yaws = [math.atan2(m.rotation[1, 0], m.rotation[0, 0]) for m in (left, right)]
    yaw = math.atan2(sum(math.sin(y) for y in yaws), sum(math.cos(y) for y in yaws))
    mid = 0.5 * (left.translation + right.translation)
    return pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, yaw), np.array([mid[0], mid[1], 0.5 * (left.translation[2] + right.translation[2])]))


def ray_exit_distance(polygon: np.ndarray, start: np.ndarray, direction: np.ndarray, margin: float) -> float:
    """Distance along a unit 2D ``direction`` from ``start`` to the boundary of a
    counter-clockwise convex ``polygon`` shrunk by ``margin`` (negative if ``start`` is outside)."""
    d = np.asarray(direction, dtype=float)
    d = d / np.linalg.norm(d)
    best = math.inf
    n = len(polygon)
    for i in range(n):
        a, b = polygon[i], polygon[(i + 1) % n]
        edge = b - a
        normal = np.array([edge[1], -edge[0]]) / np.linalg.norm(edge)  # outward for CCW
        slack = float(normal @ a) - margin - float(normal @ start)  # >= 0 inside
        rate = float(normal @ d)
        if rate > 1e-12:
            best = min(best, slack / rate)
        elif slack < 0:
            return slack
    return best


def inside_polygon_margin(polygon: np.ndarray, point: np.ndarray) -> float:
    """Signed distance of a 2D point inside a CCW convex polygon (> 0 inside) [m]."""
    return polygon_margin(polygon, point)


def sole_polygon(robot: Robot, q: np.ndarray, side: str) -> np.ndarray:
    """CCW convex polygon (4, 2) of one sole's rectangle projected on the ground at ``q`` [m]."""
    return convex_hull(robot.sole_corners_in_world(q, side)[:, :2])


def _support(robot: Robot, frame_role: str) -> list[int]:
    joint = robot.model.frames[robot.frame_id(frame_role)].parentJoint
    return list(robot.model.supports[joint])


def joint_axis_in_world(robot: Robot, data: pin.Data, joint_id: int) -> np.ndarray | None:
    """World axis (3,) of a revolute joint at the configuration of ``data``; None otherwise."""
    joint = robot.model.joints[joint_id]
    short = joint.shortname()
    local = {"JointModelRX": (1.0, 0.0, 0.0), "JointModelRY": (0.0, 1.0, 0.0), "JointModelRZ": (0.0, 0.0, 1.0)}.get(short)
    if local is None and short == "JointModelRevoluteUnaligned":
        local = tuple(np.asarray(joint.extract().axis, dtype=float))
    if local is None:
        return None
    return data.oMi[joint_id].rotation @ np.array(local)


@functools.cache
def standing_geometry(robot: Robot) -> StandingGeometry:
    """The standing numbers of ``robot`` (cached per robot object)."""
    model, data, q = robot.model, robot.data(), robot.q_standing
    pin.framesForwardKinematics(model, data, q)
    com = np.array(pin.centerOfMass(model, data, q), dtype=float)
    placements = {}
    from robots import ROLES

    for role in ROLES:
        if robot.has_role(role):
            placements[role] = pin.SE3(data.oMf[robot.frame_id(role)])
    arm_length = {}
    for side in ("left", "right"):
        hand_support = _support(robot, f"{side}_hand")
        start_role = f"{side}_shoulder" if robot.has_role(f"{side}_shoulder") else f"{side}_hand"
        shoulder_joint = robot.model.frames[robot.frame_id(start_role)].parentJoint
        chain = hand_support[hand_support.index(shoulder_joint):] if shoulder_joint in hand_support else hand_support[-3:]
        points = [data.oMi[j].translation for j in chain] + [placements[f"{side}_hand"].translation]
        arm_length[side] = float(np.sum(np.linalg.norm(np.diff(np.array(points), axis=0), axis=1)))
    heading = heading_frame(placements["left_foot"], placements["right_foot"])
    sole = robot.profile.sole
    sole_centers = {}
    for side in ("left", "right"):
        corners = robot.sole_corners_in_world(q, side)
        sole_centers[side] = corners.mean(axis=0)
    polygon = support_polygon([robot.sole_corners_in_world(q, s) for s in ("left", "right")])
    margin = min(SUPPORT_MARGIN_MAX, SUPPORT_MARGIN_FRACTION * min(sole.x_max - sole.x_min, sole.y_max - sole.y_min))
    neck: tuple[int, ...] = ()
    if robot.has_role("head"):
        head = _support(robot, "head")
        anchor_role = "torso" if robot.has_role("torso") else "base"
        anchor = set(_support(robot, anchor_role))
        neck = tuple(j for j in head if j not in anchor and j > 1)
    return StandingGeometry(
        robot=robot.name,
        com=com,
        placements=placements,
        arm_length=arm_length,
        heading=heading,
        sole_centers=sole_centers,
        support_polygon=polygon,
        support_margin=float(margin),
        neck_joints=neck,
    )


def neck_range(robot: Robot, axis_in_world: np.ndarray) -> float:
    """Largest rotation of the head about ``axis_in_world`` (positive sense) that the neck
    joints allow from the standing posture [rad]; 0 when the robot has no neck."""
    g = standing_geometry(robot)
    data = robot.data()
    pin.forwardKinematics(robot.model, data, robot.q_standing)
    total = 0.0
    for j in g.neck_joints:
        axis = joint_axis_in_world(robot, data, j)
        if axis is None:
            continue
        c = float(axis @ axis_in_world)
        if abs(c) < 0.5:
            continue
        iq = robot.model.joints[j].idx_q
        q0 = float(robot.q_standing[iq])
        lo, hi = float(robot.model.lowerPositionLimit[iq]), float(robot.model.upperPositionLimit[iq])
        total += abs(c) * ((hi - q0) if c > 0 else (q0 - lo))
    return total


def require_role(robot: Robot, role: str, action: str) -> None:
    """TaskDefinitionError when the robot has no frame for ``role``."""
    if not robot.has_role(role):
        raise TaskDefinitionError(f"{action}: {robot.name} has no '{role}' frame in its profile")
