"""``kneel(knee)``: kneel down on one knee on the floor, hold, and get up again, the other foot
staying where it stands.

The kneeling posture (:func:`kneeling`) keeps the standing foot's sole where it is and puts the
kneeling leg's shin on the floor ``KNEE_BACK`` behind the soles (at most ``KNEE_BACK_FRACTION`` of the
base's standing height), under its hip: the lowest points
of the shin's collision meshes (the front of the knee) on the floor, the shin tilted up
backwards (the knee bent ``KNEE_BEND``) so the lifted foot clears the floor, the base upright and
the centre of mass ``COM_SHARE`` of the way from the standing sole's centre towards the knee. It
is found by damped least squares on the whole body (Pinocchio). The knee then holds a contact on
the floor, a :class:`~tasks.specs.Contact` on the shin link with its **support region** (the
rectangle under the shin's vertices within ``REGION_BAND`` of the lowest, at least ``REGION_MIN``
each way: :func:`tasks.primitives.lean.hand_region`, the hands' on a table), the floor's upward
normal and the robot's sole friction: the same machinery as a thigh on a seat or a hand on a table.

The motion (dynamic: contact forces and the centroidal dynamics): shift the weight onto the
standing foot (both soles down), lower the kneeling knee to the floor on one foot (the CoM held
over the standing sole), kneel (the standing sole and the knee in contact), lift the knee and put
the foot back down (one foot again), and stand. ``kneel`` always comes back up (like ``lean_on``):
the controller and the certificate know no posture ending on a knee. "get up" after a kneel in the
same sentence is the kneel's own rise (:func:`tasks.compose.ground_actions` drops that ``stand``),
not ``stand_up`` from a seat. One knee only: both knees come down one at a time, each foot turning
onto its toes, and the planner holds a contact fixed at its frame (a toe pivot needs a frame at the
toe); ``knee="both"`` is refused.

Refused in task terms (exit 4, :class:`~tasks.exceptions.BeyondCapability`): both knees, a knee that
cannot bend ``KNEE_BEND``, a kneeling posture the legs cannot reach, a link that would go into the
floor, links that would overlap (the collision model's capsules: g1's thigh and torso), and (``objects`` of :func:`kneeling`) a scene object where the knee or the lifted foot would
go; a sentence's scene is checked by the spec's scene check (:mod:`tasks.robot_check`: the knee's
contact inside an object, a ``SceneConflict``, exit 4 too).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import pinocchio as pin

from robots import Robot, body_part, collision_model, pair_sphere_distance
from tasks.exceptions import BeyondCapability
from tasks.primitives.base import Fragment, FragmentBuilder, Primitive
from tasks.primitives.geometry import Stance
from tasks.primitives.lean import hand_region, ik_step
from tasks.primitives.seat import _legs
from tasks.scene import SceneObject, extent, rotation
from tasks.specs import Contact, FrameTarget, Pose, Vec3

PARTS = frozenset({"legs", "com", "torso"})
SIDES = ("left", "right")
OTHER = {"left": "right", "right": "left"}
SHIFT = 1.0  # [s] nominal: the weight onto the standing foot (both soles down), and back at the end
DOWN = 2.5  # [s] nominal: the knee down to the floor, on one foot
HOLD = 2.0  # [s] nominal: kneeling (the standing sole and the knee in contact)
UP = 2.5  # [s] nominal: the knee up and the foot back down, on one foot
KNEE_BACK = 0.30  # [m] the knee's lowest point at most this far behind the soles' centres (under the hip)
KNEE_BACK_FRACTION = 0.295  # ... and at most this fraction of the base's standing height (talos 1.02 m: 0.30 m;
#   g1 0.78 m: 0.23 m, its shorter legs reach no farther)
KNEE_BEND = 1.7  # [rad] the kneeling knee's bend: the shin tilted up backwards, the lifted foot off the floor
ANKLE = 0.5  # [rad] the kneeling leg's ankle pitch (toes pointed back: the lifted foot clears the floor)
COM_SHARE = 0.3  # the kneeling CoM this share of the way from the standing sole's centre to the knee
REGION_BAND = 0.005  # [m] the knee's support region: the shin's vertices this close to its lowest one
REGION_MIN = 0.02  # [m] a region at least this long and wide
ITERATIONS = 200  # damped least-squares steps per re-aim of the knee point
TOLERANCE = 0.002  # [m] the IK: the standing sole, and the knee's lowest point on the floor
XY_TOLERANCE = 0.01  # [m] the IK: the knee where asked
COM_IK_TOLERANCE = 0.03  # [m] the IK: the CoM where asked (g1: 1.5 cm short; talos on its left knee: 2.2 cm behind,
#   on its right knee 0.4 cm: the two compromises with the straight kneeling thigh differ)
FOOT_LIFT = 0.05  # [m] the kneeling leg's sole clears the floor this much half-way down and up (at 0 it dragged on
#   the floor 0.12 s after the lift-off in MuJoCo)
FOOT_CLEARANCE = 0.02  # [m] the lifted foot's lowest point at least this far above the floor
STANCE_CLEARANCE = 0.01  # [m] the standing leg's links this far above the floor (g1's ankle and shin: 2.4 cm)
BODY_CLEARANCE = 0.03  # [m] every other link (but the standing foot and the kneeling shin) this far above the floor
THIGH_CLEARANCE = 0.005  # [m] the kneeling leg's links above the knee (talos's thigh: 7 mm above the floor, around the knee)
OBJECT_MARGIN = 0.05  # [m] no scene object this close to the knee's region or the lifted foot (horizontally)
COM_TOLERANCE = 0.02  # [m] the CoM over the standing sole while on one foot
KNEEL_COM_TOLERANCE = 0.03  # [m] the CoM where the kneeling posture has it, while kneeling
SETTLE = 0.5  # [s] nominal: the CoM moves between over the standing sole and the kneeling posture's while kneeling
WAYPOINT = 0.5  # the knee half-way between standing and the floor this share of the way down (and up)
LIFT = 0.05  # [m] the half-way knee this much above the straight line (the lifted foot clears the floor)
WAYPOINT_TOLERANCE = 0.05  # [m]
FLOOR = SceneObject(name="floor", shape="box", size=(100.0, 100.0, 1.0), position=(0.0, 0.0, -0.5))


@dataclass(frozen=True, slots=True)
class Kneeling:
    """Where the robot kneels: its configuration, the knee's floor contact and the kneeling side."""

    q: np.ndarray
    contact: Contact
    side: str


