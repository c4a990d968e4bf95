"""Task specifications: what the robot should do, as data.

A :class:`TaskSpec` is a sequence of timed :class:`Phase`\\ s. Each phase holds the set of
:class:`Contact`\\ s (a foot frame fixed at a ground placement) that are active during it.
Over the whole horizon, :class:`FrameTarget`\\ s ask a frame (a hand, the head, the torso)
to reach a position and/or orientation at a time or over a time window,
:class:`CoMTarget`\\ s ask the centre of mass for a position, :class:`CoMBounds` keep it in a
box and/or over the support polygon, and :class:`JointTarget`\\ s ask a joint for an angle.

Conventions: SI units (m, s, rad, N), the world frame is z-up with the ground at z = 0,
orientations are roll-pitch-yaw ``(r, p, y)`` with ``R = Rz(y) Ry(p) Rx(r)`` (Pinocchio's
``rpy`` convention), frames are named by Pinocchio frame name or by robot role
(``left_foot``, ``right_hand``, ``head``, ``torso``, ``base``; see ``robots.ROLES``).
Every spec is frozen, validated on construction, and round-trips exactly through JSON
(:func:`tasks.serialize.spec_to_dict` / :func:`tasks.serialize.spec_from_dict`).
"""

from __future__ import annotations

import enum
import math
from collections import Counter
from dataclasses import dataclass, field

from tasks.exceptions import TaskDefinitionError
from tasks.limits import (
    MAX_ANGLE,
    MAX_CONTACTS,
    MAX_DISTANCE,
    MAX_DT,
    MAX_FRICTION,
    MAX_HORIZON,
    MAX_ITEMS,
    MAX_KNOTS,
    MAX_NAME_LENGTH,
    MAX_PHASES,
    MAX_TERMS,
    MAX_TEXT_LENGTH,
    MAX_WEIGHT,
    MIN_DT,
    MIN_HORIZON,
    horizon_message,
)
from tasks.scene import Scene

Vec3 = tuple[float, float, float]
MAX_REGION_POINTS = 16  # a contact's support region corners
MAX_REGION_EXTENT = 2.0  # [m] a region corner from its contact frame
OptVec3 = tuple[float | None, float | None, float | None]
Window = tuple[float, float]

SPEC_VERSION = 1


class Priority(enum.Enum):
    """How a target enters the optimization problem."""

    HARD = "hard"  # constraint: |error| <= tolerance
    SOFT = "soft"  # weighted least-squares cost


def _show(value) -> str:
    """A short repr for error messages (a 5,000-digit number or a long string stays short)."""
    text = repr(value)
    return text if len(text) <= 60 else f"{text[:40]}... ({len(text)} characters)"


def _num(value) -> str:
    """A number for messages: ``1e+09``, ``0.3``; a huge integer stays short."""
    return f"{value:g}" if isinstance(value, float) else _show(value)


def _is_number(v) -> bool:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return False
    return isinstance(v, int) or math.isfinite(v)  # an int is finite; float(10**400) would overflow


def _number(owner: str, field_name: str, value, *, lo: float, hi: float, unit: str = "") -> None:
    """``value`` is a finite number in [lo, hi] (TaskDefinitionError naming the field otherwise)."""
    u = f" {unit}" if unit else ""
    if not _is_number(value):
        raise TaskDefinitionError(f"{owner}: {field_name} must be a finite number{u}, got {_show(value)}")
    if not lo <= value <= hi:
        raise TaskDefinitionError(f"{owner}: {field_name} must be in [{lo:g}, {hi:g}]{u}, got {_show(value)}")


def _finite(owner: str, field_name: str, values, *, bound: float, unit: str) -> None:
    for v in values:
        if v is not None and not (_is_number(v) and -bound <= v <= bound):
            raise TaskDefinitionError(
                f"{owner}: {field_name} must hold finite numbers in [{-bound:g}, {bound:g}] {unit}, got {_show(values)}"
            )


def _vec3(owner: str, field_name: str, value, *, optional_items: bool = False, bound: float = MAX_DISTANCE,
          unit: str = "m") -> None:
    if not isinstance(value, tuple) or len(value) != 3:
        raise TaskDefinitionError(f"{owner}: {field_name} must be a 3-tuple, got {_show(value)}")
    if not optional_items and any(v is None for v in value):
        raise TaskDefinitionError(f"{owner}: {field_name} must not contain null")
    _finite(owner, field_name, value, bound=bound, unit=unit)


