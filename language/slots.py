"""Slots of a clause to an action's parameters (split from :mod:`language.rules`, issue 31).

:func:`read_slots` reads the items of one clause (side, direction, turning sign, count,
magnitudes with units, adverbs, object references) and maps them to the parameters of the
action as its vocabulary entry says; :class:`_SlotReader` does it in steps, one method per kind
of slot, each noting what its words did for ``wbmp parse``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

from language.exceptions import AmbiguousInstruction, InvalidParameter
from language.lexicon import (
    ADV,
    AGAIN,
    BODY,
    CARRIED,
    CLASSIFIER,
    DEST,
    DIR,
    IN_PLACE,
    LR,
    NUM,
    REF,
    ROT,
    SIDE,
    TIMES,
    TRIGGER,
    UNIT,
    ActionWords,
    Item,
    Lexicon,
)
from language.objects import head_noun
from language.references import TREAD_CLASSIFIERS
from tasks import MAX_REPEAT, REGISTRY, ActionSchema

MAX_COPIES = MAX_REPEAT  # "jump 3 times" repeats an action without a count parameter at most this often
OPTIONAL_DETAIL = {"mood": "mood or style", "context": "context (changes nothing)",
                   "normal_speed": "normal speed (the default)"}


def fmt(schema_name: str, param: str, value: Any) -> str:
    """``param=value unit`` for word notes (``duration=4 s``, ``arm=left``)."""
    unit = REGISTRY[schema_name].param(param).unit
    text = f"{value:.4g}" if isinstance(value, float) else str(value)
    return f"{param}={text}" + (f" {unit}" if unit and unit != "count" else "")


def read_slots(name: str, items: Sequence[Item], where: str, lx: Lexicon, normalized: str,
               note: Callable[..., None] | None = None) -> tuple[dict[str, Any], int, dict[str, str]]:
    """Parameters stated by the items of a clause (whose text is ``where``), how many copies of
    the action it asks for, and the words of each parameter.

    ``note(item, role, detail)`` is told what each item did (for ``wbmp parse``).
    """
    r = _SlotReader(name, lx.actions[name], REGISTRY[name], where, lx, normalized, note or (lambda *_: None))
    r.read(items)
    r.side()
    direction = r.direction()
    r.magnitudes(direction)
    r.sign()
    copies = r.count()
    return r.params, copies, r.sources


@dataclass(slots=True)
class _SlotReader:
    name: str
    aw: ActionWords
    schema: ActionSchema
    where: str
    lx: Lexicon
    normalized: str
    note: Callable[..., None]
    sides: list[tuple[str, Item]] = field(default_factory=list)
    directions: list[tuple[str, Item]] = field(default_factory=list)
    signs: list[tuple[int, Item]] = field(default_factory=list)
    quantities: dict[str, tuple[float, Item]] = field(default_factory=dict)
    quantity_items: dict[str, tuple[Item, Item]] = field(default_factory=dict)  # quantity -> (number, unit)
    counts: list[tuple[Any, Item]] = field(default_factory=list)
    adverbs: list[Item] = field(default_factory=list)
    adverb_values: dict[str, tuple[float, Item]] = field(default_factory=dict)
    plural: Item | None = None
    params: dict[str, Any] = field(default_factory=dict)
    sources: dict[str, str] = field(default_factory=dict)  # parameter -> the words that set it

    def misfit(self, it: Item, extra: str = "") -> InvalidParameter:
        return InvalidParameter(f'"{it.text}" does not fit {self.name} in "{self.where}"{extra}')

    def bare_left_right(self, it: Item) -> None:
        mode = self.aw.bare_left_right
        if mode == "side":
            self.sides.append((it.value, it))
        elif mode == "direction":
            self.directions.append((it.value, it))
        elif mode == "sign":
            self.signs.append((1 if it.value == "left" else -1, it))
        else:
            raise self.misfit(it)

    # -- reading -------------------------------------------------------------------------
    def read(self, items: Sequence[Item]) -> None:
        """Sort the items into the slot lists (numbers first, with their units or ``times``)."""
        consumed: set[int] = set()
        for i, it in enumerate(items):
            if i in consumed or it.kind in (TRIGGER, AGAIN, CLASSIFIER, IN_PLACE):
                continue
            nxt_i = _next_index(items, i)
            nxt = items[nxt_i] if nxt_i < len(items) else None
            if it.kind == NUM:
                if self.number(it, nxt, items, nxt_i):
                    consumed.add(nxt_i)
            elif it.kind == TIMES:
                if nxt is None or nxt.kind != NUM or nxt_i != i + 1:
                    raise InvalidParameter(f'"{it.text}" in "{self.where}" needs a number, e.g. "3 {it.text}"')
                self.counts.append((nxt.value, nxt))  # "x3"
                self.note(it, "count", "times")
                consumed.add(nxt_i)
            elif it.kind == UNIT:
                raise InvalidParameter(f'"{it.text}" in "{self.where}" needs a number in front, e.g. "30 {it.text}"')
            elif it.kind == LR:
                if nxt is not None and nxt.kind == BODY and nxt_i == i + 1 and self.aw.side is not None:
                    self.sides.append((it.value, it))  # "left hand", "左手"
                else:
                    self.bare_left_right(it)
            else:
                self.word(it)

    def number(self, it: Item, nxt: Item | None, items: Sequence[Item], nxt_i: int) -> bool:
        """A number: with a unit, ``times``, an action word (``3 squats``) or a body word; True
        if it consumed the item after it."""
        if nxt is not None and nxt.kind == UNIT:
            _add_quantity(self.quantities, self.lx, it, nxt, self.where, self.normalized)
            self.quantity_items[self.lx.units[nxt.value].quantity] = (it, nxt)
            self.note(nxt, "unit", nxt.value)
            return True
        if nxt is not None and nxt.kind == TIMES:
            self.counts.append((it.value, it))
            if (nxt.start, nxt.end) != (it.start, it.end):  # "twice" is one word
                self.note(nxt, "count", "times")
            return True
        if nxt is not None and _trigger_follows(items, nxt_i):
            self.counts.append((it.value, it))  # "3 squats", "三步", "two big steps"
        elif nxt is not None and nxt.kind == REF and items[nxt_i - 1].kind == CLASSIFIER \
                and items[nxt_i - 1].text in TREAD_CLASSIFIERS:
            self.counts.append((it.value, it))  # 走上三级台阶: three treads (language.references)
        elif nxt is not None and nxt.kind == BODY and it.value in (1, 2):
            if it.value == 2:
                self.sides.append(("both", it))  # "two hands", "两只手"
            else:
                self.note(it, "no effect", "one (body part)")
        else:
            raise InvalidParameter(f'"{it.text}" in "{self.where}" needs a unit (e.g. "{it.text} cm", '
                                   f'"{it.text} degrees", "{it.text} seconds") or "times"')
        return False

    def word(self, it: Item) -> None:
        """A word that is no number: side, body, direction, rotation, adverb or reference."""
        aw = self.aw
        if it.kind == SIDE:
            self.sides.append((it.value, it))
        elif it.kind == BODY:
            body, is_plural = it.value
            if body not in set(aw.body) | self.lx.action_bodies.get(self.name, set()):
                raise self.misfit(it)
            self.note(it, "body part", body)
            if is_plural:
                self.plural = it
        elif it.kind == DIR:
            self.directions.append((it.value, it))
        elif it.kind == ROT:
            if aw.rotation_side and aw.side is not None:
                self.sides.append(("left" if it.value > 0 else "right", it))  # a counterclockwise circle turns left
            else:
                self.signs.append((it.value, it))
        elif it.kind == ADV:
            self.adverbs.append(it)
        elif it.kind == REF and aw.object is not None:
            self.params[aw.object] = it.value
            if it.text:  # a borrowed reference has no words of its own
                self.note(it, "object", f"{aw.object}={it.value} (a thing: '{head_noun(it.value)}'; "
                                        "the scene resolves it)")
        elif it.kind == DEST and aw.destination is not None:
            self.params[aw.destination] = it.value
            self.note(it, "destination", f"{aw.destination}={it.value}")
        elif it.kind == CARRIED and aw.with_object is not None:
            self.params[aw.with_object] = it.value
            self.note(it, "carried object", f"{aw.with_object}={it.value}")
        else:  # a reference to an action without that slot (_resolve_action avoids it), or a stray kind
            raise self.misfit(it)

    # -- mapping -------------------------------------------------------------------------
    def side(self) -> None:
        """``left hand``, ``双手``, or a plural body word (``raise your hands``)."""
        aw = self.aw
        if not self.sides and self.plural is not None and aw.side is not None:
            self.sides.append(("both", self.plural))
        side = _one(self.sides, self.where, "sides")
        if side is None:
            return
        value, it = side
        if aw.side is None:
            if value not in aw.ignore_sides:
                raise self.misfit(it, ": it has no side")
            for _, s_it in self.sides:
                self.note(s_it, "no effect", f"{self.name} uses both feet anyway")
            return
        choices = self.schema.param(aw.side).choices
        if value not in choices:
            raise InvalidParameter(f'"{it.text}" in "{self.where}": {self.name} {aw.side} must be one of '
                                   f'{", ".join(choices)}')
        self.params[aw.side] = value
        for _, s_it in self.sides:
            self.note(s_it, "parameter", fmt(self.name, aw.side, value))

    def direction(self) -> str | None:
        """The direction word's parameter (or the parameters it sets, or nothing it changes)."""
        aw, directions = self.aw, self.directions
        # "sideways", "sidestep", "侧移": a side step or walk, the side named by left/right
        sideways = [(v, it) for v, it in directions if v == "sideways"]
        if sideways:
            directions = [(v, it) for v, it in directions if v != "sideways"]
            if not any(v in ("left", "right") for v, _ in directions):
                raise InvalidParameter(f'"{sideways[0][1].text}" in "{self.where}": say which side, '
                                       f'e.g. "{self.where} to the left" or "向右"')
            for _, it in sideways:
                self.note(it, "no effect", "the side is given by left/right")
        # "put the cup down to the left": down adds nothing to the way
        ignored = [(v, it) for v, it in directions if v in aw.ignore_directions]
        if ignored and len(ignored) < len(directions):
            directions = [(v, it) for v, it in directions if v not in aw.ignore_directions]
            for v, d_it in ignored:
                self.note(d_it, "no effect", f"{self.name} goes {v} anyway")
        direction = _one(directions, self.where, "directions")
        if direction is None:
            return None
        value, it = direction
        choices = self.schema.param(aw.direction).choices if aw.direction else ()
        if aw.direction and value in choices:  # choices is () without a direction
            self.params[aw.direction] = value
            detail, role = fmt(self.name, aw.direction, value), "parameter"
        elif value in aw.direction_params:
            self.params.update(aw.direction_params[value])
            detail = ", ".join(fmt(self.name, p, v) for p, v in aw.direction_params[value].items())
            role = "parameter"
        elif value not in aw.ignore_directions:
            raise self.misfit(it, f": its directions are {', '.join(choices)}" if choices else "")
        else:
            detail, role = f"{self.name} goes {value} anyway", "no effect"
        for _, d_it in directions:
            self.note(d_it, role, detail)
        return value

    def magnitudes(self, direction: str | None) -> None:
        """Adverbs (absolute values, or a scale of the registry default), then quantities with
        units: an explicit number wins over an adverb (``jump 30 cm high``)."""
        aw, values = self.aw, self.adverb_values
        for it in self.adverbs:
            mapping = aw.adverbs.get(it.value)
            if mapping is None:
                if it.value in self.lx.optional_adverbs:  # "walk slowly", "wave happily": accepted, listed
                    self.note(it, "not used", OPTIONAL_DETAIL.get(
                        it.value, f"{it.value} ({self.name} has no parameter for it)"))
                    continue
                raise self.misfit(it)
            if not mapping:
                self.note(it, "no effect", f"{it.value}: accepted, {self.name} does not change")
            for p, v in mapping.items():
                value = self.schema.param(p).default * v["scale"] if isinstance(v, dict) else v
                if p in values and values[p][0] != value:
                    raise AmbiguousInstruction(f'"{values[p][1].text}" and "{it.text}" in "{self.where}" ask for '
                                               f"different {self.name} {p}")
                values[p] = (value, it)
        self.params.update({p: v for p, (v, _) in values.items()})
        self.sources.update({p: it.text for p, (_, it) in values.items()})
        for quantity, (value, it) in self.quantities.items():
            if quantity == "length":
                param = aw.length if direction is None else aw.length_by_direction.get(direction, aw.length)
            else:
                param = getattr(aw, quantity)
            if param is None:
                raise self.misfit(it, f": {self.name} takes no {quantity}")
            self.params[param] = value
            self.sources[param] = it.text

    def sign(self) -> None:
        """Sign of a signed angle: left / counter-clockwise positive (REP 103); then the notes of
        the adverbs and numbers (which the sign may have changed)."""
        aw, params, sources = self.aw, self.params, self.sources
        sign = _one(self.signs, self.where, "turning directions")
        if sign is not None:
            value, it = sign
            if not aw.signed_angle or aw.angle is None:
                raise self.misfit(it)
            angle = params.get(aw.angle)
            if angle is None:
                angle = abs(self.schema.param(aw.angle).default)
            elif angle < 0:
                raise AmbiguousInstruction(f'"{it.text}" and a negative angle in "{self.where}": give one of them')
            params[aw.angle] = value * abs(angle)
            sources.setdefault(aw.angle, it.text)
            for _, s_it in self.signs:
                self.note(s_it, "parameter", f"sign of {aw.angle} ({'left' if value > 0 else 'right'})")
        for p, (_, it) in self.adverb_values.items():
            self.note(it, "parameter", fmt(self.name, p, params[p]) if p in params and sources.get(p) == it.text
                      else f"{p} (overridden by the number)")
        for quantity, (num_it, _) in self.quantity_items.items():
            param = next((p for p, w in sources.items() if w == self.quantities[quantity][1].text), None)
            if param is not None:
                self.note(num_it, "parameter", fmt(self.name, param, params[param]))

    def count(self) -> int:
        """The count parameter, or how many copies of an action without one."""
        count = _one(self.counts, self.where, "counts")
        if count is None:
            return 1
        n, it = count
        if isinstance(n, float):
            if not n.is_integer():
                raise InvalidParameter(f'"{it.text}" in "{self.where}": a count must be a whole number')
            n = int(n)
        copies = 1
        if self.aw.count is not None:
            self.params[self.aw.count] = n
            self.sources[self.aw.count] = it.text
            detail = fmt(self.name, self.aw.count, n)
        elif 1 <= n <= MAX_COPIES:
            copies = n
            detail = f"{n} x {self.name}"
        else:
            raise InvalidParameter(f'"{it.text}" in "{self.where}": {self.name} can be repeated 1 to '
                                   f"{MAX_COPIES} times")
        for _, c_it in self.counts:
            self.note(c_it, "count", detail)
        return copies


