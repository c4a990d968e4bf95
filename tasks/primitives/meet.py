"""Gestures where a hand meets the body: ``clap`` (the other hand), ``touch`` (a body part) and
``salute`` (the forehead).

The targets follow :mod:`tasks.primitives.arms` (HARD hand positions in the heading frame, ``S``,
``L``, ``o`` as there). A hand that *meets* a part (the other hand in a clap, the head in a salute
or a touch) is placed with the arm posed there (:func:`~tasks.primitives.bodymap.arm_configuration`)
so that its meshes are a few millimetres from the part's (coal), held within ``MEET_TOLERANCE`` at
the orientation it was placed with (:func:`meet_rotation`), and the target names the part
(``FrameTarget.meets``): the planner leaves the two parts' link pairs out there. Which links count
as the hand there is the robot's ``[collisions] meet_joints`` (G1's wrist links sit above its hand
frame's joint). Other parts are reached ``bodymap.GAP`` short, clear in the planner's model.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pinocchio as pin

from robots import Robot
from tasks.actions import TOUCH_PARTS
from tasks.exceptions import TaskDefinitionError
from tasks.primitives.arms import (
    BEND_MAX,
    BOTH_ARMS,
    SIGN,
    X,
    Y,
    Z,
    _arm_parts,
    _bent_shoulder,
    _duration,
    _hold,
    _other,
    _repeat,
    _require_reach,
    _rhythm_duration,
    arm_length,
    hip_point,
    hold_upper_arms,
    reach,
    shoulder,
)
from tasks.primitives.base import Fragment, FragmentBuilder, Primitive, rest_targets
from tasks.primitives.bodymap import (
    GAP,
    approach_posed,
    arm_configuration,
    body_map,
    clear_targets,
    hands_meet,
    hands_touch,
    meets_apart,
    stop_short,
)

TEMPLE = 0.5  # a hand meeting the side of the head goes this fraction of the way from its centre to its front
HEAD_GAP = 0.01  # [m] mesh distance of a saluting or head-touching hand from the head, the arm posed there


def meet_rotation(robot: Robot, side: str, point: np.ndarray, meet: str) -> np.ndarray:
    """The ``side`` hand's orientation (standing world frame) with its arm posed at ``point``
    (:func:`~tasks.primitives.bodymap.arm_configuration`; for the other hand, both arms at the clap
    points): the orientation the meeting point was placed with (its meshes ``MEET_GAP`` from the
    other hand's, or ``HEAD_GAP`` from the head's)."""
    points = {side: np.asarray(point, dtype=float)}
    if meet == f"{_other(side)}_hand":
        points = {s: p[0] for s, p in clap_points(robot).items()} | points
    q = arm_configuration(robot, points, natural=True)
    data = robot.data()
    pin.framesForwardKinematics(robot.model, data, q)
    return data.oMf[robot.frame_id(f"{side}_hand")].rotation.copy()



def _hold_meeting(b: FragmentBuilder, what: str, points: dict[str, np.ndarray], phase: str, parts: frozenset[str],
                  meet: dict[str, str] | None) -> Fragment:
    """:func:`tasks.primitives.arms._hold` with the hands in ``meet`` (side -> the role it touches)
    held at the orientation their arms were placed with (:func:`meet_rotation`)."""
    rotations = {s: meet_rotation(b.robot, s, points[s], role) for s, role in (meet or {}).items()}
    if meet:  # the arm that stays down stays out of the torso (G1's salute: its left upper arm was in it)
        hold_upper_arms(b, b.params["duration"], tuple(s for s in ("left", "right") if s not in points))
    return _hold(b, what, points, phase, parts, meet=meet, rotations=rotations)


# --- clap ----------------------------------------------------------------------------------
CLAP_APART = 0.2  # [L] each hand this much farther out when apart


def _hands_clear_points(robot: Robot) -> dict[str, np.ndarray]:
    """Side -> hand point in front of the chest, ``0.3 L`` below the shoulders, where the arms
    posed there clear the body by ``bodymap.CLEARANCE`` in the planner's sphere model (the hands
    go forward until the forearms do) and the two arms' sphere sets are ``CLEARANCE`` apart."""
    m = body_map(robot)
    S = {s: shoulder(robot, s) for s in ("left", "right")}
    L = min(arm_length(robot, s) for s in S)
    front = m.torso.hi[0] if m.torso is not None else 0.5 * (S["left"][0] + S["right"][0])
    x = max(0.5 * (S["left"][0] + S["right"][0]) + 0.5 * L, front + max(m.hand_back(s, X) for s in S) + GAP)
    z = 0.5 * (S["left"][2] + S["right"][2]) - 0.3 * L
    mid = 0.5 * (S["left"][1] + S["right"][1])
    together = {s: np.array([x, mid + SIGN[s] * (m.hand_back(s, SIGN[s] * Y) + 0.5 * GAP), z]) for s in ("left", "right")}
    for _ in range(2):  # forward until the forearms clear the chest, then together; once more
        together = clear_targets(robot, together, {"left": X, "right": X}, other_arm=False)
        x = max(p[0] for p in together.values())  # the hands side by side
        together = {s: np.array([x, p[1], p[2]]) for s, p in together.items()}
        together = dict(zip(("left", "right"), hands_meet(robot, together["left"], together["right"]), strict=True))
    return together


