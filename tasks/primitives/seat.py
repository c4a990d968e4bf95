"""``sit_down(object)`` and ``stand_up(object)``: sit on a seat of the scene behind the robot, and
rise from it, the feet staying where they are.

The seat is a scene object with ``seat`` set (a chair's or a bench's seat: a static upright box);
with no object said, the scene's seat (:func:`tasks.compose.ground_actions` refuses a scene without
one, in task terms). The sitting posture (:func:`sitting`) keeps the base upright and both shins
leaning forward by ``SHIN_TILT`` over the soles, and pitches the thighs back by the angle at which their lowest points
(the thigh links' collision meshes) rest on the seat's top: each thigh then holds a contact on the
seat, a :class:`~tasks.specs.Contact` on the thigh link with its **support region** (the corners of
the rectangle under the thigh's lowest vertices, within ``REGION_BAND`` of them, in the thigh frame),
the seat's upward normal and the seat's friction. The planner holds those contacts fixed in 6D
like a sole and counts their regions in the support polygon (``planner.trajopt.layout``); the
thighs' links are left out of the scene-collision rows against the seat while they sit on it (a
``touch`` target), every other body part keeps its margin.

Refused in task terms (exit 4, :class:`~tasks.exceptions.BeyondCapability`): a seat higher than the
thighs of the robot sitting with level thighs, or lower than its deepest sit (``MAX_TILT``), and a
seat not under the thighs where the robot would sit (turn your back to it, or walk to it first).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import pinocchio as pin

from robots import Robot
from tasks.exceptions import BeyondCapability
from tasks.grounding import Grounded
from tasks.primitives.base import Fragment, FragmentBuilder, Primitive
from tasks.primitives.geometry import Stance
from tasks.primitives.objects import grounded
from tasks.scene import SceneObject, on_top, rotation
from tasks.specs import Contact, FrameTarget, Pose, Vec3

PARTS = frozenset({"legs", "com", "torso"})
LOWER = 3.0  # [s] nominal: from standing onto the seat
SETTLE = 1.0  # [s] nominal: sitting, before the fragment ends (or before rising)
RISE = 3.0  # [s] nominal: from the seat to standing
SHIN_TILT = 0.5  # [rad] the shins lean forward (knees ahead of the ankles, the feet tucked under the seat): the
#   hips come 0.14 m closer to the feet, so that a forward lean brings the CoM over the soles
MAX_TILT = 0.6  # [rad] the thighs pitched back past level at most this much (a low seat)
REGION_BAND = 0.005  # [m] a thigh's support region: its collision vertices this close to its lowest one
REGION_MIN = 0.02  # [m] a support region at least this long and wide over the seat
REGION_INSET = 0.005  # [m] a support region cut to the seat's top ends this far inside its edges
SEAT_TOLERANCE = 0.002  # [m] a region corner on the seat's top face
STAND_TOLERANCE = 0.02  # [m] the base back at its standing place after rising
SIDES = ("left", "right")
HANDS_FORWARD, HANDS_OUT, HANDS_UP = 0.30, 0.32, 0.0  # [m] the hands while seated, in the sitting base frame
HANDS_TOLERANCE = 0.05  # [m]
TOUCH_TOLERANCE = 1.0  # [m] the legs' touch targets only open the seat to them: a ball wider than the motion
APPROACH = 0.5  # the legs may touch the seat from this fraction of the way down (and up to it on the way
#   up): their capsule covers reach the seat before the meshes do (talos's thigh cover: 8 mm at 3.4 s)


@dataclass(frozen=True, slots=True)
class _Leg:
    hip: int  # q index of the hip pitch joint
    knee: int
    ankle: int
    sign: float  # +1 when the pitch axes point along the robot's left (+y at standing)
    thigh: str  # the thigh link's frame name (the body the hip pitch joint moves)
    geoms: tuple[int, ...]  # collision geometries on the thigh link


def _legs(robot: Robot) -> dict[str, _Leg]:
    """Per side the three pitch joints up the leg from the sole (ankle, knee, hip) and the thigh link."""
    model, data = robot.model, robot.model.createData()
    q = robot.q_standing
    pin.computeJointJacobians(model, data, q)
    out: dict[str, _Leg] = {}
    for side in SIDES:
        fid = robot.frame_id(f"{side}_foot")
        j = int(model.frames[fid].parentJoint)
        pitch: list[tuple[int, float]] = []
        while j > 0 and len(pitch) < 3:
            S = pin.getJointJacobian(model, data, j, pin.LOCAL)[:, model.joints[j].idx_v]
            axis = data.oMi[j].rotation @ S[3:]
            if model.joints[j].nv == 1 and abs(axis[1]) > 0.9:
                pitch.append((j, float(np.sign(axis[1]))))
            j = int(model.parents[j])
        if len(pitch) < 3:
            raise BeyondCapability(f"sit_down: {robot.name}'s {side} leg has no hip, knee and ankle pitch joints")
        (ja, sa), (jk, _), (jh, _) = pitch
        thigh = next(f.name for f in model.frames if f.type == pin.FrameType.BODY and f.parentJoint == jh)
        geoms = tuple(i for i, g in enumerate(robot.collision_model.geometryObjects)
                      if g.parentJoint == jh and hasattr(g.geometry, "num_vertices"))
        out[side] = _Leg(model.joints[jh].idx_q, model.joints[jk].idx_q, model.joints[ja].idx_q, sa, thigh, geoms)
    return out


def _posture(robot: Robot, tilt: float) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The sitting configuration in the standing frame (thighs pitched back by pi/2 + ``tilt``, shins
    vertical, base upright, the soles where they stand) and the world vertices of each thigh."""
    model, data = robot.model, robot.model.createData()
    legs = _legs(robot)
    q = np.array(robot.q_standing, dtype=float)
    p = math.pi / 2 + tilt
    pin.framesForwardKinematics(model, data, q)
    sole0 = data.oMf[robot.frame_id("left_foot")].translation.copy()
    base0 = q[:3].copy()
    for leg in legs.values():  # the knee ahead of the ankle by SHIN_TILT: hip + knee = SHIN_TILT = -ankle
        q[leg.hip], q[leg.knee], q[leg.ankle] = -leg.sign * p, leg.sign * (p + SHIN_TILT), -leg.sign * SHIN_TILT
    q[:3] = base0
    q[3:7] = pin.Quaternion(np.eye(3)).coeffs()  # upright: shins vertical with the ankles at zero
    pin.framesForwardKinematics(model, data, q)
    q[:3] += sole0 - data.oMf[robot.frame_id("left_foot")].translation
    pin.framesForwardKinematics(model, data, q)
    cdata = robot.collision_model.createData()
    pin.updateGeometryPlacements(model, data, robot.collision_model, cdata, q)
    verts = {}
    for side, leg in legs.items():
        pts = [np.asarray(robot.collision_model.geometryObjects[i].geometry.vertices(), dtype=float).reshape(-1, 3)
               @ cdata.oMg[i].rotation.T + cdata.oMg[i].translation for i in leg.geoms]
        verts[side] = np.vstack(pts)
    return q, verts


