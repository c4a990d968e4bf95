"""Arm and hand gestures: ``punch``, ``hands_on_hips``, ``cross_arms``, ``arms_out``, ``point``,
``arm_circles``, ``shrug``, ``stretch`` (those where a hand meets the body, ``clap``, ``touch`` and
``salute``, are in :mod:`tasks.primitives.meet`, on the helpers here).

Every target is a HARD hand position target computed in the *heading frame* (x forward, y left,
z up, origin on the ground between the feet) from the robot's standing posture: ``S`` is the
shoulder frame of the moving arm, ``L`` the arm's length (shoulder to hand), ``o`` = +1 for the
left arm and -1 for the right one (its outward y direction). Held poses are reached at
``OUT_FRACTION`` of the duration, held until ``HOLD_END_FRACTION`` and left for the rest
position (a soft target at the end), like the posture primitives.

Motions that bring a hand to the body stop it ``bodymap.GAP`` (2 cm) short of the body part's
collision box (see :mod:`tasks.primitives.bodymap`), so they stay feasible once the planner keeps
a 1 cm self-collision margin. A point the arm cannot reach is refused with the distance and the
reach (``REACH_FRACTION * L``); the knee and the toes may be reached by bending at the hips
(up to ``BEND_MAX``), and the toes only "as far as reachable": the hand goes as low above the
toe tip as the bent reach allows.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pinocchio as pin

from robots import Robot
from tasks.exceptions import TaskDefinitionError
from tasks.primitives.base import Fragment, FragmentBuilder, Primitive, arms_of, rest_targets
from tasks.primitives.bodymap import (
    arm_configuration,
    arm_joints,
    body_map,
    clear_targets,
    stop_short,
    to_heading,
    to_standing,
)
from tasks.primitives.geometry import standing_geometry
from tasks.specs import JointTarget

OUT_FRACTION = 0.4  # held poses are reached at this fraction of the duration
HOLD_END_FRACTION = 0.6  # and left at this one
REACH_FRACTION = 0.92  # [L] farthest hand target from the shoulder (the arm nearly straight)
BEND_MAX = 0.7  # [rad] forward bend at the hips allowed to reach the knee and the toes
POSE_TOLERANCE = 0.02  # [m] held hand poses and rhythmic targets
GUARD_TOLERANCE = 0.03  # [m] punch guard / clap apart / shrug low positions
MEET_TOLERANCE = 0.002  # [m] hands that meet (clap, touch the other hand): the planner leaves their pairs out there
MEET_ORIENTATION = 0.02  # [rad] ... and their orientation at the meeting point within this
#: [m], [rad] a part a hand meets (the head) stays this close to where it stands: G1's head is on its
#: torso, and held within the hand's tolerances the touch at the temple left the forearm no room
#: from the torso (IPOPT: infeasible, every target at its bound).
PART_STILL_TOLERANCE = 0.005
PART_STILL_ORIENTATION = 0.05
RAISE_TIME = 0.8  # [s] from rest to the first pose of a rhythmic gesture
LOWER_TIME = 0.8  # [s] from the last pose back to rest
TORSO_TOLERANCE = 0.05  # [rad] stretch lean

SIGN = {"left": 1.0, "right": -1.0}
UPPER_ARM_OUT = 0.1  # [rad] shoulder roll away from the body in walks and hops (hold_upper_arms)
X, Y, Z = np.eye(3)


# --- geometry helpers ---------------------------------------------------------------------
def shoulder(robot: Robot, side: str) -> np.ndarray:
    """Shoulder frame of ``side`` in the heading frame (3,) [m] (the hand if there is no shoulder frame)."""
    g = standing_geometry(robot)
    role = f"{side}_shoulder" if f"{side}_shoulder" in g.placements else f"{side}_hand"
    return to_heading(robot, g.position(role))


def arm_length(robot: Robot, side: str) -> float:
    """Shoulder-to-hand chain length of ``side`` [m]."""
    return standing_geometry(robot).arm_length[side]


def reach(robot: Robot, side: str) -> float:
    """Farthest hand target from the shoulder [m]."""
    return REACH_FRACTION * arm_length(robot, side)


def _bent_shoulder(robot: Robot, side: str, angle: float) -> np.ndarray:
    """The shoulder after bending forward by ``angle`` about the hips (heading frame)."""
    pivot = body_map(robot).hip_pivot
    return pivot + pin.exp3(angle * Y) @ (shoulder(robot, side) - pivot)


def reach_gap(robot: Robot, side: str, point: np.ndarray, *, bend: bool = False) -> float:
    """How far ``point`` (heading frame) is beyond the ``side`` hand's reach (<= 0: reachable) [m].

    With ``bend``, the shoulder may first bend forward about the hips by up to ``BEND_MAX``.
    """
    angles = np.linspace(0.0, BEND_MAX, 15) if bend else (0.0,)
    return min(float(np.linalg.norm(point - _bent_shoulder(robot, side, a))) for a in angles) - reach(robot, side)


def _require_reach(action: str, robot: Robot, side: str, point: np.ndarray, what: str, *, bend: bool = False) -> None:
    gap = reach_gap(robot, side, point, bend=bend)
    if gap > 1e-9:
        how = f" even bending {BEND_MAX:g} rad at the hips" if bend else ""
        raise TaskDefinitionError(
            f"{action}: {robot.name}'s {side} hand cannot reach {what}{how}: it is {gap:.2f} m beyond the arm's "
            f"reach of {reach(robot, side):.2f} m from the shoulder"
        )


def _put(b: FragmentBuilder, what: str, side: str, point: np.ndarray, *, time: float | None = None,
         window: tuple[float, float] | None = None, tolerance: float = POSE_TOLERANCE, meet: str | None = None,
         rotation: np.ndarray | None = None) -> None:
    """HARD position target of the ``side`` hand at a heading-frame point. ``meet``: the role the
    hand touches there (the other hand, the head; ``FrameTarget.meets``: the planner lets their
    links meet), held within ``MEET_TOLERANCE`` and at ``rotation`` (standing world frame: the
    orientation the arm has there, :func:`tasks.primitives.meet.meet_rotation`), within ``MEET_ORIENTATION``."""
    if meet is not None and rotation is None:
        raise ValueError(f"{what}: a hand that meets {meet} needs its rotation there")  # pragma: no cover
    rpy = None if rotation is None else b.world_rotation(rotation)
    b.frame_target(what, f"{side}_hand", position=b.world(to_standing(b.robot, point)), rpy=rpy, time=time,
                   window=window, tolerance=tolerance if meet is None else MEET_TOLERANCE,
                   orientation_tolerance=MEET_ORIENTATION, meets=meet)


def _hold(b: FragmentBuilder, what: str, points: dict[str, np.ndarray], phase: str, parts: frozenset[str],
          *, meet: dict[str, str] | None = None, rotations: dict[str, np.ndarray] | None = None) -> Fragment:
    """Hands to ``points``, held from OUT_FRACTION to HOLD_END_FRACTION of the duration, back to rest
    (``meet``: side -> the role that hand touches there, at ``rotations[side]``, :func:`_put`)."""
    T = b.params["duration"]
    window = (OUT_FRACTION * T, HOLD_END_FRACTION * T)
    for side, p in points.items():
        _put(b, f"{side} hand {what}", side, p, window=window, meet=(meet or {}).get(side),
             rotation=(rotations or {}).get(side))
    for role in sorted({r for r in (meet or {}).values() if not r.endswith("_hand")}):
        # the part stays where the hand meets it (Talos leant its torso back 13 deg, the head 12 cm off the salute)
        g = standing_geometry(b.robot)
        b.frame_target(f"{role} still for the hand", role, position=b.world(g.position(role)),
                       rpy=b.world_rotation(g.rotation(role)), window=window, tolerance=PART_STILL_TOLERANCE,
                       orientation_tolerance=PART_STILL_ORIENTATION)
    rest_targets(b, [f"{s}_hand" for s in points], tau=T)
    b.phase(phase, T)
    return b.finish(parts)


def _other(side: str) -> str:
    return "right" if side == "left" else "left"


def _arm_parts(sides) -> frozenset[str]:
    return frozenset(f"{s}_arm" for s in sides)


def _duration(params: dict, robot: Robot) -> float:
    return params["duration"]


def _rhythm_duration(params: dict, robot: Robot) -> float:
    return RAISE_TIME + params["repeat"] * params["duration"] + LOWER_TIME


BOTH_ARMS = _arm_parts(("left", "right"))


UPPER_ARM_WEIGHT = 10.0  # joint-target weight holding a shoulder's roll at its standing angle (clap, salute)


def hold_upper_arms(b: FragmentBuilder, T: float, sides: tuple[str, ...], out: float = 0.0,
                    at: tuple[float, ...] = ()) -> None:
    """The ``sides`` shoulders' roll joint (the arm's second, which swings the upper arm in to the
    body) held at its standing angle over the whole gesture (a cost), turned ``out`` [rad] away
    from the body (:func:`upper_arm_out_angle`): a clap's hands come together
    by the shoulders' yaw and the elbows. The planner does not see the upper arm against the torso
    (their meshes are 9 mm apart standing, too close to keep its 1 cm margin: "touching at rest"),
    and G1's plan swung the right upper arm into the torso's meshes (coal) to bring the hands in;
    in its salute, the left arm, which stays down; in its hops and one-foot balances, an arm that
    swung for balance. Walks, steps, turns and hops hold them ``UPPER_ARM_OUT`` out: planned at
    standing, G1's simulated upper arm still grazed the torso (3 samples of "walk forward", 1 of a
    hop), the few millimetres the controller lets an untargeted arm swing. With ``at``: asked at
    those nominal times [s] only (``T`` unused), not held over the gesture."""
    for side in sides:
        j = arm_joints(b.robot, side)[1]
        name, value = b.robot.model.names[j], upper_arm_out_angle(b.robot, side, out)
        if not at:
            b.joint_targets.append(JointTarget(name=b.name(f"{side} upper arm out of the torso"), joint=name,
                                               value=value, window=b.window(0.0, T), weight=UPPER_ARM_WEIGHT))
        for tau in at:
            b.joint_targets.append(JointTarget(name=b.name(f"{side} upper arm out of the torso at {tau:g} s"),
                                               joint=name, value=value, time=b.t(tau), weight=UPPER_ARM_WEIGHT))


def upper_arm_out_angle(robot: Robot, side: str, out: float) -> float:
    """The ``side`` shoulder roll's standing angle turned ``out`` [rad] in the sense that takes the
    hand away from the body's midline (Pinocchio FK at standing), within the joint's limits."""
    model, q = robot.model, robot.q_standing.copy()
    j = arm_joints(robot, side)[1]
    i = model.joints[j].idx_q
    standing = float(q[i])
    if out == 0.0:
        return standing
    data, fid = model.createData(), robot.frame_id(f"{side}_hand")
    pin.framesForwardKinematics(model, data, q)
    y0 = SIGN[side] * data.oMf[fid].translation[1]
    q[i] = standing + 0.05
    pin.framesForwardKinematics(model, data, q)
    sense = 1.0 if SIGN[side] * data.oMf[fid].translation[1] > y0 else -1.0
    return float(np.clip(standing + sense * out, model.lowerPositionLimit[i], model.upperPositionLimit[i]))


# --- punch ---------------------------------------------------------------------------------
def punch_points(robot: Robot, side: str) -> tuple[np.ndarray, np.ndarray]:
    """(guard, hit) hand points of a punch (heading frame): the guard ``0.3 L`` ahead of and
    ``0.35 L`` below the shoulder, the hit ``0.85 L`` ahead at shoulder height, both ``0.1 L``
    towards the midline."""
    S, L, o = shoulder(robot, side), arm_length(robot, side), SIGN[side]
    guard = S + 0.3 * L * X - 0.1 * o * L * Y - 0.35 * L * Z
    hit = S + 0.85 * L * X - 0.1 * o * L * Y - 0.05 * L * Z
    return guard, hit


def _repeat(b: FragmentBuilder, side: str, n: int, d: float, start: tuple[str, np.ndarray], peak: tuple[str, np.ndarray],
            back: str, *, meet: str | None = None, rotation: np.ndarray | None = None) -> None:
    """The ``side`` hand at ``start`` when raised, then ``n`` times out to ``peak`` (at the middle of
    each ``d``-second beat) and back to the start point (at its end): punch, clap, shrug. ``meet``:
    the role the hand touches at the peak, at ``rotation`` (a clap: the other hand; :func:`_put`)."""
    (start_name, home), (peak_name, point) = start, peak
    _put(b, start_name, side, home, time=RAISE_TIME, tolerance=GUARD_TOLERANCE)
    for k in range(n):
        _put(b, f"{peak_name} #{k + 1}", side, point, time=RAISE_TIME + (k + 0.5) * d, meet=meet, rotation=rotation)
        _put(b, f"{back} #{k + 1}", side, home, time=RAISE_TIME + (k + 1) * d, tolerance=GUARD_TOLERANCE)


def build_punch(b: FragmentBuilder) -> Fragment:
    """Up to the guard, ``repeat`` times out to the hit and back to the guard, down to rest."""
    side, n, d = b.params["arm"], b.params["repeat"], b.params["duration"]
    guard, hit = punch_points(b.robot, side)
    _repeat(b, side, n, d, (f"{side} fist on guard", guard), (f"{side} punch", hit),
            f"{side} fist back on guard")
    rest_targets(b, [f"{side}_hand"], tau=_rhythm_duration(b.params, b.robot))
    b.phase("punch", _rhythm_duration(b.params, b.robot))
    return b.finish(_arm_parts((side,)))


PUNCH = Primitive(name="punch", nominal_duration=_rhythm_duration, build=build_punch,
                  parts=lambda p: _arm_parts((p["arm"],)))


def hip_point(robot: Robot, side: str, moving: tuple[str, ...]) -> np.ndarray:
    """Hand point beside the ``side`` hip at the base frame's height (heading frame)."""
    m = body_map(robot)
    o = SIGN[side]
    start = [m.hip_pivot[0], o * m.beside(side, m.hip_half_width[side] * o, o * Y), m.hip_height]
    return stop_short(robot, side, start, o * Y, moving)


