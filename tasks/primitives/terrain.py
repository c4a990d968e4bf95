"""``step_up(object, count)`` and ``step_down(object, count)``: climb onto walkable surfaces ahead,
or down from them to the floor, one station at a time (stairs, boxes, slopes).

The object is a walkable scene object (a stair tread, a box with ``walkable`` set; "the stairs"
names a flight's first tread, :mod:`tasks.terrain`). The treads climbed are that object and the
walkable objects after it straight ahead of the robot (their top centres along the heading, in
order), ``count`` of them (default: every one of them). Each tread is climbed with a step-to
gait: the right foot swings onto it, then the left one beside it, each sole flat at the height
:func:`tasks.terrain.surface_at` gives under its centre (so every sole corner must be over the
same tread: a tread shorter than the sole is refused), centred on the tread along the heading and
keeping its lateral place. A swing clears the higher of the two treads by ``SWING_CLEARANCE`` at
its middle (the planner's swing height is a height above the floor). Dynamic (contact forces), and
the CoM ends over the final feet (HARD, ``END_TOLERANCE``).

A slope (a walkable top tilted by more than 5 deg, :func:`tasks.terrain.is_slope`) is climbed at
several stations (:func:`stations`), each sole flat on the inclined plane (its rpy from the
surface normal, :func:`tasks.terrain.sole_rpy`). A height map's ground (a ``heightfield``) is walked
in strides too, at the places where the ground under each whole sole is flat within
``LEVEL_TOLERANCE`` (:func:`field_stations`). ``step_down`` walks the walkable surfaces ahead
that lie lower than the last (:func:`descent`), then the floor, with the same gait.

Refused in task terms (exit 4, :class:`~tasks.exceptions.BeyondCapability`): a rise above the
robot's ``step_height_max`` ("the 0.30 m rise onto stairs.1 is above talos's 0.20 m step"), a
tread farther than ``climb_length_max`` (or ``step_length_max``) from the last one (or from the feet:
walk closer first).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from robots import Robot, sole_corners
from tasks.exceptions import BeyondCapability, TaskDefinitionError
from tasks.grounding import Grounded
from tasks.primitives.arms import UPPER_ARM_OUT, hold_upper_arms
from tasks.primitives.base import Fragment, FragmentBuilder, Primitive
from tasks.primitives.gait import (
    OTHER,
    Segment,
    both,
    contact,
    heading_yaw,
    rz,
    sequence_duration,
    stance_from,
    start_placements,
    tau,
    write_segments,
)
from tasks.primitives.geometry import Stance, standing_geometry
from tasks.primitives.objects import grounded
from tasks.scene import Scene, SceneObject, rotation
from tasks.specs import Pose
from tasks.terrain import is_slope, sole_rpy, surface_at, top_height

PARTS = frozenset({"legs", "com"})
SWING_CLEARANCE = 0.09  # [m] a swinging sole above the higher tread at the middle of its swing (talos's
#   foot cover spheres reach 6.7 cm below its sole; the planner keeps 1 cm from objects)
END_TOLERANCE = 0.02  # [m] CoM ground projection at the end vs the point between the feet
SETTLE_FRACTION = 0.5  # opening shift and closing settle: this fraction of step_duration
LEVEL_TOLERANCE = 1e-3  # [m] every sole corner over the same surface height
WAYPOINT_TOLERANCE = 0.02  # [m] the swinging sole's lift and descent waypoints
TOE_CLEARANCE = 0.05  # [m] the sole's front edge at least this far back from a tread's front edge
EDGE = 0.02  # [m] a sole's heel past a surface's near edge (a slope's foot, a landing's seam), its toe before a slope's top
FLOOR_CLEARANCE = 0.05  # [m] the heel from the last step's foot at the end of a descent (when within reach)
REACH = 0.95  # a station at most this fraction of the robot's stride (stride()) ahead of the last one
LEAD = "right"  # the foot that steps up first
DOUBLE_SUPPORT = 0.3  # [s] at least, between two steps: the weight moves up (or down) a step onto the other
#   foot (with talos's 0.15 s the trailing sole slipped 12 mm in MuJoCo as it unloaded, limit 10 mm)


def stride(robot: Robot) -> float:
    """The longest step onto another surface [m]: the profile's ``climb_length_max``, or its
    ``step_length_max`` when that is 0."""
    return robot.profile.climb_length_max or robot.profile.step_length_max


def _yaw_of(stance: Stance) -> float:
    R = stance.heading().rotation
    return math.atan2(R[1, 0], R[0, 0])


def _along(obj: SceneObject, mid: np.ndarray, u: np.ndarray) -> float:
    return float(np.dot(np.asarray(obj.position[:2]) - mid[:2], u))


def _on_line(obj: SceneObject, mid: np.ndarray, u: np.ndarray) -> bool:
    """The heading line through the feet crosses the object's top (at its centre's distance)."""
    s = _along(obj, mid, u)
    p = mid[:2] + s * u
    return surface_at(Scene(objects=(obj,)), float(p[0]), float(p[1])).name == obj.name


def treads(scene: Scene, first: SceneObject, stance: Stance, count: int | None) -> list[SceneObject]:
    """The walkable objects climbed: ``first`` and the ones straight ahead after it, in order."""
    if not first.walkable or top_height(first) is None:
        raise TaskDefinitionError(
            f"step_up: the {first.name} is not a surface to stand on; mark it \"walkable\": true in the scene "
            "(an upright box or cylinder), or use stairs (docs/scenes.md)")
    mid, _ = heading_yaw({"left": stance.left, "right": stance.right})
    yaw = _yaw_of(stance)
    u = np.array([math.cos(yaw), math.sin(yaw)])
    s0 = _along(first, mid, u)
    if s0 <= 0 or not _on_line(first, mid, u):
        raise TaskDefinitionError(
            f"step_up: the {first.name} is not straight ahead of the robot; turn to face it first")
    ahead = sorted((o for o in scene.objects if o.walkable and o is not first and _along(o, mid, u) > s0 + 1e-9
                    and top_height(o) is not None and _on_line(o, mid, u)), key=lambda o: _along(o, mid, u))
    chain = [first, *ahead]
    if count is None:
        return chain
    if count > len(chain):
        raise TaskDefinitionError(
            f"step_up: {count} steps asked, but only {len(chain)} walkable surface(s) lie ahead from the "
            f"{first.name} ({', '.join(o.name for o in chain)}); ask for at most {len(chain)}")
    return chain[:count]


def descent(scene: Scene, named: SceneObject, stance: Stance, count: int | None) -> list[SceneObject | None]:
    """The surfaces walked down onto: the walkable objects straight ahead lower than the last (a
    slope: lower at its far edge), nearest first, then the floor (None); ``named`` among them."""
    mid, _ = heading_yaw({"left": stance.left, "right": stance.right})
    yaw = _yaw_of(stance)
    u = np.array([math.cos(yaw), math.sin(yaw)])
    here = surface_at(scene, float(mid[0]), float(mid[1]))
    ahead = sorted((o for o in scene.objects if o.walkable and o.name != here.name and _along(o, mid, u) > 0
                    and top_height(o) is not None and _on_line(o, mid, u)), key=lambda o: _along(o, mid, u))
    chain: list[SceneObject | None] = []
    level = here.height
    for obj in ahead:
        lo, hi = _extent(obj, mid, u)
        near = surface_at(Scene(objects=(obj,)), *(mid[:2] + (lo + 1e-3) * u)).height
        far = surface_at(Scene(objects=(obj,)), *(mid[:2] + (hi - 1e-3) * u)).height
        if near > level + LEVEL_TOLERANCE or far > near + LEVEL_TOLERANCE:
            break  # it goes up again: the descent ends before it
        chain.append(obj)
        level = far
    if named not in chain and here.name is not None and _along(named, mid, u) < 0:
        raise BeyondCapability(
            f"step_down: the {named.name} is behind the robot (it stands on the {here.name}, facing away from it) "
            "and it neither turns around on a tread nor walks down backwards: walk down from where the way down "
            "lies ahead (a spec's start facing it), or ask for the climb and the descent separately")
    if named not in chain:
        raise TaskDefinitionError(
            f"step_down: the {named.name} is not below the robot straight ahead ("
            + (f"it stands on the {here.name}" if here.name else "it stands on the floor")
            + "); walk down from where it stands, facing the way down")
    chain.append(None)
    return chain if count is None else chain[:count]


def _placement(robot: Robot, scene: Scene, side: str, xy: np.ndarray, yaw: float, tread: SceneObject | None) -> Pose:
    """The sole flat on the surface under ``xy`` (its height and normal: tilted on a slope), refused
    when a corner is over another surface or off its plane."""
    centre = surface_at(scene, float(xy[0]), float(xy[1]))
    rpy = sole_rpy(centre.normal, yaw)
    R = np.array(rotation(rpy))
    origin = np.array([xy[0], xy[1], centre.height])
    for corner in sole_corners(robot.profile.sole, side):
        p = origin + R @ corner
        under = surface_at(scene, float(p[0]), float(p[1]))
        if abs(under.height - p[2]) > LEVEL_TOLERANCE or under.name != _name(tread):
            raise BeyondCapability(
                f"step_up: {robot.name}'s {side} sole ({robot.profile.sole.x_max - robot.profile.sole.x_min:.2f} m "
                f"long) does not fit on the {_words(tread)} (a corner would be over "
                f"{'the floor' if under.name is None else 'the ' + under.name}); treads must be longer than the sole")
    return Pose(position=(float(xy[0]), float(xy[1]), float(centre.height)), rpy=rpy)


def _name(tread: SceneObject | None) -> str | None:
    return None if tread is None else tread.name


def _words(tread: SceneObject | None) -> str:
    return "floor" if tread is None else tread.name


def _extent(obj: SceneObject, mid: np.ndarray, u: np.ndarray) -> tuple[float, float]:
    """The object's top face from its near edge to its far edge along the horizontal ``u`` [m]."""
    if obj.shape == "cylinder":
        s = _along(obj, mid, u)
        return s - float(obj.size[0]), s + float(obj.size[0])
    R = np.array(rotation(obj.rpy))
    a, b, c = (np.asarray(obj.size) / 2)
    ends = [float(np.dot(np.asarray(obj.position[:2]) + (R @ np.array([i * a, j * b, c]))[:2] - mid[:2], u))
            for i in (-1, 1) for j in (-1, 1)]
    return min(ends), max(ends)


