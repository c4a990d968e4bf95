"""Corrections in words: "slower", "twice", 再低一点 change the last motion's actions.

A correction never parses a new sentence: it takes the actions the last motion was planned
from (each :class:`tasks.actions.Action` with every parameter it used, the robot's fitted
defaults included) and changes parameters by a fixed rule, within each parameter's range of
the registry. :func:`apply` returns the new actions and one :class:`Change` per parameter
changed (the page shows "squat duration 2 s -> 3 s").

The words (English and Chinese), after lower-casing and dropping fillers ("a bit", "please",
一点, 再):

========================  ============================================================
slower / 慢               every ``duration`` x 1.5, and the robot's ``step_duration`` x 1.5 when an
                          action steps (:data:`PACED`: walking, stepping, turning, marching)
faster / 快               the inverse of "slower"
twice / 两次              every ``repeat`` (or ``count``) = 2; actions with neither: the sequence twice
lower / 低                squat and lunge ``depth`` x 1.3 (the body goes lower); kick, jump, march,
                          stomp, hop ``height`` x 0.75; bow ``angle`` x 1.3
higher / 高               the inverse of "lower"
bigger / 大               every size (depth, angle, radius, amount, length, distance, height) x 1.3
smaller / 小              every size / 1.3
with the left hand / 用左手   every ``arm`` or ``hand`` = left (likewise right; "both hands" for ``arm``)
again / 再来一次          the same actions (answered from the motion cache)
undo / 撤销               back to the motion before the last correction (no plan)
========================  ============================================================

A word that changes nothing (faster when every duration is at its minimum, "lower" on a wave)
is refused with a one-line message naming the actions and what the word acts on.
"""

from __future__ import annotations

import re
import unicodedata
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from tasks import REGISTRY, Action
from wbmp.errors import CorrectionError

SLOWER = 1.5  # duration factor of "slower" (its inverse for "faster")
SIZE = 1.3  # size factor of "bigger" (its inverse for "smaller"), and of "lower"/"higher"
HEIGHT = 0.75  # height factor of "lower" on a lifted foot or a jump (its inverse for "higher")

SIZE_PARAMS = ("depth", "angle", "radius", "amount", "length", "distance", "height")
# actions whose timing is the robot profile's step_duration (one swing of a foot), not a parameter:
# "slower" on them changes the pace of the robot the session plans with
PACED = ("step", "walk", "walk_to", "turn", "walk_arc", "march", "lunge", "stomp")
HAND_PARAMS = ("arm", "hand")

# the words of each correction, matched on the whole normalized text (after fillers are dropped)
WORDS: dict[str, tuple[str, ...]] = {
    "slower": ("slower", "more slowly", "slowly", "slow down", "slow", "慢", "慢些", "更慢", "放慢"),
    "faster": ("faster", "more quickly", "quicker", "quickly", "speed up", "fast", "快", "快些", "更快", "加快"),
    "twice": ("twice", "two times", "2 times", "do it twice", "两次", "两遍", "做两次", "来两次"),
    "lower": ("lower", "go lower", "deeper", "低", "低些", "更低", "深", "深些", "蹲低", "蹲深"),
    "higher": ("higher", "go higher", "shallower", "高", "高些", "更高", "浅", "浅些"),
    "bigger": ("bigger", "larger", "wider", "more", "大", "大些", "更大", "幅度大"),
    "smaller": ("smaller", "less", "narrower", "小", "小些", "更小", "幅度小"),
    "left": ("with the left hand", "with your left hand", "with the left arm", "with your left arm",
             "left hand", "left arm", "use the left hand", "用左手", "换左手", "左手"),
    "right": ("with the right hand", "with your right hand", "with the right arm", "with your right arm",
              "right hand", "right arm", "use the right hand", "用右手", "换右手", "右手"),
    "both": ("with both hands", "with both arms", "both hands", "both arms", "用双手", "双手", "两只手"),
    "again": ("again", "once more", "one more time", "repeat", "do it again",
              "再来一次", "再做一次", "再来", "重复"),
    "undo": ("undo", "go back", "back", "cancel that", "撤销", "撤回", "取消", "回到上一个"),
}
FILLERS = ("a little bit", "a little", "a bit", "a lot", "much", "even", "please", "now", "just", "and", "it",
           "一点儿", "一点", "一些", "点", "再", "请", "稍微", "还要", "还", "些")