def clap_points(robot: Robot) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Side -> (together, apart) hand points (heading frame). Together: in front of the chest,
    ``0.3 L`` below the shoulders, where the arms clear the body in the planner's sphere model,
    then moved towards each other until, the arms posed there, the hands' meshes are
    ``bodymap.MEET_GAP`` apart (coal): the hands meet. Apart: each hand ``CLAP_APART * L``
    farther out."""
    return {s: (together.copy(), apart.copy()) for s, (together, apart) in _clap_points(robot).items()}


@functools.cache
def _clap_points(robot: Robot) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    L = min(arm_length(robot, s) for s in ("left", "right"))
    clear = _hands_clear_points(robot)
    together = dict(zip(("left", "right"), hands_touch(robot, clear["left"], clear["right"]), strict=True))
    return {s: (together[s], together[s] + SIGN[s] * CLAP_APART * L * Y) for s in ("left", "right")}


def build_clap(b: FragmentBuilder) -> Fragment:
    """Hands apart in front of the chest, ``repeat`` times together and apart, down to rest."""
    n, d = b.params["repeat"], b.params["duration"]
    pts = clap_points(b.robot)
    for side, (together, apart) in pts.items():
        meet = f"{_other(side)}_hand"
        _repeat(b, side, n, d, (f"{side} hand ready to clap", apart), (f"{side} hand clap", together),
                f"{side} hand apart", meet=meet, rotation=meet_rotation(b.robot, side, together, meet))
    hold_upper_arms(b, _rhythm_duration(b.params, b.robot), ("left", "right"))
    rest_targets(b, ["left_hand", "right_hand"], tau=_rhythm_duration(b.params, b.robot))
    b.phase("clap", _rhythm_duration(b.params, b.robot))
    return b.finish(BOTH_ARMS)


CLAP = Primitive(name="clap", nominal_duration=_rhythm_duration, build=build_clap, parts=lambda p: BOTH_ARMS)



# --- touch ---------------------------------------------------------------------------------
BENDING_PARTS = ("knee", "toes")
SHOULDER_INWARD = 0.6  # the other shoulder is touched at this fraction of its distance from the midline


def touch_point(robot: Robot, side: str, part: str) -> np.ndarray:
    """Heading-frame point the ``side`` hand goes to for touching ``part`` (``GAP`` short of it).

    head: beside the head on the hand's side, high enough to clear the top of the torso; shoulder: in front of the *other* shoulder, at
    ``SHOULDER_INWARD`` of its distance from the midline (its inner half); chest:
    in front of the torso, ``0.25 L`` below the shoulders; hip: outside the hip on the hand's side;
    knee: in front of the knee on the hand's side; toes: above the toe tip on the hand's side, as
    low as the arm reaches bending at the hips (moved forward to clear the thigh, at the standing
    posture); hand: the clap position (both hands). Each stops ``GAP`` short of the body's
    meshes (:func:`~tasks.primitives.bodymap.stop_short`).
    """
    m = body_map(robot)
    S, L, o = shoulder(robot, side), arm_length(robot, side), SIGN[side]
    if part == "head":
        head = _need(m.head, robot, "head")
        surface = head.hi[1] if o > 0 else -head.lo[1]
        z = head.center[2] if m.torso is None else max(head.center[2], m.beside(side, m.torso.hi[2], Z))
        start = [head.center[0], o * m.beside(side, surface, o * Y), z]
        if not meets_apart(robot, side, "head"):
            return stop_short(robot, side, start, o * Y, (side,))
        # halfway to the front of the head (the temple): the standing arm reaches it without
        # turning the hand over (beside the head's centre Talos's arm had to flip the gripper)
        start[0] = head.center[0] + TEMPLE * (head.hi[0] - head.center[0])
        return approach_posed(robot, side, start, o * Y, "head", HEAD_GAP)
    if part == "shoulder":
        other = shoulder(robot, _other(side))
        front = m.torso.hi[0] if m.torso is not None else other[0]
        return stop_short(robot, side, [m.beside(side, front, X), SHOULDER_INWARD * other[1], other[2]], X, (side,))
    if part == "chest":
        front = m.torso.hi[0] if m.torso is not None else S[0]
        return stop_short(robot, side, [m.beside(side, front, X), 0.3 * S[1], S[2] - 0.25 * L], X, (side,))
    if part == "hip":
        return hip_point(robot, side, (side,))
    if part == "knee":
        k = m.knee[side]
        return stop_short(robot, side, [m.beside(side, m.knee_front[side], X), k[1], k[2]], X, (side,), clear=False)
    if part == "toes":
        toe = m.toe[side]
        x = toe[0]  # straight above the toe tip
        lowest = _lowest_reachable(robot, side, x, toe[1])
        start = [x, toe[1], max(toe[2] + m.hand_back(side, Z) + GAP, lowest)]
        return stop_short(robot, side, start, X, (side,), clear=False)  # in front of the thigh if it is there
    if part == "hand":
        return clap_points(robot)[side][0]
    raise TaskDefinitionError(f"touch part must be one of {', '.join(TOUCH_PARTS)}, got {part!r}")  # pragma: no cover



def _lowest_reachable(robot: Robot, side: str, x: float, y: float) -> float:
    """Lowest z on the vertical line (x, y) the hand reaches bending up to BEND_MAX [m]."""
    R = reach(robot, side)
    best = math.inf
    for a in np.linspace(0.0, BEND_MAX, 15):
        s = _bent_shoulder(robot, side, a)
        h = math.hypot(x - s[0], y - s[1])
        if h <= R:
            best = min(best, s[2] - math.sqrt(R * R - h * h))
    return best


def _need(box, robot: Robot, what: str):
    if box is None:
        raise TaskDefinitionError(f"touch: {robot.name} has no collision geometry on its {what} frame to touch")
    return box


def check_touch(params: dict, robot: Robot) -> None:
    """The part must be within the hand's reach (bending at the hips for the knee and toes)."""
    side, part = params["hand"], params["part"]
    point = touch_point(robot, side, part)
    if part == "toes" and not math.isfinite(point[2]):
        raise TaskDefinitionError(f"touch: {robot.name}'s {side} hand cannot reach down above its toes")
    sides = ("left", "right") if part == "hand" else (side,)
    for s in sides:
        p = touch_point(robot, s, part)
        what = "the other hand" if part == "hand" else f"its {'other ' if part == 'shoulder' else ''}{part}"
        _require_reach("touch", robot, s, p, what, bend=part in BENDING_PARTS)