# --- hands_on_hips, cross_arms, arms_out ---------------------------------------------
def hips_points(robot: Robot) -> dict[str, np.ndarray]:
    """Side -> hand point beside that hip with both arms moving, cleared together in the
    planner's sphere model (:func:`~tasks.primitives.bodymap.clear_targets`, outwards)."""
    pts = {s: hip_point(robot, s, ("left", "right")) for s in ("left", "right")}
    return clear_targets(robot, pts, {s: SIGN[s] * Y for s in pts})


def build_hands_on_hips(b: FragmentBuilder) -> Fragment:
    """Both hands beside the hips."""
    pts = hips_points(b.robot)
    for s, p in pts.items():
        _require_reach("hands_on_hips", b.robot, s, p, "its hip")
    return _hold(b, "on the hip", pts, "hands on hips", BOTH_ARMS)


HANDS_ON_HIPS = Primitive(name="hands_on_hips", nominal_duration=_duration, build=build_hands_on_hips,
                          parts=lambda p: BOTH_ARMS)

CROSS_DROP = 0.15  # [L] the left hand lies this much lower than the right one
CROSS_ACROSS = 0.5  # each hand at this fraction of the other shoulder's distance from the midline


def cross_points(robot: Robot) -> dict[str, np.ndarray]:
    """Side -> hand point with the arms crossed: each hand in front of the *other* upper arm
    (``CROSS_ACROSS`` of its shoulder's distance from the midline), ``GAP`` in front of the torso,
    the right hand ``0.3 L`` below the shoulders and the left one ``CROSS_DROP * L`` lower; then moved forward until both arms, posed together, clear the body by
    ``bodymap.CLEARANCE`` in the planner's sphere model, but no farther than the arm reaches (on
    Talos the torso's sphere set, 27 cm in radius, cannot be cleared with the arms crossed: the
    planner then says which pair is in the way)."""
    m = body_map(robot)
    out = {}
    L = min(arm_length(robot, s) for s in ("left", "right"))
    stack = CROSS_DROP * L
    for side, drop in (("right", 0.3 * L), ("left", 0.3 * L + stack)):  # [m] below the shoulder
        S = shoulder(robot, side)
        other = shoulder(robot, _other(side))
        front = m.torso.hi[0] if m.torso is not None else S[0]
        start = [m.beside(side, front, X), CROSS_ACROSS * other[1], S[2] - drop]
        out[side] = stop_short(robot, side, start, X, ("left", "right"), clear=False)
    cleared = clear_targets(robot, out, {"left": X, "right": X}, other_arm=False)  # both arms posed, clear of the body
    return {s: _within_reach(robot, s, out[s], cleared[s]) for s in out}