FIELD_STEP = 0.01  # [m] the candidate stations on a height map, this far apart along the heading


def _fits(robot: Robot, tread: SceneObject, xy: np.ndarray, yaw: float, side: str) -> bool:
    try:
        _placement(robot, Scene(objects=(tread,)), side, xy, yaw, tread)
    except BeyondCapability:
        return False
    return True


def field_stations(robot: Robot, tread: SceneObject, mid: np.ndarray, u: np.ndarray, last: float,
                   feet: dict[str, float]) -> list[float]:
    """Stations on a height map (the soles' centre along ``u`` from ``mid``) [m]: the farthest place
    within ``REACH`` strides of the last one where both soles (at their lateral offsets ``feet``) lie
    flat on the ground under them, again and again up to the last such place on the map."""
    prof = robot.profile
    half = (prof.sole.x_max - prof.sole.x_min) / 2
    sole_mid = np.array([(prof.sole.x_min + prof.sole.x_max) / 2, 0.0])
    yaw = math.atan2(u[1], u[0])
    side_axis = np.array([-u[1], u[0]])
    lo, hi = _extent(tread, mid, u)
    n = int(math.floor((hi - lo - 2 * (EDGE + half)) / FIELD_STEP + 1e-9))
    places = [lo + EDGE + half + k * FIELD_STEP for k in range(max(n + 1, 0))]
    fit = [s for s in places if all(
        _fits(robot, tread, mid[:2] + s * u + lat * side_axis - rz(yaw)[:2, :2] @ sole_mid, yaw, side)
        for side, lat in feet.items())]
    if not fit:
        raise BeyondCapability(f"step_up: the ground of the {tread.name} has no place flat enough for "
                               f"{robot.name}'s soles (within {LEVEL_TOLERANCE * 1000:.0f} mm under every corner)")
    out: list[float] = []
    reach = REACH * stride(robot)
    while not out or out[-1] < fit[-1]:
        here = out[-1] if out else last
        ahead = [s for s in fit if here < s <= here + reach + 1e-9]
        if not ahead:
            raise BeyondCapability(
                f"step_up: no place flat enough for a sole on the {tread.name} within {reach:.2f} m of "
                f"{robot.name}'s last step ({here - last:.2f} m along it): the ground is too uneven to walk on")
        out.append(ahead[-1])
    return out


