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
import math
from dataclasses import dataclass

import coal  # type: ignore[import-untyped]
import numpy as np
import pinocchio as pin

from robots import Robot, collision_model, pair_sphere_distance
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
    l0, r0 = pl.copy(), pr.copy()
    for _ in range(CLEAR_ROUNDS):
        d, _ = hands_clearance(robot, arm_configuration(robot, {"left": pl, "right": pr}))
        step = 0.5 * (min(d, 1.0) - CLEARANCE)
        if abs(step) <= 0.5 * APPROACH_TOLERANCE:
            return tuple(pl), tuple(pr)
        pl, pr = pl + step * inward, pr - step * inward
        if np.linalg.norm(pl - l0) > MAX_CLEAR:
            break
    # the arm model does not settle (a posture the arm-only inverse kinematics misses): meshes only
    for _ in range(12):
        d = hands_distance(robot, l0, r0)
        step = 0.5 * (d - GAP)
        if abs(step) <= 0.5 * APPROACH_TOLERANCE:
            break
        l0, r0 = l0 + step * inward, r0 - step * inward
    return tuple(l0), tuple(r0)


def hands_meet(robot: Robot, left_point, right_point) -> tuple[np.ndarray, np.ndarray]:
    """The two hand points moved symmetrically along the line between them until, with the arms
    posed there (:func:`arm_configuration`), the two arms' sphere sets (the planner's model of
    the checked pairs between them) are ``CLEARANCE`` apart; their meshes are then farther."""
    pl, pr = _hands_meet_cached(robot, tuple(float(x) for x in left_point), tuple(float(x) for x in right_point))
    return np.array(pl), np.array(pr)


MEET_GAP = 0.005  # [m] mesh distance of the two hands at a clap's target, the arms posed there (a plan holds it within ~4 mm)
MEET_ROUNDS = 20


def meets_apart(robot: Robot, side: str, role: str) -> bool:
    """Whether the ``role`` frame's part can meet the ``side`` hand as a planned self-contact: it
    has links of its own there (:meth:`robots.Robot.meet_links`: the other hand, a head on its own
    neck joints, or G1's head link, fixed on the torso that carries the arms)."""
    return bool(robot.meet_links(role, f"{side}_hand"))


def meet_geometries(robot: Robot, role: str, other: str) -> tuple[int, ...]:
    """Indices of the collision geometries of the ``role`` frame's part where it meets ``other``
    (:meth:`robots.Robot.meet_links`: a hand's from ``[collisions] meet_joints`` joints up)."""
    model = robot.model
    links = robot.meet_links(role, other)
    return tuple(i for i, go in enumerate(robot.collision_model.geometryObjects)
                 if model.frames[go.parentFrame].name in links)


def posed_hands_distance(robot: Robot, q: np.ndarray, role: str = "right_hand", side: str = "left") -> float:
    """Smallest distance [m] between the ``side`` hand's meshes and those of the ``role`` frame
    (the other hand, the head) at configuration ``q``, each part as the planner leaves it out
    where they meet (:func:`meet_geometries`; coal; 0 when they intersect)."""
    cm = robot.collision_model
    data, gdata = robot.data(), pin.GeometryData(cm)
    pin.framesForwardKinematics(robot.model, data, q)
    pin.updateGeometryPlacements(robot.model, data, cm, gdata, q)
    objs = cm.geometryObjects
    best = np.inf
    hand = f"{side}_hand"
    for i in meet_geometries(robot, hand, role):
        ti = coal.Transform3s(gdata.oMg[i].rotation, gdata.oMg[i].translation)
        for j in meet_geometries(robot, role, hand):
            tj = coal.Transform3s(gdata.oMg[j].rotation, gdata.oMg[j].translation)
            best = min(best, coal.distance(objs[i].geometry, ti, objs[j].geometry, tj, coal.DistanceRequest(), coal.DistanceResult()))
    return float(best)


