"""Grounding: a spoken reference to an object (``the red box on the table``, 桌子上的红色盒子)
resolved to one :class:`~tasks.scene.SceneObject` of a scene.

A reference is ``[determiner] [modifiers] noun [relation landmark]`` in English, or
``[那个/这个] [landmark relation 的] [modifiers] noun`` in Chinese:

- the *noun* is an object's name or alias, or words of one (``box`` names ``red box``,
  ``small_box`` and ``box a``; 盒子 names 红色盒子); names compare case-blind, ``_`` and ``-`` read
  as spaces;
- a *colour* word (English or Chinese, :data:`COLOURS`) keeps the objects whose colour is nearest
  (RGB distance) to that colour among the named colours;
- a *size* word (``big``, ``small``, 大, 小) takes the largest or smallest (volume) of the candidates;
- a *relation* (:data:`RELATIONS`) to a landmark (itself a reference) keeps the objects in that
  relation to it, computed from the poses in the robot's initial frame (the scene's world: the
  robot starts at the origin facing +x, y to its left): ``on`` (resting on its top face), ``near``
  (within :data:`NEAR_DISTANCE`), ``left of`` / ``right of`` (centre beyond the landmark's side),
  ``in front of`` (between the robot's start and the landmark) and ``behind`` (beyond it).

:func:`ground` returns the one object left, or raises :class:`GroundingError` with one line: the
objects of the scene for an unknown reference, the candidates for an ambiguous one.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from tasks.actions import MAX_REFERENCE_LENGTH
from tasks.exceptions import GroundingError
from tasks.scene import Scene, SceneObject, extent

NEAR_DISTANCE = 0.5  # [m] gap between the bounding boxes of two objects "near" each other
ON_TOLERANCE = 0.03  # [m] gap between an object's bottom and the landmark's top for "on"

#: Colour names (English, Chinese) -> RGB in [0, 1].
PALETTE: dict[str, tuple[float, float, float]] = {
    "red": (0.8, 0.1, 0.1), "green": (0.15, 0.6, 0.15), "blue": (0.1, 0.25, 0.8),
    "yellow": (0.92, 0.85, 0.1), "orange": (0.95, 0.5, 0.05), "purple": (0.5, 0.15, 0.6),
    "pink": (1.0, 0.6, 0.7), "brown": (0.55, 0.35, 0.2), "black": (0.05, 0.05, 0.05),
    "white": (0.95, 0.95, 0.95), "grey": (0.5, 0.5, 0.5),
}
COLOURS: dict[str, str] = {
    **{c: c for c in PALETTE}, "gray": "grey", "violet": "purple",
    "红色": "red", "红": "red", "绿色": "green", "绿": "green", "蓝色": "blue", "蓝": "blue",
    "黄色": "yellow", "黄": "yellow", "橙色": "orange", "橘色": "orange", "橙": "orange",
    "紫色": "purple", "紫": "purple", "粉红色": "pink", "粉色": "pink", "粉": "pink",
    "棕色": "brown", "褐色": "brown", "咖啡色": "brown", "棕": "brown", "黑色": "black", "黑": "black",
    "白色": "white", "白": "white", "灰色": "grey", "灰": "grey",
}
SIZES: dict[str, str] = {
    "big": "big", "bigger": "big", "biggest": "big", "large": "big", "larger": "big", "largest": "big",
    "small": "small", "smaller": "small", "smallest": "small", "little": "small", "tiny": "small",
    "大": "big", "小": "small", "大的": "big", "小的": "small",
}
#: Relation words -> relation (English: between the noun and the landmark; Chinese: after the landmark).
RELATIONS: dict[str, str] = {
    "on top of": "on", "on": "on", "upon": "on", "near": "near", "next to": "near", "beside": "near", "by": "near",
    "close to": "near", "to the left of": "left of", "on the left of": "left of", "left of": "left of",
    "to the right of": "right of", "on the right of": "right of", "right of": "right of",
    "in front of": "in front of", "behind": "behind",
}
ZH_RELATIONS: dict[str, str] = {
    "上面": "on", "上边": "on", "上": "on", "旁边": "near", "附近": "near", "边上": "near", "旁": "near",
    "左边": "left of", "左侧": "left of", "左面": "left of", "右边": "right of", "右侧": "right of",
    "右面": "right of", "前面": "in front of", "前边": "in front of", "前方": "in front of",
    "后面": "behind", "后边": "behind", "后方": "behind",
}
LEADING = ("over to", "up to", "towards", "toward", "to", "at", "over", "into", "the", "that", "this", "a", "an",
           "那个", "这个", "那只", "这只", "那张", "这张", "一个", "那", "这", "到", "向", "往", "朝", "着", "去")


def _norm(text: str) -> str:
    return " ".join(text.lower().replace("_", " ").replace("-", " ").split())


def _is_cjk(ch: str) -> bool:
    return "\u3400" <= ch <= "\u9fff"


def strip_reference(text: str) -> str:
    """A reference without the prepositions in front (``to the table`` -> ``the table``, 到桌子 -> 桌子)."""
    out = _norm(text)
    changed = True
    while changed:
        changed = False
        for word in ("over to", "up to", "towards", "toward", "to", "at", "over", "into", "到", "向", "往", "朝", "着", "去"):
            if out.startswith(word) and (_is_cjk(word[0]) or out[len(word):len(word) + 1] in ("", " ")):
                if out[len(word):].strip():
                    out, changed = out[len(word):].strip(), True
    return out


TRAILING = ("那里", "那边", "这里", "这边", "跟前", "面前", "旁边", "前面", "附近", "边上")  # 走到桌子旁边: the table


def _bare(text: str) -> str:
    """Without leading prepositions and determiners (and a trailing 那里, 旁边 ...)."""
    out = _norm(text)
    for word in TRAILING:
        if out.endswith(word) and out[: -len(word)].strip() and "的" not in out:
            out = out[: -len(word)].strip()
    changed = True
    while changed:
        changed = False
        for word in LEADING:
            if out.startswith(word) and (_is_cjk(word[0]) or out[len(word):len(word) + 1] in ("", " ")):
                rest = out[len(word):].strip()
                if rest:
                    out, changed = rest, True
    return out


def object_names(obj: SceneObject) -> tuple[str, ...]:
    """The name and aliases, normalized (lower case, ``_``/``-`` as spaces)."""
    return tuple(_norm(n) for n in obj.names)


def names_object(obj: SceneObject, noun: str) -> bool:
    """``noun`` is the object's name or alias, or words of one (``box`` for ``red box`` and
    ``box a``), or the ending of a Chinese one (盒子 for 红色盒子)."""
    for name in object_names(obj):
        if name == noun or f" {noun} " in f" {name} " or (_is_cjk(noun[0]) and name.endswith(noun)):
            return True
    return False


def colour_name(obj: SceneObject) -> str:
    """The named colour (:data:`PALETTE`) nearest to the object's RGB."""
    rgb = obj.colour[:3]
    return min(PALETTE, key=lambda c: math.dist(PALETTE[c], rgb))