def _window(owner: str, window: Window | None) -> None:
    if window is None:
        return
    if not isinstance(window, tuple) or len(window) != 2:
        raise TaskDefinitionError(f"{owner}: window must be (t_start, t_end) [s], got {_show(window)}")
    _finite(owner, "window", window, bound=MAX_HORIZON, unit="s")
    if not 0.0 <= window[0] <= window[1]:
        raise TaskDefinitionError(f"{owner}: window must satisfy 0 <= t_start <= t_end, got {_show(window)}")


def _nonneg(owner: str, field_name: str, value: float, *, hi: float = MAX_DISTANCE, unit: str = "m") -> None:
    _number(owner, field_name, value, lo=0.0, hi=hi, unit=unit)


def _text(owner: str, field_name: str, value, *, limit: int = MAX_NAME_LENGTH) -> None:
    if not isinstance(value, str):
        raise TaskDefinitionError(f"{owner}: {field_name} must be a string, got {_show(value)}")
    if len(value) > limit:
        raise TaskDefinitionError(f"{owner}: {field_name} has {len(value)} characters; at most {limit}")


def _name(owner: str, field_name: str, value) -> None:
    """A non-empty name (an object's, a frame's) within the text limit."""
    if not isinstance(value, str) or not value:
        raise TaskDefinitionError(f"{owner}: {field_name} must be a non-empty name, got {_show(value)}")
    _text(owner, field_name, value)


@dataclass(frozen=True, slots=True, kw_only=True)
class Pose:
    """A placement in the world: position [m] and roll-pitch-yaw [rad]."""

    position: Vec3
    rpy: Vec3 = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        _vec3("pose", "position", self.position)
        _vec3("pose", "rpy", self.rpy, bound=MAX_ANGLE, unit="rad")


@dataclass(frozen=True, slots=True, kw_only=True)
class Contact:
    """A foot (or other body) held fixed in 6D at a ground placement during a phase (a body part a
    few joints from another contact, a thigh on a seat above its sole: in position, the planner's
    ``contact_position`` rows).

    Attributes:
        frame: Frame name or role (``left_foot``); its z axis is the contact normal.
        placement: Where the frame is held [m, rad].
        friction_coefficient: Coulomb friction [-]; None takes the robot profile's.
        region: The support region of a contact on another body part than a sole (a thigh on a
            seat, a hand on a table): its corner points in the contact frame [m], at least 3
            (the force points of the dynamic formulation, part of the support polygon); None (left
            out of the JSON): the profile's sole rectangle for a foot, the frame origin otherwise.
        normal: The surface's upward unit normal in the world (None, left out of the JSON: the
            placement's z axis); the friction cone opens about it.
    """

    frame: str
    placement: Pose
    friction_coefficient: float | None = None
    region: tuple[Vec3, ...] | None = field(default=None, metadata={"omit_none": True})
    normal: Vec3 | None = field(default=None, metadata={"omit_none": True})

    def __post_init__(self) -> None:
        if not isinstance(self.frame, str) or not self.frame:
            raise TaskDefinitionError("contact: frame must be a non-empty frame name or role")
        _text("contact", "frame", self.frame)
        if not isinstance(self.placement, Pose):
            raise TaskDefinitionError(f"contact {self.frame}: placement must be a Pose, got {_show(self.placement)}")
        if self.friction_coefficient is not None:
            _number(f"contact {self.frame}", "friction_coefficient", self.friction_coefficient, lo=0.0,
                    hi=MAX_FRICTION)
            if not self.friction_coefficient > 0.0:
                raise TaskDefinitionError(f"contact {self.frame}: friction_coefficient must be > 0")
        if self.region is not None:
            if not isinstance(self.region, tuple) or not 3 <= len(self.region) <= MAX_REGION_POINTS:
                raise TaskDefinitionError(f"contact {self.frame}: region must be 3 to {MAX_REGION_POINTS} points "
                                          f"[x, y, z] in the contact frame [m], got {_show(self.region)}")
            for i, point in enumerate(self.region):
                _vec3(f"contact {self.frame}", f"region[{i}]", point, bound=MAX_REGION_EXTENT)
        if self.normal is not None:
            _vec3(f"contact {self.frame}", "normal", self.normal, bound=1.0 + 1e-6, unit="")
            if abs(math.hypot(*self.normal) - 1.0) > 1e-6:
                raise TaskDefinitionError(f"contact {self.frame}: normal must be a unit vector, got {_show(self.normal)}")