def _within_reach(robot: Robot, side: str, near: np.ndarray, far: np.ndarray) -> np.ndarray:
    """``far`` if the ``side`` hand reaches it, else the farthest reachable point on the segment
    from ``near`` (bisection; ``near`` itself if that is out of reach too)."""
    if reach_gap(robot, side, far) <= 0.0:
        return far
    lo, hi = 0.0, 1.0
    for _ in range(20):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if reach_gap(robot, side, near + mid * (far - near)) <= 0.0 else (lo, mid)
    return near + lo * (far - near)


def build_cross_arms(b: FragmentBuilder) -> Fragment:
    """Both hands in front of the opposite upper arms."""
    pts = cross_points(b.robot)
    for s, p in pts.items():
        _require_reach("cross_arms", b.robot, s, p, "the other arm")
    return _hold(b, "across", pts, "cross arms", BOTH_ARMS)


CROSS_ARMS = Primitive(name="cross_arms", nominal_duration=_duration, build=build_cross_arms, parts=lambda p: BOTH_ARMS)

OUT_REACH = 0.9  # [L] arms out and pointing: hand this far from the shoulder
HOLD_TORQUE_FRACTION = 0.85  # of each arm joint's torque limit: the most a held-out arm may need against gravity
DROP_STEP = 0.05  # [rad] grid of the angle a held-out arm is lowered by
DROP_MAX = 1.0  # [rad] the lowest it goes


