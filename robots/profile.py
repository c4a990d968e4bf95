"""Robot profiles: which frames of a humanoid play which role, and how it stands.

A :class:`RobotProfile` is data. It names the Pinocchio frames that the rest of wbmp
refers to by role (``left_foot``, ``right_foot``, ``left_hand``, ``right_hand``,
``head``, ``base``, ``torso``, ``left_shoulder``, ``right_shoulder``), the sole
rectangle in the foot frame, the reference standing posture and a few gait numbers.
Built-in profiles live in ``robots/profiles/*.toml``; a user's profile is a TOML or
JSON file with the same keys plus ``urdf`` (and optionally ``srdf``, ``package_dirs``).

Every field is validated when the file is read, before any model is built: a bad value is a
:class:`~robots.exceptions.ProfileError` whose one-line message names the file, the field, what
was expected and what was found (``myrobot.toml: squat_depth_max: expected a length in metres in
(0, 1], got 'deep'``). The format and its limits are documented in ``docs/robots.md``.
"""

from __future__ import annotations

import difflib
import functools
import json
import math
import os
import re
import stat
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from robots.exceptions import ProfileError
from robots.safeio import open_regular

ROLES = (
    "left_foot",
    "right_foot",
    "left_hand",
    "right_hand",
    "head",
    "base",
    "torso",
    "left_shoulder",
    "right_shoulder",
)
REQUIRED_ROLES = ("left_foot", "right_foot", "left_hand", "right_hand", "base")
SIDE_PAIRS = (("left_foot", "right_foot"), ("left_hand", "right_hand"), ("left_shoulder", "right_shoulder"))

# Limits of a profile. A profile is a few hundred bytes; every bound is far beyond any humanoid
# and only stops typos (millimetres for metres) and hostile input.
MAX_PROFILE_BYTES = 1 << 20  # a profile file
MAX_NAME_CHARS = 64  # the robot name (also written into motion files)
MAX_TEXT_CHARS = 200  # description, frame, joint, loader and posture names
MAX_PATH_CHARS = 4096  # urdf, srdf, each package dir
MAX_PACKAGE_DIRS = 32
MAX_EXTRA_FRAMES = 64
MAX_OVERRIDES = 256  # posture_overrides entries
MAX_SOLE = 1.0  # [m] |x|, |y| of a sole rectangle edge in the foot frame
MIN_SOLE_SIDE = 0.01  # [m] shortest side of the sole rectangle
MAX_FRAME_OFFSET = 1.0  # [m] |translation| component of an extra frame from its parent
MAX_OVERRIDE = 10.0  # [rad or m] |value| of a posture override (the joint limits apply too)
NAME_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.+-]*\Z")

# Scalar fields: (lowest, highest, lowest allowed itself?, what the number is)
NUMBERS: dict[str, tuple[float, float, bool, str, str]] = {
    "friction_coefficient": (0.0, 5.0, False, "a friction coefficient", ""),
    "step_length_max": (0.0, 2.0, False, "a length in metres", ""),
    "step_width": (0.0, 1.0, True, "a length in metres", " (0 = from the standing posture)"),
    "step_duration": (0.1, 5.0, True, "a duration in seconds", ""),
    "double_support_duration": (0.05, 5.0, True, "a duration in seconds", ""),
    "squat_depth_max": (0.0, 1.0, False, "a length in metres", ""),
    "step_height_max": (0.0, 1.0, False, "a length in metres", ""),
    "climb_length_max": (0.0, 2.0, True, "a length in metres", " (0 = step_length_max)"),
    "jump_forward_speed_max": (0.0, 5.0, True, "a speed in metres per second", " (0 = no forward jumps)"),
}
SOLE_KEYS = ("x_min", "x_max", "y_min", "y_max")
COLLISION_KEYS = ("add", "remove", "body_parts", "meet_joints")
MAX_COLLISION_ENTRIES = 1024  # pairs in add/remove, names in body_parts
MAX_MEET_JOINTS = 6  # collisions.meet_joints: joints above a hand frame's joint that count as the hand
EXTRA_FRAME_KEYS = ("name", "parent", "translation")