def volume(obj: SceneObject) -> float:
    """Volume of the object's shape [m^3] (a mesh: of its bounding box)."""
    if obj.shape == "sphere":
        return 4.0 / 3.0 * math.pi * obj.size[0] ** 3
    if obj.shape == "cylinder":
        return math.pi * obj.size[0] ** 2 * obj.size[1]
    return obj.size[0] * obj.size[1] * obj.size[2]


def gap(a: SceneObject, b: SceneObject) -> float:
    """Distance between the world bounding boxes of two objects [m] (0 when they overlap)."""
    (alo, ahi), (blo, bhi) = extent(a), extent(b)
    return math.sqrt(sum(max(blo[i] - ahi[i], alo[i] - bhi[i], 0.0) ** 2 for i in range(3)))


def in_relation(obj: SceneObject, relation: str, landmark: SceneObject) -> bool:
    """``obj`` is ``relation`` (``on``, ``near``, ``left of``, ...) the landmark, in the robot's
    initial frame (x forward, y left)."""
    lo, _ = extent(obj)
    llo, lhi = extent(landmark)
    x, y = obj.position[0], obj.position[1]
    if relation == "on":
        return abs(lo[2] - lhi[2]) <= ON_TOLERANCE and llo[0] <= x <= lhi[0] and llo[1] <= y <= lhi[1]
    if relation == "near":
        return gap(obj, landmark) <= NEAR_DISTANCE
    if relation == "left of":
        return y > lhi[1]
    if relation == "right of":
        return y < llo[1]
    if relation == "in front of":
        return x < llo[0]
    if relation == "behind":
        return x > lhi[0]
    raise ValueError(f"unknown relation {relation!r}")  # pragma: no cover - RELATIONS lists them


