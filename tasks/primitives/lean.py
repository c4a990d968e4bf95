"""``lean_on(object)``: lean on a table ahead with both hands, the feet staying where they are, and
come back up.

The table is a scene object with a top face (a static upright box: :func:`tasks.scene.on_top`);
with no object said, the scene's one nearest the origin (:func:`tasks.compose.ground_actions`). The
leaning posture (:func:`leaning`) puts each hand's lowest points (the collision meshes of the hand
link and the links below it: talos's gripper, g1's rubber hand) on the table top, ``INSET`` inside
its near edge ahead of where the hand hangs, with the soles where they stand and the centre of mass
over them; it is found by damped least squares on the whole body (Pinocchio), the hands keeping
their hanging orientation as far as the reach allows. Each hand then holds a contact on the table,
a :class:`~tasks.specs.Contact` on the hand's link that touches (talos: a fingertip) with its
**support region** (the rectangle under its vertices within ``REGION_BAND`` of the lowest, at least
``REGION_MIN`` each way, :func:`hand_region`), the table's upward normal and the table's friction:
the same machinery as a thigh on a seat. While leaning the CoM is held ``COM_FORWARD`` ahead of
where it stands. The hands and their wrist links may touch the table from half-way down to
half-way up (``touch`` targets); every other body part keeps its margin.

Refused in task terms (exit 4, :class:`~tasks.exceptions.BeyondCapability`): no table top within
reach ahead (``REACH`` of the arm's length beyond the hanging hands), a top above the hanging
hands' lowest point (a lean presses down on it), one lower than the hands reach down to, and one so
low that the base would drop more than ``MAX_DROP`` (a squat, not a lean).
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

PARTS = frozenset({"legs", "com", "torso", "left_arm", "right_arm"})
DOWN = 2.0  # [s] nominal: from standing to the hands on the table
HOLD = 2.0  # [s] nominal: leaning on it
UP = 2.0  # [s] nominal: back to standing
INSET = 0.10  # [m] the hands' lowest points this far inside the table's near edge
REACH = 1.0  # [arm lengths] the near edge at most this far ahead of the hanging hands
REGION_BAND = 0.002  # [m] a hand's support region: its collision vertices this close to its lowest one (talos:
#   one fingertip; at 5 mm the band took in a second finger 2.4 mm higher, 5 x 10 cm away, that does not bear: a
#   region the planner and the controller would take for a support it is not)
REGION_MIN = 0.01  # [m] a region at least this long and wide (a fingertip's pad), about its centre
MAX_DROP = 0.12  # [m] the base at most this much lower than standing (a lean bends at the hips, not a squat)
TOLERANCE = 0.002  # [m] the IK: soles, and the hands' lowest points on the top
XY_TOLERANCE = 0.01  # [m] the IK: the hands' lowest points where asked on the table
SIDES = ("left", "right")
APPROACH = 0.5  # the hands may touch the table from this fraction of the way down (and up to it on the way up)
TOUCH_TOLERANCE = 1.0  # [m] the touch targets only open the table to the hands: a ball wider than the motion
SCAN = 0.005  # [m] the search for the near edge ahead of each hand
COM_FORWARD = 0.02  # [m] while leaning the CoM this far ahead of where it stands: a share of the weight on the
#   hands (talos: 32 to 45 N per hand planned). Left free, the plan put it 0.27 m ahead, over the table, the hands
#   pushing back at the edge of their friction cone: they slid 4 cm in MuJoCo.
COM_TOLERANCE = 0.01  # [m]
SETTLE = 0.5  # [s] nominal: the CoM in place this long before the hands touch down and after they lift off (the
#   plan's hand forces jumped to 2.7 times the lean's at the touch-down and lift-off knots with the CoM arriving)


@dataclass(frozen=True, slots=True)
class Leaning:
    """Where the robot leans: its configuration, the hands' contacts (world) and the table."""

    q: np.ndarray
    contacts: tuple[Contact, ...]
    table: SceneObject


def _vec(v) -> Vec3:
    return (float(v[0]), float(v[1]), float(v[2]))


def _hand_geoms(robot: Robot, side: str) -> tuple[int, ...]:
    model = robot.model
    joint = model.frames[robot.frame_id(f"{side}_hand")].parentJoint
    return tuple(i for i, g in enumerate(robot.collision_model.geometryObjects)
                 if g.parentJoint in model.subtrees[joint] and hasattr(g.geometry, "num_vertices"))