Vec3 = tuple[float, float, float]


# --- messages -----------------------------------------------------------------------------------


def show(value: Any) -> str:
    """A short, one-line rendering of a user's value for an error message."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return f"{str(value).lower()} (a boolean)"
    if isinstance(value, str):
        text = repr(value)
        return text if len(text) <= 60 else text[:50] + "...' (" + f"{len(value)} characters)"
    if isinstance(value, int):
        digits = len(str(abs(value))) if abs(value) < 10**60 else None
        return repr(value) if digits is not None else "an integer of more than 60 digits"
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, dict):
        return "a table" if value else "an empty table"
    if isinstance(value, list):
        return f"a list of {len(value)} item(s)" if value else "an empty list"
    return f"a {type(value).__name__}"


def display_path(path: str | Path) -> str:
    """A path as the user gave it, quoted when it holds characters that would break a line."""
    text = str(path)
    if len(text) > 160:
        text = f"{text[:70]}...{text[-70:]}"
    return text if text.isprintable() and text.strip() == text and text else repr(text)


def _suggest(name: str, known: tuple[str, ...] | list[str]) -> str:
    close = difflib.get_close_matches(str(name), list(known), n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""


def _fail(where: str, key: str, expected: str, value: Any) -> ProfileError:
    return ProfileError(f"{where}: {key}: expected {expected}, got {show(value)}")


# --- field checks ---------------------------------------------------------------------------------


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _in_range(value: Any, lo: float, hi: float, lo_closed: bool = True) -> bool:
    """A finite number in [lo, hi] (or (lo, hi]); huge integers compare without overflow."""
    if not _is_number(value):
        return False
    if isinstance(value, float) and not math.isfinite(value):
        return False
    return (lo <= value if lo_closed else lo < value) and value <= hi


def _interval(lo: float, hi: float, lo_closed: bool) -> str:
    return f"{'[' if lo_closed else '('}{lo:g}, {hi:g}]"


def check_number(where: str, key: str, value: Any) -> float:
    """One of the scalar fields of :data:`NUMBERS`, as a float."""
    lo, hi, lo_closed, what, note = NUMBERS[key]
    if not _is_number(value):
        raise _fail(where, key, f"{what} (a number)", value)
    if not _in_range(value, lo, hi, lo_closed):
        raise _fail(where, key, f"{what} in {_interval(lo, hi, lo_closed)}{note}", value)
    return float(value)


def _text(where: str, key: str, value: Any, what: str, *, limit: int = MAX_TEXT_CHARS) -> str:
    """A non-empty single-line string of at most ``limit`` characters."""
    if not isinstance(value, str) or not value.strip() or len(value) > limit or not value.isprintable():
        detail = f"{what} (a non-empty single-line string of at most {limit} characters)"
        raise _fail(where, key, detail, value)
    return value


def _name(where: str, value: Any) -> str:
    if not isinstance(value, str) or len(value) > MAX_NAME_CHARS or not NAME_PATTERN.match(value):
        expected = (f"a short robot name (letters, digits, '_', '-', '.', '+'; at most {MAX_NAME_CHARS} "
                    "characters, starting with a letter or digit)")
        raise _fail(where, "name", expected, value)
    return value


def _description(where: str, value: Any) -> str:
    if not isinstance(value, str) or len(value) > MAX_TEXT_CHARS or not value.isprintable():
        raise _fail(where, "description", f"one line of text of at most {MAX_TEXT_CHARS} characters", value)
    return value


def _table(where: str, key: str, value: Any, what: str) -> dict:
    if not isinstance(value, dict):
        raise _fail(where, key, what, value)
    return value


def _sole(where: str, value: Any) -> SoleRectangle:
    table = _table(where, "sole", value, "a table [sole] with x_min, x_max, y_min, y_max (metres)")
    unknown = [k for k in table if k not in SOLE_KEYS]
    if unknown:
        raise ProfileError(f"{where}: sole: unknown key {unknown[0]!r}{_suggest(unknown[0], SOLE_KEYS)}; "
                           f"the keys are {', '.join(SOLE_KEYS)}")
    missing = [k for k in SOLE_KEYS if k not in table]
    if missing:
        raise ProfileError(f"{where}: sole: missing {', '.join(missing)} (the sole rectangle of the left foot "
                           "in its foot frame, metres: x_min, x_max, y_min, y_max)")
    edges = {}
    for k in SOLE_KEYS:
        v = table[k]
        if not _is_number(v):
            raise _fail(where, f"sole.{k}", "a length in metres (a number)", v)
        if not _in_range(v, -MAX_SOLE, MAX_SOLE):
            raise _fail(where, f"sole.{k}", f"a length in metres in [{-MAX_SOLE:g}, {MAX_SOLE:g}]", v)
        edges[k] = float(v)
    return SoleRectangle(**edges, where=where)


def _extra_frames(where: str, value: Any) -> tuple[ExtraFrame, ...]:
    expected = "a list of tables [[extra_frames]], each with name, parent and translation = [x, y, z]"
    if not isinstance(value, list):
        raise _fail(where, "extra_frames", expected, value)
    if len(value) > MAX_EXTRA_FRAMES:
        raise _fail(where, "extra_frames", f"at most {MAX_EXTRA_FRAMES} frames", value)
    out: list[ExtraFrame] = []
    for i, entry in enumerate(value):
        key = f"extra_frames[{i}]"
        if not isinstance(entry, dict):
            raise _fail(where, key, "a table with name, parent and translation = [x, y, z]", entry)
        unknown = [k for k in entry if k not in EXTRA_FRAME_KEYS]
        if unknown:
            raise ProfileError(f"{where}: {key}: unknown key {unknown[0]!r}{_suggest(unknown[0], EXTRA_FRAME_KEYS)}; "
                               f"the keys are {', '.join(EXTRA_FRAME_KEYS)}")
        missing = [k for k in EXTRA_FRAME_KEYS if k not in entry]
        if missing:
            raise ProfileError(f"{where}: {key}: missing {', '.join(missing)} (an extra frame needs a name, the "
                               "parent frame it hangs from and a translation [x, y, z] in metres)")
        name = _text(where, f"{key}.name", entry["name"], "a frame name")
        parent = _text(where, f"{key}.parent", entry["parent"], "a frame name")
        t = entry["translation"]
        if not (isinstance(t, list) and len(t) == 3 and all(_is_number(x) for x in t)):
            raise _fail(where, f"{key}.translation", "3 numbers [x, y, z] in metres", t)
        if not all(_in_range(x, -MAX_FRAME_OFFSET, MAX_FRAME_OFFSET) for x in t):
            raise _fail(where, f"{key}.translation",
                        f"3 finite numbers in [{-MAX_FRAME_OFFSET:g}, {MAX_FRAME_OFFSET:g}] m", t)
        if name == parent:
            raise ProfileError(f"{where}: {key}.parent: a frame cannot be its own parent ({name!r})")
        if any(e.name == name for e in out):
            raise ProfileError(f"{where}: {key}.name: the extra frame {name!r} is defined twice")
        out.append(ExtraFrame(name=name, parent=parent, translation=(float(t[0]), float(t[1]), float(t[2]))))
    return tuple(out)


def _frames(where: str, value: Any) -> tuple[tuple[str, str], ...]:
    table = _table(where, "frames", value, f"a table [frames] of role = frame name (roles: {', '.join(ROLES)})")
    for role in table:
        if role not in ROLES:
            raise ProfileError(f"{where}: frames: unknown role {role!r}{_suggest(role, ROLES)}; "
                               f"the roles are {', '.join(ROLES)}")
    frames = {role: _text(where, f"frames.{role}", table[role], "a frame name of the URDF") for role in table}
    missing = [r for r in REQUIRED_ROLES if r not in frames]
    if missing:
        raise ProfileError(f"{where}: frames: missing role(s) {', '.join(missing)} "
                           f"(required: {', '.join(REQUIRED_ROLES)})")
    for left, right in SIDE_PAIRS:
        if (left in frames) != (right in frames):
            given, absent = (left, right) if left in frames else (right, left)
            raise ProfileError(f"{where}: frames: {given} is given without {absent}; give both sides or neither")
        if left in frames and frames[left] == frames[right]:
            raise ProfileError(f"{where}: frames: {left} and {right} both name {frames[left]!r}; "
                               "give each side its own frame")
    return tuple((r, frames[r]) for r in ROLES if r in frames)


def _overrides(where: str, value: Any) -> tuple[tuple[str, float], ...]:
    table = _table(where, "posture_overrides", value, "a table [posture_overrides] of joint name = value (rad or m)")
    if len(table) > MAX_OVERRIDES:
        raise _fail(where, "posture_overrides", f"at most {MAX_OVERRIDES} joints", value)
    out = []
    for joint, v in table.items():
        key = f"posture_overrides.{joint}" if str(joint).isprintable() else f"posture_overrides[{joint!r}]"
        _text(where, "posture_overrides", joint, "joint names as keys")
        if not _is_number(v):
            raise _fail(where, key, "a joint angle in radians (or a position in metres): a number", v)
        if not _in_range(v, -MAX_OVERRIDE, MAX_OVERRIDE):
            raise _fail(where, key, f"a joint value in [{-MAX_OVERRIDE:g}, {MAX_OVERRIDE:g}] (rad or m)", v)
        out.append((joint, float(v)))
    return tuple(out)


def _path(where: str, key: str, value: Any, base: Path, what: str) -> str:
    _text(where, key, value, what, limit=MAX_PATH_CHARS)
    if "\0" in value:
        raise _fail(where, key, what, value)
    p = Path(value)
    try:
        p = p.expanduser()
    except RuntimeError:  # ~user that does not exist: kept as written, reported as missing later
        pass
    return str(p if p.is_absolute() else (base / p).resolve())


def _package_dirs(where: str, value: Any, base: Path) -> tuple[str, ...]:
    expected = "a list of folders that hold the URDF's package:// meshes"
    if not isinstance(value, list) or len(value) > MAX_PACKAGE_DIRS:
        raise _fail(where, "package_dirs", f"{expected} (at most {MAX_PACKAGE_DIRS})", value)
    return tuple(_path(where, f"package_dirs[{i}]", d, base, "a folder") for i, d in enumerate(value))


# --- the profile ----------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True, kw_only=True)
class SoleRectangle:
    """Sole contact rectangle of the LEFT foot, in the foot frame [m].

    The right foot uses the mirror image (``y -> -y``). The foot frame's z axis is
    the sole normal and its origin lies on the sole surface.
    """

    x_min: float
    x_max: float
    y_min: float
    y_max: float
    where: str = field(default="profile", compare=False, repr=False)

    def __post_init__(self) -> None:
        for k in SOLE_KEYS:
            if not _in_range(getattr(self, k), -MAX_SOLE, MAX_SOLE):
                raise _fail(self.where, f"sole.{k}", f"a length in metres in [{-MAX_SOLE:g}, {MAX_SOLE:g}]",
                            getattr(self, k))
        for lo, hi, what in (("x_min", "x_max", "long (heel to toe)"), ("y_min", "y_max", "wide")):
            a, b = getattr(self, lo), getattr(self, hi)
            if not b - a >= MIN_SOLE_SIDE:
                raise ProfileError(
                    f"{self.where}: sole: expected {lo} < {hi} with a sole at least {MIN_SOLE_SIDE * 100:g} cm "
                    f"{what}, got {lo} = {a:g}, {hi} = {b:g}"
                )

    def corners(self, side: str) -> tuple[tuple[float, float], ...]:
        """Corners in the foot frame, counter-clockwise, for ``side`` 'left' or 'right' [m]."""
        ys = (self.y_min, self.y_max) if side == "left" else (-self.y_max, -self.y_min)
        return (
            (self.x_min, ys[0]),
            (self.x_max, ys[0]),
            (self.x_max, ys[1]),
            (self.x_min, ys[1]),
        )


@dataclass(frozen=True, slots=True, kw_only=True)
class CollisionTable:
    """The profile's ``[collisions]`` table: link pairs to add to or remove from the self-collision
    checks, human names of links for messages (``robots.collision``, ``docs/collisions.md``), and
    ``meet_joints``: how many joints above a hand frame's joint count as the hand in a planned
    self-contact (a clap; :meth:`robots.Robot.meet_links`; G1's wrist roll and pitch links sit
    above its hand frame's joint: 2; 0 = the hand frame's joint and below)."""

    add: tuple[tuple[str, str], ...] = ()
    remove: tuple[tuple[str, str], ...] = ()
    body_parts: tuple[tuple[str, str], ...] = ()
    meet_joints: int = 0

    def fit_key(self) -> str:
        """What the fitted collision model depends on (add, remove, body_parts; not meet_joints),
        in the text the whole table's repr had before meet_joints: the fits cached then still match."""
        return f"CollisionTable(add={self.add!r}, remove={self.remove!r}, body_parts={self.body_parts!r})"