@dataclass(frozen=True, slots=True, kw_only=True)
class Grounded:
    """A reference bound to its object: the value of an action's ``object`` parameter once
    :func:`tasks.compose.compile_actions` has resolved it against the spec's scene.

    Attributes:
        reference: The reference as said (``the red box``); what the action's JSON shows.
        obj: The object it names.
        scene: The scene (the primitives keep clear of its other objects).
        start: Where the robot stands when the action starts (a
            :class:`tasks.primitives.geometry.Stance`), or None for the standing stance.
    """

    reference: str
    obj: SceneObject
    scene: Scene
    start: Any = None

    def __str__(self) -> str:
        return self.reference


@dataclass(frozen=True, slots=True)
class _Head:
    noun: str
    colours: tuple[str, ...]
    size: str | None


def _listing(scene: Scene) -> str:
    parts = []
    for o in scene.objects:
        parts.append(o.name + (f" ({', '.join(o.aliases)})" if o.aliases else ""))
    return ", ".join(parts) if parts else "none"


def _describe(obj: SceneObject) -> str:
    x, y, z = obj.position
    return f"{obj.name} ({colour_name(obj)}, at x {x:.2f}, y {y:.2f}, z {z:.2f} m)"


def _modifiers(text: str) -> tuple[list[str], str | None] | None:
    """Colour and size words of a prefix (None if a word is neither)."""
    colours: list[str] = []
    size: str | None = None
    rest = text.replace("的", " ").strip()
    words = rest.split()
    for word in words:
        i = 0
        while i < len(word):
            for n in range(len(word) - i, 0, -1):  # longest known word first (粉红色 before 粉)
                piece = word[i:i + n]
                if piece in COLOURS:
                    colours.append(COLOURS[piece])
                    break
                if piece in SIZES:
                    if size is not None and size != SIZES[piece]:
                        return None
                    size = SIZES[piece]
                    break
            else:
                return None
            i += n
    return colours, size


def _split_points(text: str) -> Iterable[int]:
    for i in range(len(text)):
        if i == 0 or text[i - 1] == " " or (_is_cjk(text[i]) and _is_cjk(text[i - 1])):
            if text[i] != " ":
                yield i


def _head(text: str, scene: Scene, reference: str) -> _Head:
    """Noun and modifiers of a phrase without relation: the longest ending that names an object."""
    text = _bare(text)
    for i in _split_points(text):
        noun = text[i:].strip()
        if not any(names_object(o, noun) for o in scene.objects):
            continue
        mods = _modifiers(text[:i])
        if mods is not None:
            return _Head(noun, tuple(mods[0]), mods[1])
    raise GroundingError(f'no object in the scene is called "{reference}"; its objects are {_listing(scene)}', reference)


