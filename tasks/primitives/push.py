"""Pushing an object forward: ``push(object, distance, arm, direction)`` (docs/objects.md).

One hand pushes a movable box or cylinder forward (along the robot's heading) by ``distance`` on
what it stands on (a table, the floor): no grasp, the object slides with its friction. Five
phases, both feet down:

1. *approach*: :data:`APPROACH_TIME`, the hand to :data:`PRE_BACK` in front of the object's near
   face (seen from the robot), at the contact height;
2. *contact*: :data:`CONTACT_TIME`, the hand to the face, its geometry :data:`PUSH_DEPTH` into it
   (the planned press), on the straight line through targets every :data:`PUSH_STEP` that touch
   the object (left to the solver, the hand went up over the object's corner and dropped onto the
   face: the robot fell);
3. *push*: ``distance`` / :data:`PUSH_SPEED` (at least :data:`PUSH_MIN_TIME`), the hand moved
   forward by ``distance`` through targets every :data:`PUSH_STEP` (a moving planned contact);
4. *retreat*: the hand :data:`OFF_BACK` off the face (:data:`OFF_TIME`), up until its lowest point is
   :data:`LIFT_CLEARANCE` over the object's top (:data:`LIFT_OFF_TIME`: the planner keeps the object's
   collision geometry where the scene put it, so the hand leaves over it), back to :data:`PRE_BACK`
   in front of where the near face was (:data:`RETREAT_TIME`);
5. *rest*: :data:`REST_TIME`, the arm back to rest.

The hand keeps its standing orientation (talos: fingers down); its frame is placed from its
collision meshes (:func:`tasks.primitives.grasp.hand_points`): the lowest point
:data:`PUSH_CLEARANCE` above the object's bottom (what it stands on), centred on the object
laterally, the front of the meshes that face the object at the face. Every hand target on the
face names the object (``FrameTarget.touch``): the planner's scene rows, its pre-check and the
certificate's scene-collision line leave that hand and object out, as for ``touch_object``. The
planner does not move the object: its collision geometry stays where the scene puts it.

Refused before planning, in task terms: a way other than forward (``push the box to the left``:
the hand would press a side face, which no contact placement or timing here plans; the message
says how to move it there with a pick-up and a put-down instead), a fixed object, a sphere or
mesh, an object lower than the hand's clearance, a pushed path that leaves the top it stands on or comes within
:data:`PATH_CLEARANCE` of another object, the hand beyond its reach at the end of the push
("walk to it first"), or an object too heavy for the arm to push: the friction force
``mu m g`` (``mu`` the larger friction coefficient of the object and what it stands on, as
MuJoCo combines them) beyond the static force the arm can push forward at the contact, every
joint from the base to the hand within :data:`PUSH_TORQUE_FRACTION` of its torque limit
(``|g(q) + J_p^T u F| ``, the posture from :func:`tasks.primitives.grasp.carry_posture`).

The spec gets a :class:`tasks.specs.Push` (object, hand frame, direction, distance, the push
window); the simulation's certificate checks how far the object moved (``sim/grasp.py``).
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from robots import Robot
from tasks.exceptions import TaskDefinitionError
from tasks.primitives.arms import POSE_TOLERANCE, reach_gap
from tasks.primitives.base import Fragment, FragmentBuilder, Primitive, rest_targets
from tasks.primitives.geometry import Stance, standing_geometry
from tasks.primitives.grasp import carry_posture, hand_points, holding_arm, object_arm_parts
from tasks.primitives.objects import grounded
from tasks.scene import Scene, SceneObject, extent
from tasks.specs import Push

PRE_BACK = 0.06  # [m] the hand waits this far in front of the near face, and retreats this far
PUSH_DEPTH = 0.005  # [m] the hand's meshes planned this far into the face (the press)
PUSH_CLEARANCE = 0.03  # [m] the hand's lowest point above the object's bottom (what it stands on)
PATH_CLEARANCE = 0.02  # [m] the pushed object's box from every other object's box along the path
EDGE_MARGIN = 0.0  # [m] the object's centre stays this far inside its support's top face
PUSH_SPEED = 0.05  # [m/s] nominal hand speed while pushing
PUSH_MIN_TIME = 1.5  # [s]
PUSH_STEP = 0.25  # [s] a hand target on the moving face this often
PUSH_TOLERANCE = 0.005  # [m] planned hand position on the face
PUSH_TORQUE_FRACTION = 0.9  # of a joint's torque limit, pushing statically
APPROACH_TIME = 2.0  # [s]
CONTACT_TIME = 1.0  # [s]
OFF_TIME = 0.25  # [s] the hand back by OFF_BACK from the pushed face
OFF_BACK = 0.02  # [m]
LIFT_OFF_TIME = 0.75  # [s] then up until its lowest point is LIFT_CLEARANCE over the object's top
LIFT_CLEARANCE = 0.05  # [m]
RETREAT_TIME = 1.0  # [s] then back over where the object stood, to PRE_BACK in front of its near face
REST_TIME = 1.5  # [s] (1 s: the wrist, arm_*_5_joint, at the controller's 97 % torque cap on the way down)
GRAVITY = 9.81  # [m/s^2]
SUPPORT_GAP = 0.01  # [m] an object stands on another whose top is within this of its bottom


def push_time(distance: float) -> float:
    """Nominal duration of the push phase [s]."""
    return max(PUSH_MIN_TIME, distance / PUSH_SPEED)


def _duration(params: dict, robot: Robot) -> float:
    return (APPROACH_TIME + CONTACT_TIME + push_time(float(params["distance"])) + OFF_TIME + LIFT_OFF_TIME
            + RETREAT_TIME + REST_TIME)


def pushing_arm(params: dict, robot: Robot) -> str:
    """The stated arm, else the one on the object's side."""
    return holding_arm(params, robot, "push")