@dataclass(frozen=True, slots=True, kw_only=True)
class Phase:
    """A time interval with a fixed contact set.

    Attributes:
        name: Label used in reports ("stand", "squat down", "flight").
        duration: Length of the phase [s].
        contacts: Contacts held during the whole phase; empty means flight.
        swing_height: Clearance of a swinging foot: a foot frame that is in contact in some
            phase but not in this one must have its sole this high at the phase's middle [m].
    """

    name: str
    duration: float
    contacts: tuple[Contact, ...] = ()
    swing_height: float = 0.05

    def __post_init__(self) -> None:
        _text("phase", "name", self.name)
        if not (_is_number(self.duration) and self.duration > 0):
            raise TaskDefinitionError(f"phase {self.name!r}: duration must be > 0 s, got {_show(self.duration)}")
        if self.duration > MAX_HORIZON:
            raise TaskDefinitionError(
                f"phase {self.name!r}: duration {_num(self.duration)} s is longer than wbmp plans at a time "
                f"(at most {MAX_HORIZON:g} s; longer motions take minutes and gigabytes to plan): split it "
                "into several specs"
            )
        frames = [c.frame for c in self.contacts]
        if len(set(frames)) != len(frames):
            raise TaskDefinitionError(f"phase {self.name!r}: a frame appears in two contacts: {frames}")
        _nonneg(f"phase {self.name!r}", "swing_height", self.swing_height)


@dataclass(frozen=True, slots=True, kw_only=True)
class FrameTarget:
    """Ask a frame for a position and/or orientation at a time or over a window.

    Attributes:
        name: Unique label, used in reports ("right hand up #1").
        frame: Frame name or role (``right_hand``).
        position: Target position in the world [m]; None = no position target.
        rpy: Target orientation in the world [rad]; None = no orientation target.
        axes: Which position axes count, e.g. ``(False, False, True)`` for height only.
        time: Instant of the target [s]; with ``window`` None and ``time`` None: end of horizon.
        window: (t_start, t_end) [s]: the target holds on every knot inside.
        tolerance: Allowed position error for HARD targets and in reports [m].
        orientation_tolerance: Allowed orientation error [rad].
        priority: HARD (constraint) or SOFT (cost).
        weight: Cost weight for SOFT targets [1/m^2].
        touch: Name of the scene object the frame touches there (a planned contact: the scene
            collision checks leave that frame's link and its children out with that object over
            the target's time or window); None: no contact.
        meets: Frame name or role of another robot frame this one touches there (a self-contact:
            a clap's hands). The self-collision rows and checks leave out the link pairs between
            the two frames' joints and the joints below them over the target's time or window (and a
            few knots around it, ``planner.trajopt.collision.MEET_PADDING``); the target's own tolerance is then what keeps
            the two apart. None: no self-contact. Left out of the JSON when None.
    """

    name: str
    frame: str
    position: Vec3 | None = None
    rpy: Vec3 | None = None
    axes: tuple[bool, bool, bool] = (True, True, True)
    time: float | None = None
    window: Window | None = None
    tolerance: float = 0.01
    orientation_tolerance: float = 0.05
    priority: Priority = Priority.HARD
    weight: float = 100.0
    touch: str | None = None
    meets: str | None = field(default=None, metadata={"omit_none": True})

    def __post_init__(self) -> None:
        _text("target", "name", self.name)
        who = f"target {self.name!r}"
        if not isinstance(self.frame, str) or not self.frame:
            raise TaskDefinitionError(f"{who}: frame must be a frame name or role")
        _text(who, "frame", self.frame)
        if self.position is None and self.rpy is None:
            raise TaskDefinitionError(f"{who}: give a position, an rpy orientation, or both")
        if self.position is not None:
            _vec3(who, "position", self.position)
        if self.rpy is not None:
            _vec3(who, "rpy", self.rpy, bound=MAX_ANGLE, unit="rad")
        if (not isinstance(self.axes, tuple) or len(self.axes) != 3 or not all(isinstance(a, bool) for a in self.axes)
                or not any(self.axes)):
            raise TaskDefinitionError(f"{who}: axes must be three booleans, at least one true")
        if self.time is not None and self.window is not None:
            raise TaskDefinitionError(f"{who}: give time or window, not both")
        if self.time is not None:
            _nonneg(who, "time", self.time, hi=MAX_HORIZON, unit="s")
        _window(who, self.window)
        _nonneg(who, "tolerance", self.tolerance)
        _nonneg(who, "orientation_tolerance", self.orientation_tolerance, hi=MAX_ANGLE, unit="rad")
        _nonneg(who, "weight", self.weight, hi=MAX_WEIGHT, unit="")
        if not isinstance(self.priority, Priority):
            raise TaskDefinitionError(f"{who}: priority must be 'hard' or 'soft'")
        if self.touch is not None:
            _text(who, "touch", self.touch)
            if self.position is None:
                raise TaskDefinitionError(f"{who}: a touch needs a position (the point on the object)")
        if self.meets is not None:
            _text(who, "meets", self.meets)
            if self.position is None:
                raise TaskDefinitionError(f"{who}: meets needs a position (where the frame meets the other one)")
            if self.meets == self.frame:
                raise TaskDefinitionError(f"{who}: meets names the target's own frame {self.frame!r}: name the other frame")


