"""Actions on scene objects that need no grasp: ``walk_to(object)``, ``look_at(object, duration)``,
``point_at(object, arm, duration)``, ``touch_object(object, hand, duration)``.

The ``object`` parameter arrives grounded (:class:`tasks.grounding.Grounded`: the object, its scene
and where the robot stands when the action starts), resolved by
:func:`tasks.compose.compile_actions` from the words of the sentence.

- ``walk_to``: when an object is in the straight line, first walk a route around it
  (:mod:`tasks.primitives.route`: straight legs, a turn in place before each, the body kept
  ``ROUTE_MARGIN`` from every object) to the nearest place from which the straight approach below
  ends within reach; an enclosed object is refused naming what encloses it (exit 4). The approach:
  turn in place to face the object's centre, then walk straight towards it and stop
  when the front of the body (its collision geometry at the height of the object, measured by
  :func:`tasks.primitives.bodymap.body_map`) is :data:`WALK_MARGIN` from the first object in the
  way, the target itself or another one (a cup on a table: the table's edge). From there the
  object's nearest point must be within a hand's reach (``REACH_FRACTION`` of the arm from the
  shoulder, bending up to ``BEND_MAX`` at the hips: :func:`tasks.primitives.arms.reach_gap`);
  otherwise the walk is refused with the distance that remains. The footsteps are :mod:`tasks.footsteps`' turn and walk.
- ``look_at``: the head frame turned by the yaw and the pitch that point its forward axis at the
  object's centre (HARD orientation target, :data:`LOOK_TOLERANCE`), held, then forward again;
  robots without a neck (g1) and angles beyond the neck's range are refused.
- ``point_at``: the arm straight from its shoulder towards the object's centre, the hand
  ``OUT_REACH`` of the arm out (less when an object is closer: the hand stays
  :data:`POINT_CLEARANCE` clear of every object), held, then back to rest; by default the arm on
  the object's side.
- ``touch_object``: the hand out to the object's surface point nearest to the shoulder (within reach
  bending at the hips, else refused: walk to it first), its frame back from that point by the
  hand's extent in front of it less :data:`TOUCH_DEPTH`, held, then back to rest. The target names
  the object (``FrameTarget.touch``): a planned contact, which the planner's scene rows, the
  pre-check and the certificate's scene-collision line leave out for that hand and object.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import coal  # type: ignore[import-untyped]
import numpy as np
import pinocchio as pin

from robots import Robot
from tasks.exceptions import TaskDefinitionError
from tasks.footsteps import ContactSequence, turn, walk
from tasks.grounding import Grounded, ground
from tasks.primitives.arms import (
    OUT_REACH,
    POSE_TOLERANCE,
    UPPER_ARM_OUT,
    arm_length,
    hold_upper_arms,
    reach_gap,
    shoulder,
)
from tasks.primitives.base import Fragment, FragmentBuilder, Primitive, rest_targets
from tasks.primitives.bodymap import (
    ARM_IK_TOLERANCE,
    CLEARANCE,
    PLANNER_MARGIN,
    arm_configuration,
    body_map,
    reach_error,
    sphere_clearance,
    to_heading,
    to_standing,
)
from tasks.primitives.geometry import Stance, neck_range, require_role, standing_geometry
from tasks.primitives.posture import HOLD_END_FRACTION, OUT_FRACTION, head_turn_axis
from tasks.primitives.route import clearance_radius, plan_route, segment_clear
from tasks.scene import SceneObject, extent, rotation, signed_distance
from tasks.specs import Phase

WALK_MARGIN = 0.1  # [m] clearance between the body's front and the object it stops at (room for the arms)
WALK_MIN = 0.05  # [m] a shorter walk is not taken (already there)
TURN_MIN = 0.05  # [rad] a smaller turn is not taken (already facing it)
ROUTE_SLACK = 0.03  # [m] a route ends where the target is this much within reach (the legs round off small turns)
WALK_MAX = 10.0  # [m] the registry's longest walk
STAND_TIME = 1.0  # [s] walk_to when the robot is already there
END_TOLERANCE = 0.02  # [m] CoM over the final feet
LOOK_TOLERANCE = 0.05  # [rad] head orientation
POINT_CLEARANCE = 0.1  # [m] pointing hand to any object
POINT_MIN = 0.5  # [L] a hand closer than this fraction of the arm to the shoulder is no pointing
TOUCH_DEPTH = 0.0  # [m] the hand target this far past where the posed hand's meshes reach the surface (3 mm moved Talos's red box 2.8 cm planned at dt 0.1 s; 1 cm pushed it 8.7 cm)
TOUCH_GAP_TOLERANCE = 0.001  # [m] the posed hand's meshes within this of the surface: they reach it
TOUCH_ROUNDS = 20  # moves along the approach line when placing the posed hand at the surface
TOUCH_SEARCH = 0.15  # [m] the posed hand moves at most this far along the line from its first estimate
TOUCH_STEP = 0.03  # [m] a touched point too close to the body: the nearest to a point this much further ahead
TOUCH_CANDIDATES = 6
TOUCH_TOLERANCE = 0.005  # [m] hand frame to its touch target
BEHIND = math.radians(100)  # an object farther than this from the heading cannot be pointed or looked at

LEG_PARTS = frozenset({"legs", "com"})


def grounded(params: dict, action: str) -> Grounded:
    """The action's grounded object (GroundingError when it was not resolved against a scene)."""
    value = params.get("object")
    if isinstance(value, Grounded):
        return value
    if value is None:
        raise TaskDefinitionError(f'{action} needs an object: say which, e.g. "{action.replace("_", " ")} the table"')
    ground(value, None, action=action)  # raises: no scene
    raise AssertionError("unreachable")  # pragma: no cover


