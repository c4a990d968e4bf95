"""Actions that hold a scene object: ``pick_up(object, arm, height)``, ``put_down(object, arm)``.

The ``object`` parameter arrives grounded (:class:`tasks.grounding.Grounded`), like the actions of
:mod:`tasks.primitives.objects`. ``pick_up`` writes four phases, both feet down:

1. *approach*: the hand to a pre-grasp pose :data:`PRE_BACK` behind and :data:`PRE_UP` above the
   grasp pose (seen from the robot), then to the grasp pose;
2. *grasp*: the hand at the grasp pose, held :data:`CLOSE_TIME`; the object's grasp point (its
   centre, raised to :data:`GRASP_DEPTH` below its top for a tall object) sits at the hand's grasp
   offset (:func:`grasp_offset`: between the fingertips), the hand in its standing orientation;
3. *lift*: the hand raised by ``height``;
4. *hold*: the hand held there.

The spec gets a :class:`tasks.specs.Grasp` from the start of the *grasp* phase to the end of the
motion: the planner exempts the hand from the object's scene-collision rows and loads the arm with
the object's weight; the simulation attaches the object to the hand once it is held within the
grasp's tolerance (docs/objects.md).

``put_down`` lowers the held object back onto where it was picked up (the grasp pose), holds it
there :data:`RELEASE_TIME`, lets go (the grasp's ``end``, its ``place`` the object's position in the
scene), retreats to the pre-grasp pose and brings the arm back to rest.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin

from robots import Robot
from tasks.exceptions import TaskDefinitionError
from tasks.grounding import Grounded
from tasks.primitives.arms import POSE_TOLERANCE, UPPER_ARM_OUT, hold_upper_arms, reach_gap
from tasks.primitives.base import Fragment, FragmentBuilder, Primitive, rest_targets
from tasks.primitives.bodymap import body_map, to_heading, to_standing
from tasks.primitives.geometry import Stance, standing_geometry
from tasks.primitives.objects import grounded
from tasks.scene import SceneObject, extent
from tasks.specs import Grasp

PRE_BACK = 0.06  # [m] the pre-grasp pose is this far back towards the robot
PRE_UP = 0.08  # [m] and this far up
GRASP_DEPTH = 0.04  # [m] a tall object is held this far below its top (not below its centre)
GRASP_CLEARANCE = 0.03  # [m] the hand's geometry above the object's bottom (what it stands on)
GRASP_TOLERANCE = 0.03  # [m] the hand holds the object when its grasp point is this close (simulation)
GRASP_TARGET_TOLERANCE = 0.004  # [m] planned hand position at the grasp, lifted and put down
APPROACH_TIME = 1.5  # [s] nominal: rest -> pre-grasp
REACH_IN_TIME = 1.0  # [s] pre-grasp -> grasp
CLOSE_TIME = 0.5  # [s] held at the grasp (the hand closes)
LIFT_TIME = 1.0  # [s] grasp -> lifted
HOLD_TIME = 1.0  # [s] lifted, held
DURATION = APPROACH_TIME + REACH_IN_TIME + CLOSE_TIME + LIFT_TIME + HOLD_TIME


def grasp_offset(robot: Robot, side: str) -> np.ndarray:
    """Where a held object's grasp point sits in the ``side`` hand frame (3,) [m]: the centre of the
    box the fingertip frames that move with the hand span (talos: midway between its two-fingertip
    side and its one-fingertip side, where the fingers close), else the hand frame's origin.

    Not the fingertips' mean: talos has two fingertips on one side and one on the other, so their
    mean sits 1.7 cm towards the pair, and the pair's pads would sink 6 mm into a cup of 8 cm that
    the open gripper (9.2 cm between its pads) should straddle (the simulation closes the fingers
    on the object: docs/objects.md)."""
    model = robot.model
    hand = robot.frame_id(f"{side}_hand")
    joint = model.frames[hand].parentJoint
    tips = [f.name for f in model.frames if "fingertip" in f.name and f.parentJoint == joint]
    if not tips:
        return np.zeros(3)
    data = robot.data()
    pin.framesForwardKinematics(model, data, robot.q_standing)
    M = data.oMf[hand]
    points = np.array([M.actInv(data.oMf[model.getFrameId(n)].translation) for n in tips])
    return 0.5 * (points.min(axis=0) + points.max(axis=0))


def grasp_point(robot: Robot, side: str, obj: SceneObject) -> np.ndarray:
    """The object's point the ``side`` hand holds (world) [m]: its centre, raised to ``GRASP_DEPTH``
    below its top, and high enough that the hand's geometry (in its standing orientation) stays
    :data:`GRASP_CLEARANCE` above the object's bottom (the table it stands on), but not above its top."""
    lo, hi = extent(obj)
    c = np.asarray(obj.position, dtype=float).copy()
    below = float(standing_geometry(robot).rotation(f"{side}_hand") @ grasp_offset(robot, side) @ [0.0, 0.0, 1.0]) \
        - float(body_map(robot).hand_lo[side][2])  # hand geometry below the grasp point [m]
    c[2] = min(float(hi[2]), max(c[2], float(hi[2]) - GRASP_DEPTH, float(lo[2]) + below + GRASP_CLEARANCE))
    return c


def holding_arm(params: dict, robot: Robot, action: str = "pick_up") -> str:
    """The arm that picks (pushes, ...: ``action`` names it in errors): the stated one, else the
    one on the object's side."""
    if params.get("arm"):
        return str(params["arm"])
    g = grounded(params, action)
    start = g.start if isinstance(g.start, Stance) else Stance.standing(robot)
    local = start.heading().actInv(np.asarray(g.obj.position, dtype=float))
    return "left" if local[1] >= 0 else "right"