HandTarget = FrameTarget  # the name the design documents use for hand targets


@dataclass(frozen=True, slots=True, kw_only=True)
class CoMTarget:
    """Ask the centre of mass for a position (per axis; None = free) at a time or window.

    Attributes:
        name: Unique label ("squat bottom #2").
        position: Target CoM position in the world [m]; None entries are free.
        time, window, tolerance, priority, weight: as in :class:`FrameTarget`.
    """

    name: str
    position: OptVec3
    time: float | None = None
    window: Window | None = None
    tolerance: float = 0.01
    priority: Priority = Priority.HARD
    weight: float = 100.0

    def __post_init__(self) -> None:
        _text("CoM target", "name", self.name)
        who = f"CoM target {self.name!r}"
        _vec3(who, "position", self.position, optional_items=True)
        if all(v is None for v in self.position):
            raise TaskDefinitionError(f"{who}: at least one position axis must be set")
        if self.time is not None and self.window is not None:
            raise TaskDefinitionError(f"{who}: give time or window, not both")
        if self.time is not None:
            _nonneg(who, "time", self.time, hi=MAX_HORIZON, unit="s")
        _window(who, self.window)
        _nonneg(who, "tolerance", self.tolerance)
        _nonneg(who, "weight", self.weight, hi=MAX_WEIGHT, unit="")
        if not isinstance(self.priority, Priority):
            raise TaskDefinitionError(f"{who}: priority must be 'hard' or 'soft'")


@dataclass(frozen=True, slots=True, kw_only=True)
class CoMBounds:
    """Keep the centre of mass inside a box and/or over the support polygon.

    Attributes:
        name: Label ("balance").
        lower: Box lower corner in the world [m]; None entries are unbounded.
        upper: Box upper corner in the world [m]; None entries are unbounded.
        support_polygon: Keep the CoM ground projection inside the convex hull of the active
            soles, shrunk by ``margin`` (only in phases with contacts).
        margin: Inward margin of the support polygon [m].
        window: (t_start, t_end) [s]; None = the whole horizon.
    """

    name: str = "balance"
    lower: OptVec3 = (None, None, None)
    upper: OptVec3 = (None, None, None)
    support_polygon: bool = True
    margin: float = 0.02
    window: Window | None = None

    def __post_init__(self) -> None:
        _text("CoM bounds", "name", self.name)
        who = f"CoM bounds {self.name!r}"
        _vec3(who, "lower", self.lower, optional_items=True)
        _vec3(who, "upper", self.upper, optional_items=True)
        for lo, hi in zip(self.lower, self.upper, strict=True):
            if lo is not None and hi is not None and lo > hi:
                raise TaskDefinitionError(f"{who}: lower {self.lower} exceeds upper {self.upper}")
        if not isinstance(self.support_polygon, bool):
            raise TaskDefinitionError(f"{who}: support_polygon must be true or false, got {_show(self.support_polygon)}")
        _nonneg(who, "margin", self.margin)
        _window(who, self.window)