def _vec(v) -> Vec3:
    return (float(v[0]), float(v[1]), float(v[2]))


def _joint(robot: Robot, idx_q: int) -> int:
    return next(j for j in range(1, robot.model.njoints) if robot.model.joints[j].idx_q == idx_q
                and robot.model.joints[j].nq == 1)


def shin(robot: Robot, side: str) -> tuple[str, tuple[int, ...]]:
    """The shin link's frame name (the body the knee pitch joint moves) and its collision meshes."""
    model = robot.model
    jk = _joint(robot, _legs(robot)[side].knee)
    name = next(f.name for f in model.frames if f.type == pin.FrameType.BODY and f.parentJoint == jk)
    geoms = tuple(i for i, g in enumerate(robot.collision_model.geometryObjects)
                  if g.parentJoint == jk and hasattr(g.geometry, "num_vertices"))
    return name, geoms


def _vertices(robot: Robot, q: np.ndarray, geoms) -> np.ndarray:
    model, data = robot.model, robot.model.createData()
    cdata = robot.collision_model.createData()
    pin.framesForwardKinematics(model, data, q)
    pin.updateGeometryPlacements(model, data, robot.collision_model, cdata, q)
    return np.vstack([np.asarray(robot.collision_model.geometryObjects[i].geometry.vertices(), dtype=float).reshape(-1, 3)
                      @ cdata.oMg[i].rotation.T + cdata.oMg[i].translation for i in geoms])


