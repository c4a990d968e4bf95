"""Deterministic rule parser: English and Chinese sentences to registry actions.

The parser is driven by the vocabulary (:mod:`language.lexicon`), not by action-specific code:

1. normalize and atomize the text, then segment it into items (longest known phrase first);
2. refuse words that are in no list (quoting them, suggesting close actions) and negations;
3. drop polite filler and split at sequencing words and punctuation (``then``, ``然后``, ``,``)
   and at overlay words (``while``, ``同时``, ``一边``);
4. in each clause, find the action from its trigger words (``turn`` + ``head`` is turn_head,
   ``stand`` + ``foot`` is balance), then map the slots to the action's parameters as the
   vocabulary says: side (``left hand``, ``双手``), direction, sign of a turn, count (``twice``,
   ``三次``, ``3x``, ``3 squats``), length/angle/duration with units, adverbs;
5. build :class:`tasks.actions.Action` objects (the registry validates ranges), and put
   overlaid upper-body actions after the lower-body action they run with.

A clause without an action word repeats the previous action with new slots (``turn left, then
right``); ``again`` repeats the previous clause. Nothing else is guessed: every word must be
used, and a word that does not fit the action is an error.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from language.exceptions import (
    AmbiguousInstruction,
    EmptyInstruction,
    InvalidParameter,
    NoAction,
    UnknownWords,
    UnsupportedInstruction,
)
from language.lexicon import (
    ADV,
    AGAIN,
    BODY,
    CLASSIFIER,
    DIR,
    FILLER,
    LR,
    NEARMISS,
    NEG,
    NUM,
    OVERLAY,
    PUNCTUATION,
    ROT,
    SEQ,
    SIDE,
    TIMES,
    TRIGGER,
    UNIT,
    UNKNOWN,
    Item,
    Lexicon,
    get_lexicon,
)
from language.normalize import atomize, normalize
from language.plan import ActionPlan
from tasks.actions import REGISTRY, Action
from tasks.exceptions import TaskDefinitionError
from tasks.limits import MAX_REPEAT

MAX_COPIES = MAX_REPEAT  # "jump 3 times" repeats an action without a count parameter at most this often


@dataclass(frozen=True, slots=True)
class ParsedAction:
    """An action and the names of the parameters the sentence stated."""

    action: Action
    given: frozenset[str]


@dataclass(slots=True)
class _Clause:
    connector: str | None  # SEQ, OVERLAY, PUNCTUATION (a bare comma) or None (first clause)
    items: list[Item]

    def text(self, normalized: str) -> str:
        return normalized[self.items[0].start : self.items[-1].end]


def known_actions() -> str:
    """Comma-separated registry action names, for error messages."""
    return ", ".join(sorted(REGISTRY))


def parse_rules(text: str, *, lexicon: Lexicon | None = None) -> list[ParsedAction]:
    """Actions of an English or Chinese instruction, in order (overlays after their base).

    Args:
        text: The instruction, any case, punctuation or full-width characters.
        lexicon: Vocabulary to use (default: the packaged one).

    Returns:
        The parsed actions with the set of parameters each one states.

    Raises:
        EmptyInstruction: Nothing but blanks, punctuation or filler.
        UnknownWords: Words in no vocabulary list (quoted, with close actions suggested).
        UnsupportedInstruction: Negations; overlays that the registry cannot run together.
        NoAction: A part of the sentence names no action.
        AmbiguousInstruction: Two actions in one clause, or conflicting words.
        InvalidParameter: A word or number that does not fit its action, or out of range.
    """
    lx = lexicon or get_lexicon()
    normalized = normalize(text)
    items = lx.segment(atomize(normalized), normalized)
    _refuse_unknown(items, lx)
    clauses = _split(items)
    if not clauses:
        raise EmptyInstruction(f'empty instruction "{text.strip()}": say what the robot should do, e.g. "wave your right hand twice, then squat"')
    groups: list[list[tuple[_Clause, list[ParsedAction]]]] = []
    previous: list[ParsedAction] = []
    for clause in clauses:
        parsed = _parse_clause(clause, previous, lx, normalized)
        if clause.connector == OVERLAY and groups:
            groups[-1].append((clause, parsed))
        else:
            groups.append([(clause, parsed)])
        previous = parsed
    out: list[ParsedAction] = []
    for group in groups:
        out.extend(group[0][1] if len(group) == 1 else _overlay(group, normalized))
    return out


def rules_plan(text: str) -> ActionPlan:
    """The :class:`ActionPlan` of an instruction parsed by the rules (``parse(text)`` with the
    default backend; the LLM backend's few-shot examples use it too)."""
    parsed = parse_rules(text)
    return ActionPlan(actions=tuple(p.action for p in parsed), backend="rules", text=text,
                      given=tuple(p.given for p in parsed))


def _refuse_unknown(items: list[Item], lx: Lexicon) -> None:
    unknown = [it for it in items if it.kind in (UNKNOWN, NEARMISS)]
    if unknown:
        words = list(dict.fromkeys(it.text for it in unknown))
        suggestions = []
        for it in unknown:
            s = it.value if it.kind == NEARMISS else lx.suggest(it.text)
            if s and s not in suggestions:
                suggestions.append(s)
        raise UnknownWords(words, sorted(REGISTRY), suggestions)
    for it in items:
        if it.kind == NEG:
            raise UnsupportedInstruction(f'"{it.text}": negations are not understood; say only what the robot should do')


def _split(items: list[Item]) -> list[_Clause]:
    """Clauses between sequencing/overlay words and punctuation; filler dropped."""
    clauses: list[_Clause] = []
    current: list[Item] = []
    connector: str | None = None
    leading_overlay = False
    for it in items:
        if it.kind == FILLER:
            continue
        if it.kind in (SEQ, OVERLAY, PUNCTUATION):
            if current:
                _close(clauses, current, connector)
                current, connector = [], None
            if it.kind == OVERLAY:
                if not clauses:
                    leading_overlay = True  # "while squatting, wave" / "一边挥手一边蹲"
                connector = OVERLAY
            elif it.kind == SEQ and clauses and connector != OVERLAY:
                connector = SEQ
            elif clauses and connector is None:
                connector = PUNCTUATION
            continue
        current.append(it)
    if current:
        _close(clauses, current, connector)
        connector = None
    if clauses:
        clauses[0].connector = None
    if len(clauses) >= 2:
        if leading_overlay:
            clauses[1].connector = OVERLAY
        if connector == OVERLAY:  # "wave and squat at the same time"
            clauses[-1].connector = OVERLAY
    return clauses


def _close(clauses: list[_Clause], items: list[Item], connector: str | None) -> None:
    """End a clause; after a bare comma, a part without an action word continues the last clause."""
    if connector == PUNCTUATION and clauses and not any(it.kind in (TRIGGER, AGAIN) for it in items):
        clauses[-1].items.extend(items)  # "walk forward, 2 meters" is one walk
    else:
        clauses.append(_Clause(connector, items))


def _resolve_action(clause: _Clause, lx: Lexicon, normalized: str) -> str | None:
    """The action a clause names (None if it has no trigger word)."""
    triggers = [it for it in clause.items if it.kind == TRIGGER]
    if not triggers:
        return None
    bodies = {it.value[0] for it in clause.items if it.kind == BODY}
    per_trigger = []
    for t in triggers:
        with_body = {a for a, b in t.value if b is not None and b in bodies}
        plain = {a for a, b in t.value if b is None}
        cands = with_body or plain
        if not cands:
            need = sorted({b for _, b in t.value if b})
            raise NoAction(f'"{t.text}" alone does not name an action: say what to move, e.g. "{t.text} your {need[0]}"')
        per_trigger.append(cands)
    common = set.intersection(*per_trigger)
    names = common if common else set.union(*per_trigger)
    absorbed = {other for n in names for other in lx.actions[n].absorbs}
    if names - absorbed:
        names -= absorbed
    if len(names) == 1:
        return next(iter(names))
    raise AmbiguousInstruction(
        f'"{clause.text(normalized)}" names {len(names)} actions ({", ".join(sorted(names))}): '
        f'join them with "then" or "while", or use one of them'
    )


def _parse_clause(clause: _Clause, previous: list[ParsedAction], lx: Lexicon, normalized: str) -> list[ParsedAction]:
    name = _resolve_action(clause, lx, normalized)
    if name is None:
        if all(it.kind in (AGAIN, CLASSIFIER) for it in clause.items):
            if not previous:
                raise NoAction(f'"{clause.text(normalized)}" repeats nothing: say the action first')
            return list(previous)
        if not previous:
            raise NoAction(f'no action in "{clause.text(normalized)}": known actions are {known_actions()}')
        name = previous[-1].action.name  # "turn left, then right"
    params, copies, sources = _slots(name, clause, lx, normalized)
    try:
        action = Action(name=name, params=params)
    except TaskDefinitionError as e:
        words = next((w for p, w in sources.items() if str(e).startswith(f"{name} {p} ")), None)
        where = clause.text(normalized)
        quote = f'"{words}" in "{where}"' if words and words != where else f'"{where}"'
        raise InvalidParameter(f"{quote}: {e}") from None
    parsed = ParsedAction(action, frozenset(params))
    return [parsed] * copies


def _slots(name: str, clause: _Clause, lx: Lexicon, normalized: str) -> tuple[dict[str, Any], int, dict[str, str]]:
    """Parameters stated in a clause, how many copies of the action it asks for, and the words of each parameter."""
    aw = lx.actions[name]
    schema = REGISTRY[name]
    items = clause.items
    where = clause.text(normalized)
    sides: list[tuple[str, Item]] = []
    directions: list[tuple[str, Item]] = []
    signs: list[tuple[int, Item]] = []
    quantities: dict[str, tuple[float, Item]] = {}
    counts: list[tuple[Any, Item]] = []
    adverbs: list[Item] = []
    plural: Item | None = None
    allowed_bodies = set(aw.body) | _with_body(lx, name)
    consumed: set[int] = set()

    def misfit(it: Item, extra: str = "") -> InvalidParameter:
        return InvalidParameter(f'"{it.text}" does not fit {name} in "{where}"{extra}')

    def bare_left_right(it: Item) -> None:
        mode = aw.bare_left_right
        if mode == "side":
            sides.append((it.value, it))
        elif mode == "direction":
            directions.append((it.value, it))
        elif mode == "sign":
            signs.append((1 if it.value == "left" else -1, it))
        else:
            raise misfit(it)

    for i, it in enumerate(items):
        if i in consumed or it.kind in (TRIGGER, AGAIN, CLASSIFIER):
            continue
        nxt_i = _next_index(items, i)
        nxt = items[nxt_i] if nxt_i < len(items) else None
        if it.kind == NUM:
            if nxt is not None and nxt.kind == UNIT:
                _add_quantity(quantities, lx, it, nxt, where, normalized)
                consumed.add(nxt_i)
            elif nxt is not None and nxt.kind == TIMES:
                counts.append((it.value, it))
                consumed.add(nxt_i)
            elif nxt is not None and _trigger_follows(items, nxt_i):
                counts.append((it.value, it))  # "3 squats", "三步", "two big steps"
            elif nxt is not None and nxt.kind == BODY and it.value in (1, 2):
                if it.value == 2:
                    sides.append(("both", it))  # "two hands", "两只手"
            else:
                raise InvalidParameter(f'"{it.text}" in "{where}" needs a unit (e.g. "{it.text} cm", "{it.text} degrees", "{it.text} seconds") or "times"')
        elif it.kind == TIMES:
            if nxt is not None and nxt.kind == NUM and nxt_i == i + 1:
                counts.append((nxt.value, nxt))  # "x3"
                consumed.add(nxt_i)
            else:
                raise InvalidParameter(f'"{it.text}" in "{where}" needs a number, e.g. "3 {it.text}"')
        elif it.kind == UNIT:
            raise InvalidParameter(f'"{it.text}" in "{where}" needs a number in front, e.g. "30 {it.text}"')
        elif it.kind == LR:
            if nxt is not None and nxt.kind == BODY and nxt_i == i + 1 and aw.side is not None:
                sides.append((it.value, it))  # "left hand", "左手"
            else:
                bare_left_right(it)
        elif it.kind == SIDE:
            sides.append((it.value, it))
        elif it.kind == BODY:
            body, is_plural = it.value
            if body not in allowed_bodies:
                raise misfit(it)
            if is_plural:
                plural = it
        elif it.kind == DIR:
            directions.append((it.value, it))
        elif it.kind == ROT:
            signs.append((it.value, it))
        elif it.kind == ADV:
            adverbs.append(it)
        else:  # pragma: no cover - every item kind is handled above
            raise misfit(it)

    params: dict[str, Any] = {}
    sources: dict[str, str] = {}  # parameter -> the words that set it (for error messages)
    # side: "left hand", "双手", or a plural body word ("raise your hands")
    if not sides and plural is not None and aw.side is not None:
        sides.append(("both", plural))
    side = _one(sides, where, "sides")
    if side is not None:
        value, it = side
        if aw.side is None:
            if value not in aw.ignore_sides:
                raise misfit(it, ": it has no side")
        else:
            choices = schema.param(aw.side).choices
            if value not in choices:
                raise InvalidParameter(f'"{it.text}" in "{where}": {name} {aw.side} must be one of {", ".join(choices)}')
            params[aw.side] = value
    # direction
    direction = _one(directions, where, "directions")
    direction_value = None
    if direction is not None:
        direction_value, it = direction
        choices = schema.param(aw.direction).choices if aw.direction else ()
        if aw.direction and direction_value in choices:  # choices is () without a direction
            params[aw.direction] = direction_value
        elif direction_value in aw.direction_params:
            params.update(aw.direction_params[direction_value])
        elif direction_value not in aw.ignore_directions:
            raise misfit(it, f": its directions are {', '.join(choices)}" if choices else "")
    # adverbs (absolute values, or a scale of the registry default)
    adverb_values: dict[str, tuple[float, Item]] = {}
    for it in adverbs:
        mapping = aw.adverbs.get(it.value)
        if mapping is None:
            raise misfit(it)
        for p, v in mapping.items():
            value = schema.param(p).default * v["scale"] if isinstance(v, dict) else v
            if p in adverb_values and adverb_values[p][0] != value:
                raise AmbiguousInstruction(f'"{adverb_values[p][1].text}" and "{it.text}" in "{where}" ask for different {name} {p}')
            adverb_values[p] = (value, it)
    params.update({p: v for p, (v, _) in adverb_values.items()})
    sources.update({p: it.text for p, (_, it) in adverb_values.items()})
    # quantities with units: an explicit number wins over an adverb ("jump 30 cm high")
    for quantity, (value, it) in quantities.items():
        if quantity == "length":
            param = aw.length if direction_value is None else aw.length_by_direction.get(direction_value, aw.length)
        else:
            param = getattr(aw, quantity)
        if param is None:
            raise misfit(it, f": {name} takes no {quantity}")
        params[param] = value
        sources[param] = it.text
    # sign of a signed angle: left / counter-clockwise positive (REP 103)
    sign = _one(signs, where, "turning directions")
    if sign is not None:
        value, it = sign
        if not aw.signed_angle or aw.angle is None:
            raise misfit(it)
        angle = params.get(aw.angle)
        if angle is None:
            angle = abs(schema.param(aw.angle).default)
        elif angle < 0:
            raise AmbiguousInstruction(f'"{it.text}" and a negative angle in "{where}": give one of them')
        params[aw.angle] = sign[0] * abs(angle)
        sources.setdefault(aw.angle, it.text)
    # count
    copies = 1
    count = _one(counts, where, "counts")
    if count is not None:
        n, it = count
        if isinstance(n, float):
            if not n.is_integer():
                raise InvalidParameter(f'"{it.text}" in "{where}": a count must be a whole number')
            n = int(n)
        if aw.count is not None:
            params[aw.count] = n
            sources[aw.count] = it.text
        elif 1 <= n <= MAX_COPIES:
            copies = n
        else:
            raise InvalidParameter(f'"{it.text}" in "{where}": {name} can be repeated 1 to {MAX_COPIES} times')
    return params, copies, sources


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
        raise AmbiguousInstruction(
            f'"{quantities[unit.quantity][1].text}" and "{normalized[num.start : unit_item.end]}" in "{where}": give one {unit.quantity}'
        )
    quantities[unit.quantity] = (value, Item(NUM, value, normalized[num.start : unit_item.end], num.start, unit_item.end))


def _one(values: list[tuple[Any, Item]], where: str, what: str) -> tuple[Any, Item] | None:
    """The single distinct value of a slot (None if absent; an error if two differ)."""
    if not values:
        return None
    distinct = {v for v, _ in values}
    if len(distinct) > 1:
        words = " and ".join(f'"{it.text}"' for _, it in values)
        raise AmbiguousInstruction(f"{words} in \"{where}\" are conflicting {what}: give one")
    return values[0]


def _with_body(lx: Lexicon, name: str) -> set[str]:
    return lx.action_bodies.get(name, set())


def _overlay(group: list[tuple[_Clause, list[ParsedAction]]], normalized: str) -> list[ParsedAction]:
    """Actions said to run at the same time: the one that is not upper-body first, the others overlaid.

    At most one action of the group may use more than the upper body (registry ``body`` is
    ``lower`` or ``whole``); it becomes the base. If all are upper-body, the first one said is
    the base. Which body parts really collide (two actions on one arm) is the tasks layer's call.
    """
    for clause, parsed in group:
        if len(parsed) != 1:
            raise UnsupportedInstruction(
                f'"{clause.text(normalized)}": an action repeated by count cannot run at the same time as another; '
                f'use a count the action has (e.g. "wave twice")'
            )
    actions = [parsed[0] for _, parsed in group]
    bases = [p for p in actions if REGISTRY[p.action.name].body != "upper"]
    if len(bases) > 1:
        upper = ", ".join(n for n, s in REGISTRY.items() if s.body == "upper")
        said = " and ".join(f'"{c.text(normalized)}"' for c, ps in group if REGISTRY[ps[0].action.name].body != "upper")
        names = " and ".join(p.action.name for p in bases)
        raise UnsupportedInstruction(
            f"cannot do {said} at the same time: {names} both move the legs or the whole body; "
            f"only upper-body actions ({upper}) can run alongside another action"
        )
    base = bases[0] if bases else actions[0]
    out = [base]
    for p in actions:
        if p is not base:
            out.append(ParsedAction(Action(name=p.action.name, params=_given_params(p), overlay=True), p.given))
    return out


def _given_params(p: ParsedAction) -> dict[str, Any]:
    return {k: v for k, v in p.action.params.items() if k in p.given}


__all__ = ["ParsedAction", "known_actions", "parse_rules", "rules_plan"]