def _poses(robot: Robot, stance: Stance, g: Grounded, side: str, height: float) -> dict[str, np.ndarray]:
    """World positions [m] of the hand frame: ``pre``, ``grasp``, ``lift``; its orientation ``R``."""
    T = stance.transform_from_standing(robot)
    R = T.rotation @ standing_geometry(robot).rotation(f"{side}_hand")
    hand = grasp_point(robot, side, g.obj) - R @ grasp_offset(robot, side)
    forward = T.rotation @ standing_geometry(robot).heading.rotation[:, 0]
    up = np.array([0.0, 0.0, 1.0])
    return {"pre": hand - PRE_BACK * forward + PRE_UP * up, "grasp": hand, "lift": hand + height * up, "R": R}


def _check(params: dict, robot: Robot) -> None:
    g = grounded(params, "pick_up")
    obj = g.obj
    if not obj.movable:
        raise TaskDefinitionError(f"pick_up: the {obj.name} is fixed in the scene (movable: false); it cannot be picked up")
    if not robot.has_role("left_hand") or not robot.has_role("right_hand"):
        raise TaskDefinitionError(f"pick_up: {robot.name} has no hand frames")
    if params.get("arm") == "both" and obj.shape != "box":
        raise TaskDefinitionError(f"pick_up: the {obj.name} is a {obj.shape}; both hands pick up a box (pressing its sides)")
    if not isinstance(g.start, Stance):
        return  # where the robot will stand is not known yet (an action before it may walk)
    if params.get("arm") == "both":
        _check_both_reach(robot, g.start, obj, "pick_up", f"walk to the {obj.name} and pick it up with both hands")
        return
    side = holding_arm(params, robot)
    T = g.start.transform_from_standing(robot)
    point = to_heading(robot, T.actInv(grasp_point(robot, side, obj)))
    gap = reach_gap(robot, side, point, bend=True)
    if gap > 1e-9:
        raise TaskDefinitionError(
            f"pick_up: the {obj.name} is {gap:.2f} m beyond the {side} hand's reach from where the robot stands: "
            f'walk to it first ("walk to the {obj.name} and pick it up")')


def build_pick_up(b: FragmentBuilder) -> Fragment:
    """Approach, grasp, lift by ``height``, hold (see the module docstring)."""
    g = grounded(b.params, "pick_up")
    _check(b.params, b.robot)
    if not isinstance(g.start, Stance):
        g = dataclasses.replace(g, start=b.stance)
        b.params["object"] = g
        _check(b.params, b.robot)
    if b.params.get("arm") == "both":
        return _build_both(b, g)
    side = holding_arm(b.params, b.robot)
    height = float(b.params["height"])
    poses = _poses(b.robot, b.stance, g, side, height)
    rpy = b.world_rotation(b.geometry.rotation(f"{side}_hand"))
    name = g.obj.name
    t_pre = APPROACH_TIME
    t_in = t_pre + REACH_IN_TIME
    t_close = t_in + CLOSE_TIME
    t_lift = t_close + LIFT_TIME
    role = f"{side}_hand"

    def put(what: str, key: str, **when) -> None:
        b.frame_target(what, role, position=tuple(float(x) for x in poses[key]), rpy=rpy,
                       tolerance=GRASP_TARGET_TOLERANCE if key != "pre" else POSE_TOLERANCE, **when)

    put(f"{side} hand above the {name}", "pre", time=t_pre)
    put(f"{side} hand at the {name}", "grasp", window=(t_in, t_close))
    put(f"{side} hand lifts the {name}", "lift", window=(t_lift, DURATION))
    b.holds.append(b.name(f"{side} hand lifts the {name}"))  # held until the arm or the feet move again
    b.phase(f"approach the {name}", t_in)
    b.phase(f"grasp the {name}", t_close)
    b.phase(f"lift the {name}", t_lift)
    b.phase(f"hold the {name}", DURATION)
    offset = grasp_offset(b.robot, side)
    center = np.asarray(g.obj.position, dtype=float) - grasp_point(b.robot, side, g.obj)  # grasp point -> centre (world)
    offset_centre = offset + poses["R"].T @ center
    b.grasps.append(Grasp(
        name=b.name(f"{side} hand holds the {name}"), object=name, frame=b.robot.frame(role),
        offset=(float(offset_centre[0]), float(offset_centre[1]), float(offset_centre[2])),
        start=b.t(t_in), lift=height, hold=b.window(t_lift, DURATION), tolerance=GRASP_TOLERANCE))
    return b.finish(frozenset({f"{side}_arm", "torso"}))


def object_arm_parts(params: dict) -> frozenset[str]:
    """The body parts an object action moves: the stated arm (or both) with the torso, else the arm on
    the object's side, else both arms."""
    arm = params.get("arm")
    if arm == "both":
        return frozenset({"left_arm", "right_arm", "torso"})
    if arm:
        return frozenset({f"{arm}_arm", "torso"})
    g = params.get("object")
    if isinstance(g, Grounded) and isinstance(g.start, Stance):
        local = g.start.heading().actInv(np.asarray(g.obj.position, dtype=float))
        return frozenset({"left_arm" if local[1] >= 0 else "right_arm", "torso"})
    return frozenset({"left_arm", "right_arm", "torso"})