def _collisions(where: str, value: Any) -> CollisionTable:
    table = _table(where, "collisions", value,
                   "a table [collisions] with add = [[link, link], ...], remove = [[link, link], ...] "
                   "and body_parts = {link = \"name\"}, meet_joints = N")
    unknown = [k for k in table if k not in COLLISION_KEYS]
    if unknown:
        raise ProfileError(f"{where}: collisions: unknown key {unknown[0]!r}{_suggest(unknown[0], COLLISION_KEYS)}; "
                           f"the keys are {', '.join(COLLISION_KEYS)}")
    lists: dict[str, tuple[tuple[str, str], ...]] = {}
    for key in ("add", "remove"):
        entries = table.get(key, [])
        if not isinstance(entries, list) or len(entries) > MAX_COLLISION_ENTRIES:
            raise _fail(where, f"collisions.{key}",
                        f"a list of link pairs [[link, link], ...] (at most {MAX_COLLISION_ENTRIES})", entries)
        pairs = []
        for i, pair in enumerate(entries):
            k = f"collisions.{key}[{i}]"
            if not isinstance(pair, list) or len(pair) != 2:
                raise _fail(where, k, "a pair of link names [link, link]", pair)
            a = _text(where, k, pair[0], "a link name")
            b = _text(where, k, pair[1], "a link name")
            if a == b:
                raise ProfileError(f"{where}: {k}: a link cannot collide with itself ({a!r}); name two links")
            pairs.append((a, b))
        lists[key] = tuple(pairs)
    both = {tuple(sorted(p)) for p in lists["add"]} & {tuple(sorted(p)) for p in lists["remove"]}
    if both:
        a, b = sorted(both)[0]
        raise ProfileError(f"{where}: collisions: the pair [{a!r}, {b!r}] is both added and removed; keep one")
    names = table.get("body_parts", {})
    if not isinstance(names, dict) or len(names) > MAX_COLLISION_ENTRIES:
        raise _fail(where, "collisions.body_parts", 'a table of link = "human name" (left forearm)', names)
    parts = tuple((_text(where, "collisions.body_parts", link, "link names as keys"),
                   _text(where, f"collisions.body_parts.{link}", text, "a human name such as 'left forearm'"))
                  for link, text in names.items())
    meet = table.get("meet_joints", 0)
    if not isinstance(meet, int) or isinstance(meet, bool) or not 0 <= meet <= MAX_MEET_JOINTS:
        raise _fail(where, "collisions.meet_joints",
                    f"a whole number of joints in [0, {MAX_MEET_JOINTS}] above the hand frame's joint", meet)
    return CollisionTable(add=lists["add"], remove=lists["remove"], body_parts=parts, meet_joints=meet)