@functools.cache
def _hands_touch_cached(robot: Robot, left: tuple, right: tuple, gap: float) -> tuple:
    pl, pr = np.array(left), np.array(right)
    inward = (pr - pl) / np.linalg.norm(pr - pl)
    for _ in range(MEET_ROUNDS):
        d = posed_hands_distance(robot, arm_configuration(robot, {"left": pl, "right": pr}, natural=True))
        if not np.isfinite(d):  # a hand without collision meshes: the points as given
            break
        step = 0.5 * (d - gap)
        if abs(step) <= 0.25 * APPROACH_TOLERANCE:
            break
        pl, pr = pl + step * inward, pr - step * inward
    return tuple(pl), tuple(pr)


def hands_touch(robot: Robot, left_point, right_point, gap: float = MEET_GAP) -> tuple[np.ndarray, np.ndarray]:
    """The two hand points moved symmetrically along the line between them until, with the arms
    posed there (:func:`arm_configuration`), the two hands' meshes are ``gap`` apart (coal): a
    clap. The planner leaves the hands' pairs out there (``FrameTarget.meets``)."""
    pl, pr = _hands_touch_cached(robot, tuple(float(x) for x in left_point), tuple(float(x) for x in right_point),
                                 float(gap))
    return np.array(pl), np.array(pr)


@functools.cache
def _approach_cached(robot: Robot, side: str, point: tuple, u: tuple, role: str, gap: float) -> tuple | None:
    """The approached point, or None when the posed hand does not come within ``gap`` of the part
    before moving ``MAX_APPROACH`` (an arm too short for it, icub's for its head; no meshes)."""
    p, u_ = np.array(point), np.array(u)
    start = p.copy()
    for _ in range(MEET_ROUNDS):
        d = posed_hands_distance(robot, arm_configuration(robot, {side: p}, natural=True), role, side)
        if not np.isfinite(d):
            return None
        step = min(d - gap, MAX_APPROACH)
        if abs(step) <= 0.25 * APPROACH_TOLERANCE:
            return tuple(p)
        p = p - 0.7 * step * u_
        if float(np.dot(start - p, u_)) > MAX_APPROACH:
            return None
    return tuple(p)


def approach_posed(robot: Robot, side: str, point, u, role: str, gap: float) -> np.ndarray:
    """``point`` moved along unit direction ``-u`` (towards the body) until, with the ``side`` arm
    posed there (:func:`arm_configuration`, the other arm standing), that hand's meshes are ``gap``
    from the ``role`` frame's (the head's; coal): a salute, a touch. The planner leaves that pair
    out there (``FrameTarget.meets``)."""
    found = _approach_cached(robot, side, tuple(float(x) for x in point), tuple(float(x) for x in u), role, float(gap))
    if found is None:  # the arm does not bring the hand there: the standing hand stopped short, as for any part
        return stop_short(robot, side, point, u, (side,))
    return np.array(found)


def obstacles_for(robot: Robot, moving: tuple[str, ...]) -> tuple[int, ...]:
    """Every collision geometry except those of the moving arms."""
    m = body_map(robot)
    skip = set().union(*(m.arm_geometries[s] for s in moving))
    return tuple(i for i in range(len(m.boxes)) if i not in skip)


@functools.cache
def _stop_short_cached(robot: Robot, side: str, point: tuple, u: tuple, moving: tuple[str, ...], clear: bool) -> tuple:
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
    return tuple(clear_targets(robot, {side: p}, {side: u_})[side]) if clear else tuple(p)


def stop_short(robot: Robot, side: str, point, u, moving: tuple[str, ...], *, clear: bool = True) -> np.ndarray:
    """``point`` moved against unit direction ``u`` until the ``side`` hand's meshes (standing
    orientation) are ``GAP`` from the rest of the body (the ``moving`` arms excluded), measured
    with coal; it never moves closer than that, nor more than ``MAX_APPROACH``; a point closer
    than ``GAP`` is first moved out along ``u``. Then, the planner's sphere model being larger
    than the meshes, moved back out along ``u`` until the arm posed there clears the body by
    ``CLEARANCE`` in that model (:func:`clear_targets`; the other arm standing), unless ``clear``
    is False (a target reached by bending the body, which an arm alone cannot model)."""
    return np.array(_stop_short_cached(robot, side, tuple(float(x) for x in point), tuple(float(x) for x in u),
                                       tuple(moving), clear))