def support(scene: Scene, obj: SceneObject) -> SceneObject | None:
    """The object ``obj`` stands on (its top within :data:`SUPPORT_GAP` of ``obj``'s bottom, under
    its centre); None: the floor."""
    lo, _ = extent(obj)
    c = np.asarray(obj.position, dtype=float)
    for o in scene.objects:
        if o.name == obj.name:
            continue
        olo, ohi = extent(o)
        if abs(float(ohi[2]) - float(lo[2])) <= SUPPORT_GAP and olo[0] <= c[0] <= ohi[0] and olo[1] <= c[1] <= ohi[1]:
            return o
    return None


def friction_force(scene: Scene, obj: SceneObject) -> tuple[float, float, str]:
    """(force [N], mu, what it stands on): the Coulomb friction that resists sliding ``obj``."""
    under = support(scene, obj)
    mu_under = scene.floor_friction if under is None else under.friction
    mu = max(float(obj.friction), float(mu_under))
    return mu * float(obj.mass) * GRAVITY, mu, "the floor" if under is None else f"the {under.name}"


def _heading_box(stance: Stance, obj: SceneObject) -> tuple[np.ndarray, np.ndarray]:
    """(centre, half extents) of the object's axis-aligned box in the heading frame where the robot stands."""
    H = stance.heading()
    c = H.actInv(np.asarray(obj.position, dtype=float))
    lo, hi = (np.asarray(v, dtype=float) for v in extent(obj))
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    local = (corners - H.translation) @ H.rotation
    return np.asarray(c, dtype=float), 0.5 * (local.max(axis=0) - local.min(axis=0))