def _start(g: Grounded, robot: Robot) -> Stance:
    return g.start if isinstance(g.start, Stance) else Stance.standing(robot)


def _yaw(stance: Stance) -> float:
    R = stance.heading().rotation
    return math.atan2(R[1, 0], R[0, 0])


def _wrap(a: float) -> float:
    return math.atan2(math.sin(a), math.cos(a))


# --- walk_to ------------------------------------------------------------------------------
def body_front(robot: Robot, z_range: tuple[float, float]) -> tuple[float, float]:
    """(front, half width) of the standing body [m], heading frame: the farthest forward point of
    the collision geometry between heights ``z_range``, and the largest lateral extent."""
    boxes = body_map(robot).boxes
    level = [b for b in boxes if b.lo[2] <= z_range[1] and b.hi[2] >= z_range[0]]
    front = max(float(b.hi[0]) for b in (level or boxes))
    half = max(max(abs(float(b.lo[1])), abs(float(b.hi[1]))) for b in boxes)
    return front, half


@dataclass(frozen=True, slots=True, kw_only=True)
class Leg:
    """One leg of a walk: turn in place, then walk straight forward.

    Attributes:
        angle: Turn first [rad] (left positive; 0: none).
        distance: Then walk forward [m] (0: none).
    """

    angle: float
    distance: float


@dataclass(frozen=True, slots=True, kw_only=True)
class WalkPlan:
    """Where ``walk_to`` goes: legs (turn, straight walk) along a route, the object it stops at.

    Attributes:
        legs: The legs in order; the last one is the approach: facing the target's centre, forward
            until the body's front is :data:`WALK_MARGIN` from the first object ahead.
        stop: The object whose margin ends the walk (the target or one in the way).
        reach_gap: Shoulder to the target's surface at the end, minus the arm's reach [m] (<= 0).
        waypoints: (x, y) of the point between the feet where each leg starts, then where the walk
            ends [m] (the route around the objects in the way; two points for a straight walk).
    """

    legs: tuple[Leg, ...]
    stop: SceneObject
    reach_gap: float
    waypoints: tuple[tuple[float, float], ...] = ()

    @property
    def angle(self) -> float:
        """The first turn [rad]."""
        return self.legs[0].angle

    @property
    def distance(self) -> float:
        """The distance walked [m]."""
        return sum(leg.distance for leg in self.legs)


def reach_gaps(robot: Robot, obj: SceneObject, mid: np.ndarray, yaw: float) -> dict[str, float]:
    """Per arm, how far the object's point nearest to the shoulder is beyond the hand's reach
    (bending up to ``BEND_MAX`` at the hips, :func:`tasks.primitives.arms.reach_gap`) for the robot
    standing at ``mid`` (x, y) facing ``yaw`` [m]; <= 0: within reach."""
    c, s = math.cos(yaw), math.sin(yaw)
    lo, hi = extent(obj)
    out = {}
    for side in ("left", "right"):
        p = shoulder(robot, side)
        world = np.array([mid[0] + c * p[0] - s * p[1], mid[1] + s * p[0] + c * p[1], p[2]])
        surface = np.clip(world, lo, hi) if obj.shape == "mesh" else nearest_surface_point(obj, world)
        near = surface - np.array([mid[0], mid[1], 0.0])
        local = np.array([c * near[0] + s * near[1], -s * near[0] + c * near[1], near[2]])
        out[side] = reach_gap(robot, side, local, bend=True)
    return out


def _surface_gap(obj: SceneObject, point: np.ndarray) -> float:
    d = signed_distance(obj, point)
    return float(np.linalg.norm(point - np.asarray(obj.position))) if d is None else d


@dataclass(frozen=True, slots=True)
class _Straight:
    """The straight approach from a point: the walk (or why not), the object it stops at."""

    yaw: float  # facing the target's centre [rad]
    distance: float  # [m]
    stop: SceneObject
    gap: float  # reach gap at the end [m]
    error: str  # "" when the approach ends within reach