# --- both hands: a box pressed between the palms --------------------------------------------
SQUEEZE = 0.01  # [m] each hand's geometry planned this far inside the box's side face (the press)
PRE_SIDE = 0.08  # [m] the pre-grasp poses are this far out from the sides
PRE_UP_BOTH = 0.15  # [m] and this far up (the hands come from below the surface's height, beside the body)
BOTH_TURN = np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])  # about the heading y axis, -90 deg:
# a hand that hangs down in its standing orientation points forward, the arms reach out under the box's weight
BOTH_TOLERANCE = 0.03  # [m] a hand holds the box when the box's centre is this close to its held place (simulation)
WRIST_CLEAR = 0.01  # [m] the arm's meshes above the hand (the wrist) alongside the box stay this far off its face
FRONT_INSET = 0.01  # [m] a hand longer than the box: its fingertips this far short of the far face (the wrist back)
RISE_BACK = 0.03  # [m] the hands first rise to the pre-grasp height with their geometry this far behind the box's near face
HOLD_IN = 0.06  # [m] the lifted box is held this much nearer the chest than where it stood (the shoulders' lever)
RISE_TIME = 1.0  # [s] nominal: rest -> the hands raised in front of the body, behind the box
BESIDE_TIME = 1.6  # [s] nominal: raised -> beside the box (its pre-grasp poses); then in to the press by APPROACH_TIME + REACH_IN_TIME


def hand_points(robot: Robot, side: str, *, arm: bool = False) -> np.ndarray:
    """Vertices (n, 3) [m] of the collision meshes of the ``side`` hand (its frame's joint and the joints
    below) at the standing posture, relative to the hand frame, in heading axes (a primitive shape:
    the corners of its box). With ``arm``: those of the arm above the hand instead (the joints from
    the shoulder to the wrist that carry only this hand)."""
    model, data = robot.model, robot.data()
    cm = robot.collision_model
    gd = pin.GeometryData(cm)
    pin.framesForwardKinematics(model, data, robot.q_standing)
    pin.updateGeometryPlacements(model, data, cm, gd, robot.q_standing)
    fid = robot.frame_id(f"{side}_hand")
    below = set(model.subtrees[model.frames[fid].parentJoint])
    if arm:
        below = set(carrying_joints(robot, side)[1]) - below
    Hs = standing_geometry(robot).heading.rotation
    origin = data.oMf[fid].translation
    points = []
    for i, go in enumerate(cm.geometryObjects):
        if go.parentJoint not in below:
            continue
        geometry = go.geometry
        if hasattr(geometry, "vertices") and int(getattr(geometry, "num_vertices", False)):
            local = np.asarray(geometry.vertices(), dtype=float)
        elif hasattr(geometry, "halfSide"):
            h = np.asarray(geometry.halfSide, dtype=float)
            local = np.array([[a * h[0], b_ * h[1], c_ * h[2]] for a in (-1, 1) for b_ in (-1, 1) for c_ in (-1, 1)])
        else:
            continue
        M = gd.oMg[i]
        points.append((local @ M.rotation.T + M.translation - origin) @ Hs)
    if not points:
        return np.zeros((1, 3))
    return np.concatenate(points)


def both_turn(robot: Robot, side: str) -> np.ndarray:
    """The turn (3, 3) (heading axes) from the ``side`` hand's standing orientation to the one that
    holds a box with both hands: about the heading's lateral axis, by the multiple of 90 deg that
    brings its fingers (from its wrist, the hand frame's joint, to the middle of its collision
    meshes) nearest to forward. talos's hands hang down standing: :data:`BOTH_TURN` (-90 deg); g1's
    point forward with the elbows bent: none."""
    model, data = robot.model, robot.data()
    pin.framesForwardKinematics(model, data, robot.q_standing)
    fid = robot.frame_id(f"{side}_hand")
    wrist = data.oMi[model.frames[fid].parentJoint].translation - data.oMf[fid].translation
    points = hand_points(robot, side)
    fingers = 0.5 * (points.min(axis=0) + points.max(axis=0)) - standing_geometry(robot).heading.rotation.T @ wrist
    angle = np.arctan2(fingers[0], -fingers[2])  # from hanging down (heading -z) towards forward (+x)
    quarter = round(angle / (np.pi / 2))  # 1: forward already, 0: down, ...
    return np.linalg.matrix_power(BOTH_TURN, (1 - quarter) % 4)


def both_rotation(robot: Robot, side: str) -> np.ndarray:
    """The ``side`` hand's orientation holding a box with both hands (standing world frame): its
    standing orientation turned by :func:`both_turn` (heading axes)."""
    Hs = standing_geometry(robot).heading.rotation
    return Hs @ both_turn(robot, side) @ Hs.T @ standing_geometry(robot).rotation(f"{side}_hand")