@lru_cache(maxsize=8)
def _bottom(robot: Robot, tilt: float) -> float:
    _, verts = _posture(robot, tilt)
    return float(min(v[:, 2].min() for v in verts.values()))


def _vec(v) -> Vec3:
    return (float(v[0]), float(v[1]), float(v[2]))


def _region(verts: np.ndarray, seat: SceneObject) -> np.ndarray:
    """Corners (4, 3) of a thigh's support region (world): the rectangle, in the seat's frame, of its
    vertices within ``REGION_BAND`` of the lowest one, cut to the seat's top ``REGION_INSET`` inside its edges."""
    R, c = np.asarray(rotation(seat.rpy)), np.asarray(seat.position)
    z = float(verts[:, 2].min())
    low = (verts[verts[:, 2] <= z + REGION_BAND] - c) @ R
    half = np.asarray(seat.size[:2]) / 2 - REGION_INSET
    lo = np.maximum(low[:, :2].min(axis=0), -half)
    hi = np.minimum(low[:, :2].max(axis=0), half)
    if np.any(hi - lo < REGION_MIN):
        lo, hi = low[:, :2].min(axis=0), low[:, :2].max(axis=0)  # not over the seat: refused by the caller
    local = np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]])
    return np.column_stack([local, np.zeros(4)]) @ R.T + np.array([c[0], c[1], z])