def _clip_strip(polygon: np.ndarray, w: float) -> np.ndarray:
    """The part of a convex polygon (k, 2) of (along, across) points with ``|across| <= w`` (its vertices)."""
    for sign in (1.0, -1.0):
        out = []
        k = len(polygon)
        for i in range(k):
            a, b = polygon[i], polygon[(i + 1) % k]
            ina, inb = sign * a[1] <= w, sign * b[1] <= w
            if ina:
                out.append(a)
            if ina != inb:
                t = (sign * w - a[1]) / (b[1] - a[1])
                out.append(a + t * (b - a))
        polygon = np.array(out).reshape(-1, 2)
        if len(polygon) == 0:
            break
    return polygon


def _straight(robot: Robot, target: SceneObject, objects: tuple[SceneObject, ...], p0: np.ndarray,
              slack: float = 0.0) -> _Straight:
    """Face the target's centre from ``p0`` (x, y) and walk until the body's front is the margin
    from the first object ahead (the target or another); within reach means a gap <= -``slack``."""
    to = np.asarray(target.position[:2], dtype=float) - p0
    if float(np.linalg.norm(to)) < 1e-6:
        raise TaskDefinitionError(f"walk_to: the robot stands on the {target.name}'s centre; nowhere to walk")
    u = to / np.linalg.norm(to)
    n = np.array([-u[1], u[0]])
    yaw = math.atan2(u[1], u[0])
    stop_at, stop_obj = math.inf, target
    for obj in objects:
        lo, hi = extent(obj)
        front, half = body_front(robot, (lo[2], hi[2]))
        corners = np.array([(lo[0], lo[1]), (hi[0], lo[1]), (hi[0], hi[1]), (lo[0], hi[1])]) - p0
        inside = _clip_strip(np.stack([corners @ u, corners @ n], axis=1), half + WALK_MARGIN)
        if len(inside) == 0 or float(inside[:, 0].max()) <= 0.0:
            continue  # beside or behind the path
        s = float(inside[:, 0].min()) - WALK_MARGIN - front
        if s < stop_at:
            stop_at, stop_obj = s, obj
    distance = max(0.0, stop_at if math.isfinite(stop_at) else 0.0)
    best = min(reach_gaps(robot, target, p0 + distance * u, yaw).values())
    error = ""
    if best > 1e-9 - slack:
        if stop_obj is not target:
            error = (f"walk_to: the {stop_obj.name} is in the way to the {target.name}: stopping {WALK_MARGIN:g} m "
                     f"before it leaves the {target.name} {best:.2f} m beyond the arm's reach")
        else:
            error = (f"walk_to: the {target.name} is out of reach from any stance {WALK_MARGIN:g} m away from it: its "
                     f"nearest point is {best:.2f} m beyond the arm's reach (too low, too high or too deep)")
    elif distance > WALK_MAX:
        error = f"walk_to: the {target.name} is {distance:.1f} m away; walk_to walks at most {WALK_MAX:g} m"
    return _Straight(yaw=yaw, distance=distance, stop=stop_obj, gap=best, error=error)


def _leg(angle: float, distance: float) -> Leg:
    return Leg(angle=angle if abs(angle) >= TURN_MIN else 0.0, distance=distance if distance >= WALK_MIN else 0.0)


def walk_plan(robot: Robot, g: Grounded) -> WalkPlan:
    """The legs that bring the robot facing ``g.obj`` within reach (see :func:`_walk_plan`; the
    route is searched once per robot, object, scene and start)."""
    return _walk_plan(robot, g)