@functools.cache
def _drop(robot: Robot, side: str, u: tuple[float, float, float], reach_fraction: float = OUT_REACH) -> float:
    gravity_v = [robot.model.joints[j].idx_v for j in arm_joints(robot, side)]
    limits = np.asarray(robot.model.effortLimit, dtype=float)[gravity_v]
    data = robot.data()

    def holds(k: int) -> bool:
        point = shoulder(robot, side) + reach_fraction * arm_length(robot, side) * _lowered(u, k * DROP_STEP)
        tau = pin.computeGeneralizedGravity(robot.model, data, arm_configuration(robot, {side: point}))[gravity_v]
        return bool(np.all(np.abs(tau) <= HOLD_TORQUE_FRACTION * limits))

    if holds(0):
        return 0.0
    lo, hi = 0, round(DROP_MAX / DROP_STEP)  # bisection: the gravity torque falls as the arm is lowered
    if not holds(hi):
        return DROP_MAX
    while hi - lo > 1:
        mid = (lo + hi) // 2
        lo, hi = (lo, mid) if holds(mid) else (mid, hi)
    return hi * DROP_STEP


def _lowered(u, angle: float) -> np.ndarray:
    """Horizontal unit vector ``u`` tilted down by ``angle`` [rad]."""
    return math.cos(angle) * np.asarray(u, dtype=float) - math.sin(angle) * Z