STEP_RANGE = (0.1, 5.0)  # [s] a profile's step_duration (robots.profile.NUMBERS)
_LOOKUP = {phrase: kind for kind, phrases in WORDS.items() for phrase in phrases}
_SPLIT = re.compile("\\s*(?:,|\uff0c|\u3001|;|\uff1b|\\band\\b|然后再|并且|和)\\s*")
_THEN = re.compile(r"^\s*(?:and\s+)?(?:then|after that|afterwards|next)\b[\s,]*"
                   r"|^\s*(?:然后|接着|之后|再然后)[\s\uff0c,]*", re.IGNORECASE)


@dataclass(frozen=True)
class Change:
    """One parameter changed by a correction."""

    action: int  # 1-based index of the action
    name: str  # the action's name
    param: str
    old: Any
    new: Any
    unit: str

    def describe(self) -> str:
        """``2. squat duration 2 s -> 3 s (x1.5)``."""
        def show(v: Any) -> str:
            if isinstance(v, float):
                return f"{v:.3g}" + (f" {self.unit}" if self.unit and self.unit != "count" else "")
            return str(v)

        where = f"{self.action}. {self.name}" if self.action else self.name
        line = f"{where} {self.param} {show(self.old)} -> {show(self.new)}"
        if isinstance(self.old, float) and isinstance(self.new, float) and self.old:
            line += f" (x{self.new / self.old:.3g})"
        return line

    def to_dict(self) -> dict[str, Any]:
        """JSON form for the page."""
        return {"action": self.action, "name": self.name, "param": self.param, "old": self.old, "new": self.new,
                "unit": self.unit, "text": self.describe()}


def normalize(text: str) -> str:
    """Lower case, NFKC, no trailing punctuation, single spaces."""
    text = unicodedata.normalize("NFKC", text).lower().strip()
    text = re.sub("[.!?\u3002\uff01\uff1f~\uff5e]+$", "", text).strip()
    return re.sub(r"\s+", " ", text)


def _kind(part: str) -> str | None:
    part = part.strip()
    if part in _LOOKUP:
        return _LOOKUP[part]
    for filler in sorted(FILLERS, key=len, reverse=True):
        if filler.isascii():
            part = re.sub(rf"\b{re.escape(filler)}\b", " ", part)
        else:
            part = part.replace(filler, " ")
    part = re.sub(r"\s+", " ", part).strip()
    if part in _LOOKUP:
        return _LOOKUP[part]
    compact = part.replace(" ", "")
    return _LOOKUP.get(compact) if compact and not compact.isascii() else None


def parse_correction(text: str) -> tuple[str, ...] | None:
    """The corrections a text asks for, in order, or None when it is not made only of corrections
    (then it is a new sentence). ``"slower and lower"`` -> ``("slower", "lower")``."""
    norm = normalize(text)
    if not norm:
        return None
    whole = _kind(norm)
    if whole is not None:
        return (whole,)
    kinds = []
    for part in _SPLIT.split(norm):
        if not part.strip():
            continue
        kind = _kind(part)
        if kind is None:
            return None
        kinds.append(kind)
    return tuple(kinds) or None


def continuation(text: str) -> str | None:
    """The sentence after a leading "then" / 然后 (a continuation of the last motion), or None."""
    m = _THEN.match(text)
    if m is None:
        return None
    rest = text[m.end():].strip()
    return rest or None


@dataclass(frozen=True)
class Actions:
    """The actions of a motion as a correction sees them: every parameter used, and which ones
    the user stated (a stated value beyond the robot's limit is refused, a default is fitted)."""

    actions: tuple[Action, ...]
    given: tuple[frozenset[str], ...]
    step_duration: float | None = None  # the robot's pace [s] (None: not known, never changed)

    def stated(self) -> tuple[Action, ...]:
        """Actions holding only the stated parameters (the others come back as the registry's
        defaults, fitted to the robot again when planned)."""
        return tuple(Action(name=a.name, params={k: v for k, v in a.params.items() if k in g},
                            overlay=a.overlay) for a, g in zip(self.actions, self.given, strict=True))


def _scale(factor: float, params: Sequence[str], only: Callable[[str], bool] = lambda _: True):
    def rule(action: Action) -> dict[str, Any]:
        out = {}
        for p in params:
            if p in action.params and only(action.name):
                value = action.params.get(p)
                if isinstance(value, (int, float)) and not isinstance(value, bool):
                    out[p] = float(value) * factor
        return out
    return rule


_LOWER_DEPTH = ("squat", "lunge")
_LIFTS = ("kick", "jump", "march", "stomp", "hop", "pick_up")