@functools.lru_cache(maxsize=64)
def _walk_plan(robot: Robot, g: Grounded) -> WalkPlan:
    """The legs that bring the robot facing ``g.obj`` within reach: one straight walk when nothing
    is in the way, else a route around the objects (:func:`tasks.primitives.route.plan_route`)
    followed by the straight approach.

    Raises:
        TaskDefinitionError: the robot stands on the object's centre, the object is farther than
            :data:`WALK_MAX` in a straight line, or out of reach from where a walk towards it stops.
        SceneConflict: the object is enclosed by others (named), or no place around it is within reach.
    """
    target = g.obj
    start = _start(g, robot)
    p0 = np.asarray(start.heading().translation[:2], dtype=float)
    yaw0 = _yaw(start)
    straight = _straight(robot, target, g.scene.objects, p0)
    if not straight.error or straight.stop is target:
        if straight.error:
            raise TaskDefinitionError(straight.error)
        end = p0 + straight.distance * np.array([math.cos(straight.yaw), math.sin(straight.yaw)])
        return WalkPlan(legs=(_leg(_wrap(straight.yaw - yaw0), straight.distance),), stop=straight.stop,
                        reach_gap=straight.gap, waypoints=((float(p0[0]), float(p0[1])), (float(end[0]), float(end[1]))))
    # something is in the way: route around it to a place from which the straight approach works
    objects = g.scene.objects
    radii = [clearance_radius(robot, o) for o in objects]
    route = plan_route(p0, target, objects, radii,
                       lambda xy: _straight(robot, target, objects, xy, ROUTE_SLACK).error)
    legs: list[Leg] = []
    p, yaw = p0.copy(), yaw0
    points = [tuple(p0)]
    for w in route.waypoints[1:]:
        d = np.asarray(w) - p
        dist = float(np.linalg.norm(d))
        if dist < WALK_MIN:
            continue
        leg = _leg(_wrap(math.atan2(d[1], d[0]) - yaw), dist)
        ahead = p + leg.distance * np.array([math.cos(yaw + leg.angle), math.sin(yaw + leg.angle)])
        if leg.angle == 0.0 and not segment_clear(p, ahead, objects, radii):
            leg = Leg(angle=_wrap(math.atan2(d[1], d[0]) - yaw), distance=leg.distance)  # the small turn matters here
        yaw += leg.angle
        p = p + leg.distance * np.array([math.cos(yaw), math.sin(yaw)])
        legs.append(leg)
        points.append(tuple(p))
    last = _straight(robot, target, objects, p)
    if last.error:  # pragma: no cover - the route ends where the approach was accepted
        raise TaskDefinitionError(last.error)
    legs.append(_leg(_wrap(last.yaw - yaw), last.distance))
    yaw += legs[-1].angle
    points.append(tuple(p + legs[-1].distance * np.array([math.cos(yaw), math.sin(yaw)])))
    return WalkPlan(legs=tuple(legs), stop=last.stop, reach_gap=last.gap,
                    waypoints=tuple((float(x), float(y)) for x, y in points))


def _walk_sequences(robot: Robot, g: Grounded) -> list[ContactSequence]:
    plan = walk_plan(robot, g)
    start = _start(g, robot)
    left, right = start.left, start.right
    out = []
    for i, leg in enumerate(plan.legs):
        label = f"leg {i + 1}: " if len(plan.legs) > 1 else ""
        if leg.angle:
            seq = turn(robot, leg.angle, left=left, right=right, label=label)
            out.append(seq)
            left, right = seq.left, seq.right
        if leg.distance:
            seq = walk(robot, leg.distance, "forward", left=left, right=right, label=label)
            out.append(seq)
            left, right = seq.left, seq.right
    return out


def _walk_duration(params: dict, robot: Robot) -> float:
    seqs = _walk_sequences(robot, grounded(params, "walk_to"))
    return sum(s.duration for s in seqs) if seqs else STAND_TIME


def _walk_check(params: dict, robot: Robot) -> None:
    _walk_sequences(robot, grounded(params, "walk_to"))


def build_walk_to(b: FragmentBuilder) -> Fragment:
    """Turn, walk, CoM back over the final feet (like ``walk``)."""
    g = grounded(b.params, "walk_to")
    seqs = _walk_sequences(b.robot, g)
    if not seqs:
        b.phase(f"already at the {g.obj.name}", STAND_TIME)
        return b.finish(LEG_PARTS)
    phases: list[Phase] = [p for s in seqs for p in s.phases]
    k = 0
    for phase in phases[:-1]:
        n = phase.duration / b.dt
        k += max(1, math.floor(n + 1e-9) if len(phase.contacts) == 2 else round(n))
        b.phase(phase.name, k * b.dt / b.scale, phase.contacts, swing_height=phase.swing_height)
    total = sum(s.duration for s in seqs)
    b.phase(phases[-1].name, total, phases[-1].contacts, swing_height=phases[-1].swing_height)
    end = Stance(left=seqs[-1].left, right=seqs[-1].right)
    home = end.transform_from_standing(b.robot).act(standing_geometry(b.robot).com)
    b.com_target(f"CoM over the feet at the {g.obj.name}", (float(home[0]), float(home[1]), None), time=total,
                 tolerance=END_TOLERANCE)
    b.end_stance = end
    # the upper arms held a little out, as in a walk (G1's left upper arm grazed the torso's meshes)
    hold_upper_arms(b, total, ("left", "right"), out=UPPER_ARM_OUT)
    return b.finish(LEG_PARTS, dynamic=True)