def held_out_direction(robot: Robot, side: str, u: np.ndarray) -> np.ndarray:
    """Unit vector (heading frame) along which the ``side`` arm is held out towards horizontal ``u``:
    ``u`` itself when the arm, posed there (:func:`~tasks.primitives.bodymap.arm_configuration`,
    ``OUT_REACH * L`` from the shoulder), needs at most ``HOLD_TORQUE_FRACTION`` of each arm joint's
    torque limit against gravity (Pinocchio), else ``u`` lowered by the smallest multiple of
    ``DROP_STEP`` that does (at most ``DROP_MAX``). Why: held straight out to the side at shoulder
    height, Talos's arm needs 1.07-1.09 x the 22.3 N m limit of its shoulder roll joint
    (``arm_left_2_joint``); the controller saturated it and the hands sagged 5.4 cm below their
    plan in MuJoCo. Talos lowers its arms by 0.55 rad; g1 (20 % of its limit) keeps them level."""
    return _lowered(u, _drop(robot, side, tuple(float(x) for x in u)))


def arms_out_point(robot: Robot, side: str) -> np.ndarray:
    """Hand point of an arm held out to its side (heading frame): ``OUT_REACH * L`` from the shoulder,
    at shoulder height or as little below it as the arm's torque limits allow (:func:`held_out_direction`)."""
    return shoulder(robot, side) + OUT_REACH * arm_length(robot, side) * held_out_direction(robot, side, SIGN[side] * Y)