def contact_poses(robot: Robot, stance: Stance, obj: SceneObject, side: str, distance: float) -> dict[str, np.ndarray]:
    """Heading-frame positions [m] of the ``side`` hand frame: ``pre`` (in front of the near face),
    ``contact`` (at the face), ``end`` (pushed by ``distance``), ``back`` (retreated)."""
    c, half = _heading_box(stance, obj)
    pts = hand_points(robot, side)  # the hand's meshes relative to its frame, heading axes
    bottom, top = c[2] - half[2], c[2] + half[2]
    z = bottom + PUSH_CLEARANCE - float(pts[:, 2].min())
    facing = pts[(pts[:, 2] + z >= bottom) & (pts[:, 2] + z <= top)]
    if len(facing) == 0:
        raise TaskDefinitionError(
            f"push: the {obj.name} is {2 * half[2] * 100:.0f} cm high; the {side} hand's geometry stays "
            f"{PUSH_CLEARANCE * 100:g} cm above what it stands on, so it would pass over it")
    front = float(facing[:, 0].max())
    y = c[1] - 0.5 * float(pts[:, 1].min() + pts[:, 1].max())
    x = c[0] - half[0] - front + PUSH_DEPTH
    contact = np.array([x, y, z])
    up = np.array([0.0, 0.0, top + LIFT_CLEARANCE - (z + float(pts[:, 2].min()))])  # the hand's lowest point over the top
    ahead = np.array([1.0, 0.0, 0.0])
    off = contact + (distance - OFF_BACK) * ahead
    return {"pre": contact - PRE_BACK * ahead, "contact": contact, "end": contact + distance * ahead,
            "off": off, "up": off + up, "back": contact - PRE_BACK * ahead + up}


def push_capacity(robot: Robot, side: str, hand_in_standing: pin.SE3) -> tuple[float, str]:
    """(largest static forward push [N], the joint that limits it) of the ``side`` hand at
    ``hand_in_standing`` (standing world frame, legs standing; the arm's posture from
    :func:`tasks.primitives.grasp.carry_posture`): every joint from the base to the hand within
    :data:`PUSH_TORQUE_FRACTION` of its limit with ``tau = g(q) + J_p^T u F``."""
    model, data = robot.model, robot.data()
    q = robot.q_standing.copy()
    for name, value in carry_posture(robot, side, hand_in_standing).items():
        q[model.joints[model.getJointId(name)].idx_q] = value
    fid = robot.frame_id(f"{side}_hand")
    g = pin.computeGeneralizedGravity(model, data, q)[6:]
    J = pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL_WORLD_ALIGNED)[:3, 6:]
    u = standing_geometry(robot).heading.rotation[:, 0]
    a = J.T @ u
    limit = PUSH_TORQUE_FRACTION * np.asarray(robot.torque_limits, dtype=float)
    joint = model.frames[fid].parentJoint
    best, who = math.inf, ""
    for j in model.supports[joint]:
        if j <= 1 or model.joints[j].nv != 1:
            continue
        i = model.joints[j].idx_v - 6
        if abs(a[i]) < 1e-9:
            continue
        room = (limit[i] - g[i]) / a[i] if a[i] > 0 else (limit[i] + g[i]) / -a[i]
        if room < best:
            best, who = max(0.0, float(room)), model.names[j]
    return best, who