# --- look_at ------------------------------------------------------------------------------
def look_rotation(robot: Robot, stance: Stance, obj: SceneObject) -> tuple[np.ndarray, float, float]:
    """(world orientation (3, 3) of the head frame looking at the object's centre, yaw left of the
    heading [rad], pitch down [rad]) from ``stance``."""
    geo = standing_geometry(robot)
    T = stance.transform_from_standing(robot)
    head = T.act(geo.position("head"))
    d = np.asarray(obj.position, dtype=float) - head
    yaw_s = _yaw(stance)
    psi = math.atan2(d[1], d[0])
    phi = math.atan2(-d[2], math.hypot(d[0], d[1]))
    Q = pin.rpy.rpyToMatrix(0.0, 0.0, psi) @ pin.rpy.rpyToMatrix(0.0, phi, 0.0) @ pin.rpy.rpyToMatrix(0.0, 0.0, -yaw_s)
    return Q @ T.rotation @ geo.rotation("head"), _wrap(psi - yaw_s), phi


def _look_check(params: dict, robot: Robot) -> None:
    g = grounded(params, "look_at")
    require_role(robot, "head", "look_at")
    if not standing_geometry(robot).neck_joints:
        raise TaskDefinitionError(f"{robot.name} has no neck joint to look at the {g.obj.name}")
    _, yaw, pitch = look_rotation(robot, _start(g, robot), g.obj)
    for angle, words in ((yaw, ("left", "right")), (pitch, ("down", "up"))):
        direction = words[0] if angle >= 0 else words[1]
        r = neck_range(robot, head_turn_axis(robot, direction))
        if abs(angle) > r + 1e-9:
            raise TaskDefinitionError(
                f"look_at: the {g.obj.name} is {abs(angle):.2f} rad {direction} of where the head looks, beyond "
                f"{robot.name}'s neck range of {r:.2f} rad {direction}: walk to it or turn towards it first")


def build_look_at(b: FragmentBuilder) -> Fragment:
    """Head towards the object, held, then forward again."""
    g = grounded(b.params, "look_at")
    _look_check(b.params, b.robot)
    T = b.params["duration"]
    R, _, _ = look_rotation(b.robot, b.stance, g.obj)
    b.frame_target(f"head looking at the {g.obj.name}", "head", rpy=tuple(float(x) for x in pin.rpy.matrixToRpy(R)),
                   window=(OUT_FRACTION * T, HOLD_END_FRACTION * T), orientation_tolerance=LOOK_TOLERANCE)
    b.frame_target("head forward again", "head", rpy=b.world_rotation(b.geometry.rotation("head")), time=T,
                   orientation_tolerance=LOOK_TOLERANCE)
    b.phase(f"look at the {g.obj.name}", T)
    return b.finish(frozenset({"head"}))


# --- point_at -----------------------------------------------------------------------------
def pointing_arm(params: dict, robot: Robot) -> str:
    """The arm that points: the stated one, else the one on the object's side."""
    if params.get("arm"):
        return str(params["arm"])
    g = grounded(params, "point_at")
    local = _start(g, robot).heading().actInv(np.asarray(g.obj.position, dtype=float))
    return "left" if local[1] >= 0 else "right"


def point_target(robot: Robot, stance: Stance, obj: SceneObject, side: str,
                 objects: tuple[SceneObject, ...] = ()) -> tuple[np.ndarray, np.ndarray]:
    """(shoulder, hand target) in the world [m]: the hand on the line from the shoulder to the
    object's centre, ``OUT_REACH`` of the arm out or less, :data:`POINT_CLEARANCE` clear of ``objects``."""
    T = stance.transform_from_standing(robot)
    sh = np.asarray(T.act(to_standing(robot, shoulder(robot, side))), dtype=float)
    d = np.asarray(obj.position, dtype=float) - sh
    u = d / np.linalg.norm(d)
    forward = T.rotation @ standing_geometry(robot).heading.rotation[:, 0]
    if math.acos(max(-1.0, min(1.0, float(u @ forward)))) > BEHIND:
        raise TaskDefinitionError(f"point_at: the {obj.name} is behind the robot; turn or walk towards it first")
    L = arm_length(robot, side)
    s = OUT_REACH * L
    while s >= POINT_MIN * L:
        hand = sh + s * u
        if all(_surface_gap(o, hand) >= POINT_CLEARANCE for o in objects):
            return sh, hand
        s -= 0.01
    raise TaskDefinitionError(
        f"point_at: the {obj.name} is too close to point at with the {side} arm (the hand would come within "
        f"{POINT_CLEARANCE:g} m of an object); step back first")


def _point_check(params: dict, robot: Robot) -> None:
    g = grounded(params, "point_at")
    side = pointing_arm(params, robot)
    point_target(robot, _start(g, robot), g.obj, side, g.scene.objects)


def build_point_at(b: FragmentBuilder) -> Fragment:
    """The arm straight towards the object, held, back to rest."""
    g = grounded(b.params, "point_at")
    side = pointing_arm(b.params, b.robot)
    _, hand = point_target(b.robot, b.stance, g.obj, side, g.scene.objects)
    T = b.params["duration"]
    b.frame_target(f"{side} hand pointing at the {g.obj.name}", f"{side}_hand", position=tuple(float(x) for x in hand),
                   window=(OUT_FRACTION * T, HOLD_END_FRACTION * T), tolerance=POSE_TOLERANCE)
    rest_targets(b, [f"{side}_hand"], tau=T)
    b.phase(f"point at the {g.obj.name}", T)
    return b.finish(frozenset({f"{side}_arm"}))