def lowest_points(robot: Robot, q: np.ndarray) -> dict[str, float]:
    """Per link (body frame name) its collision meshes' lowest point [m] at ``q``."""
    model, data = robot.model, robot.model.createData()
    cdata = robot.collision_model.createData()
    pin.framesForwardKinematics(model, data, q)
    pin.updateGeometryPlacements(model, data, robot.collision_model, cdata, q)
    out: dict[str, float] = {}
    for i, g in enumerate(robot.collision_model.geometryObjects):
        if not hasattr(g.geometry, "num_vertices"):
            continue
        z = float((np.asarray(g.geometry.vertices(), dtype=float).reshape(-1, 3) @ cdata.oMg[i].rotation.T
                   + cdata.oMg[i].translation)[:, 2].min())
        name = next(f.name for f in model.frames if f.type == pin.FrameType.BODY and f.parentJoint == g.parentJoint)
        out[name] = min(out.get(name, np.inf), z)
    return out


def _solve(robot: Robot, side: str, knee_goal: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Whole-body damped least squares (standing frame): the standing sole fixed, the kneeling
    shin's lowest point at ``knee_goal``, its knee bent ``KNEE_BEND`` and its ankle straight, the
    base upright, the CoM ``COM_SHARE`` of the way from the standing sole to the knee; returns q,
    the shin's lowest point reached and the CoM."""
    model, data = robot.model, robot.model.createData()
    legs = _legs(robot)
    stand = OTHER[side]
    q0 = np.asarray(robot.q_standing, dtype=float)
    pin.framesForwardKinematics(model, data, q0)
    foot = data.oMf[robot.frame_id(f"{stand}_foot")].copy()
    sole = foot.translation.copy()
    name, geoms = shin(robot, side)
    fid = robot.frame_id(name)
    com_goal = sole + COM_SHARE * (knee_goal - sole)
    q = q0.copy()
    leg = legs[side]
    q[leg.knee] = leg.sign * KNEE_BEND  # start bent: the IK keeps the knee's side of its limits
    lo, hi = model.lowerPositionLimit[7:], model.upperPositionLimit[7:]
    chain = [int(j) for j in model.supports[model.frames[robot.frame_id(f"{side}_foot")].parentJoint]
             if model.joints[j].nq == 1]  # the kneeling leg: all straight but the knee and the ankle pitch
    want = {model.joints[j].idx_q: 0.0 for j in chain} | {leg.knee: leg.sign * KNEE_BEND, leg.ankle: leg.sign * ANKLE}
    sel = np.zeros((len(chain), model.nv))
    for i, j in enumerate(chain):
        sel[i, model.joints[j].idx_v] = 1.0
    offset = np.zeros(3)
    low = knee_goal
    for _ in range(5):  # the lowest point moves on the shin as it turns: re-aim the frame
        pin.framesForwardKinematics(model, data, q)
        verts = _vertices(robot, q, geoms)
        low = verts[np.argmin(verts[:, 2])]
        offset = data.oMf[fid].translation - low
        for _ in range(ITERATIONS):
            pin.computeJointJacobians(model, data, q)
            pin.framesForwardKinematics(model, data, q)
            fs = robot.frame_id(f"{stand}_foot")
            J = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)[:3]
            Jb = pin.getJointJacobian(model, data, 1, pin.LOCAL_WORLD_ALIGNED)[3:]
            rows = [pin.getFrameJacobian(model, data, fs, pin.LOCAL), J, Jb, pin.jacobianCenterOfMass(model, data, q)[:2], sel]
            base = pin.log3(data.oMi[1].rotation)
            errs = [pin.log6(data.oMf[fs].actInv(foot)).vector, knee_goal + offset - data.oMf[fid].translation,
                    -base, com_goal[:2] - data.com[0][:2],
                    np.array([want[model.joints[j].idx_q] - q[model.joints[j].idx_q] for j in chain])]
            W = np.asarray([10.0] * 6 + [5.0] * 3 + [1.0] * 3 + [10.0] * 2 + [0.5] * len(chain))
            q, step = ik_step(model, q, q0, rows, errs, W, damping=1e-2, pull=1e-3, lo=lo, hi=hi)
            if step < 1e-7:
                break
    verts = _vertices(robot, q, geoms)
    low = verts[np.argmin(verts[:, 2])]
    com = pin.centerOfMass(model, data, q)
    return q, low, com