def _both_poses(robot: Robot, stance: Stance, obj: SceneObject, height: float) -> dict[str, dict[str, np.ndarray]]:
    """World positions [m] of each hand frame (``rise``, ``pre``, ``grasp``, ``lift``) and its
    orientation ``R`` pressing the box's left and right sides (seen from the robot): each hand's
    geometry (standing orientation) :data:`SQUEEZE` inside its face, as low as keeps it
    :data:`GRASP_CLEARANCE` above the box's bottom, centred on the box's height if higher; centred
    on the box front to back, or, a hand longer than the box, as far back as keeps its fingertips
    :data:`FRONT_INSET` short of the far face (the wrist, wider than the hand, clear of the near
    face: centred, talos's forearm spheres reach 2 cm into the box).

    ``rise``: the pre-grasp height and side, the hand's geometry :data:`RISE_BACK` behind the box's
    near face (so behind the edge of what it stands on): the hands come up from beside the body in
    front of it, then forward over the surface. ``lift``: raised by ``height`` and :data:`HOLD_IN`
    nearer the robot (at most the box's half depth): the held box nearer the chest shortens the
    shoulders' lever on the arms' own weight and the box's (docs/objects.md)."""
    T = stance.transform_from_standing(robot)
    H = T * standing_geometry(robot).heading  # the heading frame where the robot stands
    c = H.actInv(np.asarray(obj.position, dtype=float))  # the box's centre in that frame
    R_box = H.rotation.T @ np.asarray(pin.rpy.rpyToMatrix(*obj.rpy))
    half = np.abs(R_box) @ (np.asarray(obj.size, dtype=float) / 2)  # half extents along the heading axes
    out = {}
    for side, sign in (("left", 1.0), ("right", -1.0)):
        turned = hand_points(robot, side) @ both_turn(robot, side).T  # the hand's collision meshes, turned (heading axes)
        lo, hi = turned.min(axis=0), turned.max(axis=0)
        inner = lo[1] if sign > 0 else hi[1]  # the hand's side towards the box
        y = c[1] + sign * (half[1] - SQUEEZE) - inner
        x = min(c[0] - 0.5 * (lo[0] + hi[0]), c[0] + half[0] - FRONT_INSET - hi[0])
        z = max(c[2] - 0.5 * (lo[2] + hi[2]), c[2] - half[2] + GRASP_CLEARANCE - lo[2])
        arm = hand_points(robot, side, arm=True) @ both_turn(robot, side).T + [x, 0.0, z]  # the wrist, forearm
        beside = (np.abs(arm[:, 0] - c[0]) < half[0]) & (np.abs(arm[:, 2] - c[2]) < half[2])  # alongside the box
        if beside.any():  # a wrist wider than the hand (g1) stays WRIST_CLEAR off the face: the hand stops short of it
            face = c[1] + sign * half[1]
            wrist = arm[beside, 1].min() if sign > 0 else arm[beside, 1].max()
            y = max(y, face + WRIST_CLEAR - wrist) if sign > 0 else min(y, face - WRIST_CLEAR - wrist)
        grasp = np.array([x, y, z])
        R = T.rotation @ both_rotation(robot, side)
        pre = grasp + np.array([0.0, sign * PRE_SIDE, PRE_UP_BOTH])
        rise = np.array([min(pre[0], c[0] - half[0] - RISE_BACK - hi[0]), pre[1], pre[2]])
        lift = grasp + np.array([-min(HOLD_IN, half[0]), 0.0, height])
        out[side] = {"rise": H.act(rise), "pre": H.act(pre), "grasp": H.act(grasp), "lift": H.act(lift), "R": R}
    return out


def _check_both_reach(robot: Robot, stance: Stance, obj: SceneObject, action: str, example: str) -> None:
    """Both press poses of the box within their hands' reach from ``stance`` (bending at the hips)."""
    poses = _both_poses(robot, stance, obj, 0.0)
    for side in ("left", "right"):
        point = to_heading(robot, stance.transform_from_standing(robot).actInv(poses[side]["grasp"]))
        gap = reach_gap(robot, side, point, bend=True)
        if gap > 1e-9:
            raise TaskDefinitionError(
                f"{action}: the {obj.name}'s {side} side is {gap:.2f} m beyond the {side} hand's reach from where the "
                f'robot stands: walk to it first ("{example}")')


def _build_both(b: FragmentBuilder, g: Grounded) -> Fragment:
    """Both hands press the box's sides, lift it by ``height`` and hold it: two :class:`Grasp` of the
    same object over the same window (the payload is shared; the simulation welds it to both hands)."""
    height = float(b.params["height"])
    poses = _both_poses(b.robot, b.stance, g.obj, height)
    name = g.obj.name
    t_pre = APPROACH_TIME
    t_in = t_pre + REACH_IN_TIME
    t_close = t_in + CLOSE_TIME
    t_lift = t_close + LIFT_TIME
    for side in ("left", "right"):
        role = f"{side}_hand"
        rpy = b.world_rotation(both_rotation(b.robot, side))
        p = poses[side]

        def put(what: str, key: str, role: str = role, rpy: tuple = rpy, p: dict = p, **when) -> None:
            b.frame_target(what, role, position=tuple(float(x) for x in p[key]), rpy=rpy,
                           tolerance=GRASP_TARGET_TOLERANCE if key not in ("rise", "pre") else POSE_TOLERANCE, **when)

        put(f"{side} hand raised before the {name}", "rise", time=RISE_TIME)
        put(f"{side} hand beside the {name}", "pre", time=BESIDE_TIME)
        put(f"{side} hand presses the {name}", "grasp", window=(t_in, t_close))
        put(f"{side} hand lifts the {name}", "lift", window=(t_lift, DURATION))
        b.holds.append(b.name(f"{side} hand lifts the {name}"))
        offset = p["R"].T @ (np.asarray(g.obj.position, dtype=float) - p["grasp"])
        b.grasps.append(Grasp(
            name=b.name(f"{side} hand holds the {name}"), object=name, frame=b.robot.frame(role),
            offset=(float(offset[0]), float(offset[1]), float(offset[2])),
            start=b.t(t_in), lift=height, hold=b.window(t_lift, DURATION), tolerance=BOTH_TOLERANCE))
    b.phase(f"approach the {name}", t_in)
    b.phase(f"press the {name}", t_close)
    b.phase(f"lift the {name}", t_lift)
    b.phase(f"hold the {name}", DURATION)
    # G1's upper arms pressed into the torso's meshes holding the box (plan 19 knots, sim up to 39)
    hold_upper_arms(b, DURATION, ("left", "right"), out=UPPER_ARM_OUT)
    return b.finish(frozenset({"left_arm", "right_arm", "torso"}))


PICK_UP = Primitive(name="pick_up", nominal_duration=lambda params, robot: DURATION, build=build_pick_up,
                    parts=object_arm_parts, check=_check)

