"""Where a robot's body parts are, from its collision meshes, for the arm and hand motions.

Motions that bring a hand *to* the body (touch, hands on hips, cross the arms, clap, salute)
must stop the hand short of the body: once the planner avoids self-collision with a margin of
1 cm, a target inside that margin is infeasible. :func:`body_map` measures, once per robot at
its standing posture and with Pinocchio/coal numerics on the URDF collision geometry:

- each *part*'s axis-aligned box in the heading frame (x forward, y left, z up, origin on the
  ground between the feet): the head (geometry of the head frame's link), the torso/chest (the
  torso frame's link), the hips (every geometry that is neither arm nor leg-below-the-hip and
  crosses the base frame's height), each knee (the leg joint halfway between the hip and the
  sole, and the front of the leg geometry at that height), each toe tip (front edge of the sole);
- each hand's extent around its frame (the geometry of the hand frame's joint and its subtree,
  at the standing orientation).

A hand target for "touch part P from direction u" puts the hand frame at ``surface + extent of
the hand back towards the body + GAP`` along ``u``: with the hand at its standing orientation,
``GAP`` (2 cm) is the clearance between the hand's geometry and the part's box. Boxes are
axis-aligned, so they contain the meshes and the real clearance is at least that.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import coal  # type: ignore[import-untyped]
import numpy as np
import pinocchio as pin

from robots.model import Robot
from tasks.primitives.geometry import standing_geometry

GAP = 0.02  # [m] hand-to-body clearance of body-touching targets (>= the planner's 1 cm self-collision margin)
SLAB = 0.05  # [m] half-height of the horizontal slab in which the hip and knee extents are measured


@dataclass(frozen=True, eq=False)
class Box:
    """An axis-aligned box in the heading frame [m]."""

    lo: np.ndarray
    hi: np.ndarray

    @property
    def center(self) -> np.ndarray:
        """Centre (3,) [m]."""
        return 0.5 * (self.lo + self.hi)


@dataclass(frozen=True, eq=False)
class BodyMap:
    """Body parts of a robot standing at ``q_standing``, in the heading frame [m].

    Attributes:
        robot: Robot name.
        head: Box of the head geometry (None if the robot has no head frame or no geometry on it).
        torso: Box of the torso frame's geometry (None if absent).
        hip_half_width: Side -> lateral extent of the body at the base frame's height [m] (> 0 left, < 0 right).
        hip_height: Height of the base frame [m].
        knee: Side -> knee joint position (3,).
        knee_front: Side -> front (x) of that leg's geometry at knee height.
        toe: Side -> middle of the front edge of the sole (3,).
        hip_pivot: Mean position of the first leg joints (3,): the point the torso bends about.
        hand_lo, hand_hi: Side -> extent of the hand geometry around the hand frame (3,), standing orientation.
        boxes: Heading-frame box of every collision geometry at the standing posture.
        placements: Standing world placement of every collision geometry.
        hand_geometries, arm_geometries: Side -> indices of the hand's / the whole arm's geometries.
        hand_position: Side -> standing hand frame position in the heading frame (3,).
    """

    robot: str
    head: Box | None
    torso: Box | None
    hip_half_width: dict[str, float]
    hip_height: float
    knee: dict[str, np.ndarray]
    knee_front: dict[str, float]
    toe: dict[str, np.ndarray]
    hip_pivot: np.ndarray
    hand_lo: dict[str, np.ndarray]
    hand_hi: dict[str, np.ndarray]
    boxes: tuple[Box, ...]
    placements: tuple[pin.SE3, ...]
    hand_geometries: dict[str, tuple[int, ...]]
    arm_geometries: dict[str, tuple[int, ...]]
    hand_position: dict[str, np.ndarray]

    def hand_back(self, side: str, u: np.ndarray) -> float:
        """How far the ``side`` hand's geometry reaches from its frame against direction ``u`` [m]."""
        corners = _corners(self.hand_lo[side], self.hand_hi[side])
        return float(max(0.0, -(corners @ np.asarray(u, dtype=float)).min()))

    def beside(self, side: str, surface: float, u: np.ndarray) -> float:
        """Coordinate along unit axis ``u`` of a hand frame that stops ``GAP`` short of a surface at ``surface``."""
        return surface + self.hand_back(side, u) + GAP


def _corners(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    return np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])


def to_standing(robot: Robot, point_in_heading) -> np.ndarray:
    """A heading-frame point (3,) in the standing world frame [m]."""
    return standing_geometry(robot).heading.act(np.asarray(point_in_heading, dtype=float))


def to_heading(robot: Robot, point_in_standing) -> np.ndarray:
    """A standing-world point (3,) in the heading frame [m]."""
    return standing_geometry(robot).heading.actInv(np.asarray(point_in_standing, dtype=float))


def _joint_chain(robot: Robot, role: str) -> list[int]:
    joint = robot.model.frames[robot.frame_id(role)].parentJoint
    return list(robot.model.supports[joint])