@dataclass(frozen=True, slots=True, kw_only=True)
class ExtraFrame:
    """A frame that wbmp adds to the model: ``parent`` frame + a fixed translation [m]."""

    name: str
    parent: str
    translation: Vec3


@dataclass(frozen=True, slots=True, kw_only=True)
class RobotProfile:
    """Everything wbmp needs to know about a humanoid beyond its URDF.

    Attributes:
        name: Short name (``talos``).
        description: One line for ``wbmp robots``.
        loader: ``example_robot_data`` loader name, or None for a URDF profile.
        urdf: Path to the URDF for a user profile (absolute, or relative to the profile file).
        srdf: Optional SRDF path (reference configurations are read from it).
        package_dirs: Directories searched for ``package://`` meshes.
        frames: Role -> Pinocchio frame name (see ``ROLES``).
        extra_frames: Frames added to the model before roles are resolved.
        sole: Left-foot sole rectangle in the foot frame [m].
        reference_posture: Name of a reference configuration (SRDF/loader), or ``"q0"``.
        posture_overrides: Joint name -> angle [rad] applied on top of the reference.
        friction_coefficient: Foot/ground Coulomb friction [-].
        step_length_max: Longest forward step the gait generator plans [m].
        step_width: Nominal lateral distance between the feet [m]; 0 = from the posture.
        step_duration: Single-support duration of one step [s].
        double_support_duration: Double-support duration between steps [s].
        squat_depth_max: Deepest CoM lowering the squat primitive allows [m].
        step_height_max: Highest rise one step climbs (a stair tread, a box underfoot) [m].
        climb_length_max: Longest step onto a higher or lower surface (stairs, a slope) [m]; 0:
            ``step_length_max``. A step-to climb stands on both feet between steps, so it may
            be longer than a walking stride (g1: 0.26 m, its 0.25 m stair treads, certified).
        jump_forward_speed_max: Fastest forward take-off a jump's landing absorbs [m/s] (its
            distance over the flight time; 0: forward jumps are refused). Calibrated in MuJoCo:
            talos 0.5 m/s (0.10 m with a 5 cm rise); g1's forward jumps all fall, so 0.
        collisions: Self-collision pairs to add or remove, and body-part names (``[collisions]``).
        source: The file the profile was read from ("" when built in code).
    """

    name: str
    description: str = ""
    loader: str | None = None
    urdf: str | None = None
    srdf: str | None = None
    package_dirs: tuple[str, ...] = ()
    frames: tuple[tuple[str, str], ...] = ()
    extra_frames: tuple[ExtraFrame, ...] = ()
    sole: SoleRectangle
    reference_posture: str = "q0"
    posture_overrides: tuple[tuple[str, float], ...] = ()
    friction_coefficient: float = 0.7
    step_length_max: float = 0.25
    step_width: float = 0.0
    step_duration: float = 0.8
    double_support_duration: float = 0.2
    squat_depth_max: float = 0.3
    step_height_max: float = 0.15
    climb_length_max: float = 0.0
    jump_forward_speed_max: float = 0.5
    collisions: CollisionTable = field(default_factory=CollisionTable)
    source: str = field(default="", compare=False)

    def __post_init__(self) -> None:
        # The checks that hold for a profile built in code too (from_mapping checked every type).
        where = self.where
        _name(where, self.name)
        if (self.loader is None) == (self.urdf is None):
            both = "both" if self.loader is not None else "neither"
            raise ProfileError(f"{where}: expected exactly one of 'loader' (an example-robot-data robot) or "
                               f"'urdf' (a URDF file), got {both}")
        if self.loader is not None and (self.srdf is not None or self.package_dirs):
            key = "srdf" if self.srdf is not None else "package_dirs"
            raise ProfileError(f"{where}: {key}: only applies with 'urdf' (a loader robot brings its own files)")
        _frames(where, dict(self.frames))
        if not isinstance(self.sole, SoleRectangle):
            raise _fail(where, "sole", "a SoleRectangle", self.sole)
        for key in NUMBERS:
            check_number(where, key, getattr(self, key))

    @property
    def where(self) -> str:
        """How error messages name this profile: its file, or ``profile 'name'``."""
        return display_path(self.source) if self.source else f"profile {self.name!r}"

    def frame(self, role: str) -> str | None:
        """Frame name playing ``role``, or None when the robot lacks it (e.g. no head)."""
        return dict(self.frames).get(role)

    @classmethod
    def known_keys(cls) -> tuple[str, ...]:
        """The keys a profile file may hold, in the documented order."""
        return tuple(k for k in cls.__dataclass_fields__ if k != "source")

    @classmethod
    def from_mapping(cls, data: Any, *, source: str = "") -> RobotProfile:
        """Build a profile from the parsed TOML/JSON mapping, checking every field.

        Relative paths are resolved against the profile file's folder (the working directory
        when ``source`` is empty).

        Raises:
            ProfileError: a key is unknown or missing, or a value has the wrong type or range;
                the message names the file, the field and what was expected.
        """
        where = display_path(source) if source else "profile"
        if not isinstance(data, dict):
            raise _fail(where, "the top level", "a table of profile keys (name, loader or urdf, frames, sole, ...)",
                        data)
        known = cls.known_keys()
        for key in data:
            if key not in known:
                shown = repr(key) if isinstance(key, str) else show(key)
                raise ProfileError(f"{where}: unknown key {shown}{_suggest(key, known)}; "
                                   f"the keys are {', '.join(known)}")
        if "name" not in data:
            raise ProfileError(f"{where}: name: missing (a short robot name such as 'myrobot')")
        name = _name(where, data["name"])
        if source and name in builtin_names() and Path(source).resolve().parent != PROFILE_DIR.resolve():
            raise ProfileError(f"{where}: name: {name!r} is a built-in robot; give your profile its own name "
                               f"(built-in: {', '.join(builtin_names())})")
        if "sole" not in data:
            raise ProfileError(f"{where}: sole: missing (a table [sole] with x_min, x_max, y_min, y_max in metres)")
        if "frames" not in data:
            raise ProfileError(f"{where}: frames: missing (a table [frames] of role = frame name; "
                               f"required roles: {', '.join(REQUIRED_ROLES)})")
        base = Path(source).parent if source else Path.cwd()
        kwargs: dict[str, Any] = {"name": name, "source": source}
        for key, value in data.items():
            if key == "name":
                continue
            if value is None:
                raise _fail(where, key, "a value (leave the key out instead of null)", value)
            if key == "description":
                kwargs[key] = _description(where, value)
            elif key in ("loader", "reference_posture"):
                kwargs[key] = _text(where, key, value,
                                    "an example-robot-data robot name" if key == "loader" else
                                    "a reference configuration name ('q0' or one from the SRDF)")
            elif key in ("urdf", "srdf"):
                kwargs[key] = _path(where, key, value, base, f"the path of the {key.upper()} file")
            elif key == "package_dirs":
                kwargs[key] = _package_dirs(where, value, base)
            elif key == "frames":
                kwargs[key] = _frames(where, value)
            elif key == "extra_frames":
                kwargs[key] = _extra_frames(where, value)
            elif key == "sole":
                kwargs[key] = _sole(where, value)
            elif key == "posture_overrides":
                kwargs[key] = _overrides(where, value)
            elif key == "collisions":
                kwargs[key] = _collisions(where, value)
            else:
                kwargs[key] = check_number(where, key, value)
        return cls(**kwargs)

    @classmethod
    def from_file(cls, path: str | Path) -> RobotProfile:
        """Read a TOML (``.toml``, or any other name) or JSON (``.json``) profile file.

        Raises:
            ProfileError: the file is missing, unreadable, not UTF-8, not valid TOML/JSON, or a
                field is wrong (see :meth:`from_mapping`).
        """
        return cls.from_mapping(read_profile_file(path), source=str(path))