def _lower(factor_depth: float, factor_height: float):
    def rule(action: Action) -> dict[str, Any]:
        out: dict[str, Any] = {}
        if action.name in _LOWER_DEPTH:
            out.update(_scale(factor_depth, ("depth",))(action))
        if action.name in _LIFTS:
            out.update(_scale(factor_height, ("height",))(action))
        if action.name == "bow":
            out.update(_scale(factor_depth, ("angle",))(action))
        return out
    return rule


def _count(action: Action) -> dict[str, Any]:
    for p in ("repeat", "count"):
        if p in action.params and action.params.get(p) is not None:
            return {p: 2}
    return {}


def _hand(side: str):
    def rule(action: Action) -> dict[str, Any]:
        schema = REGISTRY[action.name]
        for p in HAND_PARAMS:
            names = [q.name for q in schema.params]
            if p in names and side in schema.param(p).choices:
                return {p: side}
        return {}
    return rule


_DURATION = "a duration or the pace of a step"

RULES: dict[str, tuple[Callable[[Action], dict[str, Any]], str]] = {
    "slower": (_scale(SLOWER, ("duration",)), _DURATION),
    "faster": (_scale(1 / SLOWER, ("duration",)), _DURATION),
    "twice": (_count, "a count"),
    "lower": (_lower(SIZE, HEIGHT), "a squat or lunge depth, a bow's angle or a lifted foot's height"),
    "higher": (_lower(1 / SIZE, 1 / HEIGHT), "a squat or lunge depth, a bow's angle or a lifted foot's height"),
    "bigger": (_scale(SIZE, SIZE_PARAMS), "a size (depth, angle, radius, amount, length, distance, height)"),
    "smaller": (_scale(1 / SIZE, SIZE_PARAMS), "a size (depth, angle, radius, amount, length, distance, height)"),
    "left": (_hand("left"), "a hand or arm"),
    "right": (_hand("right"), "a hand or arm"),
    "both": (_hand("both"), "both arms"),
}


def _clamped(action: Action, param: str, value: Any) -> Any:
    spec = REGISTRY[action.name].param(param)
    if spec.kind == "int":
        value = int(round(value))
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        if spec.minimum is not None:
            value = max(value, spec.minimum)
        if spec.maximum is not None:
            value = min(value, spec.maximum)
        if spec.kind == "float":
            value = float(value)
    return value


def apply(kinds: Sequence[str], current: Actions) -> tuple[Actions, list[Change]]:
    """The actions after the corrections ``kinds`` (from :func:`parse_correction`; "again" and
    "undo" are the session's business and change nothing here) and the changes made.

    Raises:
        CorrectionError: a correction that changes no parameter of these actions.
    """
    actions = list(current.actions)
    given = [set(g) for g in current.given]
    step = current.step_duration
    changes: list[Change] = []
    for kind in kinds:
        if kind in ("again", "undo"):
            continue
        if kind == "twice" and not any(_count(a) for a in actions):
            if 2 * len(actions) > _max_actions():
                raise CorrectionError(f"'twice' would make {2 * len(actions)} actions; wbmp plans at most "
                                      f"{_max_actions()} at a time")
            n = len(actions)
            actions += actions
            given += [set(g) for g in given]
            changes.append(Change(action=n + 1, name="sequence", param="copies", old=1, new=2, unit="count"))
            continue
        rule, what = RULES[kind]
        changed = False
        for i, action in enumerate(actions):
            new = {p: _clamped(action, p, v) for p, v in rule(action).items()}
            new = {p: v for p, v in new.items() if v != action.params.get(p)}
            if not new:
                continue
            changed = True
            for p, v in new.items():
                changes.append(Change(action=i + 1, name=action.name, param=p, old=action.params.get(p), new=v,
                                      unit=REGISTRY[action.name].param(p).unit))
            actions[i] = Action(name=action.name, params={**action.params, **new}, overlay=action.overlay)
            given[i] |= set(new)
        if kind in ("slower", "faster") and step is not None and any(a.name in PACED for a in actions):
            lo, hi = STEP_RANGE
            paced = min(max(step * (SLOWER if kind == "slower" else 1 / SLOWER), lo), hi)
            if paced != step:
                changed = True
                changes.append(Change(action=0, name="robot", param="step_duration", old=step, new=paced, unit="s"))
                step = paced
        if not changed:
            names = ", ".join(dict.fromkeys(a.name for a in actions))
            raise CorrectionError(f"'{kind}' changes {what}, and none of the last motion's actions ({names}) has "
                                  "one it can change (or each is already at its limit): say a new sentence instead")
    return Actions(actions=tuple(actions), given=tuple(frozenset(g) for g in given), step_duration=step), changes


def _max_actions() -> int:
    from tasks import MAX_ACTIONS

    return MAX_ACTIONS