def _trigger_follows(items: Sequence[Item], j: int) -> bool:
    """True if ``items[j]`` is a trigger, possibly after adverbs (``two big steps``)."""
    while j < len(items) and items[j].kind == ADV:
        j += 1
    return j < len(items) and items[j].kind == TRIGGER


def _next_index(items: Sequence[Item], i: int) -> int:
    """Index of the next item after ``i`` that is not a classifier (个, 只); ``len(items)`` if none."""
    j = i + 1
    while j < len(items) and items[j].kind == CLASSIFIER:
        j += 1
    return j


def _add_quantity(quantities: dict, lx: Lexicon, num: Item, unit_item: Item, where: str, normalized: str) -> None:
    unit = lx.units[unit_item.value]
    value = num.value * unit.factor
    if unit.quantity != "angle":  # 30 cm is 0.3 m, not 0.30000000000000004; degrees stay exact radians
        value = float(f"{value:.12g}")
    if unit.quantity in quantities:
        raise AmbiguousInstruction(f'"{quantities[unit.quantity][1].text}" and "{normalized[num.start:unit_item.end]}" '
                                   f'in "{where}": give one {unit.quantity}')
    quantities[unit.quantity] = (value, Item(NUM, value, normalized[num.start:unit_item.end], num.start, unit_item.end))


def _one(values: list[tuple[Any, Item]], where: str, what: str) -> tuple[Any, Item] | None:
    """The single distinct value of a slot (None if absent; an error if two differ)."""
    if not values:
        return None
    if len({v for v, _ in values}) > 1:
        words = " and ".join(f'"{it.text}"' for _, it in values)
        raise AmbiguousInstruction(f"{words} in \"{where}\" are conflicting {what}: give one")
    return values[0]