def _check(params: dict, robot: Robot) -> None:
    g = grounded(params, "push")
    obj = g.obj
    if not obj.movable:
        raise TaskDefinitionError(f"push: the {obj.name} is fixed in the scene (movable: false); it cannot be pushed")
    if obj.shape not in ("box", "cylinder"):
        raise TaskDefinitionError(f"push: the {obj.name} is a {obj.shape}; wbmp pushes boxes and cylinders")
    if not robot.has_role("left_hand") or not robot.has_role("right_hand"):
        raise TaskDefinitionError(f"push: {robot.name} has no hand frames")
    way = params.get("direction") or "forward"
    if way != "forward":
        cm = f"{float(params['distance']) * 100:.0f} cm"
        said = {"left": f"{cm} to the left", "right": f"{cm} to the right", "backward": f"{cm} back"}[way]
        raise TaskDefinitionError(
            f"push: wbmp pushes objects forward only (along the robot's heading), not {way}: to move the {obj.name} "
            f'{said}, pick it up and put it down there ("pick up the {obj.name}, then put it down {said}")')
    if not isinstance(g.start, Stance):
        return
    stance, side, distance = g.start, pushing_arm(params, robot), float(params["distance"])
    H = stance.heading()
    u = H.rotation[:, 0]
    lo, hi = (np.asarray(v, dtype=float) for v in extent(obj))
    under = support(g.scene, obj)
    end = np.asarray(obj.position, dtype=float) + distance * u
    if under is not None:
        ulo, uhi = extent(under)
        if not (ulo[0] + EDGE_MARGIN <= end[0] <= uhi[0] - EDGE_MARGIN and ulo[1] + EDGE_MARGIN <= end[1] <= uhi[1] - EDGE_MARGIN):
            raise TaskDefinitionError(f"push: pushed {distance:g} m the {obj.name} would go over the edge of the "
                                      f"{under.name}; push it less far")
    for other in g.scene.objects:
        if other.name == obj.name or (under is not None and other.name == under.name):
            continue
        olo, ohi = (np.asarray(v, dtype=float) for v in extent(other))
        for s in np.linspace(0.0, distance, 7):
            d = np.maximum(0.0, np.maximum(lo + s * u - ohi, olo - hi - s * u))
            if float(np.linalg.norm(d)) < PATH_CLEARANCE:
                raise TaskDefinitionError(f"push: the {other.name} is in the way of the {obj.name} within {s:.2f} m; "
                                          "push it less far")
    poses = contact_poses(robot, stance, obj, side, distance)
    gap = max(reach_gap(robot, side, poses[k], bend=True) for k in ("contact", "end"))
    if gap > 1e-9:
        raise TaskDefinitionError(
            f"push: the {obj.name} is {gap:.2f} m beyond the {side} hand's reach from where the robot stands "
            f'(pushed {distance:g} m): walk to it first ("walk to the {obj.name} and push it")')
    force, mu, what = friction_force(g.scene, obj)
    R = standing_geometry(robot).rotation(f"{side}_hand")
    capacity, joint = math.inf, ""
    for k in ("contact", "end"):
        try:
            cap, j = push_capacity(robot, side, pin.SE3(R, _standing(robot, poses[k])))
        except TaskDefinitionError:
            raise TaskDefinitionError(
                f"push: the {side} hand cannot push the {obj.name}'s near face {'there' if k == 'contact' else 'that far'} "
                f'with the legs standing: walk to it first ("walk to the {obj.name} and push it")') from None
        if cap < capacity:
            capacity, joint = cap, j
    if capacity <= 0.0:
        raise TaskDefinitionError(
            f"push: pushed {distance:g} m the {obj.name} takes the {side} hand so far out that the arm's own weight needs "
            f"more than {PUSH_TORQUE_FRACTION * 100:.0f} % of {joint}'s torque limit: push it less far, or walk closer first")
    if force > capacity:
        raise TaskDefinitionError(
            f"push: the {obj.name} ({obj.mass:g} kg, friction {mu:g} on {what}) needs {force:.0f} N to slide; the "
            f"{side} arm can push {capacity:.0f} N forward there ({joint} at {PUSH_TORQUE_FRACTION * 100:.0f} % of its "
            "torque limit): lighten it in the scene")


def _standing(robot: Robot, heading_point: np.ndarray) -> np.ndarray:
    return np.asarray(standing_geometry(robot).heading.act(np.asarray(heading_point, dtype=float)), dtype=float)