# --- put_down ---------------------------------------------------------------------------
LOWER_TIME = 1.5  # [s] nominal: held pose -> the grasp pose over where the object was
RELEASE_TIME = 0.5  # [s] held there; the hand lets go at its end
RETREAT_TIME = 1.0  # [s] up and back to the pre-grasp pose
REST_TIME = 1.0  # [s] then back to rest
PUT_DURATION = LOWER_TIME + RELEASE_TIME + RETREAT_TIME + REST_TIME


PLACE_MARGIN = 0.02  # [m] a placed object's footprint stays this far inside the destination's top face
ABOVE_TIME = 1.0  # [s] nominal: held pose -> above the place (a destination), then down in the rest of LOWER_TIME
PLACE_GRID = 7  # points per side of the destination's face tried when the spot is beyond comfortable reach
PLACE_REACH_MARGIN = 0.03  # [m] a place this far within the hand's reach is comfortable
REACH_AHEAD = 0.45  # [m] the hand's comfortable reach ahead of the body (heading frame): where a spot is chosen


def destination(params: dict) -> Grounded | None:
    """The grounded object a put_down puts its object on (None: back where it was)."""
    value = params.get("on")
    if value is None or isinstance(value, Grounded):
        return value
    from tasks.grounding import ground

    ground(value, None, action="put_down")  # raises: no scene
    raise AssertionError("unreachable")  # pragma: no cover


def place_point(robot: Robot, stance: Stance, obj: SceneObject, on: SceneObject, side: str) -> np.ndarray:
    """Where the object's centre goes on ``on``'s top face (world) [m]: where it stood when that is
    on this face, else the point of the face (its footprint :data:`PLACE_MARGIN` inside the edges)
    nearest to a spot :data:`REACH_AHEAD` ahead of the robot on the ``side`` hand's side, among those
    :data:`PLACE_REACH_MARGIN` within the hand's reach (if none is, the one nearest to reach); its
    bottom on the face. Faces are taken axis-aligned (the destination's bounding box)."""
    lo, hi = extent(obj)
    olo, ohi = extent(on)
    half = 0.5 * (np.asarray(hi) - np.asarray(lo))
    below = float(obj.position[2] - lo[2])  # centre above the object's bottom [m]
    if on.shape not in ("box", "cylinder"):
        raise TaskDefinitionError(f"put_down: the {on.name} has no flat top to put the {obj.name} on")
    if on.name == obj.name:
        raise TaskDefinitionError(f"put_down: the {obj.name} cannot be put on itself")
    x0, x1 = olo[0] + half[0] + PLACE_MARGIN, ohi[0] - half[0] - PLACE_MARGIN
    y0, y1 = olo[1] + half[1] + PLACE_MARGIN, ohi[1] - half[1] - PLACE_MARGIN
    if x0 > x1 or y0 > y1:
        raise TaskDefinitionError(f"put_down: the {on.name}'s top is too small for the {obj.name}")
    top = float(ohi[2])
    at = np.asarray(obj.position, dtype=float)
    if x0 <= at[0] <= x1 and y0 <= at[1] <= y1 and abs(at[2] - below - top) <= 0.03:
        return np.array([at[0], at[1], top + below])  # it stood there: back to its place
    lateral = float(body_map(robot).hand_position[side][1])
    T = stance.transform_from_standing(robot)
    ahead = T.act(to_standing(robot, [REACH_AHEAD, lateral, 0.0]))
    spot = np.array([min(max(ahead[0], x0), x1), min(max(ahead[1], y0), y1), top + below])
    best: tuple[float, float, np.ndarray] | None = None
    for x in np.linspace(x0, x1, PLACE_GRID):  # the spot, or the face's point nearest to it within comfortable reach
        for y in np.linspace(y0, y1, PLACE_GRID):
            for p in (spot, np.array([x, y, top + below])):
                gap = reach_gap(robot, side, to_heading(robot, T.actInv(grasp_point(robot, side, _moved(obj, p)))),
                                bend=True)
                key = (max(gap + PLACE_REACH_MARGIN, 0.0), float(np.linalg.norm(p[:2] - spot[:2])))
                if best is None or key < best[:2]:
                    best = (*key, p)
    assert best is not None
    return best[2]


SHIFT_DEFAULT = 0.2  # [m] "put it down to the left": a direction said without a distance
SUPPORT_GAP = 0.03  # [m] a surface within this of the object's bottom carries it


def shift(params: dict, stance: Stance) -> np.ndarray | None:
    """The put_down's shift (3,) in the world [m] from its ``direction`` and ``distance`` (the
    robot's heading where it stands), or None: no direction, or ``backward`` without a distance
    ("put the cup back": where it was)."""
    direction = params.get("direction")
    distance = params.get("distance")
    if direction is None or (direction == "backward" and distance is None):
        return None
    d = SHIFT_DEFAULT if distance is None else float(distance)
    local = {"forward": (1.0, 0.0), "backward": (-1.0, 0.0), "left": (0.0, 1.0), "right": (0.0, -1.0)}[str(direction)]
    return stance.heading().rotation @ np.array([local[0], local[1], 0.0]) * d


def _spot_words(params: dict, obj: SceneObject, on: SceneObject | None) -> str:
    """The spot in words: "0.20 m to the left of where the cup stood"."""
    direction = str(params.get("direction"))
    d = SHIFT_DEFAULT if params.get("distance") is None else float(params["distance"])
    how = {"forward": "further from the robot than", "backward": "closer to the robot than", "left": "to the left of",
           "right": "to the right of"}[direction]
    return f"{d:.2f} m {how} " + (f"its place on the {on.name}" if on is not None else f"where the {obj.name} stood")