# -- the planner's sphere model ------------------------------------------------------------------
#
# The planner keeps the *sphere sets* of every checked link pair ``PLANNER_MARGIN`` apart
# (robots.collision: spheres cover capsules that enclose the meshes, so they stick out of them,
# by 10 cm in front of Talos's chest). A hand target placed by the meshes alone can therefore be
# unreachable without a collision row failing, for the hand or for the forearm behind it. The
# functions below pose the arms at the targets (position inverse kinematics of the arm joints,
# Pinocchio) and measure the sphere-set distances of the checked pairs that involve a moving arm.

PLANNER_MARGIN = 0.01  # [m] the planner's self-collision margin (PlannerSettings.collision.margin; a test keeps them equal)
SPHERE_GAP = 0.01  # [m] room left beyond the margin between sphere sets at a target (the plan's posture differs from ours)
CLEARANCE = PLANNER_MARGIN + SPHERE_GAP  # [m] sphere-set distance at a body-touching target
ARM_IK_ITERATIONS = 150
ARM_IK_DAMPING = 1e-2
ARM_IK_POSTURE = 1e-4  # pull towards the standing arm posture (picks the elbow of a redundant arm)
ARM_IK_STEP = 0.3  # [rad] largest joint step of an iteration
CLEAR_ROUNDS = 15  # at most this many moves out when clearing a target
CLEAR_STEP_MIN = 0.002  # [m] a move out is at least this long
MAX_CLEAR = 0.15  # [m] a target moved farther than this to clear is left where the meshes put it


@dataclass(frozen=True, eq=False)
class Spheres:
    """The collision model's sphere sets, flattened: one row per sphere.

    Attributes:
        joint: Joint id per sphere.
        local: Centre in the joint frame (S, 3) [m].
        radius: Radius (S,) [m].
        link: Link index per sphere (into ``links``).
        links: Link names.
        pairs: Checked link pairs (as link indices).
    """

    joint: np.ndarray
    local: np.ndarray
    radius: np.ndarray
    link: np.ndarray
    links: tuple[str, ...]
    pairs: tuple[tuple[int, int], ...]


@functools.cache
def spheres(robot: Robot) -> Spheres:
    """The sphere sets of the planner's collision model of ``robot`` (cached per robot object)."""
    cm = collision_model(robot)
    links = cm.links
    index = {name: i for i, name in enumerate(links)}
    joint, local, radius, link = [], [], [], []
    for c in cm.capsules:
        pts, r = c.spheres()
        joint += [c.joint] * len(pts)
        local.append(pts)
        radius += [r] * len(pts)
        link += [index[c.link]] * len(pts)
    return Spheres(joint=np.array(joint, dtype=int), local=np.vstack(local), radius=np.array(radius),
                   link=np.array(link, dtype=int), links=links,
                   pairs=tuple((index[a], index[b]) for a, b in cm.pairs))


def arm_joints(robot: Robot, side: str) -> tuple[int, ...]:
    """Joint ids of the ``side`` arm, from the first joint off the trunk to the hand's joint."""
    trunk = set(_joint_chain(robot, "torso" if robot.has_role("torso") else "base"))
    return tuple(j for j in _joint_chain(robot, f"{side}_hand") if j not in trunk and j > 0)