def read_profile_file(path: str | Path) -> Any:
    """The parsed content of a profile file (checked to be a small UTF-8 TOML/JSON file)."""
    path = Path(path)
    where = display_path(path)
    try:
        st = path.stat()
    except (FileNotFoundError, NotADirectoryError):
        raise ProfileError(f"{where}: profile file does not exist") from None
    except (OSError, ValueError) as e:
        raise ProfileError(f"{where}: cannot read the profile file: {getattr(e, 'strerror', None) or e}") from None
    if stat.S_ISDIR(st.st_mode):
        raise ProfileError(f"{where}: is a directory, not a profile file (give path/to/robot.toml)")
    if not stat.S_ISREG(st.st_mode):
        raise ProfileError(f"{where}: is not a regular file (a profile is a .toml or .json file)")
    too_big = f"{where}: the profile file is larger than {MAX_PROFILE_BYTES // 1024} kB (a profile is a few kB)"
    if st.st_size > MAX_PROFILE_BYTES:
        raise ProfileError(too_big)
    try:  # replaced by a FIFO or a device since the stat: refused, never waited on
        with open_regular(path, MAX_PROFILE_BYTES) as f:
            raw = f.read(MAX_PROFILE_BYTES + 1)
    except OSError as e:
        raise ProfileError(f"{where}: cannot read the profile file: {e.strerror or e}") from None
    if len(raw) > MAX_PROFILE_BYTES:
        raise ProfileError(too_big)
    text = _decode(where, raw)
    if not text.strip():
        raise ProfileError(f"{where}: the profile file is empty; a profile needs name, loader or urdf, "
                           "[frames] and [sole] (see docs/robots.md)")
    is_json = path.suffix.lower() == ".json"
    try:
        if is_json:
            return json.loads(text, object_pairs_hook=functools.partial(_no_duplicates, where))
        return tomllib.loads(text)
    except json.JSONDecodeError as e:
        raise ProfileError(f"{where}: not valid JSON: {e.msg} (line {e.lineno}, column {e.colno})") from None
    except tomllib.TOMLDecodeError as e:
        hint = ""
        if "overwrite" in str(e).lower():
            hint = " (a key or table given twice?)"
        elif text.lstrip().startswith(("{", "[{", "[\n", "[ ")):
            hint = " (this looks like JSON: name the file .json)"
        raise ProfileError(f"{where}: not valid TOML: {e}{hint}") from None
    except RecursionError:
        raise ProfileError(f"{where}: the profile nests too deeply to be a profile") from None
    except ValueError as e:  # e.g. a number literal of thousands of digits
        kind = "JSON" if is_json else "TOML"
        reason = "a number has too many digits" if "digits" in str(e) else str(e).splitlines()[0][:200]
        raise ProfileError(f"{where}: not valid {kind}: {reason}") from None