def build_arms_out(b: FragmentBuilder) -> Fragment:
    """Arm(s) straight out to the side."""
    sides = arms_of(b.params["arm"])
    return _hold(b, "out to the side", {s: arms_out_point(b.robot, s) for s in sides}, "arms out", _arm_parts(sides))


ARMS_OUT = Primitive(name="arms_out", nominal_duration=_duration, build=build_arms_out,
                     parts=lambda p: _arm_parts(arms_of(p["arm"])))


def point_direction(side: str, direction: str) -> np.ndarray:
    """Unit vector (heading frame) along which the ``side`` arm points for ``direction``:
    straight for forward and its own side; up is tilted 0.5 forward (up and ahead: with a straight
    arm up Talos saturates its shoulder torque and misses the target by 9 cm in MuJoCo); down is
    tilted 0.5 forward (clear of the leg);
    across the body (the right arm pointing left) goes diagonally forward, clear of the chest."""
    o = SIGN[side]
    if direction == "forward":
        u = X
    elif direction == "up":
        u = Z + 0.5 * X
    elif direction == "down":
        u = -Z + 0.5 * X
    elif SIGN[direction] == o:
        u = o * Y
    else:
        u = X - o * Y
    return u / np.linalg.norm(u)


POINT_REACHES = (OUT_REACH, 0.8, 0.7)  # [L] a pointing hand's distances from the shoulder, tried in turn ...
POINT_DROP = 0.15  # [rad] ... for the first whose arm, held that far below the named direction, holds


def point_arm(params: dict) -> str:
    """The pointing arm: the one named, else the one on the named side ("point to your left": the
    left arm, straight out; the right arm could only point across the chest), else the right."""
    if params.get("arm"):
        return params["arm"]
    return params["direction"] if params.get("direction") in SIGN else "right"


def point_point(robot: Robot, side: str, direction: str) -> np.ndarray:
    """Hand point (heading frame) of the ``side`` arm pointing towards ``direction``. A horizontal
    direction is held at shoulder height with the hand ``OUT_REACH * L`` from the shoulder, or
    closer (``POINT_REACHES``: the elbow bent) when the straight arm needs more than
    ``HOLD_TORQUE_FRACTION`` of a joint's torque limit, lowered by at most ``POINT_DROP``; if no
    reach holds there, the straight arm lowered as little as it needs (:func:`held_out_direction`).
    Talos's straight arm out to the side needs 1.07 x its shoulder roll limit (it used to be
    lowered 0.55 rad, 32 deg: "point to your left" then pointed at the floor's edge); at 0.8 L
    its elbow bends and it needs 0.93 x, at 0.7 L 0.80 x, level. G1's arm holds level (0.20 x)."""
    u = point_direction(side, direction)
    if abs(u[2]) >= 1e-12:
        return shoulder(robot, side) + OUT_REACH * arm_length(robot, side) * u
    key = tuple(float(x) for x in u)
    for reach_fraction in POINT_REACHES:
        drop = _drop(robot, side, key, reach_fraction)
        if drop <= POINT_DROP + 1e-9:
            return shoulder(robot, side) + reach_fraction * arm_length(robot, side) * _lowered(u, drop)
    return shoulder(robot, side) + OUT_REACH * arm_length(robot, side) * held_out_direction(robot, side, u)


FOLD_POINT = (0.2, 0.15, 0.4)  # [L] ahead, outwards, above the shoulder: the hand on the way up (elbow bent)
FOLD_FRACTION = 0.2  # of the duration: the folded arm on the way up, and (1 - it) on the way down


def fold_point(robot: Robot, side: str) -> np.ndarray:
    """Hand point (heading frame) of the ``side`` arm raised with its elbow bent, on the way to
    pointing up: ``FOLD_POINT`` (ahead, outwards, above) in units of the arm's length from the shoulder."""
    f, o, u = FOLD_POINT
    return shoulder(robot, side) + arm_length(robot, side) * (f * X + SIGN[side] * o * Y + u * Z)