@dataclass(frozen=True, slots=True, kw_only=True)
class JointTarget:
    """Ask one joint for an angle [rad] (or position [m]) at a time or window, as a cost."""

    name: str
    joint: str
    value: float
    time: float | None = None
    window: Window | None = None
    weight: float = 10.0

    def __post_init__(self) -> None:
        _text("joint target", "name", self.name)
        who = f"joint target {self.name!r}"
        if not isinstance(self.joint, str) or not self.joint:
            raise TaskDefinitionError(f"{who}: joint must be a joint name, got {_show(self.joint)}")
        _text(who, "joint", self.joint)
        _number(who, "value", self.value, lo=-MAX_ANGLE, hi=MAX_ANGLE, unit="rad")
        if self.time is not None and self.window is not None:
            raise TaskDefinitionError(f"{who}: give time or window, not both")
        if self.time is not None:
            _nonneg(who, "time", self.time, hi=MAX_HORIZON, unit="s")
        _window(who, self.window)
        _nonneg(who, "weight", self.weight, hi=MAX_WEIGHT, unit="")


@dataclass(frozen=True, slots=True, kw_only=True)
class Grasp:
    """A hand holding a scene object: from ``start`` the object moves with the hand, until ``end``.

    The object's centre sits at ``offset`` in the hand frame while it is held (docs/objects.md):
    the planner exempts the pair (the hand's links, the object) from its scene-collision rows, the
    payload check loads the arm with the object's weight there, and the simulation attaches the
    object to the hand once the hand holds it within ``tolerance`` (a weld: the named
    simplification of a gripper that closes).

    Attributes:
        name: Unique label ("1 pick_up: grasp the cup").
        object: The scene object's name.
        frame: The holding frame (a hand: ``gripper_right_base_link``).
        offset: The object's centre in the hand frame while held [m].
        start: When the hand closes on the object [s].
        end: When the hand lets it go [s]; None = held to the end of the motion.
        lift: How high the object is asked to rise above where it stood [m] (0: not asked).
        hold: (t_start, t_end) [s] over which the object is held lifted by ``lift``; None = none.
        place: Where the object's centre is put when it is let go [m]; None = not put down.
        tolerance: The hand holds the object when its centre is within this of ``offset`` [m].
        offer: Where the object's centre is held out to a person (hand_over) [m]; None = not handed over.
        offer_window: (t_start, t_end) [s] over which it is held there; None = none.
    """

    name: str
    object: str
    frame: str
    offset: Vec3
    start: float
    end: float | None = None
    lift: float = 0.0
    hold: Window | None = None
    place: Vec3 | None = None
    tolerance: float = 0.03
    offer: Vec3 | None = None
    offer_window: Window | None = None

    def __post_init__(self) -> None:
        _text("grasp", "name", self.name)
        who = f"grasp {self.name!r}"
        for key in ("object", "frame"):
            _name(who, key, getattr(self, key))
        _vec3(who, "offset", self.offset)
        _nonneg(who, "start", self.start, hi=MAX_HORIZON, unit="s")
        if self.end is not None:
            _nonneg(who, "end", self.end, hi=MAX_HORIZON, unit="s")
            if self.end <= self.start:
                raise TaskDefinitionError(f"{who}: end {_num(self.end)} s must be after start {_num(self.start)} s")
        _nonneg(who, "lift", self.lift)
        _window(who, self.hold)
        if self.place is not None:
            _vec3(who, "place", self.place)
        _nonneg(who, "tolerance", self.tolerance)
        if not self.tolerance > 0.0:
            raise TaskDefinitionError(f"{who}: tolerance must be > 0 m")
        if self.offer is not None:
            _vec3(who, "offer", self.offer)
        _window(who, self.offer_window)
        if (self.offer is None) != (self.offer_window is None):
            raise TaskDefinitionError(f"{who}: offer and offer_window go together (a point and when it is held there)")