def _in_the_way(objects: tuple[SceneObject, ...], points: np.ndarray, top: float) -> SceneObject | None:
    """A scene object whose footprint (``OBJECT_MARGIN`` around it) holds one of ``points`` (world,
    horizontally) and that rises above ``top`` [m] (an object on the floor where the knee goes)."""
    for obj in objects:
        lo, hi = extent(obj)
        if hi[2] <= top:
            continue
        for p in points:
            if lo[0] - OBJECT_MARGIN <= p[0] <= hi[0] + OBJECT_MARGIN and lo[1] - OBJECT_MARGIN <= p[1] <= hi[1] + OBJECT_MARGIN:
                return obj
    return None


@lru_cache(maxsize=8)
def _posture(robot: Robot, side: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The kneeling configuration in the standing frame, the knee's lowest point and the CoM.

    Raises:
        BeyondCapability: the knee cannot bend enough, or the IK does not reach the posture.
    """
    leg = _legs(robot)[side]
    jk = _joint(robot, leg.knee)
    bend = max(abs(float(robot.model.lowerPositionLimit[leg.knee])), abs(float(robot.model.upperPositionLimit[leg.knee])))
    if bend < KNEE_BEND - 1e-9:
        raise BeyondCapability(f"kneel: {robot.name}'s knees bend at most {bend:.2f} rad ({robot.model.names[jk]}); "
                               f"kneeling needs {KNEE_BEND:.2f} rad")
    back = min(KNEE_BACK, KNEE_BACK_FRACTION * float(robot.q_standing[2]))
    g = np.array([-back, 0.0, 0.0])
    pin_data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, pin_data, np.asarray(robot.q_standing, dtype=float))
    g[1] = float(pin_data.oMf[robot.frame_id(f"{side}_foot")].translation[1])
    q, low, com = _solve(robot, side, g)
    stand = OTHER[side]
    sole = pin_data.oMf[robot.frame_id(f"{stand}_foot")].translation
    want = sole + COM_SHARE * (g - sole)
    if abs(float(low[2])) > TOLERANCE or float(np.linalg.norm(low[:2] - g[:2])) > XY_TOLERANCE \
            or float(np.linalg.norm(com[:2] - want[:2])) > COM_IK_TOLERANCE:
        raise BeyondCapability(f"kneel: {robot.name} cannot reach a kneeling posture with its {side} knee on the floor "
                               f"{back:.2f} m behind its feet (the knee reaches {low[0]:.2f}, {low[1]:.2f}, {low[2]:.3f} m)")
    lows = lowest_points(robot, q)
    shin_name, _ = shin(robot, side)
    model = robot.model
    stand_chain = [int(j) for j in model.supports[model.frames[robot.frame_id(f"{stand}_foot")].parentJoint]]
    stand_joints = set(stand_chain[-1:])
    for link, z in lows.items():
        j = model.frames[robot.frame_id(link)].parentJoint
        if link == shin_name or j in stand_joints:
            continue
        limit = FOOT_CLEARANCE if j in set(model.subtrees[jk]) else THIGH_CLEARANCE if j in set(model.supports[jk]) \
            else STANCE_CLEARANCE if j in stand_chain[2:] else BODY_CLEARANCE
        if z < limit:
            where = f"{-z:.3f} m into the floor" if z < 0 else f"within {z:.3f} m of the floor"
            raise BeyondCapability(f"kneel: kneeling on its {side} knee, {robot.name}'s {link} would go {where}: "
                                   "its legs do not fold that way")
    _apart(robot, q, side)
    return q, low, com


def _apart(robot: Robot, q: np.ndarray, side: str) -> None:
    """Refuse a kneeling posture whose legs and trunk overlap in the robot's collision model (the
    capsules the planner keeps apart): g1's standing thigh, its hip flexed 1.4 rad, passes 2.6 cm into
    its torso, and its plan failed on that pair after 70 s. The arms are left out: the plan moves them
    (at talos's posture the hanging left forearm's capsule is in the pelvis's; planned, 34 mm apart)."""
    model = robot.model
    hands = [set(model.supports[model.frames[robot.frame_id(f"{s}_hand")].parentJoint]) for s in SIDES
             if robot.has_role(f"{s}_hand")]
    arms = {int(j) for mine in hands for j in mine if sum(j in h for h in hands) == 1}  # one hand's chain, not the torso
    arms |= {int(k) for j in arms for k in model.subtrees[j]}
    joint = {model.frames[g.parentFrame].name: int(g.parentJoint) for g in robot.collision_model.geometryObjects}
    cm = collision_model(robot)
    data = model.createData()
    pin.forwardKinematics(model, data, q)
    worst = min(((pair_sphere_distance(cm, a, b, data), a, b) for a, b in cm.pairs
                 if joint.get(a) not in arms and joint.get(b) not in arms), default=None)
    if worst is not None and worst[0] < 0.0:
        d, a, b = worst
        raise BeyondCapability(f"kneel: kneeling on its {side} knee, {robot.name}'s {body_part(robot, a)} would pass "
                               f"{-d:.3f} m into its {body_part(robot, b)}: its body does not fold that way")


def kneeling(robot: Robot, stance: Stance, side: str = "right", objects: tuple[SceneObject, ...] = ()) -> Kneeling:
    """The robot kneeling on its ``side`` knee, its other foot at ``stance`` (module docstring).

    Raises:
        BeyondCapability: the knee cannot bend enough, no posture reaches the floor, or a scene
            object stands where the knee or the lifted foot would go.
    """
    q, _, _ = _posture(robot, side)
    q = q.copy()
    T = stance.transform_from_standing(robot)
    q[:7] = pin.SE3ToXYZQUAT(T * pin.XYZQUATToSE3(q[:7]))
    model, data = robot.model, robot.model.createData()
    pin.framesForwardKinematics(model, data, q)
    name, geoms = shin(robot, side)
    verts = _vertices(robot, q, geoms)
    floor = float(T.translation[2])
    ground = FLOOR if abs(floor) < 1e-9 else SceneObject(name="floor", shape="box", size=FLOOR.size,
                                                          position=(0.0, 0.0, floor - FLOOR.size[2] / 2))
    world = hand_region(verts, ground, band=REGION_BAND, minimum=REGION_MIN)
    foot = data.oMf[robot.frame_id(f"{side}_foot")].translation
    obj = _in_the_way(objects, np.vstack([world, foot[None]]), floor + 0.005)
    if obj is not None:
        raise BeyondCapability(f"kneel: the {obj.name} is where {robot.name}'s {side} knee would go down "
                               f"(at {world[:, 0].mean():.2f}, {world[:, 1].mean():.2f} m): step away from it first")
    M = data.oMf[robot.frame_id(name)]
    contact = Contact(frame=name, placement=Pose(position=_vec(M.translation), rpy=_vec(pin.rpy.matrixToRpy(M.rotation))),
                      friction_coefficient=robot.profile.friction_coefficient,
                      region=tuple(_vec(M.actInv(c)) for c in world), normal=_vec(np.asarray(rotation(ground.rpy))[:, 2]))
    return Kneeling(q=q, contact=contact, side=side)


@lru_cache(maxsize=16)
def _cached(robot: Robot, stance: Stance, side: str) -> Kneeling:
    return kneeling(robot, stance, side)


def nominal_duration(params: dict, robot: Robot) -> float:
    """Shift, down, kneel, up, shift back [s]."""
    return SHIFT + DOWN + HOLD + UP + SHIFT


def build(b: FragmentBuilder) -> Fragment:
    """Onto the standing foot, the knee down, kneel, the knee up, both feet down."""
    side = b.params.get("knee", "right")
    stand = OTHER[side]
    k = _cached(b.robot, b.stance, side)
    sole = b.world(b.geometry.sole_centers[stand])
    t1, t2, t3, t4 = SHIFT, SHIFT + DOWN, SHIFT + DOWN + HOLD, SHIFT + DOWN + HOLD + UP
    one = b.contacts((stand,))
    b.phase(f"shift onto the {stand} foot", t1)
    b.phase(f"{side} knee down", t2, one, swing_height=FOOT_LIFT)
    b.phase(f"kneel on the {side} knee", t3, (*one, k.contact))
    b.phase(f"{side} knee up", t4, one, swing_height=FOOT_LIFT)
    b.phase("both feet down", nominal_duration(b.params, b.robot))
    b.com_target(f"CoM over the {stand} sole", (sole[0], sole[1], None), window=(t1, t2), tolerance=COM_TOLERANCE)
    b.com_target(f"CoM over the {stand} sole again", (sole[0], sole[1], None), window=(t3, t4), tolerance=COM_TOLERANCE)
    home = b.world(b.geometry.com)
    b.com_target("CoM back between the feet", (home[0], home[1], None), time=nominal_duration(b.params, b.robot),
                 tolerance=0.01)
    model, data = b.robot.model, b.robot.model.createData()
    pin.framesForwardKinematics(model, data, k.q)
    kneel_com = pin.centerOfMass(model, data, k.q)
    b.com_target(f"CoM between the {stand} sole and the {side} knee", (kneel_com[0], kneel_com[1], None),
                 window=(t2 + SETTLE, t3 - SETTLE), tolerance=KNEEL_COM_TOLERANCE)
    name, _ = shin(b.robot, side)
    down = np.asarray(k.contact.placement.position)
    pin.framesForwardKinematics(model, data, np.asarray(b.robot.q_standing, dtype=float))
    up = np.asarray(b.world(data.oMf[b.robot.frame_id(name)].translation))
    for what, tau in ((f"{side} knee half-way down", t1 + WAYPOINT * DOWN), (f"{side} knee half-way up", t4 - WAYPOINT * UP)):
        b.targets.append(FrameTarget(name=b.name(what), frame=name, position=_vec(0.5 * (up + down) + [0.0, 0.0, LIFT]),
                                     time=b.t(tau), tolerance=WAYPOINT_TOLERANCE))
    return b.finish(PARTS, dynamic=True)


def _check(params: dict, robot: Robot) -> None:
    if params.get("knee") == "both":
        raise BeyondCapability(f"kneel: {robot.name} kneels on one knee only (both knees come down one at a time, each "
                               "foot turning onto its toes, which is not planned yet): say \"kneel on one knee\"")
    _cached(robot, Stance.standing(robot), params.get("knee", "right"))


KNEEL = Primitive(name="kneel", nominal_duration=nominal_duration, build=build, parts=lambda p: PARTS,
                  check=lambda p, r: _check(p, r), dynamic=True)

PRIMITIVES = (KNEEL,)

__all__ = ["FLOOR", "KNEEL", "PRIMITIVES", "Kneeling", "kneeling", "lowest_points", "shin"]