def hand_vertices(robot: Robot, q: np.ndarray) -> dict[str, np.ndarray]:
    """Per side the world vertices (n, 3) of the hand's collision meshes at ``q``."""
    model, data = robot.model, robot.model.createData()
    cdata = robot.collision_model.createData()
    pin.framesForwardKinematics(model, data, q)
    pin.updateGeometryPlacements(model, data, robot.collision_model, cdata, q)
    out = {}
    for side in SIDES:
        pts = [np.asarray(robot.collision_model.geometryObjects[i].geometry.vertices(), dtype=float).reshape(-1, 3)
               @ cdata.oMg[i].rotation.T + cdata.oMg[i].translation for i in _hand_geoms(robot, side)]
        out[side] = np.vstack(pts)
    return out


@lru_cache(maxsize=4)
def _standing(robot: Robot) -> tuple[dict[str, np.ndarray], float]:
    """The hanging hands' lowest points (standing frame) and the arm's length (shoulder to hand)."""
    q = np.asarray(robot.q_standing, dtype=float)
    verts = hand_vertices(robot, q)
    model, data = robot.model, robot.model.createData()
    pin.framesForwardKinematics(model, data, q)
    fid = robot.frame_id("left_hand")
    j = int(model.frames[fid].parentJoint)
    while int(model.parents[j]) > 0 and model.names[int(model.parents[j])] != "root_joint" \
            and sum(int(model.frames[robot.frame_id(f"{s}_hand")].parentJoint) in model.subtrees[int(model.parents[j])]
                    for s in SIDES) == 1:
        j = int(model.parents[j])  # up the arm to its first joint (the one below the shared torso)
    arm = float(np.linalg.norm(data.oMf[fid].translation - data.oMi[j].translation))
    return {s: v[np.argmin(v[:, 2])] for s, v in verts.items()}, arm


def _solve(robot: Robot, goals: dict[str, np.ndarray]) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Whole-body damped least squares (standing frame): soles fixed, CoM over them, each hand's
    lowest point at ``goals[side]``, the hands turned as they hang standing as far as the reach
    allows; returns q and the hands' lowest points reached."""
    model, data = robot.model, robot.model.createData()
    q0 = np.asarray(robot.q_standing, dtype=float)
    pin.framesForwardKinematics(model, data, q0)
    com0 = pin.centerOfMass(model, data, q0).copy()
    feet = {s: data.oMf[robot.frame_id(f"{s}_foot")].copy() for s in SIDES}
    hands = {s: robot.frame_id(f"{s}_hand") for s in SIDES}
    R0 = {s: data.oMf[hands[s]].rotation.copy() for s in SIDES}
    low, _ = _standing(robot)
    offset = {s: data.oMf[hands[s]].translation - low[s] for s in SIDES}  # hand frame above its lowest point
    q = q0.copy()
    lo, hi = model.lowerPositionLimit[7:], model.upperPositionLimit[7:]
    reached = dict(low)
    for _ in range(4):  # the lowest point moves on the hand as it turns: re-aim the frame
        frame_goal = {s: goals[s] + offset[s] for s in SIDES}
        for _ in range(150):
            pin.computeJointJacobians(model, data, q)
            pin.framesForwardKinematics(model, data, q)
            rows, errs, w = [], [], []
            for s in SIDES:
                fid = robot.frame_id(f"{s}_foot")
                rows.append(pin.getFrameJacobian(model, data, fid, pin.LOCAL))
                errs.append(pin.log6(data.oMf[fid].actInv(feet[s])).vector)
                w += [10.0] * 6
                J = pin.getFrameJacobian(model, data, hands[s], pin.LOCAL_WORLD_ALIGNED)
                M = data.oMf[hands[s]]
                rows += [J[:3], J[3:]]
                errs += [frame_goal[s] - M.translation, pin.log3(R0[s] @ M.rotation.T)]
                w += [3.0] * 3 + [0.3] * 3
            rows.append(pin.jacobianCenterOfMass(model, data, q)[:2])
            errs.append(com0[:2] - data.com[0][:2])
            w += [5.0] * 2
            q, step = ik_step(model, q, q0, rows, errs, np.asarray(w), damping=1.1e-2, pull=1e-2, lo=lo, hi=hi)
            if step < 1e-6:
                break
        verts = hand_vertices(robot, q)
        reached = {s: v[np.argmin(v[:, 2])] for s, v in verts.items()}
        for s in SIDES:
            offset[s] = offset[s] + (goals[s] - reached[s])
    return q, reached