def _supports(scene, obj: SceneObject, on: SceneObject | None, bottom: float) -> list[SceneObject | None]:
    """The surfaces that may carry ``obj`` with its bottom at ``bottom`` [m]: ``on`` when given, else
    every other box or cylinder whose top is within :data:`SUPPORT_GAP` of it (None: the floor)."""
    if on is not None:
        return [on]
    if bottom <= SUPPORT_GAP:
        return [None]
    return [o for o in (scene.objects if scene is not None else ()) if o.name != obj.name
            and o.shape in ("box", "cylinder") and abs(float(extent(o)[1][2]) - bottom) <= SUPPORT_GAP]


def shifted_place(params: dict, stance: Stance, g: Grounded, on: SceneObject | None, place: np.ndarray) -> np.ndarray:
    """``place`` moved by the put_down's :func:`shift`: the object's footprint must lie on the top face
    of the surface under it (``on``, or the one it stood on; the floor for an object on the floor),
    and no other object may stand there.

    Raises:
        TaskDefinitionError: off the surface (with how far its edge is) or the spot taken.
    """
    move = shift(params, stance)
    if move is None:
        return place
    obj = g.obj
    lo, hi = (np.asarray(v, dtype=float) for v in extent(obj))
    half = 0.5 * (hi - lo)
    below = float(obj.position[2] - lo[2])
    at = place + move
    bottom = float(place[2]) - below
    spot = _spot_words(params, obj, on)
    surfaces = _supports(g.scene, obj, on, bottom)
    if not surfaces:
        raise TaskDefinitionError(f"put_down: nothing carries the {obj.name} {spot}")
    fits = [s for s in surfaces if s is None or _inside(at, half, s)]
    if not fits:
        s = surfaces[0]
        assert s is not None
        slo, shi = (np.asarray(v, dtype=float) for v in extent(s))
        unit = move / np.linalg.norm(move)
        room = min(((shi[i] - half[i] - place[i]) / unit[i] if unit[i] > 0 else (slo[i] + half[i] - place[i]) / unit[i])
                   for i in (0, 1) if abs(unit[i]) > 1e-9)
        raise TaskDefinitionError(
            f"put_down: {spot}, the {obj.name} would be off the top of the {s.name}: it can move at most "
            f"{max(room, 0.0):.2f} m that way; say a shorter distance")
    for other in (g.scene.objects if g.scene is not None else ()):
        if other.name == obj.name or other in fits:
            continue
        olo, ohi = extent(other)
        if all(at[i] - half[i] < ohi[i] and at[i] + half[i] > olo[i] for i in range(3)):
            raise TaskDefinitionError(f"put_down: the {other.name} stands {spot}; choose another spot")
    return at


def _inside(at: np.ndarray, half: np.ndarray, surface: SceneObject) -> bool:
    slo, shi = extent(surface)
    return all(slo[i] <= at[i] - half[i] and at[i] + half[i] <= shi[i] for i in (0, 1))


def put_place(params: dict, robot: Robot, stance: Stance, side: str) -> np.ndarray:
    """Where a put_down puts its object's centre (world) [m]: where it stood, or on ``on``'s top
    (:func:`place_point`), moved by the ``direction`` and ``distance`` (:func:`shifted_place`)."""
    g = grounded(params, "put_down")
    on = destination(params)
    place = np.asarray(g.obj.position, dtype=float) if on is None else place_point(robot, stance, g.obj, on.obj, side)
    return shifted_place(params, stance, g, None if on is None else on.obj, place)


def _moved(obj: SceneObject, position: np.ndarray) -> SceneObject:
    """The object with its centre at ``position`` [m]."""
    return dataclasses.replace(obj, position=(float(position[0]), float(position[1]), float(position[2])))


def _put_check(params: dict, robot: Robot) -> None:
    g = grounded(params, "put_down")
    if not g.obj.movable:
        raise TaskDefinitionError(f"put_down: the {g.obj.name} is fixed in the scene; nothing holds it")
    if params.get("distance") is not None and params.get("direction") is None:
        raise TaskDefinitionError(f"put_down: {float(params['distance']):.2f} m which way? say a direction "
                                  f'("put the {g.obj.name} down 20 cm to the left")')
    on = destination(params)
    moving = shift(params, g.start) is not None if isinstance(g.start, Stance) else False
    if params.get("arm") == "both":
        if on is not None or moving:
            where = f"on the {on.obj.name}" if on is not None else "on another spot"
            raise TaskDefinitionError(f"put_down: the {g.obj.name} is held with both hands: it is put back where it was "
                                      f"(putting it {where} is not supported yet)")
        return
    if (on is None and not moving) or not isinstance(g.start, Stance) or not params.get("arm"):
        return
    side = str(params["arm"])
    moved = _moved(g.obj, put_place(params, robot, g.start, side))
    T = g.start.transform_from_standing(robot)
    point = to_heading(robot, T.actInv(grasp_point(robot, side, moved)))
    gap = reach_gap(robot, side, point, bend=True)
    if gap <= 1e-9:
        return
    if moving:
        where = _spot_words(params, g.obj, None if on is None else on.obj)
        raise TaskDefinitionError(
            f"put_down: {where} is {gap:.2f} m beyond the {side} hand's reach from where the robot stands: "
            "say a shorter distance or walk closer first")
    assert on is not None
    raise TaskDefinitionError(
        f"put_down: the top of the {on.obj.name} is {gap:.2f} m beyond the {side} hand's reach from where the robot "
        f'stands: walk to the {on.obj.name} first ("walk to the {on.obj.name} and put the {g.obj.name} on it")')