def limits_touch(robot: Robot) -> dict[str, str]:
    """Parts out of reach, and how low the toes are reached."""
    notes = []
    for part in TOUCH_PARTS:
        try:
            check_touch({"hand": "right", "part": part}, robot)
        except TaskDefinitionError:
            notes.append(f"{part} out of reach")
    try:
        z = touch_point(robot, "right", "toes")[2]
        notes.append(f"toes: the hand stops {z:.2f} m above the ground")
    except TaskDefinitionError:
        pass
    return {"part": "; ".join(notes) + f" on {robot.name}"} if notes else {}


def touch_parts(params: dict) -> frozenset[str]:
    """The touching arm (both for the other hand; torso, legs and CoM when bending)."""
    parts = BOTH_ARMS if params["part"] == "hand" else _arm_parts((params["hand"],))
    if params["part"] in BENDING_PARTS:
        parts |= {"torso", "legs", "com"}
    return parts


def build_touch(b: FragmentBuilder) -> Fragment:
    """Hand(s) to the touch point, held, back to rest."""
    check_touch(b.params, b.robot)
    side, part = b.params["hand"], b.params["part"]
    sides = ("left", "right") if part == "hand" else (side,)
    what = "at the other hand" if part == "hand" else f"at the {part}"
    return _hold_meeting(b, what, {s: touch_point(b.robot, s, part) for s in sides}, f"touch {part}",
                         touch_parts(b.params), _touch_meets(b.robot, part, sides))


