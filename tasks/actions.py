"""Actions: what a user asks for, before it becomes a TaskSpec.

An :class:`Action` names a primitive of the registry and its parameters in SI units. The
registry (:data:`REGISTRY`) lists every primitive with a typed parameter schema (names,
units, defaults, ranges, choices) that the language layer, the CLI (``wbmp actions``) and
the LLM backend's JSON schema are all generated from. Each primitive also declares which
body part it drives, so upper-body actions can be overlaid on lower-body ones.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from tasks.exceptions import TaskDefinitionError, UnknownAction
from tasks.limits import MAX_ACTIONS, MAX_DISTANCE, MAX_REPEAT

SIDES = ("left", "right")
ARMS = ("left", "right", "both")
DIRECTIONS = ("forward", "backward", "left", "right")
REACH_DIRECTIONS = ("forward", "up", "down", "left", "right", "backward")
HEAD_DIRECTIONS = ("left", "right", "up", "down")
KICK_DIRECTIONS = ("forward", "side")
POINT_DIRECTIONS = ("forward", "left", "right", "up", "down")
STRETCH_DIRECTIONS = ("up", "left", "right", "backward")
TOUCH_PARTS = ("head", "shoulder", "chest", "hip", "knee", "hand", "toes")
MAX_REFERENCE_LENGTH = 200  # characters of an object reference (tasks.grounding)


@dataclass(frozen=True, slots=True, kw_only=True)
class Param:
    """One parameter of a primitive.

    Attributes:
        name: Parameter name (``depth``).
        kind: ``float``, ``int``, ``choice``, ``vec3``, ``bool`` or ``object`` (a reference to a
            scene object as said, ``the red box``; :func:`tasks.compose.compile_actions` resolves
            it against the spec's scene, :mod:`tasks.grounding`).
        unit: SI unit (``m``, ``s``, ``rad``) or ``""``/``count``.
        default: Value used when the user does not give one (None = optional, no value).
        minimum, maximum: Inclusive range for ``float``/``int`` (robot limits may be tighter).
        choices: Allowed values for ``choice``.
        description: One line for ``wbmp actions``.
    """

    name: str
    kind: str
    unit: str = ""
    default: Any = None
    minimum: float | None = None
    maximum: float | None = None
    choices: tuple[str, ...] = ()
    description: str = ""

    def validate(self, action: str, value: Any) -> Any:
        """Return ``value`` normalized to the parameter's type, or raise TaskDefinitionError."""
        who = f"{action} {self.name}"
        if value is None:
            return None
        if self.kind == "float":
            if not _finite_number(value):
                raise TaskDefinitionError(f"{who} must be a number [{self.unit}], got {_short(value)}")
            value = float(value)
        elif self.kind == "int":
            if isinstance(value, float) and value.is_integer():
                value = int(value)
            if isinstance(value, bool) or not isinstance(value, int):
                raise TaskDefinitionError(f"{who} must be a whole number, got {_short(value)}")
        elif self.kind == "choice":
            if not isinstance(value, str) or value not in self.choices:
                raise TaskDefinitionError(f"{who} must be one of {', '.join(self.choices)}, got {_short(value)}")
            return value
        elif self.kind == "vec3":
            if (not isinstance(value, (list, tuple)) or len(value) != 3
                    or not all(_finite_number(x) and abs(x) <= MAX_DISTANCE for x in value)):
                raise TaskDefinitionError(
                    f"{who} must be three numbers within {MAX_DISTANCE:g} {self.unit}, got {_short(value)}"
                )
            return tuple(float(x) for x in value)
        elif self.kind == "bool":
            if not isinstance(value, bool):
                raise TaskDefinitionError(f"{who} must be true or false, got {_short(value)}")
            return value
        elif self.kind == "object":
            text = getattr(value, "reference", value)  # a grounded reference keeps its words
            if not isinstance(text, str) or not text.strip() or len(text) > MAX_REFERENCE_LENGTH:
                raise TaskDefinitionError(
                    f"{who} must name an object of the scene in at most {MAX_REFERENCE_LENGTH} characters "
                    f"(\"the red box\"), got {_short(value)}"
                )
            return value if text is not value else text.strip()
        if self.minimum is not None and value < self.minimum:
            raise TaskDefinitionError(f"{who} {_fmt(value, self.unit)} is below the minimum {_fmt(self.minimum, self.unit)}")
        if self.maximum is not None and value > self.maximum:
            raise TaskDefinitionError(f"{who} {_fmt(value, self.unit)} is above the maximum {_fmt(self.maximum, self.unit)}")
        return value

    def to_json_schema(self) -> dict[str, Any]:
        """JSON-schema fragment of this parameter."""
        if self.kind == "float":
            s: dict[str, Any] = {"type": "number"}
        elif self.kind == "int":
            s = {"type": "integer"}
        elif self.kind == "choice":
            s = {"type": "string", "enum": list(self.choices)}
        elif self.kind == "vec3":
            s = {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3}
        elif self.kind == "object":
            s = {"type": "string"}  # non-empty, at most MAX_REFERENCE_LENGTH: checked by validate()
        else:
            s = {"type": "boolean"}
        if self.minimum is not None:
            s["minimum"] = self.minimum
        if self.maximum is not None:
            s["maximum"] = self.maximum
        desc = self.description + (f" [{self.unit}]" if self.unit and self.unit != "count" else "")
        if desc:
            s["description"] = desc
        if self.default is not None:
            s["default"] = list(self.default) if isinstance(self.default, tuple) else self.default
        return s


def _finite_number(value: Any) -> bool:
    """A bool-free int or float that is finite and converts to a float."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return False
    if isinstance(value, int):
        return abs(value) < 10**300  # float() of a larger one overflows
    return math.isfinite(value)


def _short(value: Any) -> str:
    """A repr for messages, cut short (a reply may hold a 5,000-digit number or a huge list)."""
    text = repr(value)
    return text if len(text) <= 60 else f"{text[:40]}... ({len(text)} characters)"


def _fmt(value: float, unit: str) -> str:
    text = f"{value:g}" if isinstance(value, float) or abs(value) < 10**15 else _short(value)
    return f"{text} {unit}".strip() if unit not in ("", "count") else text


@dataclass(frozen=True, slots=True, kw_only=True)
class ActionSchema:
    """A primitive's signature: name, body part, parameters.

    Attributes:
        name: Registry key (``squat``).
        summary: One sentence for ``wbmp actions``.
        body: ``lower`` (legs, CoM), ``upper`` (arms, head) or ``whole``; an ``upper`` action can
            be overlaid on a ``lower`` one.
        dynamic: Needs contact forces (steps, jumps).
        params: Parameter schemas.
    """

    name: str
    summary: str
    body: str
    params: tuple[Param, ...] = ()
    dynamic: bool = False

    def param(self, name: str) -> Param:
        """The parameter ``name`` (TaskDefinitionError listing the known ones otherwise)."""
        for p in self.params:
            if p.name == name:
                return p
        raise TaskDefinitionError(
            f"{self.name} has no parameter {name!r}; its parameters are {', '.join(p.name for p in self.params) or 'none'}"
        )

    def resolve(self, params: Mapping[str, Any]) -> dict[str, Any]:
        """Validated parameters with defaults filled in."""
        out = {}
        for key, value in params.items():
            out[key] = self.param(key).validate(self.name, value)
        for p in self.params:
            if out.get(p.name) is None:
                out[p.name] = p.default
        return out

    def to_json_schema(self) -> dict[str, Any]:
        """JSON schema of ``{"action": name, "params": {...}}`` for this primitive."""
        return {
            "type": "object",
            "properties": {
                "action": {"const": self.name},
                "params": {
                    "type": "object",
                    "properties": {p.name: p.to_json_schema() for p in self.params},
                    "additionalProperties": False,
                },
                "overlay": {"type": "boolean"},
            },
            "required": ["action"],
            "additionalProperties": False,
            "description": self.summary,
        }


@dataclass(frozen=True, slots=True, kw_only=True)
class Action:
    """One requested action: a registry name and parameters (SI units).

    ``overlay=True`` means the action runs at the same time as the previous one (``wave while
    squatting`` is ``[squat, wave(overlay=True)]``); otherwise actions run one after another.

    ``defaulted`` names the parameters the caller did not state (filled from the registry
    default; computed here, not compared): the primitives fit those to the robot (a default
    beyond the robot's limit becomes the limit, :func:`tasks.primitives.base.fit_defaults`),
    while a stated value beyond it is refused.
    """

    name: str
    params: Mapping[str, Any] = field(default_factory=dict)
    overlay: bool = False
    defaulted: frozenset[str] = field(default=frozenset(), compare=False)

    def __post_init__(self) -> None:
        schema = get_action(self.name)
        stated = {k for k, v in self.params.items() if v is not None}
        resolved = schema.resolve(self.params)
        object.__setattr__(self, "params", _FrozenDict(resolved))
        kept = {k for k in self.defaulted if k in resolved}  # a fitted default stays a default
        filled = {k for k, v in resolved.items() if k not in stated and v is not None}
        object.__setattr__(self, "defaulted", frozenset(filled | kept))

    def to_dict(self) -> dict[str, Any]:
        """``{"action": name, "params": {...}}`` (+ ``"overlay": true`` when set)."""
        params = {k: _plain(v) for k, v in self.params.items() if v is not None}
        out: dict[str, Any] = {"action": self.name, "params": params}
        if self.overlay:
            out["overlay"] = True
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Action:
        """Inverse of :meth:`to_dict` (TaskDefinitionError on bad content)."""
        if not isinstance(data, Mapping) or "action" not in data:
            raise TaskDefinitionError(f"an action must be an object with an 'action' key, got {data!r}")
        unknown = sorted(set(data) - {"action", "params", "overlay"})
        if unknown:
            raise TaskDefinitionError(f"action {data.get('action')!r}: unknown key(s) {unknown}")
        params = data.get("params") or {}
        if not isinstance(params, Mapping):
            raise TaskDefinitionError(f"action {data['action']!r}: params must be an object")
        overlay = data.get("overlay", False)
        if not isinstance(overlay, bool):
            raise TaskDefinitionError(f"action {data['action']!r}: overlay must be true or false")
        return cls(name=str(data["action"]), params=dict(params), overlay=overlay)


def _plain(value: Any) -> Any:
    """A parameter's JSON form: a list for a vector, the words for a grounded reference."""
    if isinstance(value, tuple):
        return list(value)
    return getattr(value, "reference", value)


class _FrozenDict(dict):
    """A dict that refuses mutation and hashes by content (keeps Action frozen in spirit)."""

    def _refuse(self, *args, **kwargs):
        raise TypeError("action parameters are read-only; build a new Action")

    __setitem__ = __delitem__ = clear = pop = popitem = setdefault = update = _refuse

    def __hash__(self) -> int:  # type: ignore[override]
        return hash(tuple(sorted(self.items())))


def _choice(name: str, choices: tuple[str, ...], default: str | None, description: str) -> Param:
    return Param(name=name, kind="choice", choices=choices, default=default, description=description)


def _repeat(default: int = 1) -> Param:
    return Param(name="repeat", kind="int", unit="count", default=default, minimum=1, maximum=MAX_REPEAT,
                 description="how many times")


def _object(description: str) -> Param:
    return Param(name="object", kind="object", description=f"{description}, as said (\"the red box\", 桌子上的杯子)")


REGISTRY: dict[str, ActionSchema] = {
    s.name: s
    for s in (
        ActionSchema(name="stand", summary="Stand still in the reference posture.", body="whole", params=(
            Param(name="duration", kind="float", unit="s", default=1.0, minimum=0.2, maximum=30.0,
                  description="how long"),
        )),
        ActionSchema(name="squat", summary="Lower the body by bending the knees, then stand up again.", body="lower", params=(
            Param(name="depth", kind="float", unit="m", default=0.15, minimum=0.02, maximum=0.6,
                  description="how far the centre of mass goes down"),
            _repeat(1),
            Param(name="duration", kind="float", unit="s", default=2.0, minimum=0.8, maximum=10.0,
                  description="time for one squat, down and up"),
        )),
        ActionSchema(name="wave", summary="Raise a hand above the shoulder and wave it side to side.", body="upper", params=(
            _choice("arm", ARMS, "right", "which hand waves"),
            _repeat(2),
            Param(name="duration", kind="float", unit="s", default=0.8, minimum=0.3, maximum=4.0,
                  description="time for one wave, out and back"),
        )),
        # --- arm, hand and head gestures (tasks/primitives/arms.py, head.py) ---
        ActionSchema(name="punch", summary="Punch straight ahead from a guard position, then lower the arm.", body="upper", params=(
            _choice("arm", SIDES, "right", "which arm punches"),
            _repeat(1),
            Param(name="duration", kind="float", unit="s", default=1.0, minimum=0.5, maximum=4.0,
                  description="time for one punch, out and back to the guard"),
        )),
        ActionSchema(name="clap", summary="Clap the hands in front of the chest.", body="upper", params=(
            _repeat(3),
            Param(name="duration", kind="float", unit="s", default=0.8, minimum=0.4, maximum=4.0,
                  description="time for one clap, together and apart"),
        )),
        ActionSchema(name="touch", summary="Touch a body part with a hand (stopping 2 cm short of it).", body="upper", params=(
            _choice("hand", SIDES, "right", "which hand touches"),
            _choice("part", TOUCH_PARTS, "head", "what it touches (shoulder: the other one; hand: the other hand)"),
            Param(name="duration", kind="float", unit="s", default=3.0, minimum=1.0, maximum=10.0,
                  description="time to touch, hold and come back"),
        )),
        ActionSchema(name="hands_on_hips", summary="Put both hands on the hips, hold, and let them down.", body="upper", params=(
            Param(name="duration", kind="float", unit="s", default=3.0, minimum=1.0, maximum=30.0,
                  description="time to put them, hold and come back"),
        )),
        ActionSchema(name="cross_arms", summary="Cross the arms in front of the chest, hold, and let them down.", body="upper", params=(
            Param(name="duration", kind="float", unit="s", default=3.0, minimum=1.0, maximum=30.0,
                  description="time to cross, hold and come back"),
        )),
        ActionSchema(name="arms_out", summary="Hold the arms straight out to the sides at shoulder height.", body="upper", params=(
            _choice("arm", ARMS, "both", "which arm"),
            Param(name="duration", kind="float", unit="s", default=2.5, minimum=1.0, maximum=30.0,
                  description="time to raise, hold and lower"),
        )),
        ActionSchema(name="point", summary="Point with a straight arm in a direction.", body="upper", params=(
            _choice("arm", SIDES, None, "which arm points (default: the one on the named side, else the right)"),
            _choice("direction", POINT_DIRECTIONS, "forward", "where to point"),
            Param(name="duration", kind="float", unit="s", default=3.0, minimum=1.0, maximum=30.0,
                  description="time to point, hold and lower"),
        )),
        ActionSchema(name="touch_object", summary="Touch an object of the scene with one hand (a planned contact).",
                     body="upper", params=(
            _object("the object to touch"),
            _choice("hand", SIDES, None, "which hand touches (default: the one on the object's side)"),
            Param(name="duration", kind="float", unit="s", default=3.0, minimum=1.0, maximum=30.0,
                  description="time to reach out, touch, hold and come back"),
        )),
        ActionSchema(name="salute", summary="Raise a hand to the forehead in a salute.", body="upper", params=(
            _choice("arm", SIDES, "right", "which hand salutes"),
            Param(name="duration", kind="float", unit="s", default=2.5, minimum=1.0, maximum=30.0,
                  description="time to salute, hold and lower"),
        )),
        ActionSchema(name="arm_circles", summary="Hold the arms out to the sides and circle the hands.", body="upper", params=(
            _choice("arm", ARMS, "both", "which arm"),
            _repeat(2),
            Param(name="radius", kind="float", unit="m", default=0.08, minimum=0.02, maximum=0.3,
                  description="radius of the circle the hand draws"),
            Param(name="duration", kind="float", unit="s", default=1.6, minimum=0.8, maximum=8.0,
                  description="time for one circle"),
        )),
        ActionSchema(name="shrug", summary="Shrug: open both forearms, palms up, and lift them.", body="upper", params=(
            _repeat(1),
            Param(name="duration", kind="float", unit="s", default=1.2, minimum=0.6, maximum=4.0,
                  description="time for one shrug, up and down"),
        )),
        ActionSchema(name="stretch", summary="Stretch both arms overhead, optionally leaning the upper body.", body="whole", params=(
            _choice("direction", STRETCH_DIRECTIONS, "up", "up, or the side the upper body leans to"),
            Param(name="angle", kind="float", unit="rad", default=0.15, minimum=0.05, maximum=0.5,
                  description="lean of the upper body (not used for up)"),
            Param(name="duration", kind="float", unit="s", default=5.0, minimum=1.0, maximum=10.0,
                  description="time to stretch, hold and come back"),
        )),
        ActionSchema(name="nod", summary="Nod the head (robots with a neck).", body="upper", params=(
            _repeat(2),
            Param(name="angle", kind="float", unit="rad", default=0.3, minimum=0.05, maximum=0.8,
                  description="how far the head tips down"),
            Param(name="duration", kind="float", unit="s", default=0.8, minimum=0.4, maximum=4.0,
                  description="time for one nod, down and up"),
        )),
        ActionSchema(name="shake_head", summary="Shake the head from side to side (robots with a neck).", body="upper", params=(
            _repeat(2),
            Param(name="angle", kind="float", unit="rad", default=0.4, minimum=0.05, maximum=1.2,
                  description="how far the head turns to each side"),
            Param(name="duration", kind="float", unit="s", default=1.2, minimum=0.5, maximum=4.0,
                  description="time for one shake, left and right"),
        )),
        ActionSchema(name="reach", summary="Move a hand to a point, given in the base frame or as a direction.", body="upper", params=(
            _choice("hand", SIDES, "right", "which hand reaches"),
            Param(name="target", kind="vec3", unit="m", default=None,
                  description="point to reach in the robot's base frame (x forward, y left, z up)"),
            _choice("direction", REACH_DIRECTIONS, None,
                    "direction to reach in, from the hand's rest position (forward when no target is given)"),
            Param(name="distance", kind="float", unit="m", default=0.2, minimum=0.0, maximum=1.5,
                  description="how far to reach along direction"),
            Param(name="duration", kind="float", unit="s", default=2.0, minimum=0.5, maximum=10.0,
                  description="time to reach and come back"),
        )),
        ActionSchema(name="raise_arms", summary="Raise one or both arms overhead.", body="upper", params=(
            _choice("arm", ARMS, "both", "which arm"),
            Param(name="duration", kind="float", unit="s", default=2.0, minimum=0.5, maximum=10.0,
                  description="time to raise and lower"),
        )),
        ActionSchema(name="bow", summary="Bend the torso forward and come back up.", body="whole", params=(
            Param(name="angle", kind="float", unit="rad", default=0.35, minimum=0.05, maximum=1.0,
                  description="forward tilt of the torso"),
            Param(name="duration", kind="float", unit="s", default=2.5, minimum=0.8, maximum=10.0,
                  description="time to bow and come back"),
        )),
        ActionSchema(name="turn_head", summary="Look in a direction by turning the head (robots with a neck).", body="upper", params=(
            _choice("direction", HEAD_DIRECTIONS, "left", "where to look"),
            Param(name="angle", kind="float", unit="rad", default=0.5, minimum=0.05, maximum=1.3,
                  description="how far to turn"),
            Param(name="duration", kind="float", unit="s", default=2.0, minimum=0.5, maximum=10.0,
                  description="time to look and come back"),
        )),
        ActionSchema(name="lean", summary="Shift the body's weight in a direction without moving the feet.", body="lower", params=(
            _choice("direction", DIRECTIONS, "forward", "lean direction"),
            Param(name="amount", kind="float", unit="m", default=0.04, minimum=0.005, maximum=0.3,
                  description="centre-of-mass shift"),
            Param(name="duration", kind="float", unit="s", default=2.0, minimum=0.5, maximum=10.0,
                  description="time to lean and come back"),
        )),
        ActionSchema(name="balance", summary="Stand on one foot, then put the other foot down again.", body="lower", params=(
            _choice("foot", SIDES, "left", "the stance foot"),
            Param(name="duration", kind="float", unit="s", default=2.0, minimum=0.5, maximum=20.0,
                  description="time on one foot"),
        )),
        ActionSchema(name="step", summary="Take steps in a direction.", body="lower", dynamic=True, params=(
            _choice("direction", DIRECTIONS, "forward", "step direction"),
            Param(name="length", kind="float", unit="m", default=0.15, minimum=0.01, maximum=2.0,
                  description="length of each step"),
            Param(name="count", kind="int", unit="count", default=2, minimum=1, maximum=20,
                  description="number of steps"),
        )),
        ActionSchema(name="walk", summary="Walk a distance in a direction.", body="lower", dynamic=True, params=(
            _choice("direction", DIRECTIONS, "forward", "walking direction"),
            Param(name="distance", kind="float", unit="m", default=0.6, minimum=0.05, maximum=10.0,
                  description="distance to cover"),
        )),
        ActionSchema(name="turn", summary="Turn in place (left/counter-clockwise positive).", body="lower", dynamic=True, params=(
            Param(name="angle", kind="float", unit="rad", default=math.pi / 2, minimum=-math.pi, maximum=math.pi,
                  description="yaw change, left positive (REP 103)"),
        )),
        ActionSchema(name="jump", summary="Crouch, jump up (and optionally forward), land on both feet.", body="lower", dynamic=True, params=(
            Param(name="height", kind="float", unit="m", default=0.05, minimum=0.01, maximum=1.5,
                  description="rise of the centre of mass from take-off to the top of the flight"),
            Param(name="forward", kind="float", unit="m", default=0.0, minimum=0.0, maximum=2.0,
                  description="forward displacement"),
        )),
        ActionSchema(name="kick", summary="Stand on one foot and kick with the other, forward or to the side.",
                     body="lower", params=(
            _choice("leg", SIDES, "right", "the kicking leg"),
            _choice("direction", KICK_DIRECTIONS, "forward", "kick forward or out to the side"),
            Param(name="height", kind="float", unit="m", default=0.12, minimum=0.02, maximum=1.0,
                  description="height of the kicking sole above the ground at the top of the kick"),
            Param(name="duration", kind="float", unit="s", default=1.6, minimum=0.8, maximum=6.0,
                  description="time on one foot: lift, kick, put down"),
        )),
        ActionSchema(name="march", summary="March (step) in place: lift the feet in turn and put them back.",
                     body="lower", dynamic=True, params=(
            Param(name="count", kind="int", unit="count", default=4, minimum=1, maximum=20,
                  description="number of foot lifts, alternating, the right foot first"),
            Param(name="height", kind="float", unit="m", default=0.08, minimum=0.02, maximum=0.5,
                  description="how high each sole lifts"),
        )),
        ActionSchema(name="walk_arc", summary="Walk along a circle (a full circle by default) or an arc of it.",
                     body="lower", dynamic=True, params=(
            Param(name="radius", kind="float", unit="m", default=0.5, minimum=0.1, maximum=10.0,
                  description="radius of the circle, from its centre to the point between the feet"),
            _choice("side", SIDES, "left", "side of the circle's centre (left: counter-clockwise)"),
            Param(name="angle", kind="float", unit="rad", default=2 * math.pi, minimum=0.1, maximum=2 * math.pi,
                  description="how much of the circle to walk (the robot turns as much)"),
        )),
        ActionSchema(name="hop", summary="Hop on one foot, in place or forward (robots whose leg can push off alone).",
                     body="lower", dynamic=True, params=(
            _choice("foot", SIDES, "right", "the foot to hop on"),
            Param(name="count", kind="int", unit="count", default=2, minimum=1, maximum=10,
                  description="number of hops"),
            Param(name="height", kind="float", unit="m", default=0.025, minimum=0.01, maximum=0.3,
                  description="rise of the centre of mass during each flight"),
            Param(name="forward", kind="float", unit="m", default=0.0, minimum=0.0, maximum=1.0,
                  description="forward displacement of each hop (0: in place)"),
        )),
        ActionSchema(name="lunge", summary="Step out with one leg, lower the body, come back up and step back.",
                     body="lower", dynamic=True, params=(
            _choice("leg", SIDES, "right", "the leg that steps out"),
            _choice("direction", KICK_DIRECTIONS, "forward", "lunge forward or out to the side"),
            Param(name="length", kind="float", unit="m", default=None, minimum=0.05, maximum=1.0,
                  description="how far the foot steps out (default: the robot's longest step)"),
            Param(name="depth", kind="float", unit="m", default=0.1, minimum=0.02, maximum=0.6,
                  description="how far the centre of mass goes down"),
            Param(name="duration", kind="float", unit="s", default=1.2, minimum=0.6, maximum=6.0,
                  description="time to go down and up with the feet apart"),
        )),
        ActionSchema(name="stomp", summary="Lift one foot and put it down on its place, a number of times.",
                     body="lower", dynamic=True, params=(
            _choice("leg", SIDES, "right", "the stomping leg"),
            Param(name="count", kind="int", unit="count", default=2, minimum=1, maximum=10,
                  description="number of stomps"),
            Param(name="height", kind="float", unit="m", default=0.1, minimum=0.02, maximum=0.5,
                  description="how high the sole lifts"),
        )),
        ActionSchema(name="jog", summary="Jog in place or run forward: strides with a flight phase (robots whose legs can).",
                     body="lower", dynamic=True, params=(
            Param(name="count", kind="int", unit="count", default=6, minimum=1, maximum=20,
                  description="number of strides (flights)"),
            Param(name="forward", kind="float", unit="m", default=0.0, minimum=0.0, maximum=5.0,
                  description="distance covered (0: jog in place)"),
        )),
        # --- actions on scene objects, without a grasp (tasks/primitives/objects.py) ---
        ActionSchema(name="walk_to", summary="Walk to an object of the scene and stop facing it, within arm's reach.",
                     body="lower", dynamic=True, params=(
            _object("the object to walk to"),
            Param(name="carrying", kind="object", default=None,
                  description="an object a hand holds and carries along (\"with the cup\"); it must be held already"),
        )),
        ActionSchema(name="step_up", summary="Step up onto a walkable surface ahead (a box), up a flight of stairs or "
                     "up a slope, both feet on each tread.", body="lower", dynamic=True, params=(
            _object("the tread or box to step onto first (\"the stairs\": their first step)"),
            Param(name="count", kind="int", unit="count", default=None, minimum=1, maximum=50,
                  description="how many treads to climb (default: every walkable surface straight ahead)"),
        )),
        ActionSchema(name="step_down", summary="Walk down a slope or a flight of stairs ahead onto the floor, both feet "
                     "on each step (from where the robot stands on them).", body="lower", dynamic=True, params=(
            _object("the slope or the stairs to walk down (\"the stairs\": their first step)"),
            Param(name="count", kind="int", unit="count", default=None, minimum=1, maximum=50,
                  description="how many steps down (default: down to the floor)"),
        )),
        ActionSchema(name="sit_down", summary="Sit down on a seat of the scene behind the robot (a chair, a bench), "
                     "the feet staying where they are.", body="whole", params=(
            Param(name="object", kind="object", default=None,
                  description="the seat to sit on, as said (\"the chair\"; default: the scene's seat)"),
        )),
        ActionSchema(name="stand_up", summary="Stand up from the seat the robot sits on (after sit_down).",
                     body="whole", params=(
            Param(name="object", kind="object", default=None,
                  description="the seat it sits on (default: the one it sat down on)"),
        )),
        ActionSchema(name="lean_on", summary="Lean on a table ahead with both hands (the feet staying where they "
                     "are), then come back up.", body="whole", dynamic=True, params=(
            Param(name="object", kind="object", default=None,
                  description="the table to lean on, as said (\"the table\"; default: the scene's table)"),
        )),
        ActionSchema(name="kneel", summary="Kneel down on one knee on the floor (the other foot staying where it "
                     "stands), hold, then get up again.", body="whole", dynamic=True, params=(
            _choice("knee", ARMS, "right", "which knee goes down on the floor (both: refused, one knee at a time is "
                    "not planned yet)"),
        )),
        ActionSchema(name="look_at", summary="Turn the head towards an object of the scene (robots with a neck).",
                     body="upper", params=(
            _object("the object to look at"),
            Param(name="duration", kind="float", unit="s", default=2.5, minimum=1.0, maximum=30.0,
                  description="time to look, hold and look forward again"),
        )),
        ActionSchema(name="point_at", summary="Point at an object of the scene with a straight arm.", body="upper", params=(
            _object("the object to point at"),
            _choice("arm", SIDES, None, "which arm points (default: the one on the object's side)"),
            Param(name="duration", kind="float", unit="s", default=3.0, minimum=1.0, maximum=30.0,
                  description="time to point, hold and lower"),
        )),
        # --- actions that hold an object (tasks/primitives/grasp.py) ---
        ActionSchema(name="pick_up", summary="Pick up a movable object of the scene with one hand, lift it and hold it.",
                     body="upper", params=(
            _object("the object to pick up"),
            _choice("arm", ARMS, None, "which hand picks it up, or both (a box pressed between them) (default: the one "
                    "on the object's side)"),
            Param(name="height", kind="float", unit="m", default=0.1, minimum=0.02, maximum=0.3,
                  description="how high the object is lifted"),
        )),
        ActionSchema(name="put_down", summary="Put a held object down (where it was picked up, or on another object) and let go of it.",
                     body="upper", params=(
            _object("the held object to put down"),
            _choice("arm", ARMS, None, "which hand holds it, or both (a box held with both hands) (default: the hand "
                    "that holds it)"),
            Param(name="on", kind="object", default=None,
                  description="where to put it: on top of this object (default: back where it was)"),
            _choice("direction", DIRECTIONS, None, "put it this way (seen from the robot) from where it was, or from "
                    "its place on `on`; backward without a distance: back where it was (\"put it back\")"),
            Param(name="distance", kind="float", unit="m", default=None, minimum=0.02, maximum=1.0,
                  description="how far that way (default 0.2 m with a direction)"),
        )),
        ActionSchema(name="touch_object", summary="Touch an object of the scene with one hand (a planned contact).",
                     body="upper", params=(
            _object("the object to touch"),
            _choice("hand", SIDES, None, "which hand touches (default: the one on the object's side)"),
            Param(name="duration", kind="float", unit="s", default=3.0, minimum=1.0, maximum=30.0,
                  description="time to reach out, touch, hold and come back"),
        )),
        # --- handing over and pushing (tasks/primitives/handover.py, push.py) ---
        ActionSchema(name="hand_over", summary="Hold a picked-up object out in front of the robot at chest height, "
                     "for a person to take it (picks it up first when no hand holds it).", body="upper", params=(
            _object("the object to hand over"),
            _choice("arm", SIDES, None, "which hand holds it (default: the one that picked it up)"),
        )),
        ActionSchema(name="push", summary="Push a movable box or cylinder forward by a distance on what it stands on, "
                     "with one hand on its near face (it slides with its friction).",
                     body="upper", params=(
            _object("the object to push"),
            Param(name="distance", kind="float", unit="m", default=0.1, minimum=0.02, maximum=0.3,
                  description="how far the object is pushed forward (along the robot's heading)"),
            _choice("arm", SIDES, None, "which hand pushes (default: the one on the object's side)"),
            _choice("direction", DIRECTIONS, "forward", "which way (seen from the robot): forward only; the others are "
                    "refused (pick the object up and put it down there)"),
        )),
    )
}


def get_action(name: str) -> ActionSchema:
    """Registry entry of ``name`` (UnknownAction naming close matches otherwise)."""
    try:
        return REGISTRY[name]
    except KeyError:
        raise UnknownAction(name, sorted(REGISTRY)) from None


def actions_json_schema() -> dict[str, Any]:
    """JSON schema of an action list ``{"actions": [...]}``: the same for every parser backend."""
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": "wbmp action plan",
        "type": "object",
        "properties": {
            "actions": {"type": "array", "minItems": 1, "maxItems": MAX_ACTIONS,
                        "items": {"oneOf": [s.to_json_schema() for s in REGISTRY.values()]}},
        },
        "required": ["actions"],
    }