def build_put_down(b: FragmentBuilder) -> Fragment:
    """Lower the held object back onto where it was picked up, let go, retreat, arm back to rest.

    The release is a :class:`~tasks.specs.Grasp` with ``end`` and ``place`` set; composing closes
    the grasp that holds the object with it (:func:`tasks.compose.compile_actions` refuses a
    put_down of an object no hand holds).
    """
    g = grounded(b.params, "put_down")
    if not isinstance(g.start, Stance):
        g = dataclasses.replace(g, start=b.stance)
        b.params["object"] = g
    if b.params.get("arm") == "both":
        return _put_down_both(b, g)
    side = holding_arm(b.params, b.robot) if b.params.get("arm") else _held_side(b, g)
    b.params["arm"] = side
    _put_check(b.params, b.robot)
    on = destination(b.params)
    place = put_place(b.params, b.robot, b.stance, side)
    g = dataclasses.replace(g, obj=_moved(g.obj, place))
    poses = _poses(b.robot, b.stance, g, side, 0.0)
    rpy = b.world_rotation(b.geometry.rotation(f"{side}_hand"))
    name, role = g.obj.name, f"{side}_hand"
    t_low = LOWER_TIME
    t_rel = t_low + RELEASE_TIME
    t_back = t_rel + RETREAT_TIME
    if on is not None:  # from above: the held object comes down onto the destination, not through its edge
        b.frame_target(f"{side} hand holds the {name} above the {on.obj.name}", role,
                       position=tuple(float(x) for x in poses["grasp"] + PRE_UP * np.array([0.0, 0.0, 1.0])), rpy=rpy,
                       time=ABOVE_TIME, tolerance=POSE_TOLERANCE)
    where = f" on the {on.obj.name}" if on is not None else ""
    move = shift(b.params, b.stance)
    if move is not None:
        where += f" {np.linalg.norm(move):.2f} m {b.params['direction']}"
    b.frame_target(f"{side} hand puts the {name} down{where}", role, position=tuple(float(x) for x in poses["grasp"]),
                   rpy=rpy, window=(t_low, t_rel), tolerance=GRASP_TARGET_TOLERANCE)
    b.frame_target(f"{side} hand off the {name}", role, position=tuple(float(x) for x in poses["pre"]), rpy=rpy,
                   time=t_back, tolerance=POSE_TOLERANCE)
    rest_targets(b, [role], tau=PUT_DURATION)
    b.phase(f"lower the {name}", t_low)
    b.phase(f"let go of the {name}", t_rel)
    b.phase(f"retreat from the {name}", PUT_DURATION)
    b.grasps.append(Grasp(
        name=b.name(f"{side} hand lets go of the {name}"), object=name, frame=b.robot.frame(role), offset=(0.0, 0.0, 0.0),
        start=b.t0, end=b.t(t_rel), place=(float(place[0]), float(place[1]), float(place[2])),
        tolerance=GRASP_TOLERANCE))
    return b.finish(frozenset({f"{side}_arm", "torso"}))


# Both hands (a box): the hands stay at their press poses one knot after the welds let go (the
# planner's scene rows leave the box to the arms a few knots after a release), then out beside the
# box (its pre-grasp poses), back in front of the body (the pick-up's raised poses) and to rest, each
# about as long as the pick-up's approach took. Without the stay the planned hands were already
# moving apart as the welds let go (the reference's velocity leads its knots; the forearms, within
# the scene clearance of the box at the press, had to leave it in one knot): the box still welded to
# both, the arms pulled against each other and arm_*_2_joint reached the controller's 97 % cap just
# before the release; the faster retreat (0.5 s to beside, 0.5 s up, 1 s to rest) held
# arm_*_5_joint (3 N m) at that cap for a second (docs/objects.md).
PUT_BESIDE_TIME = 3.0  # [s] nominal: let go at LOWER_TIME + RELEASE_TIME, then out beside the box (its pre-grasp poses)
PUT_RAISED_TIME = 4.0  # [s] back in front of the body (the pick-up's raised poses)
PUT_DURATION_BOTH = 5.75  # [s] the arms at rest


def _put_down_both(b: FragmentBuilder, g: Grounded) -> Fragment:
    """Both hands lower the box back onto where it was picked up (the press poses), hold it there,
    let go (a release per hand: each closes its hand's grasp), move out beside it and up (the
    pre-grasp poses), back in front of the body (the raised poses: the fingers over the surface
    only above it), and the arms to rest: the pick-up's approach in reverse."""
    _put_check(b.params, b.robot)
    _check_both_reach(b.robot, b.stance, g.obj, "put_down", f"walk to where the {g.obj.name} stood and put it down")
    poses = _both_poses(b.robot, b.stance, g.obj, 0.0)
    name = g.obj.name
    t_rel = LOWER_TIME + RELEASE_TIME
    let_go = t_rel + b.dt / b.scale  # one knot on: the hands still at the box as the welds let go
    place = tuple(float(x) for x in g.obj.position)
    for side in ("left", "right"):
        role = f"{side}_hand"
        rpy = b.world_rotation(both_rotation(b.robot, side))
        p = poses[side]
        b.frame_target(f"{side} hand puts the {name} down", role, position=tuple(float(x) for x in p["grasp"]), rpy=rpy,
                       window=(LOWER_TIME, let_go), tolerance=GRASP_TARGET_TOLERANCE)
        b.frame_target(f"{side} hand off the {name}", role, position=tuple(float(x) for x in p["pre"]), rpy=rpy,
                       time=PUT_BESIDE_TIME, tolerance=POSE_TOLERANCE)
        b.frame_target(f"{side} hand back before the {name}", role, position=tuple(float(x) for x in p["rise"]), rpy=rpy,
                       time=PUT_RAISED_TIME, tolerance=POSE_TOLERANCE)
        b.grasps.append(Grasp(
            name=b.name(f"{side} hand lets go of the {name}"), object=name, frame=b.robot.frame(role),
            offset=(0.0, 0.0, 0.0), start=b.t0, end=b.t(t_rel), place=(place[0], place[1], place[2]),
            tolerance=GRASP_TOLERANCE))
    rest_targets(b, ["left_hand", "right_hand"], tau=PUT_DURATION_BOTH)
    b.phase(f"lower the {name}", LOWER_TIME)
    b.phase(f"let go of the {name}", let_go)
    b.phase(f"retreat from the {name}", PUT_DURATION_BOTH)
    hold_upper_arms(b, PUT_DURATION_BOTH, ("left", "right"), out=UPPER_ARM_OUT)  # as when picking it up (G1)
    return b.finish(frozenset({"left_arm", "right_arm", "torso"}))