def _point_parts(params: dict) -> frozenset[str]:
    arm = params.get("arm")
    if arm:
        return frozenset({f"{arm}_arm"})
    g = params.get("object")
    if isinstance(g, Grounded) and g.start is not None:
        local = g.start.heading().actInv(np.asarray(g.obj.position, dtype=float))
        return frozenset({"left_arm" if local[1] >= 0 else "right_arm"})
    return frozenset({"left_arm", "right_arm"})  # not known yet: claim both


def _hold_duration(params: dict, robot: Robot) -> float:
    return float(params["duration"])


# --- touch_object -------------------------------------------------------------------------
def nearest_surface_point(obj: SceneObject, point: np.ndarray) -> np.ndarray:
    """The point of ``obj``'s surface nearest to a world point outside it (3,) [m] (box, cylinder, sphere)."""
    R = np.array(rotation(obj.rpy))
    c = np.asarray(obj.position, dtype=float)
    local = R.T @ (np.asarray(point, dtype=float) - c)
    if obj.shape == "sphere":
        return c + obj.size[0] * (point - c) / max(float(np.linalg.norm(point - c)), 1e-12)
    if obj.shape == "box":
        half = np.asarray(obj.size) / 2
        q = np.clip(local, -half, half)
    elif obj.shape == "cylinder":
        radius, length = obj.size
        rxy = math.hypot(local[0], local[1])
        scale = min(1.0, radius / rxy) if rxy > 0 else 1.0
        q = np.array([local[0] * scale, local[1] * scale, float(np.clip(local[2], -length / 2, length / 2))])
    else:
        raise TaskDefinitionError(f"touch_object: the {obj.name} is a mesh; wbmp touches boxes, cylinders and spheres")
    return c + R @ q


def touching_hand(params: dict, robot: Robot, stance: Stance | None = None) -> str:
    """The hand that touches: the stated one, else the one nearer to the object (the smaller reach gap)."""
    if params.get("hand"):
        return str(params["hand"])
    g = grounded(params, "touch_object")
    st = stance if stance is not None else _start(g, robot)
    gaps = reach_gaps(robot, g.obj, np.asarray(st.heading().translation[:2], dtype=float), _yaw(st))
    return min(("left", "right"), key=lambda side: gaps[side])