def build_push(b: FragmentBuilder) -> Fragment:
    """Approach, contact, push by ``distance`` (a moving planned contact), retreat, rest."""
    import dataclasses

    g = grounded(b.params, "push")
    if not isinstance(g.start, Stance):
        g = dataclasses.replace(g, start=b.stance)
        b.params["object"] = g
    _check(b.params, b.robot)
    side = pushing_arm(b.params, b.robot)
    distance = float(b.params["distance"])
    poses = contact_poses(b.robot, b.stance, g.obj, side, distance)
    H = b.stance.heading()
    rpy = b.world_rotation(b.geometry.rotation(f"{side}_hand"))
    name, role = g.obj.name, f"{side}_hand"
    t_pre = APPROACH_TIME
    t_on = t_pre + CONTACT_TIME
    t_end = t_on + push_time(distance)
    t_back = t_end + OFF_TIME + LIFT_OFF_TIME + RETREAT_TIME

    def world(key_or_point) -> tuple[float, float, float]:
        p = poses[key_or_point] if isinstance(key_or_point, str) else key_or_point
        w = H.act(np.asarray(p, dtype=float))
        return (float(w[0]), float(w[1]), float(w[2]))

    b.frame_target(f"{side} hand in front of the {name}", role, position=world("pre"), rpy=rpy, time=t_pre,
                   tolerance=POSE_TOLERANCE)
    # in to the face on the straight line, every PUSH_STEP (the hand's path is planned, not left to the NLP)
    a = max(1, round(CONTACT_TIME / PUSH_STEP))
    for i in range(1, a):
        p = poses["pre"] + i / a * (poses["contact"] - poses["pre"])
        b.frame_target(f"{side} hand nears the {name} ({i}/{a - 1})", role, position=world(p), rpy=rpy,
                       time=t_pre + i / a * CONTACT_TIME, tolerance=PUSH_TOLERANCE, touch=name)
    b.frame_target(f"{side} hand on the {name}", role, position=world("contact"), rpy=rpy, time=t_on,
                   tolerance=PUSH_TOLERANCE, touch=name)
    n = max(1, round((t_end - t_on) / PUSH_STEP))
    for i in range(1, n + 1):
        s = i / n
        p = poses["contact"] + s * (poses["end"] - poses["contact"])
        b.frame_target(f"{side} hand pushes the {name} ({i}/{n})", role, position=world(p), rpy=rpy,
                       time=t_on + s * (t_end - t_on), tolerance=PUSH_TOLERANCE, touch=name)
    # off the face, then up over the object (the planner keeps it where the scene put it), then back
    b.frame_target(f"{side} hand off the {name}", role, position=world("off"), rpy=rpy, time=t_end + OFF_TIME,
                   tolerance=PUSH_TOLERANCE, touch=name)
    m = max(1, round(LIFT_OFF_TIME / PUSH_STEP))
    for i in range(1, m + 1):
        p = poses["off"] + i / m * (poses["up"] - poses["off"])
        b.frame_target(f"{side} hand above the {name} ({i}/{m})", role, position=world(p), rpy=rpy,
                       time=t_end + OFF_TIME + i / m * LIFT_OFF_TIME, tolerance=POSE_TOLERANCE, touch=name)
    b.frame_target(f"{side} hand back from the {name}", role, position=world("back"), rpy=rpy, time=t_back,
                   tolerance=POSE_TOLERANCE)
    total = _duration(b.params, b.robot)
    rest_targets(b, [role], tau=total)
    b.phase(f"approach the {name}", t_on)
    b.phase(f"push the {name}", t_end)
    b.phase(f"retreat from the {name}", total)
    u = H.rotation[:, 0]
    b.pushes.append(Push(name=b.name(f"{side} hand pushes the {name}"), object=name, frame=b.robot.frame(role),
                         direction=(float(u[0]), float(u[1]), 0.0), distance=distance, start=b.t(t_on), end=b.t(t_end)))
    return b.finish(frozenset({f"{side}_arm", "torso"}))


PUSH = Primitive(name="push", nominal_duration=_duration, build=build_push, parts=object_arm_parts, check=_check)

PRIMITIVES = (PUSH,)

__all__ = ["PRIMITIVES", "PUSH", "build_push", "contact_poses", "friction_force", "push_capacity", "pushing_arm",
           "support"]