def _split_relation(text: str) -> tuple[str, str, str] | None:
    """(head, relation, landmark) of a reference, or None without a relation."""
    if "的" in text:  # 桌子上的红色盒子: landmark + relation word, then the head
        before, _, after = text.rpartition("的")
        for word in sorted(ZH_RELATIONS, key=len, reverse=True):
            if before.endswith(word) and before[: -len(word)].strip() and after.strip():
                return after.strip(), ZH_RELATIONS[word], before[: -len(word)].strip()
    padded = f" {text} "
    best: tuple[int, str] | None = None
    for phrase in RELATIONS:
        i = padded.find(f" {phrase} ", 1)
        if i > 0 and (best is None or i < best[0] or (i == best[0] and len(phrase) > len(best[1]))):
            best = (i, phrase)
    if best is None:
        return None
    i, phrase = best
    head, landmark = padded[:i].strip(), padded[i + len(phrase) + 1:].strip()
    if not head or not landmark:
        return None
    return head, RELATIONS[phrase], landmark


def ground(reference: Any, scene: Scene | None, *, action: str = "") -> SceneObject:
    """The object of ``scene`` that ``reference`` names.

    Args:
        reference: What the sentence says (``the red box``, ``that table``, 桌子上的红色盒子).
        scene: The scene; None raises (a sentence with an object needs ``--scene``).
        action: The action name, for the message when there is no scene.

    Raises:
        GroundingError: no scene, an empty or too long reference, no object with that name
            (the message lists the scene's objects), none left after the colour, size and relation
            words, or several (the message names them).
    """
    if not isinstance(reference, str) or not reference.strip() or len(reference) > MAX_REFERENCE_LENGTH:
        raise GroundingError(f"an object reference must be a non-empty text of at most {MAX_REFERENCE_LENGTH} "
                             f"characters, got {reference!r:.60}", str(reference)[:60])
    said = strip_reference(reference)
    if scene is None:
        who = f"{action} " if action else ""
        raise GroundingError(f'{who}"{said}" refers to an object, but there is no scene: give one with --scene FILE '
                             "(docs/scenes.md)", said)
    if not scene.objects:
        raise GroundingError(f'no object in the scene is called "{said}"; the scene has no objects', said)
    return _resolve(_bare(said), scene, said)


def _resolve(text: str, scene: Scene, said: str) -> SceneObject:
    split = _split_relation(text)
    relation = landmark = None
    head_text = text
    if split is not None:
        head_text, relation, landmark_text = split
        landmark = _resolve(_bare(landmark_text), scene, landmark_text)
    head = _head(head_text, scene, said if split is None else head_text)
    candidates = [o for o in scene.objects if names_object(o, head.noun)]
    for colour in head.colours:
        kept = [o for o in candidates if colour_name(o) == colour]
        if not kept:
            seen = ", ".join(f"{o.name} ({colour_name(o)})" for o in candidates)
            raise GroundingError(f'no {colour} {head.noun} in the scene for "{said}": {seen}', said)
        candidates = kept
    if relation is not None and landmark is not None:
        kept = [o for o in candidates if o is not landmark and in_relation(o, relation, landmark)]
        if not kept:
            seen = ", ".join(_describe(o) for o in candidates if o is not landmark) or "none"
            raise GroundingError(f'no {head.noun} is {relation} the {landmark.name} for "{said}"; '
                                 f"the {head.noun} candidates are {seen}", said)
        candidates = kept
    if head.size is not None and len(candidates) > 1:
        pick = max if head.size == "big" else min
        best = pick(candidates, key=volume)
        if sum(1 for o in candidates if math.isclose(volume(o), volume(best), rel_tol=1e-6)) == 1:
            candidates = [best]
    if len(candidates) > 1:
        names = [o.name for o in candidates]
        raise GroundingError(f'"{said}" could be {" or ".join(_describe(o) for o in candidates)}: say which one '
                             "(by its name, colour, size, or where it is)", said, names)
    return candidates[0]


__all__ = [
    "COLOURS",
    "NEAR_DISTANCE",
    "ON_TOLERANCE",
    "PALETTE",
    "RELATIONS",
    "SIZES",
    "ZH_RELATIONS",
    "Grounded",
    "GroundingError",
    "colour_name",
    "gap",
    "ground",
    "in_relation",
    "names_object",
    "object_names",
    "strip_reference",
    "volume",
]