def _ahead(table: SceneObject, T: pin.SE3, start: np.ndarray, reach: float) -> np.ndarray | None:
    """The first point (standing frame) straight ahead of ``start`` at the table's top height whose
    ``INSET`` neighbourhood lies on the top, scanning ``reach`` [m] forward (None: none)."""
    top = float(table.position[2] + table.size[2] / 2)
    for dx in np.arange(0.0, reach + INSET + 1e-9, SCAN):
        p = np.array([start[0] + dx, start[1], 0.0])
        world = T.act(p)
        world[2] = top
        if all(on_top(table, world + T.rotation @ np.array([ex, ey, 0.0]), tolerance=0.01)
               for ex in (-INSET, 0.0, INSET) for ey in (-INSET / 2, 0.0, INSET / 2)):
            return np.array([p[0], p[1], top - float(T.translation[2])])
    return None


def _touching_link(robot: Robot, side: str, q: np.ndarray) -> str:
    """The link of the hand whose collision mesh holds the hand's lowest vertex at ``q`` (talos: a
    fingertip, its origin 3.4 cm from the contact; the hand frame is 16 cm above it).

    **Why that link:** the contact's region then lies next to its frame (talos: 3.4 cm; 16 cm below the
    hand frame), and MuJoCo reports the touch on that link."""
    model, data = robot.model, robot.model.createData()
    cdata = robot.collision_model.createData()
    pin.framesForwardKinematics(model, data, q)
    pin.updateGeometryPlacements(model, data, robot.collision_model, cdata, q)
    lowest, name = math.inf, robot.frame(f"{side}_hand")
    for i in _hand_geoms(robot, side):
        g = robot.collision_model.geometryObjects[i]
        z = float((np.asarray(g.geometry.vertices(), dtype=float).reshape(-1, 3) @ cdata.oMg[i].rotation.T
                   + cdata.oMg[i].translation)[:, 2].min())
        if z < lowest:
            lowest, name = z, model.frames[g.parentFrame].name
    return name


def ik_step(model: pin.Model, q: np.ndarray, q0: np.ndarray, rows: list[np.ndarray], errs: list[np.ndarray],
            weights: np.ndarray, *, damping: float, pull: float, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, float]:
    """One half step of a damped, weighted least-squares inverse kinematics (lean's and kneel's postures):
    the task rows ``rows`` (Jacobians) and errors ``errs`` weighted by ``weights``, Levenberg damping
    ``damping``, a pull of strength ``pull`` towards ``q0``, the joints clipped to ``[lo, hi]``.
    Returns the new configuration and the full step's norm."""
    A, b = np.vstack(rows) * weights[:, None], np.concatenate(errs) * weights
    H = A.T @ A + damping * np.eye(model.nv)
    dv = np.linalg.solve(H, A.T @ b + pull * pin.difference(model, q, q0))
    q = pin.integrate(model, q, 0.5 * dv)
    q[7:] = np.clip(q[7:], lo, hi)
    return q, float(np.linalg.norm(dv))


def hand_region(verts: np.ndarray, table: SceneObject, *, band: float = REGION_BAND,
                minimum: float = REGION_MIN) -> np.ndarray:
    """Corners (4, 3) of a body part's support region on a surface (world): the rectangle, in the
    surface's frame, of its vertices within ``band`` of the lowest one (a hand: ``REGION_BAND``), at
    least ``minimum`` each way (``REGION_MIN``) about its centre. A knee on the floor
    (:mod:`tasks.primitives.kneel`) takes its own band."""
    R, c = np.asarray(rotation(table.rpy)), np.asarray(table.position)
    z = float(verts[:, 2].min())
    low = (verts[verts[:, 2] <= z + band] - c) @ R
    lo, hi = low[:, :2].min(axis=0), low[:, :2].max(axis=0)
    mid, half = (lo + hi) / 2, np.maximum((hi - lo) / 2, minimum / 2)
    lo, hi = mid - half, mid + half
    local = np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]])
    return np.column_stack([local, np.zeros(4)]) @ R.T + np.array([c[0], c[1], z])