def fold_waypoints(b: FragmentBuilder, sides) -> None:
    """Each ``side`` hand at :func:`fold_point` at ``FOLD_FRACTION`` of the duration (raising) and at
    ``1 - FOLD_FRACTION`` (lowering), HARD within ``GUARD_TOLERANCE``."""
    T = b.params["duration"]
    for side in sides:
        for what, tau in (("on the way up", FOLD_FRACTION * T), ("on the way down", (1.0 - FOLD_FRACTION) * T)):
            _put(b, f"{side} hand folded {what}", side, fold_point(b.robot, side), time=tau, tolerance=GUARD_TOLERANCE)


def build_point(b: FragmentBuilder) -> Fragment:
    """The arm straight along the pointing direction. Pointing up, the arm is raised (and lowered)
    through :func:`fold_point`, the elbow bent: the upper arm then passes the horizontal with the
    forearm folded. A straight arm passing it needs 1.03 x the torque limit of Talos's shoulder
    joint (``arm_right_2_joint``, 22 N m) just to hold it against gravity."""
    side, direction = point_arm(b.params), b.params["direction"]
    if direction == "up":
        fold_waypoints(b, (side,))
    return _hold(b, f"pointing {direction}", {side: point_point(b.robot, side, direction)}, f"point {direction}",
                 _arm_parts((side,)))


POINT = Primitive(name="point", nominal_duration=_duration, build=build_point, parts=lambda p: _arm_parts((point_arm(p),)))


# --- arm_circles ---------------------------------------------------------------------------
CIRCLE_POINTS = 8  # targets per circle
CIRCLE_OUT = 0.75  # [L] circle centre out from the shoulder


def circle_points(robot: Robot, side: str, radius: float, n: int = CIRCLE_POINTS) -> tuple[np.ndarray, list[np.ndarray]]:
    """(centre, points) of one arm circle (heading frame): the centre is ``CIRCLE_OUT * L`` out to
    the side at shoulder height, the circle lies in the plane across the arm (x-z), starting at
    the top and going forward first."""
    c = shoulder(robot, side) + SIGN[side] * CIRCLE_OUT * arm_length(robot, side) * Y
    return c, [c + radius * (math.sin(2 * math.pi * k / n) * X + math.cos(2 * math.pi * k / n) * Z) for k in range(n)]


def check_arm_circles(params: dict, robot: Robot) -> None:
    """The circle must stay within reach."""
    for side in arms_of(params["arm"]):
        _, pts = circle_points(robot, side, params["radius"])
        worst = max(pts, key=lambda p: reach_gap(robot, side, p))
        _require_reach("arm_circles", robot, side, worst, f"a circle of radius {params['radius']:g} m")


def build_arm_circles(b: FragmentBuilder) -> Fragment:
    """Arm(s) out, ``repeat`` circles of ``CIRCLE_POINTS`` targets each, back to rest."""
    check_arm_circles(b.params, b.robot)
    n, d = b.params["repeat"], b.params["duration"]
    sides = arms_of(b.params["arm"])
    for side in sides:
        _, pts = circle_points(b.robot, side, b.params["radius"])
        for c in range(n):
            for k, p in enumerate(pts):
                _put(b, f"{side} hand circle #{c + 1} point {k + 1}", side, p,
                     time=RAISE_TIME + (c + k / CIRCLE_POINTS) * d)
        _put(b, f"{side} hand circle end", side, pts[0], time=RAISE_TIME + n * d)
    T = _rhythm_duration(b.params, b.robot)
    rest_targets(b, [f"{s}_hand" for s in sides], tau=T)
    # leave and come back to rest with the upper arm out: G1's wound in, into the torso's meshes
    hold_upper_arms(b, T, sides, out=UPPER_ARM_OUT, at=(0.0, T))
    b.phase("arm circles", T)
    return b.finish(_arm_parts(sides))


ARM_CIRCLES = Primitive(name="arm_circles", nominal_duration=_rhythm_duration, build=build_arm_circles,
                        parts=lambda p: _arm_parts(arms_of(p["arm"])), check=check_arm_circles)


# --- shrug ---------------------------------------------------------------------------------
SHRUG_LIFT = 0.12  # [L] how far the hands go up at each shrug


def shrug_points(robot: Robot, side: str) -> tuple[np.ndarray, np.ndarray]:
    """(low, high) hand points of the shrug gesture (heading frame): forearms open forward and
    out, hands ``0.6 L`` below the shoulder, lifted by ``SHRUG_LIFT * L``."""
    S, L, o = shoulder(robot, side), arm_length(robot, side), SIGN[side]
    low = S + 0.35 * L * X + 0.3 * o * L * Y - 0.6 * L * Z
    return low, low + SHRUG_LIFT * L * Z