@dataclass(frozen=True, slots=True)
class Sitting:
    """Where the robot sits: its configuration and the thighs' seat contacts (world)."""

    q: np.ndarray
    contacts: tuple[Contact, ...]
    seat: SceneObject


def sitting(robot: Robot, stance: Stance, seat: SceneObject) -> Sitting:
    """The robot sitting on ``seat`` with its feet at ``stance`` (see the module's docstring).

    Raises:
        BeyondCapability: the seat is too high, too low, or not under the thighs.
    """
    T = stance.transform_from_standing(robot)
    top = float(seat.position[2] + seat.size[2] / 2) - float(T.translation[2])  # in the standing frame
    level, deepest = _bottom(robot, 0.0), _bottom(robot, MAX_TILT)
    if top > level + SEAT_TOLERANCE:
        raise BeyondCapability(f"sit_down: the {seat.name}'s top at {top:.2f} m is above {robot.name}'s thighs "
                               f"sitting with level thighs ({level:.2f} m): choose a lower seat")
    if top < deepest - SEAT_TOLERANCE:
        raise BeyondCapability(f"sit_down: the {seat.name}'s top at {top:.2f} m is below {robot.name}'s deepest "
                               f"sit ({deepest:.2f} m): choose a higher seat")
    lo, hi = 0.0, MAX_TILT
    for _ in range(40):  # the thighs' lowest point falls as they pitch back past level
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if _bottom(robot, mid) > top else (lo, mid)
    q, verts = _posture(robot, 0.5 * (lo + hi))
    model, data = robot.model, robot.model.createData()
    base = T * pin.XYZQUATToSE3(q[:7])
    q[:7] = pin.SE3ToXYZQUAT(base)
    pin.framesForwardKinematics(model, data, q)
    normal = np.asarray(rotation(seat.rpy))[:, 2]
    contacts = []
    for side, leg in _legs(robot).items():
        world = _region(verts[side] @ T.rotation.T + T.translation, seat)
        M = data.oMf[robot.frame_id(leg.thigh)]
        for corner in world:
            if not on_top(seat, corner, tolerance=SEAT_TOLERANCE):
                raise BeyondCapability(
                    f"sit_down: the {seat.name} is not under {robot.name}'s {side} thigh where it would sit "
                    f"(at {corner[0]:.2f}, {corner[1]:.2f}, {corner[2]:.2f} m): turn your back to it and walk to it first")
        region = tuple(_vec(M.actInv(corner)) for corner in world)
        contacts.append(Contact(frame=leg.thigh, placement=Pose(position=_vec(M.translation),
                                                                 rpy=_vec(pin.rpy.matrixToRpy(M.rotation))),
                                friction_coefficient=seat.friction, region=region, normal=_vec(normal)))
    return Sitting(q=q, contacts=tuple(contacts), seat=seat)


def _seat(b: FragmentBuilder, action: str) -> Sitting:
    g: Grounded = grounded(b.params, action)
    return sitting(b.robot, b.stance, g.obj)


def _leg_roots(robot: Robot) -> list[str]:
    """Per leg the link of its first joint below the base (talos: the hip yaw link, whose mesh hangs
    6 mm above the seat under the sitting thigh)."""
    model = robot.model
    out = []
    for side in SIDES:
        j = int(model.frames[robot.frame_id(f"{side}_foot")].parentJoint)
        while int(model.parents[j]) > 1:
            j = int(model.parents[j])
        out.append(next(f.name for f in model.frames if f.type == pin.FrameType.BODY and f.parentJoint == j))
    return out