def touch_target(robot: Robot, stance: Stance, obj: SceneObject, side: str) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_touch_target`, computed once per robot, stance, object and hand (the pre-check and the build ask)."""
    point, hand = _touch_target(robot, stance, obj, side)
    return np.array(point), np.array(hand)


@functools.cache
def _touch_target(robot: Robot, stance: Stance, obj: SceneObject, side: str) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """(point touched on the object's surface, hand frame target) in the world [m]: the surface point
    nearest to the shoulder; the hand frame on the shoulder-to-point line where, with the arm posed
    there (:func:`tasks.primitives.bodymap.arm_configuration`, the posture the planner's warm start
    takes), the hand's collision meshes reach the object's surface (coal), then :data:`TOUCH_DEPTH`
    further in. When the posed arm's spheres come closer to the body than the planner keeps them
    (``bodymap.CLEARANCE``: G1's wrist 3 cm into its torso at a box 0.16 m from its chest), the
    surface point nearest to the point above it (level with the shoulder) :data:`TOUCH_STEP` further
    ahead is tried, up to :data:`TOUCH_CANDIDATES` times. When the arm alone does not reach there (a touch that bends at
    the hips), the hand frame is back from the point by the hand's extent in front of its frame
    (standing orientation) less :data:`TOUCH_DEPTH`.

    Raises:
        TaskDefinitionError: the point is beyond the hand's reach even bending at the hips (walk to
            the object first), the arm touches it only through the body (step back), or the object
            is a mesh.
    """
    T = stance.transform_from_standing(robot)
    H = stance.heading()
    sh = np.asarray(T.act(to_standing(robot, shoulder(robot, side))), dtype=float)
    surface = nearest_surface_point(obj, sh)
    gap = reach_gap(robot, side, np.asarray(H.actInv(surface), dtype=float), bend=True)
    if gap > 1e-9:
        raise TaskDefinitionError(
            f"touch_object: the {obj.name} is {gap:.2f} m beyond the {side} hand's reach from where the robot "
            f'stands: walk to it first ("walk to the {obj.name} and touch it")')
    u = (surface - sh) / np.linalg.norm(surface - sh)
    front = hand_front(robot, side, H.rotation.T @ u)
    M = T.inverse() * pin.SE3(np.array(rotation(obj.rpy)), np.asarray(obj.position, dtype=float))
    closest = -math.inf
    fwd = H.rotation[:, 0]
    ahead = max(0.0, float(fwd @ (surface - sh)))
    for k in range(TOUCH_CANDIDATES):
        ref = sh + (ahead + k * TOUCH_STEP) * fwd if k else sh
        if k and (signed_distance(obj, ref) or 0.0) <= 0.0:
            break
        point = nearest_surface_point(obj, ref)
        way = (point - sh) / np.linalg.norm(point - sh)
        posed = _posed_touch(robot, side, _key(to_heading(robot, T.actInv(point - front * way))),
                             _key(to_heading_axis(robot, T, way)), _shape_key(obj), _key(M.rotation.ravel()),
                             _key(M.translation))
        if posed is None:
            break
        hand = np.asarray(posed) + TOUCH_DEPTH * to_heading_axis(robot, T, way)
        clear = sphere_clearance(robot, arm_configuration(robot, {side: hand}, natural=True), side, other_arm=False)[0]
        if clear >= CLEARANCE:
            return _key(point), _key(T.act(to_standing(robot, hand)))
        closest = max(closest, clear)
    if math.isfinite(closest):
        raise TaskDefinitionError(
            f"touch_object: the {obj.name} is too close to the body for the {side} hand to touch it: the arm "
            f"would come {PLANNER_MARGIN - closest:.2f} m nearer to the body than the planner lets it; step back first")
    return _key(surface), _key(surface - (front - TOUCH_DEPTH) * u)


def to_heading_axis(robot: Robot, T: pin.SE3, u: np.ndarray) -> np.ndarray:
    """A world direction (3,) as a heading-frame direction of the standing robot ``T`` carries to the stance."""
    return np.asarray(standing_geometry(robot).heading.rotation.T @ (T.rotation.T @ u), dtype=float)


def _key(x) -> tuple[float, ...]:
    return tuple(round(float(v), 9) for v in np.asarray(x, dtype=float).ravel())


def _shape_key(obj: SceneObject) -> tuple:
    if obj.shape not in ("box", "cylinder", "sphere"):
        raise TaskDefinitionError(f"touch_object: the {obj.name} is a mesh; wbmp touches boxes, cylinders and spheres")
    return (obj.shape, *(float(v) for v in obj.size))


def object_shape(key: tuple) -> coal.ShapeBase:
    """The coal shape of a scene object's ``(shape, *size)`` (box sides; cylinder radius, length along z; sphere radius)."""
    kind, *size = key
    return {"box": lambda: coal.Box(*size), "cylinder": lambda: coal.Cylinder(*size),
            "sphere": lambda: coal.Sphere(*size)}[kind]()


def posed_object_gap(robot: Robot, side: str, q: np.ndarray, shape: coal.ShapeBase, placement: pin.SE3) -> float:
    """Smallest coal distance [m] from the ``side`` hand's collision meshes at configuration ``q``
    (standing world) to ``shape`` at ``placement`` (standing world); <= 0 when they touch."""
    cm = robot.collision_model
    data, gdata = robot.data(), pin.GeometryData(cm)
    pin.framesForwardKinematics(robot.model, data, q)
    pin.updateGeometryPlacements(robot.model, data, cm, gdata, q)
    at = coal.Transform3s(placement.rotation, placement.translation)
    return float(min(coal.distance(cm.geometryObjects[i].geometry, coal.Transform3s(gdata.oMg[i].rotation,
                                   gdata.oMg[i].translation), shape, at, coal.DistanceRequest(), coal.DistanceResult())
                     for i in body_map(robot).hand_geometries[side]))


@functools.cache
def _posed_touch(robot: Robot, side: str, first: tuple, u: tuple, shape: tuple, rot: tuple,
                 pos: tuple) -> tuple[float, ...] | None:
    """The heading-frame hand point on the line ``first + s u`` where the posed hand's meshes reach
    the object (within :data:`TOUCH_GAP_TOLERANCE`, from outside), or None when the arm alone does
    not bring the hand there (within ``TOUCH_SEARCH``)."""
    p0, u_ = np.array(first), np.array(u)
    placement = pin.SE3(np.array(rot).reshape(3, 3), np.array(pos))
    geometry = object_shape(shape)
    s, outside = 0.0, None
    for _ in range(TOUCH_ROUNDS):
        p = p0 + s * u_
        q = arm_configuration(robot, {side: p}, natural=True)
        if reach_error(robot, q, side, p) > ARM_IK_TOLERANCE or abs(s) > TOUCH_SEARCH:
            return None
        d = posed_object_gap(robot, side, q, geometry, placement)
        if 0.0 < d <= TOUCH_GAP_TOLERANCE:
            return tuple(float(x) for x in p)
        if d > 0.0:  # outside: on by the distance (the meshes move about as far as the hand frame)
            outside, s = s, s + d
        else:  # in it: halfway back to the last point outside (or 2 cm back)
            s = 0.5 * (outside + s) if outside is not None else s - 0.02
    return None


@functools.cache
def _hand_vertices(robot: Robot, side: str) -> np.ndarray:
    """Vertices (n, 3) of the ``side`` hand's collision meshes at the standing posture, heading
    frame, relative to the hand frame [m] (the corners of the box of a primitive shape)."""
    bm = body_map(robot)
    cm = robot.collision_model
    points = []
    for i in bm.hand_geometries[side]:
        geometry = cm.geometryObjects[i].geometry
        M = bm.placements[i]
        if hasattr(geometry, "vertices") and geometry.num_vertices:
            local = np.asarray(geometry.vertices(), dtype=float)
            points.append(np.array([to_heading(robot, M.act(v)) for v in local[:: max(1, len(local) // 400)]]))
        else:  # a primitive shape (talos's wrist cylinders): its box's corners, already in the heading frame
            points.append(_box_corners(bm, i))
    return np.concatenate(points) - bm.hand_position[side]


def _box_corners(bm, i: int) -> np.ndarray:
    """The 8 corners of geometry ``i``'s box in the body map (heading frame, standing posture)."""
    b = bm.boxes[i]
    return np.array([(x, y, z) for x in (b.lo[0], b.hi[0]) for y in (b.lo[1], b.hi[1]) for z in (b.lo[2], b.hi[2])])


def hand_front(robot: Robot, side: str, u: np.ndarray) -> float:
    """How far the ``side`` hand's collision meshes reach from its frame along ``u`` (heading frame,
    standing orientation) [m]."""
    return float(max(0.0, float((_hand_vertices(robot, side) @ np.asarray(u, dtype=float)).max())))


def _touch_check(params: dict, robot: Robot) -> None:
    g = grounded(params, "touch_object")
    if g.start is None:
        return  # where the robot stands is not known yet (after a walk): checked when it is
    touch_target(robot, g.start, g.obj, touching_hand(params, robot, g.start))


def build_touch_object(b: FragmentBuilder) -> Fragment:
    """The hand out to the object's surface, held there (a planned contact), back to rest."""
    g = grounded(b.params, "touch_object")
    side = touching_hand(b.params, b.robot, b.stance)
    _, hand = touch_target(b.robot, b.stance, g.obj, side)
    T = b.params["duration"]
    b.frame_target(f"{side} hand touching the {g.obj.name}", f"{side}_hand", position=tuple(float(x) for x in hand),
                   window=(OUT_FRACTION * T, HOLD_END_FRACTION * T), tolerance=TOUCH_TOLERANCE, touch=g.obj.name)
    rest_targets(b, [f"{side}_hand"], tau=T)
    b.phase(f"touch the {g.obj.name}", T)
    return b.finish(frozenset({f"{side}_arm"}))


def _touch_parts(params: dict) -> frozenset[str]:
    hand = params.get("hand")
    if hand:
        return frozenset({f"{hand}_arm"})
    return frozenset({"left_arm", "right_arm"})  # the hand is chosen where the robot stands: claim both


WALK_TO = Primitive(name="walk_to", nominal_duration=_walk_duration, build=build_walk_to, parts=lambda p: LEG_PARTS,
                    check=_walk_check, dynamic=True)
LOOK_AT = Primitive(name="look_at", nominal_duration=_hold_duration, build=build_look_at,
                    parts=lambda p: frozenset({"head"}), check=_look_check,
                    limits=lambda robot: ({} if robot.has_role("head") and standing_geometry(robot).neck_joints
                                          else {"object": f"not available: {robot.name} has no neck joint"}))
POINT_AT = Primitive(name="point_at", nominal_duration=_hold_duration, build=build_point_at, parts=_point_parts,
                     check=_point_check)

TOUCH_OBJECT = Primitive(name="touch_object", nominal_duration=_hold_duration, build=build_touch_object,
                         parts=_touch_parts, check=_touch_check)

PRIMITIVES = (WALK_TO, LOOK_AT, POINT_AT, TOUCH_OBJECT)

__all__ = [
    "LOOK_AT",
    "LOOK_TOLERANCE",
    "POINT_AT",
    "POINT_CLEARANCE",
    "PRIMITIVES",
    "TOUCH_DEPTH",
    "TOUCH_OBJECT",
    "WALK_MARGIN",
    "WALK_TO",
    "WalkPlan",
    "body_front",
    "grounded",
    "look_rotation",
    "nearest_surface_point",
    "point_target",
    "pointing_arm",
    "touch_target",
    "touching_hand",
    "walk_plan",
]