def leaning(robot: Robot, stance: Stance, table: SceneObject) -> Leaning:
    """The robot leaning on ``table`` with both hands, its feet at ``stance`` (module docstring).

    Raises:
        BeyondCapability: no top within reach ahead, a top too high or too low.
    """
    T = stance.transform_from_standing(robot)
    low, arm = _standing(robot)
    top = float(table.position[2] + table.size[2] / 2) - float(T.translation[2])  # in the standing frame
    hanging = min(float(p[2]) for p in low.values())
    if top > hanging - TOLERANCE:
        raise BeyondCapability(f"lean on: the {table.name}'s top at {top:.2f} m is above {robot.name}'s hands hanging "
                               f"({hanging:.2f} m): leaning presses down on a lower surface; choose a lower table")
    goals = {}
    for s in SIDES:
        p = _ahead(table, T, low[s], REACH * arm)
        if p is None:
            raise BeyondCapability(f"lean on: the {table.name}'s top is not within {robot.name}'s reach ahead of its "
                                   f"{s} hand ({REACH * arm:.2f} m): walk to it first")
        goals[s] = p
    q, reached = _solve(robot, goals)
    miss = {s: goals[s] - reached[s] for s in SIDES}
    if max(abs(float(m[2])) for m in miss.values()) > TOLERANCE or \
            max(float(np.linalg.norm(m[:2])) for m in miss.values()) > XY_TOLERANCE:
        deepest = max(float(r[2]) for r in reached.values())
        raise BeyondCapability(f"lean on: the {table.name}'s top at {top:.2f} m is below where {robot.name}'s hands "
                               f"reach down to {float(goals['left'][0]):.2f} m ahead ({deepest:.2f} m): choose a higher table")
    drop = float(robot.q_standing[2] - q[2])
    if drop > MAX_DROP:
        raise BeyondCapability(f"lean on: the {table.name}'s top at {top:.2f} m is too low for {robot.name} to lean on: its "
                               f"base would drop {drop:.2f} m (more than {MAX_DROP:.2f} m, a squat); choose a higher table")
    model, data = robot.model, robot.model.createData()
    q[:7] = pin.SE3ToXYZQUAT(T * pin.XYZQUATToSE3(q[:7]))
    pin.framesForwardKinematics(model, data, q)
    normal = np.asarray(rotation(table.rpy))[:, 2]
    verts = hand_vertices(robot, q)
    contacts = []
    for s in SIDES:
        world = hand_region(verts[s], table)
        frame = _touching_link(robot, s, q)
        M = data.oMf[model.getFrameId(frame)]
        contacts.append(Contact(frame=frame, placement=Pose(position=_vec(M.translation),
                                                                                rpy=_vec(pin.rpy.matrixToRpy(M.rotation))),
                                friction_coefficient=table.friction, region=tuple(_vec(M.actInv(c)) for c in world),
                                normal=_vec(normal)))
    return Leaning(q=q, contacts=tuple(contacts), table=table)


@lru_cache(maxsize=16)
def _cached(robot: Robot, stance: Stance, table: SceneObject) -> Leaning:
    return leaning(robot, stance, table)


def _lean(b: FragmentBuilder) -> Leaning:
    g: Grounded = grounded(b.params, "lean_on")
    return _cached(b.robot, b.stance, g.obj)


def build_lean_on(b: FragmentBuilder) -> Fragment:
    """Hands down onto the table (both feet down), lean on it (feet and hands in contact), come back up."""
    s = _lean(b)
    b.phase("hands down", DOWN)
    b.phase("leaning", DOWN + HOLD, (*b.contacts(), *s.contacts))
    b.phase("back up", DOWN + HOLD + UP)
    com = pin.centerOfMass(b.robot.model, b.robot.model.createData(), np.asarray(b.robot.q_standing, dtype=float))
    ahead = b.world(com + np.array([COM_FORWARD, 0.0, 0.0]))
    b.com_target("CoM over the front of the soles", (ahead[0], ahead[1], None), window=(DOWN - SETTLE, DOWN + HOLD + SETTLE),
                 tolerance=COM_TOLERANCE)
    model, data = b.robot.model, b.robot.model.createData()
    pin.framesForwardKinematics(model, data, s.q)
    for c in s.contacts:  # the wrist link too (one joint up): g1's hangs 3 mm above the table by its hand's edge
        wrist = int(model.parents[model.frames[b.robot.frame_id(c.frame)].parentJoint])
        frame = next(f.name for f in model.frames if f.type == pin.FrameType.BODY and f.parentJoint == wrist)
        what = f"{frame} at the {s.table.name}"
        b.targets.append(FrameTarget(name=b.name(what), frame=frame, position=_vec(data.oMf[model.getFrameId(frame)].translation),
                                     window=b.window(APPROACH * DOWN, DOWN + HOLD + (1 - APPROACH) * UP),
                                     tolerance=TOUCH_TOLERANCE, touch=s.table.name))
    return b.finish(PARTS, dynamic=True)


def _check(params: dict, robot: Robot) -> None:
    g = grounded(params, "lean_on")
    _cached(robot, g.start if isinstance(g.start, Stance) else Stance.standing(robot), g.obj)


LEAN_ON = Primitive(name="lean_on", nominal_duration=lambda p, r: DOWN + HOLD + UP, build=build_lean_on,
                    parts=lambda p: PARTS, check=lambda p, r: _check(p, r))

PRIMITIVES = (LEAN_ON,)

__all__ = ["LEAN_ON", "PRIMITIVES", "Leaning", "hand_vertices", "ik_step", "leaning"]