@functools.cache
def body_map(robot: Robot) -> BodyMap:
    """The body parts of ``robot`` (cached per robot object)."""
    model, data = robot.model, robot.data()
    cm = robot.collision_model
    gdata = pin.GeometryData(cm)
    pin.framesForwardKinematics(model, data, robot.q_standing)
    pin.updateGeometryPlacements(model, data, cm, gdata, robot.q_standing)
    heading = standing_geometry(robot).heading

    boxes = []
    for i, go in enumerate(cm.geometryObjects):
        geom = go.geometry
        geom.computeLocalAABB()
        a = geom.aabb_local
        M = gdata.oMg[i]
        world = _corners(np.array(a.min_), np.array(a.max_)) @ M.rotation.T + M.translation
        local = (world - heading.translation) @ heading.rotation
        boxes.append((go, Box(local.min(axis=0), local.max(axis=0))))

    trunk_role = "torso" if robot.has_role("torso") else "base"
    trunk = set(_joint_chain(robot, trunk_role))
    arm_joints: set[int] = set()
    for side in ("left", "right"):
        arm_joints |= set(_joint_chain(robot, f"{side}_hand")) - trunk
    base_joints = set(_joint_chain(robot, "base"))
    leg_joints = {side: [j for j in _joint_chain(robot, f"{side}_foot") if j not in base_joints] for side in ("left", "right")}

    def frame_box(role: str) -> Box | None:
        if not robot.has_role(role):
            return None
        fid = robot.frame_id(role)
        own = [b for go, b in boxes if go.parentFrame == fid]
        return _union(own) if own else None

    hip_height = float(to_heading(robot, standing_geometry(robot).position("base"))[2])
    body = [b for go, b in boxes if go.parentJoint not in arm_joints]
    slab = [b for b in body if b.lo[2] <= hip_height + SLAB and b.hi[2] >= hip_height - SLAB]
    hip = {"left": max(float(b.hi[1]) for b in slab), "right": min(float(b.lo[1]) for b in slab)}

    knee, knee_front, toe = {}, {}, {}
    for side in ("left", "right"):
        chain = leg_joints[side]
        sole = to_heading(robot, robot.sole_corners_in_world(robot.q_standing, side).mean(axis=0))
        top = to_heading(robot, data.oMi[chain[0]].translation)
        middle = 0.5 * (top[2] + sole[2])
        j_knee = min(chain, key=lambda j: abs(float(to_heading(robot, data.oMi[j].translation)[2]) - middle))
        knee[side] = to_heading(robot, data.oMi[j_knee].translation)
        leg = [b for go, b in boxes if go.parentJoint in chain and b.lo[2] <= knee[side][2] + SLAB and b.hi[2] >= knee[side][2] - SLAB]
        knee_front[side] = max((float(b.hi[0]) for b in leg), default=float(knee[side][0]))
        corners = np.array([to_heading(robot, c) for c in robot.sole_corners_in_world(robot.q_standing, side)])
        toe[side] = np.array([corners[:, 0].max(), corners[:, 1].mean(), 0.0])
    pivot = np.mean([to_heading(robot, data.oMi[leg_joints[s][0]].translation) for s in ("left", "right")], axis=0)

    hand_lo, hand_hi, hand_geoms, arm_geoms, hand_pos = {}, {}, {}, {}, {}
    for side in ("left", "right"):
        fid = robot.frame_id(f"{side}_hand")
        joint = model.frames[fid].parentJoint
        subtree = set(model.subtrees[joint])
        hand = [b for go, b in boxes if go.parentJoint in subtree]
        hand_geoms[side] = tuple(i for i, (go, _) in enumerate(boxes) if go.parentJoint in subtree)
        arm = set(_joint_chain(robot, f"{side}_hand")) - trunk
        arm_geoms[side] = tuple(i for i, (go, _) in enumerate(boxes) if go.parentJoint in arm or go.parentJoint in subtree)
        frame = heading.actInv(data.oMf[fid].translation)
        hand_pos[side] = frame
        if hand:
            u = _union(hand)
            hand_lo[side], hand_hi[side] = u.lo - frame, u.hi - frame
        else:
            hand_lo[side], hand_hi[side] = np.zeros(3), np.zeros(3)

    return BodyMap(robot=robot.name, head=frame_box("head"), torso=frame_box("torso"), hip_half_width=hip,
                   hip_height=hip_height, knee=knee, knee_front=knee_front, toe=toe, hip_pivot=pivot,
                   hand_lo=hand_lo, hand_hi=hand_hi, boxes=tuple(b for _, b in boxes),
                   placements=tuple(pin.SE3(gdata.oMg[i]) for i in range(len(boxes))),
                   hand_geometries=hand_geoms, arm_geometries=arm_geoms, hand_position=hand_pos)


NEAR = 0.15  # [m] geometries whose boxes are farther than this from the hand's box are ignored
MAX_APPROACH = 0.12  # [m] a hand moves at most this far towards the body when stopping short
APPROACH_TOLERANCE = 0.002  # [m] stop when the mesh distance is this close to GAP