@dataclass(frozen=True, slots=True, kw_only=True)
class Push:
    """A hand pushing a movable scene object: between ``start`` and ``end`` the hand moves it by
    ``distance`` along ``direction`` (it slides with its friction; docs/objects.md).

    The planner does not move the object (its hand targets on the face name it:
    ``FrameTarget.touch``); the simulation's certificate checks how far it moved.

    Attributes:
        name: Unique label ("1 push: right hand pushes the red box").
        object: The scene object's name (movable).
        frame: The pushing frame (a hand's frame name).
        direction: The push direction, a horizontal unit vector (world).
        distance: How far the object is to move along it [m].
        start: When the hand touches the object [s].
        end: When the push ends [s].
    """

    name: str
    object: str
    frame: str
    direction: Vec3
    distance: float
    start: float
    end: float

    def __post_init__(self) -> None:
        _text("push", "name", self.name)
        who = f"push {self.name!r}"
        for key in ("object", "frame"):
            _name(who, key, getattr(self, key))
        _vec3(who, "direction", self.direction)
        if abs(math.hypot(*self.direction) - 1.0) > 1e-6 or abs(self.direction[2]) > 1e-6:
            raise TaskDefinitionError(f"{who}: direction must be a horizontal unit vector, got {_show(self.direction)}")
        _nonneg(who, "distance", self.distance)
        _nonneg(who, "start", self.start, hi=MAX_HORIZON, unit="s")
        _nonneg(who, "end", self.end, hi=MAX_HORIZON, unit="s")
        if self.end <= self.start:
            raise TaskDefinitionError(f"{who}: end {_num(self.end)} s must be after start {_num(self.start)} s")


MAX_START_SIZE = 200  # numbers of a start configuration (nq: talos 39, the largest robot under 100)
START_QUATERNION_TOLERANCE = 1e-6  # |norm - 1| of the start's base quaternion


@dataclass(frozen=True, slots=True, kw_only=True)
class StartState:
    """Where a motion starts, at rest: the configuration of its first knot (``wbmp serve``'s
    "then <sentence>" starts where the last motion ended). None in a spec: the robot's
    standing posture with its feet centred on x = y = 0.

    Attributes:
        q: The configuration in Pinocchio's order (nq): base position [m], base orientation as
            a unit quaternion (x, y, z, w), then the joint angles [rad] in the model's order.
            The velocity is zero: a motion starts at rest.
    """

    q: tuple[float, ...]

    def __post_init__(self) -> None:
        if not isinstance(self.q, tuple) or not 8 <= len(self.q) <= MAX_START_SIZE:
            raise TaskDefinitionError(f"start: q must list 8 to {MAX_START_SIZE} numbers (the base position, its "
                                      f"quaternion x y z w, the joint angles), got {_show(self.q)}")
        _finite("start", "q", self.q, bound=MAX_DISTANCE, unit="(m, -, rad)")
        norm = math.sqrt(sum(float(x) ** 2 for x in self.q[3:7]))
        if abs(norm - 1.0) > START_QUATERNION_TOLERANCE:
            raise TaskDefinitionError(f"start: q[3:7] is the base orientation as a unit quaternion (x, y, z, w); its "
                                      f"norm is {norm:.6g}: normalize it")