def stations(robot: Robot, chain: list[SceneObject | None], mid: np.ndarray, u: np.ndarray,
             start: float, down: bool = False,
             feet: dict[str, float] | None = None) -> list[tuple[SceneObject | None, float]]:
    """Where both soles stand in turn: (surface, the soles' centre along ``u`` from ``mid``) [m].

    A flat tread: one station, centred on it, or (up) back from its front edge by ``TOE_CLEARANCE``, or
    at most ``REACH`` steps ahead of the last one (but not off its near edge). A slope: evenly spaced
    stations at most ``REACH`` apart from ``EDGE`` past its near edge to ``EDGE`` before its far one.
    The floor (None, at the end of a descent): ``EDGE`` past the last surface's far edge, or farther
    out to ``REACH`` (the heel away from the riser or the slope's foot)."""
    half = (robot.profile.sole.x_max - robot.profile.sole.x_min) / 2
    reach = REACH * stride(robot)
    out: list[tuple[SceneObject | None, float]] = []
    last, edge = start, start
    for tread in chain:
        if tread is None:
            out.append((None, max(edge + EDGE + half, min(last + reach, edge + FLOOR_CLEARANCE + half))))
            break
        lo, hi = _extent(tread, mid, u)
        edge = hi
        if tread.shape == "heightfield":
            out += [(tread, s) for s in field_stations(robot, tread, mid, u, last, feet or {"left": 0.0})]
        elif is_slope(tread):
            first, final = lo + EDGE + half, hi - EDGE - half
            n = max(1, math.ceil((final - first) / reach - 1e-9) + 1) if final > first else 1
            out += [(tread, first + (final - first) * i / max(n - 1, 1)) for i in range(n)]
        else:
            s = _along(tread, mid, u) if down else min(_along(tread, mid, u), hi - TOE_CLEARANCE - half)
            if s > last + reach:  # a landing after a slope: its near end
                s = max(last + reach, lo + EDGE + half)
            out.append((tread, s))
        last = out[-1][1]
    return out