def build_shrug(b: FragmentBuilder) -> Fragment:
    """Both hands open, ``repeat`` lifts, back to rest."""
    n, d = b.params["repeat"], b.params["duration"]
    for side in ("left", "right"):
        low, high = shrug_points(b.robot, side)
        _repeat(b, side, n, d, (f"{side} hand open", low), (f"{side} hand shrug", high), f"{side} hand down")
    rest_targets(b, ["left_hand", "right_hand"], tau=_rhythm_duration(b.params, b.robot))
    b.phase("shrug", _rhythm_duration(b.params, b.robot))
    return b.finish(BOTH_ARMS)


SHRUG = Primitive(name="shrug", nominal_duration=_rhythm_duration, build=build_shrug, parts=lambda p: BOTH_ARMS)


# --- stretch -------------------------------------------------------------------------------
STRETCH_HEIGHT = 0.75  # [L] hands above the shoulders (raise_arms' height: 0.85 L tipped Talos' ZMP out)
STRETCH_FORWARD = 0.25  # [L] and ahead of them (the arms go up through the front)
STRETCH_AXES = {"left": (X, -1.0), "right": (X, 1.0), "backward": (Y, -1.0)}


def stretch_rotation(direction: str, angle: float) -> np.ndarray:
    """Heading-frame rotation (3, 3) of the upper body leaning towards ``direction`` (identity for up)."""
    if direction == "up":
        return np.eye(3)
    axis, sign = STRETCH_AXES[direction]
    return pin.exp3(sign * angle * axis)


def stretch_points(robot: Robot, direction: str, angle: float) -> dict[str, np.ndarray]:
    """Side -> raised hand point (heading frame), turned with the upper body about the hips."""
    R = stretch_rotation(direction, angle)
    pivot = body_map(robot).hip_pivot
    out = {}
    for side in ("left", "right"):
        S, L = shoulder(robot, side), arm_length(robot, side)
        up = S + STRETCH_HEIGHT * L * Z + STRETCH_FORWARD * L * X
        out[side] = pivot + R @ (up - pivot)
    return out


def stretch_parts(params: dict) -> frozenset[str]:
    """Both arms; the torso, legs and CoM too when leaning."""
    return BOTH_ARMS | ({"torso", "legs", "com"} if params["direction"] != "up" else set())


def build_stretch(b: FragmentBuilder) -> Fragment:
    """Both hands overhead; leaning: the torso turned by ``angle``, held, upright again."""
    direction, angle, T = b.params["direction"], b.params["angle"], b.params["duration"]
    if direction != "up":
        if not b.robot.has_role("torso"):
            raise TaskDefinitionError(f"stretch: {b.robot.name} has no torso frame to lean")
        g = b.geometry
        R = g.heading.rotation @ stretch_rotation(direction, angle) @ g.heading.rotation.T
        b.frame_target(f"torso leaning {direction}", "torso", rpy=b.world_rotation(R @ g.rotation("torso")),
                       window=(OUT_FRACTION * T, HOLD_END_FRACTION * T), orientation_tolerance=TORSO_TOLERANCE)
        b.frame_target("torso upright again", "torso", rpy=b.world_rotation(g.rotation("torso")), time=T,
                       orientation_tolerance=TORSO_TOLERANCE)
    fold_waypoints(b, ("left", "right"))  # both arms past the horizontal with the elbows bent, as point up
    return _hold(b, "stretched up", stretch_points(b.robot, direction, angle), f"stretch {direction}", stretch_parts(b.params))


STRETCH = Primitive(name="stretch", nominal_duration=_duration, build=build_stretch, parts=stretch_parts)

PRIMITIVES = (PUNCH, HANDS_ON_HIPS, CROSS_ARMS, ARMS_OUT, POINT, ARM_CIRCLES, SHRUG, STRETCH)

__all__ = [
    "PRIMITIVES",
    "arms_out_point",
    "circle_points",
    "cross_points",
    "hips_points",
    "hold_upper_arms",
    "point_point",
    "punch_points",
    "reach_gap",
    "shoulder",
    "shrug_points",
    "stretch_points",
    "upper_arm_out_angle",
]