def forearm_radius(robot: Robot, side: str) -> float:
    """Largest sphere radius [m] on the lower half of the ``side`` arm (its joints from the elbow on)."""
    s = spheres(robot)
    chain = arm_joints(robot, side)
    lower = set(chain[len(chain) // 2:])
    radii = [float(r) for r, j in zip(s.radius, s.joint, strict=True) if int(j) in lower]
    return max(radii, default=0.0)


def _arm_links(robot: Robot, side: str) -> set[int]:
    """Link indices (into :attr:`Spheres.links`) that move with the ``side`` arm."""
    s = spheres(robot)
    hand_joint = robot.model.frames[robot.frame_id(f"{side}_hand")].parentJoint
    moving = set(arm_joints(robot, side)) | set(robot.model.subtrees[hand_joint])
    return {int(li) for li, j in zip(s.link, s.joint, strict=True) if int(j) in moving}


def arm_configuration(robot: Robot, points: dict[str, np.ndarray], *, natural: bool = False) -> np.ndarray:
    """The standing configuration with each ``side`` arm's joints moved so that its hand frame
    reaches heading-frame ``points[side]``.

    Position inverse kinematics of the arm joints (damped least squares within the joint
    limits, pulled towards the standing arm posture) from the standing arm and from
    ``ARM_IK_SEEDS`` fixed pseudo-random arm postures; of the postures that reach the point (within
    ``ARM_IK_TOLERANCE``), the one that clears the body by ``CLEARANCE`` in the sphere model (other arm
    standing), else the closest to standing; a point out of reach is approached as closely as
    the arm goes. ``natural``: from the standing arm only (the posture a planner pulled towards
    standing takes; the two arms of a symmetric robot mirror each other): the meeting points of a
    clap or a salute and their hand orientations."""
    q = robot.q_standing.copy()
    for side, p in points.items():
        arm = _arm_ik(robot, side, tuple(float(x) for x in p), 0 if natural else ARM_IK_SEEDS)
        q[_arm_q(robot, side)] = arm
    return q


def reach_error(robot: Robot, q: np.ndarray, side: str, point) -> float:
    """Distance [m] from the ``side`` hand frame at ``q`` to heading-frame ``point``."""
    data = robot.data()
    pin.framesForwardKinematics(robot.model, data, q)
    return float(np.linalg.norm(to_heading(robot, data.oMf[robot.frame_id(f"{side}_hand")].translation) - point))


ARM_IK_SEEDS = 8  # pseudo-random starting arm postures besides the standing one
ARM_IK_TOLERANCE = 0.005  # [m] a posture within this of the point reaches it


def _arm_q(robot: Robot, side: str) -> list[int]:
    return [robot.model.joints[j].idx_q for j in arm_joints(robot, side)]


@functools.cache
def _arm_ik(robot: Robot, side: str, point: tuple, n_seeds: int = ARM_IK_SEEDS) -> np.ndarray:
    model, data = robot.model, robot.data()
    iq = _arm_q(robot, side)
    iv = [model.joints[j].idx_v for j in arm_joints(robot, side)]
    fid = robot.frame_id(f"{side}_hand")
    goal = to_standing(robot, np.array(point))
    lo = np.maximum(model.lowerPositionLimit[iq], -math.pi)
    hi = np.minimum(model.upperPositionLimit[iq], math.pi)
    stand = robot.q_standing[iq]
    rng = np.random.default_rng(0)
    seeds = [stand] + [lo + rng.random(len(iq)) * (hi - lo) for _ in range(n_seeds)]
    found = []
    for seed in seeds:
        q = robot.q_standing.copy()
        q[iq] = seed
        for _ in range(ARM_IK_ITERATIONS):
            pin.computeJointJacobians(model, data, q)
            pin.updateFramePlacements(model, data)
            J = pin.getFrameJacobian(model, data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)[:3, iv]
            e = data.oMf[fid].translation - goal
            H = J.T @ J + (ARM_IK_DAMPING + ARM_IK_POSTURE) * np.eye(len(iv))
            dq = -np.linalg.solve(H, J.T @ e + ARM_IK_POSTURE * (q[iq] - stand))
            dq *= min(1.0, ARM_IK_STEP / max(float(np.abs(dq).max()), 1e-12))
            q[iq] = np.clip(q[iq] + dq, lo, hi)
            if float(np.abs(dq).max()) < 1e-6:
                break
        pin.framesForwardKinematics(model, data, q)
        err = float(np.linalg.norm(data.oMf[fid].translation - goal))
        clear = sphere_clearance(robot, q, side, other_arm=False)[0] if err < ARM_IK_TOLERANCE else -math.inf
        found.append(((err >= ARM_IK_TOLERANCE, clear < CLEARANCE, err if err >= ARM_IK_TOLERANCE else 0.0,
                       float(np.linalg.norm(q[iq] - stand))), q[iq].copy()))
    best = min(found, key=lambda f: f[0])
    if best[0][0] and n_seeds < ARM_IK_SEEDS:  # the standing arm does not get there: every seed
        return _arm_ik(robot, side, point, ARM_IK_SEEDS)
    return best[1]


def _closest_pair(robot: Robot, q: np.ndarray, pairs: list[tuple[int, int]]) -> tuple[float, tuple[str, str]]:
    """Smallest sphere-set distance [m] at ``q`` over link ``pairs`` (indices), and that pair's names."""
    s = spheres(robot)
    if not pairs:
        return math.inf, ("", "")
    data = robot.data()
    pin.forwardKinematics(robot.model, data, q)
    cm = collision_model(robot)
    best, which = math.inf, ("", "")
    for a, b in pairs:  # with the covers the planner checks the pair with (robots.collision)
        d = pair_sphere_distance(cm, s.links[a], s.links[b], data)
        if d < best:
            best, which = d, (s.links[a], s.links[b])
    return best, which


def sphere_clearance(robot: Robot, q: np.ndarray, side: str, *, other_arm: bool = True) -> tuple[float, tuple[str, str]]:
    """Smallest sphere-set distance [m] at ``q`` over the checked pairs that involve a link of
    the ``side`` arm, and that pair (link names); pairs with the other arm's links are left out
    with ``other_arm=False``."""
    mine = _arm_links(robot, side)
    theirs = _arm_links(robot, "right" if side == "left" else "left")
    pairs = [(a, b) for a, b in spheres(robot).pairs if (a in mine) != (b in mine)
             and (other_arm or not ({a, b} & theirs))]
    return _closest_pair(robot, q, pairs)


def hands_clearance(robot: Robot, q: np.ndarray) -> tuple[float, tuple[str, str]]:
    """Smallest sphere-set distance [m] at ``q`` over the checked pairs between the two arms."""
    left, right = _arm_links(robot, "left"), _arm_links(robot, "right")
    pairs = [(a, b) for a, b in spheres(robot).pairs if (a in left and b in right) or (a in right and b in left)]
    return _closest_pair(robot, q, pairs)


def clear_targets(robot: Robot, points: dict[str, np.ndarray], directions: dict[str, np.ndarray], *,
                  other_arm: bool = True) -> dict[str, np.ndarray]:
    """Each hand point moved out along its unit direction until, with the arms posed at the points
    (:func:`arm_configuration`), every checked pair involving that arm is ``CLEARANCE`` apart in
    the planner's sphere model (pairs between the two arms left out with ``other_arm=False``).

    A point already clear is not moved; a point that would move farther than ``MAX_CLEAR`` (the
    arm-only posture is then a poor model of the planner's, e.g. G1's short arms) is returned
    unmoved (the planner will explain if it is blocked)."""
    start = {s: np.asarray(p, dtype=float).copy() for s, p in points.items()}
    pts = {s: p.copy() for s, p in start.items()}
    for _ in range(CLEAR_ROUNDS):
        q = arm_configuration(robot, pts)
        moved = False
        for s in pts:
            d, _ = sphere_clearance(robot, q, s, other_arm=other_arm)
            if d < CLEARANCE - 0.5 * APPROACH_TOLERANCE:
                pts[s] = pts[s] + max(CLEARANCE - d, CLEAR_STEP_MIN) * np.asarray(directions[s], dtype=float)
                moved = True
        if not moved:
            break
    # more than MAX_CLEAR away: the arm-only posture is not the planner's; keep the mesh-based point
    return {s: p if np.linalg.norm(p - start[s]) <= MAX_CLEAR else start[s] for s, p in pts.items()}


def _union(boxes: list[Box]) -> Box:
    return Box(np.min([b.lo for b in boxes], axis=0), np.max([b.hi for b in boxes], axis=0))


__all__ = [
    "GAP",
    "MEET_GAP",
    "BodyMap",
    "Box",
    "approach_posed",
    "body_map",
    "hands_distance",
    "hands_meet",
    "hands_touch",
    "meet_geometries",
    "meets_apart",
    "mesh_distance",
    "obstacles_for",
    "posed_hands_distance",
    "stop_short",
    "to_heading",
    "to_standing",
]