def _decode(where: str, raw: bytes) -> str:
    if raw.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise ProfileError(f"{where}: the profile file is UTF-16 text; save it as UTF-8")
    if raw.startswith(b"\xef\xbb\xbf"):  # a UTF-8 byte-order mark: harmless, dropped
        raw = raw[3:]
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as e:
        raise ProfileError(f"{where}: the profile file is not UTF-8 text (byte 0x{raw[e.start]:02x} at offset "
                           f"{e.start}); save it as UTF-8") from None


def _no_duplicates(where: str, pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            raise ProfileError(f"{where}: key {key!r} is given twice in the same object")
        out[key] = value
    return out


PROFILE_DIR = Path(__file__).with_name("profiles")


@functools.cache
def _builtin_files() -> tuple[Path, ...]:
    return tuple(sorted(PROFILE_DIR.glob("*.toml"), key=lambda p: (p.stem != "talos", p.stem)))


def builtin_names() -> tuple[str, ...]:
    """Names of the built-in profiles (a built-in profile's name is its file's stem), talos first."""
    return tuple(p.stem for p in _builtin_files())


@functools.cache
def _builtin_profiles() -> tuple[RobotProfile, ...]:
    return tuple(RobotProfile.from_file(os.fspath(p)) for p in _builtin_files())


def builtin_profiles() -> dict[str, RobotProfile]:
    """The profiles shipped with wbmp, by name (talos first: the default)."""
    return {p.name: p for p in _builtin_profiles()}