def _held_side(b: FragmentBuilder, g: Grounded) -> str:
    return holding_arm({"object": g}, b.robot)


PUT_DOWN = Primitive(name="put_down", nominal_duration=lambda params, robot: PUT_DURATION_BOTH if params.get("arm") == "both"
                     else PUT_DURATION, build=build_put_down,
                     parts=object_arm_parts, check=_put_check)

# --- carrying -------------------------------------------------------------------------
CARRY_WEIGHT = 1000.0  # cost weight of each carrying joint's angle while the feet move [1/rad^2]
IK_ITERATIONS = 100
IK_SEEDS = 8  # random starting postures besides the standing one (seeded: the same posture every time)
IK_DAMPING = 1e-4  # damped least squares [m^2]
IK_TURN_WEIGHT = 0.3  # [m/rad] the hand's orientation error counts this much against its position error
IK_TORSO_COST = 10.0  # a torso joint's angle away from standing counts this many times an arm joint's
IK_TOLERANCE = 2e-3  # [m] weighted pose error of a carry posture


def carrying_joints(robot: Robot, side: str) -> tuple[list[int], list[int]]:
    """Pinocchio joint indices (torso, arm) from the base to the ``side`` hand: the torso joints carry
    both hands, the arm joints only this one."""
    model = robot.model
    other = "right" if side == "left" else "left"
    mine = [j for j in model.supports[model.frames[robot.frame_id(f"{side}_hand")].parentJoint] if j > 1]
    both = set(model.supports[model.frames[robot.frame_id(f"{other}_hand")].parentJoint])
    one_dof = [j for j in mine if model.joints[j].nv == 1]
    return [j for j in one_dof if j in both], [j for j in one_dof if j not in both]


def carry_posture(robot: Robot, side: str, hand_in_standing: pin.SE3) -> dict[str, float]:
    """Joint angles [rad] of the torso and the ``side`` arm that hold the ``side`` hand frame at
    ``hand_in_standing`` (standing world frame), with the base and legs at their standing posture:
    what a carried object's joints keep while the feet move, so the hand moves with the body.

    Damped least squares (orientation weighted :data:`IK_TURN_WEIGHT`) within the joint limits, from
    the standing posture and :data:`IK_SEEDS` seeded random postures; of the solutions within
    :data:`IK_TOLERANCE`, the one nearest the standing posture (torso joints counted
    :data:`IK_TORSO_COST` times).

    Raises:
        TaskDefinitionError: no solution holds the hand there.
    """
    model, data = robot.model, robot.data()
    fid = robot.frame_id(f"{side}_hand")
    torso, arm = carrying_joints(robot, side)
    joints = torso + arm
    cols = [model.joints[j].idx_v for j in joints]
    rows = [model.joints[j].idx_q for j in joints]
    lo, hi = model.lowerPositionLimit[rows], model.upperPositionLimit[rows]
    W = np.array([1.0, 1.0, 1.0, IK_TURN_WEIGHT, IK_TURN_WEIGHT, IK_TURN_WEIGHT])  # [m/rad]
    cost = np.array([IK_TORSO_COST if j in torso else 1.0 for j in joints])
    rng = np.random.default_rng(0)
    seeds = [robot.q_standing[rows]] + [rng.uniform(lo, hi) for _ in range(IK_SEEDS)]
    best: tuple[float, np.ndarray] | None = None
    worst = np.inf
    for seed in seeds:
        q = robot.q_standing.copy()
        q[rows] = seed
        for _ in range(IK_ITERATIONS):
            pin.framesForwardKinematics(model, data, q)
            err = W * pin.log6(data.oMf[fid].actInv(hand_in_standing)).vector
            if np.linalg.norm(err) < 0.1 * IK_TOLERANCE:
                break
            J = W[:, None] * pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL)[:, cols]
            q[rows] = np.clip(q[rows] + J.T @ np.linalg.solve(J @ J.T + IK_DAMPING * np.eye(6), err), lo, hi)
        pin.framesForwardKinematics(model, data, q)
        miss = float(np.linalg.norm(W * pin.log6(data.oMf[fid].actInv(hand_in_standing)).vector))
        worst = min(worst, miss)
        if miss <= IK_TOLERANCE:
            away = float(np.sum(cost * (q[rows] - robot.q_standing[rows]) ** 2))
            if best is None or away < best[0]:
                best = (away, q[rows].copy())
    if best is None:
        raise TaskDefinitionError(
            f"the {side} arm cannot carry its object where it lifted it with the legs standing "
            f"({worst * 100:.1f} cm off); lift it less high")
    return {model.names[j]: float(v) for j, v in zip(joints, best[1], strict=True)}


PRIMITIVES = (PICK_UP, PUT_DOWN)

__all__ = ["GRASP_TOLERANCE", "PICK_UP", "PRIMITIVES", "PUT_DOWN", "build_pick_up", "build_put_down", "carry_posture",
           "carrying_joints", "destination", "grasp_offset", "grasp_point", "holding_arm", "object_arm_parts", "place_point", "put_place",
           "shift", "shifted_place"]