def _touch_meets(robot: Robot, part: str, sides: tuple[str, ...]) -> dict[str, str] | None:
    """The roles the touching hands meet: the other hand, or the head (the planner leaves those
    pairs out there); other parts are reached ``GAP`` short, clear in the planner's model."""
    if part == "hand":
        return {s: f"{_other(s)}_hand" for s in sides}
    if part == "head":
        return {s: "head" for s in sides if meets_apart(robot, s, "head")} or None
    return None


TOUCH = Primitive(name="touch", nominal_duration=_duration, build=build_touch, parts=touch_parts,
                  check=check_touch, limits=limits_touch)



def salute_point(robot: Robot, side: str) -> np.ndarray:
    """Hand point of a salute (heading frame): ``GAP`` in front of the forehead on the hand's side,
    a quarter of the head's height above its centre."""
    m = body_map(robot)
    head = m.head
    if head is None:
        raise TaskDefinitionError(f"salute: {robot.name} has no collision geometry on its head frame")
    o = SIGN[side]
    y = o * 0.5 * (head.hi[1] if o > 0 else -head.lo[1])
    start = [m.beside(side, head.hi[0], X), head.center[1] + y, head.center[2] + 0.25 * (head.hi[2] - head.lo[2])]
    if not meets_apart(robot, side, "head"):  # G1: the head is on the torso, kept GAP short in the sphere model
        return stop_short(robot, side, start, X, (side,))
    return approach_posed(robot, side, start, X, "head", HEAD_GAP)


def check_salute(params: dict, robot: Robot) -> None:
    """The forehead must be within the arm's reach."""
    _require_reach("salute", robot, params["arm"], salute_point(robot, params["arm"]), "its forehead")


def build_salute(b: FragmentBuilder) -> Fragment:
    """The hand at the forehead, held."""
    check_salute(b.params, b.robot)
    side = b.params["arm"]
    return _hold_meeting(b, "at the forehead", {side: salute_point(b.robot, side)}, "salute", _arm_parts((side,)),
                         {side: "head"} if meets_apart(b.robot, side, "head") else None)


SALUTE = Primitive(name="salute", nominal_duration=_duration, build=build_salute,
                   parts=lambda p: _arm_parts((p["arm"],)), check=check_salute)


PRIMITIVES = (CLAP, TOUCH, SALUTE)

__all__ = ["PRIMITIVES", "clap_points", "meet_rotation", "salute_point", "touch_point"]