def _top(robot: Robot, side: str, pose: Pose) -> float:
    """The highest sole corner of a placement [m] (a tilted sole's toe on a slope)."""
    R = np.array(rotation(pose.rpy))
    return float(max((np.asarray(pose.position) + R @ c)[2] for c in sole_corners(robot.profile.sole, side)))


def _ground_between(scene: Scene, chain: list[SceneObject | None], a: np.ndarray, b: np.ndarray) -> float:
    """The highest height-map ground on the line from ``a`` to ``b`` (a bump between two steps) [m]."""
    if not any(t is not None and t.shape == "heightfield" for t in chain):
        return 0.0
    return max(surface_at(scene, *(a[:2] + f * (b[:2] - a[:2]))).height for f in np.linspace(0.0, 1.0, 21))


@dataclass(frozen=True, slots=True)
class Swing:
    """One swing of the climb: segment index, side, lift-off and landing sole positions, and the
    height its sole passes at (the higher tread plus ``SWING_CLEARANCE``) [m]."""

    segment: int
    side: str
    start: tuple[float, float, float]
    end: tuple[float, float, float]
    height: float


def plan_steps(robot: Robot, g: Grounded, count: int | None, stance: Stance | None = None,
               down: bool = False) -> tuple[list[Segment], dict[str, Pose], list[Swing]]:
    """The phases of the climb (``down``: of the descent), the final sole placements and the swings."""
    st = stance if stance is not None else (g.start if isinstance(g.start, Stance) else Stance.standing(robot))
    chain: list[SceneObject | None] = (descent(g.scene, g.obj, st, count) if down
                                       else list(treads(g.scene, g.obj, st, count)))
    where = start_placements(robot, st)
    mid, _ = heading_yaw(where)
    yaw = _yaw_of(st)
    u = np.array([math.cos(yaw), math.sin(yaw)])
    prof = robot.profile
    sole_mid = np.array([(prof.sole.x_min + prof.sole.x_max) / 2, 0.0])
    settle = SETTLE_FRACTION * prof.step_duration
    segs = [Segment(name="shift weight", duration=settle, contacts=both(robot, where))]
    cur = dict(where)
    swings: list[Swing] = []
    side_axis = np.array([-u[1], u[0]])
    feet = {side: float(np.dot(np.asarray(p.position[:2]) + rz(yaw)[:2, :2] @ sole_mid - mid[:2], side_axis))
            for side, p in where.items()}
    plan = stations(robot, chain, mid, u, float(sole_mid[0]), down, feet)
    for i, (tread, s) in enumerate(plan):
        for side in (LEAD, OTHER[LEAD]):
            here = np.asarray(cur[side].position)
            lateral = float(np.dot(here[:2] - mid[:2], np.array([-u[1], u[0]])))
            xy = mid[:2] + s * u + lateral * np.array([-u[1], u[0]]) - rz(yaw)[:2, :2] @ sole_mid
            target = _placement(robot, g.scene, side, xy, yaw, tread)
            rise = target.position[2] - here[2]
            length = float(np.linalg.norm(np.asarray(target.position[:2]) - here[:2]))
            if abs(rise) > prof.step_height_max + 1e-9:
                raise BeyondCapability(
                    f"the {abs(rise):.2f} m {'drop' if rise < 0 else 'rise'} onto the {_words(tread)} is above "
                    f"{robot.name}'s {prof.step_height_max:.2f} m step (step_height_max of its profile): choose lower "
                    "steps, or another robot")
            if length > stride(robot) + 1e-9:
                hint = ("walk closer to it first" if i == 0 else "the treads are too deep for it")
                raise BeyondCapability(
                    f"step_{'down' if down else 'up'}: the {side} foot would step {length:.2f} m onto the "
                    f"{_words(tread)}, beyond {robot.name}'s {stride(robot):.2f} m step: {hint}")
            height = max(_top(robot, side, cur[side]), _top(robot, side, target),
                         _ground_between(g.scene, chain, here, np.asarray(target.position))) + SWING_CLEARANCE
            swings.append(Swing(len(segs), side, cur[side].position, target.position, height))
            segs.append(Segment(name=f"step {i + 1}: {side} foot onto the {_words(tread)}", duration=prof.step_duration,
                                contacts=(contact(robot, OTHER[side], cur[OTHER[side]]),), swing_height=height))
            cur[side] = target
            last = i == len(plan) - 1 and side == OTHER[LEAD]
            segs.append(Segment(name="settle" if last else f"step {i + 1}: double support",
                                duration=settle if last else max(prof.double_support_duration, DOUBLE_SUPPORT),
                                contacts=both(robot, cur), rounding="nearest" if last else "floor"))
    return segs, cur, swings