def mesh_distance(robot: Robot, side: str, point, obstacles: tuple[int, ...]) -> float:
    """Smallest distance [m] from the ``side`` hand's collision meshes, translated (standing
    orientation) so that its frame is at heading-frame ``point``, to the standing meshes of
    ``obstacles`` (coal); ``inf`` when none is within ``NEAR`` of the hand."""
    m = body_map(robot)
    shift = np.asarray(point, dtype=float) - m.hand_position[side]
    heading = standing_geometry(robot).heading
    shift_world = heading.rotation @ shift
    hand = m.hand_geometries[side]
    lo = np.min([m.boxes[i].lo for i in hand], axis=0) + shift
    hi = np.max([m.boxes[i].hi for i in hand], axis=0) + shift
    objs = robot.collision_model.geometryObjects
    best = np.inf
    for j in obstacles:
        b = m.boxes[j]
        if np.any(b.lo > hi + NEAR) or np.any(b.hi < lo - NEAR):
            continue
        tj = coal.Transform3s(m.placements[j].rotation, m.placements[j].translation)
        for i in hand:
            ti = coal.Transform3s(m.placements[i].rotation, m.placements[i].translation + shift_world)
            best = min(best, coal.distance(objs[i].geometry, ti, objs[j].geometry, tj, coal.DistanceRequest(), coal.DistanceResult()))
    return float(best)


def hands_distance(robot: Robot, left_point, right_point) -> float:
    """Smallest distance [m] between the two hands' meshes (standing orientation), their frames
    translated to heading-frame points (coal)."""
    m = body_map(robot)
    heading = standing_geometry(robot).heading
    objs = robot.collision_model.geometryObjects
    shifts = {s: heading.rotation @ (np.asarray(p, dtype=float) - m.hand_position[s])
              for s, p in (("left", left_point), ("right", right_point))}
    best = np.inf
    for i in m.hand_geometries["left"]:
        ti = coal.Transform3s(m.placements[i].rotation, m.placements[i].translation + shifts["left"])
        for j in m.hand_geometries["right"]:
            tj = coal.Transform3s(m.placements[j].rotation, m.placements[j].translation + shifts["right"])
            best = min(best, coal.distance(objs[i].geometry, ti, objs[j].geometry, tj, coal.DistanceRequest(), coal.DistanceResult()))
    return float(best)


@functools.cache
def _hands_meet_cached(robot: Robot, left: tuple, right: tuple) -> tuple:
    pl, pr = np.array(left), np.array(right)
    inward = (pr - pl) / np.linalg.norm(pr - pl)  # from the left hand towards the right one
    for _ in range(12):
        d = hands_distance(robot, pl, pr)
        step = 0.5 * (d - GAP)
        if abs(step) <= 0.5 * APPROACH_TOLERANCE:
            break
        pl, pr = pl + step * inward, pr - step * inward
    return tuple(pl), tuple(pr)


def hands_meet(robot: Robot, left_point, right_point) -> tuple[np.ndarray, np.ndarray]:
    """The two hand points moved symmetrically along the line between them until the hands'
    meshes (standing orientation) are ``GAP`` apart (coal)."""
    pl, pr = _hands_meet_cached(robot, tuple(float(x) for x in left_point), tuple(float(x) for x in right_point))
    return np.array(pl), np.array(pr)


def obstacles_for(robot: Robot, moving: tuple[str, ...]) -> tuple[int, ...]:
    """Every collision geometry except those of the moving arms."""
    m = body_map(robot)
    skip = set().union(*(m.arm_geometries[s] for s in moving))
    return tuple(i for i in range(len(m.boxes)) if i not in skip)


@functools.cache
def _stop_short_cached(robot: Robot, side: str, point: tuple, u: tuple, moving: tuple[str, ...]) -> tuple:
    p, u_ = np.array(point), np.array(u)
    obstacles = obstacles_for(robot, moving)
    travelled = 0.0
    for _ in range(12):
        d = mesh_distance(robot, side, p, obstacles)
        if d < GAP:  # too close (or inside): back off along u
            p = p + (GAP - d + 0.5 * APPROACH_TOLERANCE) * u_
            continue
        step = min(d - GAP, MAX_APPROACH - travelled)
        if not np.isfinite(d) or step <= APPROACH_TOLERANCE:
            break
        p, travelled = p - step * u_, travelled + step
    return tuple(p)


def stop_short(robot: Robot, side: str, point, u, moving: tuple[str, ...]) -> np.ndarray:
    """``point`` moved against unit direction ``u`` until the ``side`` hand's meshes (standing
    orientation) are ``GAP`` from the rest of the body (the ``moving`` arms excluded), measured
    with coal; it never moves closer than that, nor more than ``MAX_APPROACH``; a point closer
    than ``GAP`` is first moved out along ``u``."""
    return np.array(_stop_short_cached(robot, side, tuple(float(x) for x in point), tuple(float(x) for x in u), tuple(moving)))


def _union(boxes: list[Box]) -> Box:
    return Box(np.min([b.lo for b in boxes], axis=0), np.max([b.hi for b in boxes], axis=0))


__all__ = ["GAP", "BodyMap", "Box", "body_map", "hands_distance", "hands_meet", "mesh_distance", "obstacles_for", "stop_short", "to_heading", "to_standing"]