@dataclass(frozen=True, slots=True, kw_only=True)
class TaskSpec:
    """A whole-body motion request, independent of any solver.

    Attributes:
        robot: Robot name (``talos``) or profile path.
        phases: Consecutive phases; the horizon is the sum of their durations.
        targets: Frame targets (hands, head, torso...).
        com_targets: Centre-of-mass targets.
        com_bounds: Centre-of-mass bounds.
        joint_targets: Joint angle targets (costs).
        dt: Knot spacing of the transcription [s] (rounded per phase to whole knots).
        dynamic: Model CoM dynamics with contact forces (needed for jumps and fast steps).
        posture_weight: Cost weight pulling towards the standing posture [-].
        smoothness_weight: Cost weight on accelerations [-].
        name: A label for reports.
        description: Free text (the sentence it came from).
        scene: The world around the robot (a floor plus named objects; docs/scenes.md); null = the floor only.
        grasps: Objects of the scene held by a hand over a time window (docs/objects.md).
        pushes: Objects of the scene a hand pushes over a time window (docs/objects.md).
        start: Where the motion starts, at rest (null: standing with the feet centred on x = y = 0);
            the first phase's contacts must be where the feet are in it.
    """

    robot: str = "talos"
    phases: tuple[Phase, ...]
    targets: tuple[FrameTarget, ...] = ()
    com_targets: tuple[CoMTarget, ...] = ()
    com_bounds: tuple[CoMBounds, ...] = (CoMBounds(),)
    joint_targets: tuple[JointTarget, ...] = ()
    dt: float = 0.075
    dynamic: bool = False
    posture_weight: float = 1e-2
    smoothness_weight: float = 1e-3
    name: str = ""
    description: str = ""
    scene: Scene | None = None
    grasps: tuple[Grasp, ...] = ()
    pushes: tuple[Push, ...] = ()
    start: StartState | None = None

    def __post_init__(self) -> None:
        _text("task spec", "robot", self.robot, limit=MAX_TEXT_LENGTH)
        if self.start is not None and not isinstance(self.start, StartState):
            raise TaskDefinitionError(f"task spec: start must be a StartState or None, got {_show(self.start)}")
        if self.scene is not None and not isinstance(self.scene, Scene):
            raise TaskDefinitionError(f"task spec: scene must be a Scene or None, got {_show(self.scene)}")
        _text("task spec", "name", self.name, limit=MAX_TEXT_LENGTH)
        _text("task spec", "description", self.description, limit=MAX_TEXT_LENGTH)
        if not self.phases:
            raise TaskDefinitionError("task spec: at least one phase is needed")
        if len(self.phases) > MAX_PHASES:
            raise TaskDefinitionError(
                f"task spec: {len(self.phases)} phases; wbmp plans at most {MAX_PHASES} phases at a time: "
                "split it into several specs"
            )
        _number("task spec", "dt", self.dt, lo=MIN_DT, hi=MAX_DT, unit="s")
        if not isinstance(self.dynamic, bool):
            raise TaskDefinitionError(f"task spec: dynamic must be true or false, got {_show(self.dynamic)}")
        _nonneg("task spec", "posture_weight", self.posture_weight, hi=MAX_WEIGHT, unit="")
        _nonneg("task spec", "smoothness_weight", self.smoothness_weight, hi=MAX_WEIGHT, unit="")
        horizon = self.horizon
        if horizon > MAX_HORIZON + 1e-9:
            raise TaskDefinitionError(f"task spec: {horizon_message(horizon, 'split it into several specs')}")
        if horizon < MIN_HORIZON - 1e-12:
            raise TaskDefinitionError(
                f"task spec: the motion lasts {horizon:g} s; it must last at least {MIN_HORIZON:g} s (the planner "
                f"needs 4 knot intervals of at least {MIN_DT:g} s)"
            )
        intervals = max(1, round(horizon / self.dt))
        if intervals > MAX_KNOTS:
            raise TaskDefinitionError(
                f"task spec: {horizon:g} s on a dt = {self.dt:g} s grid is {intervals} knot intervals; wbmp plans "
                f"at most {MAX_KNOTS} at a time ({MAX_KNOTS * 0.075:g} s at dt = 0.075 s): raise dt or shorten the motion"
            )
        for phase in self.phases:
            if len(phase.contacts) > MAX_CONTACTS:
                raise TaskDefinitionError(
                    f"phase {phase.name!r}: {len(phase.contacts)} contacts; a phase holds at most {MAX_CONTACTS}"
                )
        items: tuple[FrameTarget | CoMTarget | CoMBounds | JointTarget, ...] = (
            *self.targets, *self.com_targets, *self.com_bounds, *self.joint_targets)
        if len(items) > MAX_ITEMS:
            raise TaskDefinitionError(
                f"task spec: {len(items)} targets and bounds; wbmp plans at most {MAX_ITEMS} at a time: "
                "split it into several specs"
            )
        for ft in self.targets:
            if ft.touch is not None and (self.scene is None or ft.touch not in {o.name for o in self.scene.objects}):
                raise TaskDefinitionError(f"target {ft.name!r}: touch names {ft.touch!r}, which is no object of the "
                                          "spec's scene (give the scene, or name one of its objects)")
        counts = Counter(t.name for t in items)
        dup = sorted(n for n, c in counts.items() if c > 1)
        if dup:
            raise TaskDefinitionError(f"task spec: names must be unique, repeated: {dup[:10]}")
        self._check_grasps(horizon)
        self._check_pushes(horizon)
        grid = horizon / intervals
        terms = 0
        in_order: tuple[FrameTarget | CoMTarget | CoMBounds | JointTarget, ...] = (
            *self.targets, *self.com_targets, *self.joint_targets, *self.com_bounds)
        for item in in_order:
            t = getattr(item, "time", None)
            w = item.window
            latest = max([x for x in (t, *(w or ())) if x is not None], default=0.0)
            if latest > horizon + 1e-9:
                raise TaskDefinitionError(
                    f"{type(item).__name__} {item.name!r}: time {latest:g} s is after the end of the "
                    f"motion ({horizon:g} s)"
                )
            if w is not None:
                terms += int((w[1] - w[0]) / grid) + 1
            elif isinstance(item, CoMBounds):
                terms += intervals + 1
            else:
                terms += 1
        if terms > MAX_TERMS:
            raise TaskDefinitionError(
                f"task spec: its targets and bounds apply at {terms} knots in all (a window counts each knot "
                f"inside it); wbmp plans at most {MAX_TERMS}: use fewer or shorter windows, or split the spec"
            )

    def _check_grasps(self, horizon: float) -> None:
        """Each grasp names an object of the scene, within the horizon; a hand holds one at a time, and an
        object is held by one hand at a time, or by two together (same start and end: a box between them)."""
        if not self.grasps:
            return
        names = {o.name: o for o in self.scene.objects} if self.scene is not None else {}
        for g in self.grasps:
            if not isinstance(g, Grasp):
                raise TaskDefinitionError(f"task spec: grasps must hold Grasp items, got {_show(g)}")
            if g.object not in names:
                known = ", ".join(sorted(names)) or "none (the spec has no scene)"
                raise TaskDefinitionError(f"grasp {g.name!r}: no object {g.object!r} in the scene; its objects: {known}")
            if not names[g.object].movable:
                raise TaskDefinitionError(f"grasp {g.name!r}: the {g.object} is fixed to the world (movable: false); "
                                          "only a movable object can be picked up")
            latest = max(x for x in (g.start, g.end, *(g.hold or ()), *(g.offer_window or ())) if x is not None)
            if latest > horizon + 1e-9:
                raise TaskDefinitionError(f"grasp {g.name!r}: time {latest:g} s is after the end of the motion ({horizon:g} s)")
        spans = sorted(((g.start, horizon if g.end is None else g.end, g) for g in self.grasps), key=lambda x: x[:2])
        for i, (_s0, e0, g0) in enumerate(spans):
            for s1, _e1, g1 in spans[i + 1:]:
                two_hands = g1.object == g0.object and g1.frame != g0.frame and abs(s1 - g0.start) < 1e-9 \
                    and g1.end == g0.end  # both hands hold it together
                if s1 < e0 - 1e-9 and (g1.frame == g0.frame or g1.object == g0.object) and not two_hands:
                    raise TaskDefinitionError(f"grasps {g0.name!r} and {g1.name!r} overlap in time on the same hand "
                                              "or object; let go first")

    def _check_pushes(self, horizon: float) -> None:
        """Each push names a movable object of the scene, within the horizon."""
        names = {o.name: o for o in self.scene.objects} if self.scene is not None else {}
        for p in self.pushes:
            if not isinstance(p, Push):
                raise TaskDefinitionError(f"task spec: pushes must hold Push items, got {_show(p)}")
            if p.object not in names or not names[p.object].movable:
                raise TaskDefinitionError(f"push {p.name!r}: no movable object {p.object!r} in the scene")
            if p.end > horizon + 1e-9:
                raise TaskDefinitionError(f"push {p.name!r}: time {p.end:g} s is after the end of the motion ({horizon:g} s)")

    @property
    def horizon(self) -> float:
        """Total duration [s]."""
        return float(sum(p.duration for p in self.phases))

    def phase_start_times(self) -> tuple[float, ...]:
        """Start time of each phase [s]."""
        out, t = [], 0.0
        for p in self.phases:
            out.append(t)
            t += p.duration
        return tuple(out)

    def phase_at(self, t: float) -> int:
        """Index of the phase active at time ``t`` [s] (the later one at a boundary)."""
        starts = self.phase_start_times()
        idx = 0
        for i, s in enumerate(starts):
            if t >= s - 1e-9:
                idx = i
        return idx

    def contact_frames(self) -> tuple[str, ...]:
        """Every frame that is in contact in some phase, in order of first appearance."""
        seen: list[str] = []
        for p in self.phases:
            for c in p.contacts:
                if c.frame not in seen:
                    seen.append(c.frame)
        return tuple(seen)