def _count(params: dict) -> int | None:
    value = params.get("count")
    return None if value is None else int(value)


def _plan(params: dict, robot: Robot, down: bool, stance: Stance | None = None):
    action = "step_down" if down else "step_up"
    return plan_steps(robot, grounded(params, action), _count(params), stance, down=down)


def _build(b: FragmentBuilder, down: bool = False) -> Fragment:
    segs, end, swings = _plan(b.params, b.robot, down, b.stance)
    bounds = write_segments(b, segs)
    for sw in swings:
        # lift straight up, pass over the riser, come straight down: the sole above its lift-off
        # place a third into the swing and above its landing place two thirds into it
        k0, k1 = bounds[sw.segment], bounds[sw.segment + 1]
        for frac, (x, y, _z), when in ((1 / 3, sw.start, "lifted"), (2 / 3, sw.end, "over its landing")):
            b.frame_target(f"{sw.side} foot {when} ({segs[sw.segment].name})", f"{sw.side}_foot",
                           position=(x, y, sw.height), time=tau(b, k0 + round(frac * (k1 - k0))),
                           tolerance=WAYPOINT_TOLERANCE)
    b.end_stance = stance_from(end)
    home = b.end_stance.transform_from_standing(b.robot).act(standing_geometry(b.robot).com)
    b.com_target(f"CoM over the feet on the last {'step' if down else 'tread'}", (float(home[0]), float(home[1]), None),
                 time=tau(b, bounds[-1]), tolerance=END_TOLERANCE)
    # as in walks: G1's left upper arm went into the torso's meshes climbing the stairs (16 samples).
    # Not on a height map: with the shoulders held out, talos's ramp walk (examples/scenes/
    # heightmap.json) landed its last right step 32 mm off its placement (the certificate's 20 mm)
    if not any(o.shape == "heightfield" for o in grounded(b.params, "step_down" if down else "step_up").scene.objects):
        hold_upper_arms(b, b.nominal, ("left", "right"), out=UPPER_ARM_OUT)
    return b.finish(PARTS, dynamic=True)


def _limits(robot: Robot) -> dict[str, str]:
    prof = robot.profile
    return {"object": f"rises of at most {prof.step_height_max:.2f} m, treads at most {stride(robot):.2f} m "
                      f"apart on {robot.name}"}


STEP_UP = Primitive(name="step_up", nominal_duration=lambda p, r: sequence_duration(_plan(p, r, False)[0]),
                    build=_build, parts=lambda p: PARTS, check=lambda p, r: _plan(p, r, False) and None,
                    limits=_limits, dynamic=True)
STEP_DOWN = Primitive(name="step_down", nominal_duration=lambda p, r: sequence_duration(_plan(p, r, True)[0]),
                      build=lambda b: _build(b, down=True), parts=lambda p: PARTS,
                      check=lambda p, r: _plan(p, r, True) and None, limits=_limits, dynamic=True)

PRIMITIVES = (STEP_UP, STEP_DOWN)

__all__ = ["PRIMITIVES", "STEP_DOWN", "STEP_UP", "SWING_CLEARANCE", "descent", "field_stations", "plan_steps", "stations", "treads"]