def _touch(b: FragmentBuilder, s: Sitting, window: tuple[float, float], hold: bool = False) -> None:
    """The thighs rest on the seat over ``window`` (nominal s): the legs' links may touch it then
    (the planner's scene rows and checks leave them out with the seat; every other part keeps clear)."""
    model, data = b.robot.model, b.robot.model.createData()
    pin.framesForwardKinematics(model, data, s.q)
    for frame in _leg_roots(b.robot):
        p = _vec(data.oMf[b.robot.frame_id(frame)].translation)
        b.targets.append(FrameTarget(name=b.name(f"{frame} at the {s.seat.name}"), frame=frame, position=p,
                                     window=b.window(*window), tolerance=TOUCH_TOLERANCE, touch=s.seat.name))
        if hold:  # seated until the next action moves the legs (stand_up) or the motion ends
            b.holds.append(b.name(f"{frame} at the {s.seat.name}"))


def _hands(b: FragmentBuilder, s: Sitting, window: tuple[float, float], hold: bool = False) -> None:
    """Both hands forward over the thighs while seated (hanging, they would be inside the thighs)."""
    base = pin.XYZQUATToSE3(s.q[:7])
    for side, sign in (("left", 1.0), ("right", -1.0)):
        if not b.robot.has_role(f"{side}_hand"):
            continue
        p = base.act(np.array([HANDS_FORWARD, sign * HANDS_OUT, HANDS_UP]))
        what = f"{side} hand over the thighs"
        b.frame_target(what, f"{side}_hand", position=tuple(float(c) for c in p), window=window,
                       tolerance=HANDS_TOLERANCE)
        if hold:
            b.holds.append(b.name(what))


def build_sit_down(b: FragmentBuilder) -> Fragment:
    """Lower onto the seat (both feet down), then sit: feet and thighs in contact."""
    s = _seat(b, "sit_down")
    b.phase("sit down", LOWER)
    b.phase("sitting", LOWER + SETTLE, (*b.contacts(), *s.contacts))
    _touch(b, s, (APPROACH * LOWER, LOWER + SETTLE), hold=True)
    _hands(b, s, (LOWER, LOWER + SETTLE), hold=True)
    b.end_contacts = s.contacts  # it stays seated: the phases after it keep the thighs on the seat
    return b.finish(PARTS)


def build_stand_up(b: FragmentBuilder) -> Fragment:
    """Sit a moment (feet and thighs in contact), then rise to the standing posture over the feet."""
    s = _seat(b, "stand_up")
    b.phase("sitting", SETTLE, (*b.contacts(), *s.contacts))
    b.phase("stand up", SETTLE + RISE)
    _touch(b, s, (0.0, SETTLE + (1 - APPROACH) * RISE))
    _hands(b, s, (0.0, SETTLE))
    base = b.geometry.position("base") if "base" in b.geometry.placements else None
    if base is not None:
        b.frame_target("base back where it stands", "base", position=b.world(base), time=SETTLE + RISE,
                       tolerance=STAND_TOLERANCE)
    return b.finish(PARTS)


def _check(params: dict, robot: Robot, action: str) -> None:
    g = grounded(params, action)
    sitting(robot, g.start if isinstance(g.start, Stance) else Stance.standing(robot), g.obj)


SIT_DOWN = Primitive(name="sit_down", nominal_duration=lambda p, r: LOWER + SETTLE, build=build_sit_down,
                     parts=lambda p: PARTS, check=lambda p, r: _check(p, r, "sit_down"))
STAND_UP = Primitive(name="stand_up", nominal_duration=lambda p, r: SETTLE + RISE, build=build_stand_up,
                     parts=lambda p: PARTS, check=lambda p, r: _check(p, r, "stand_up"))

PRIMITIVES = (SIT_DOWN, STAND_UP)

__all__ = ["PRIMITIVES", "SIT_DOWN", "STAND_UP", "Sitting", "sitting"]
