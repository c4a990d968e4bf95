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

import math
from dataclasses import dataclass, field
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
    AUX,
    BODY,
    CLASSIFIER,
    DIR,
    FILLER,
    IN_PLACE,
    LR,
    NEARMISS,
    NEG,
    OVERLAY,
    PUNCTUATION,
    REF,
    SEQ,
    STOP,
    SUBJECT,
    TRIGGER,
    UNKNOWN,
    Item,
    Lexicon,
    get_lexicon,
)
from language.normalize import atomize, normalize
from language.objects import deictic_goal, travel_direction
from language.plan import ActionPlan, ParsedAction, WordUse
from language.references import around, nouns, references
from language.returns import go_back, marks, stands_back_up
from language.slots import MAX_COPIES, fmt, read_slots
from tasks import REGISTRY, Action, TaskDefinitionError

AND_WORDS = ("and", "和", "并", "并且")  # "slowly and deeply": adverbs joined by these stay with their action


@dataclass(slots=True)
class _Clause:
    connector: str | None  # SEQ, OVERLAY, PUNCTUATION (a bare comma) or None (first clause)
    items: list[Item]
    index: int = -1  # position among the clauses (set once split)

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
        UnsupportedInstruction: Negations; overlays that the registry cannot run together;
            ``walk in place`` without the ``march`` action.
        NoAction: A part of the sentence names no action.
        AmbiguousInstruction: Two actions in one clause, or conflicting words.
        InvalidParameter: A word or number that does not fit its action, or out of range.
    """
    return parse_rules_explained(text, lexicon=lexicon)[0]


@dataclass(slots=True)
class _Uses:
    """What each item did: item id -> (item, role, detail, clause index or None)."""

    notes: dict[int, tuple[Item, str, str, int | None]] = field(default_factory=dict)

    def add(self, it: Item, role: str, detail: str = "", clause: int | None = None) -> None:
        self.notes[id(it)] = (it, role, detail, clause)

    def words(self, items: list[Item], first_action: dict[int, int]) -> tuple[WordUse, ...]:
        """One WordUse per phrase of the instruction, in order (items of one phrase joined)."""
        out: list[WordUse] = []
        by_span: dict[tuple[int, int], int] = {}
        for it in items:
            note = self.notes.get(id(it))
            if note is None:
                continue
            _, role, detail, clause = note
            action = first_action.get(clause) if clause is not None else None
            use = WordUse(it.text, role, detail, None if action is None else action + 1)
            key = (it.start, it.end)
            if key in by_span:  # "转身" is turn + around: one line, both details
                prev = out[by_span[key]]
                extra = use.detail if prev.role == use.role else f"{use.role}: {use.detail}".strip(": ")
                out[by_span[key]] = WordUse(prev.text, prev.role, "; ".join(d for d in (prev.detail, extra) if d), prev.action)
            else:
                by_span[key] = len(out)
                out.append(use)
        return tuple(out)


def parse_rules_explained(text: str, *, lexicon: Lexicon | None = None) -> tuple[list[ParsedAction], tuple[WordUse, ...]]:
    """:func:`parse_rules`, and what each word did (for ``wbmp parse``)."""
    lx = lexicon or get_lexicon()
    normalized = normalize(text)
    items = references(around(nouns(lx.segment(atomize(normalized), normalized)), lx, normalized), lx, normalized)
    _refuse_unknown(items, lx)
    _refuse_deictic_goals(items, lx, normalized)
    uses = _Uses()
    clauses = _split(items, uses, frozenset(lx.optional_adverbs))
    clauses = _stops(clauses, uses, normalized)
    if not clauses:
        raise EmptyInstruction(f'empty instruction "{text.strip()}": say what the robot should do, e.g. "wave your right hand twice, then squat"')
    groups: list[list[tuple[_Clause, list[ParsedAction]]]] = []
    previous: list[ParsedAction] = []
    history: list[ParsedAction] = []  # every action so far, for "walk back" (language.returns)
    for clause in clauses:
        parsed = _parse_clause(clause, previous, lx, normalized, uses)
        if not parsed:  # a "stop" that ends the motion before it
            continue
        if stands_back_up(parsed, history, clause.items):  # "squats down and stands back up": the squat did
            for it in clause.items:
                uses.add(it, "no effect", f"{history[-1].action.name} ends standing", clause.index)
            continue
        back, start = marks(clause.items)
        if back:
            parsed, detail = go_back(parsed, history, start, clause.text(normalized))
            for it in back if detail else ():
                if it.kind == DIR:
                    uses.add(it, "parameter", detail, clause.index)
        history.extend(parsed)
        if clause.connector == OVERLAY and groups:
            groups[-1].append((clause, parsed))
        else:
            groups.append([(clause, parsed)])
        previous = parsed
    if not groups:
        raise EmptyInstruction(f'empty instruction "{text.strip()}": say what the robot should do, e.g. "wave your right hand twice, then squat"')
    out: list[ParsedAction] = []
    first_action: dict[int, int] = {}
    for group in groups:
        if len(group) == 1:
            first_action.setdefault(group[0][0].index, len(out))
            out.extend(group[0][1])
        else:
            for clause_index, p in _overlay(group, normalized):
                first_action.setdefault(clause_index, len(out))
                out.append(p)
    return out, uses.words(items, first_action)


def rules_plan(text: str) -> ActionPlan:
    """The :class:`ActionPlan` of an instruction parsed by the rules (``parse(text)`` with the
    default backend; the LLM backend's few-shot examples use it too)."""
    parsed, words = parse_rules_explained(text)
    return ActionPlan(actions=tuple(p.action for p in parsed), backend="rules", text=text,
                      given=tuple(p.given for p in parsed), words=words)




COME_WORDS = ("come", "comes", "came", "coming", "过来", "来")  # "come over here": towards the speaker, no way
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


AIMING = ("walk", "step", "jog", "turn", "point", "reach", "turn_head", "walk_arc", "lean", "jump", "hop")  # and
# every action with an object: actions whose motion goes or aims somewhere


def _refuse_deictic_goals(items: list[Item], lx: Lexicon, normalized: str) -> None:
    """``walk towards me``, ``point at yourself``, ``come to me``: where that is, nobody said."""
    part: list[Item] = []
    for it in [*items, None]:
        if it is not None and it.kind not in (SEQ, OVERLAY, PUNCTUATION):
            part.append(it)
            continue
        framed = {a for _, _, a in lx.frames}  # "hand the cup to me": the frame says who takes it
        aims = any(t.kind == TRIGGER and any((a in AIMING or lx.actions[a].object is not None) and a not in framed
                                             for a, _ in t.value) for t in part)
        held = next((part[k + 1] for k in range(len(part) - 1) if part[k].text == "把" and part[k + 1].kind in (BODY, LR)
                     and any(t.kind == TRIGGER and any(lx.actions[a].object is not None for a, _ in t.value)
                             for t in part)), None)
        if held is not None:  # 把手放在头上: a hand is no object to put down
            said = normalized[part[0].start:part[-1].end]
            raise InvalidParameter(f'"{held.text}" in "{said}": a part of the body is no object of the scene; say '
                                   'what to put, or use the body action (e.g. 摸头, 双手叉腰)')
        word = deictic_goal(part) if aims else None
        if word is not None:
            said = normalized[part[0].start:part[-1].end]
            raise InvalidParameter(f'"{word.text}" in "{said}": where that is, the robot cannot know; name a thing '
                                   'of the scene (e.g. "walk to the table", with --scene) or a way (e.g. "walk forward")')
        part = []


def _split(items: list[Item], uses: _Uses, optional: frozenset[str] = frozenset()) -> list[_Clause]:
    """Clauses between sequencing/overlay words and punctuation; filler, subjects and verb forms
    dropped (and noted). A ``stop`` starts a clause of its own."""
    clauses: list[_Clause] = []
    current: list[Item] = []
    connector: str | None = None
    leading_overlay = False
    joined_by = ""  # the sequencing word before the current part
    dropped = {FILLER: "filler", SUBJECT: "subject", AUX: "verb form"}
    for it in items:
        if it.kind in dropped:
            uses.add(it, dropped[it.kind])
            continue
        if it.kind in (SEQ, OVERLAY, PUNCTUATION):
            if it.kind != PUNCTUATION and it.text:  # an implied sequence (走过去拿起) has no words
                uses.add(it, "sequence" if it.kind == SEQ else "at the same time")
            if current:
                _close(clauses, current, connector, optional, joined_by)
                current, connector = [], None
            joined_by = it.text if it.kind == SEQ else ""
            if it.kind == OVERLAY:
                if not clauses:
                    leading_overlay = True  # "while squatting, wave" / "一边挥手一边蹲"
                connector = OVERLAY
            elif it.kind == SEQ and clauses and connector != OVERLAY:
                connector = SEQ
            elif clauses and connector is None:
                connector = PUNCTUATION
            continue
        if it.kind == STOP and current:  # "walks forward and stops": "stops" is a clause of its own
            _close(clauses, current, connector, optional, joined_by)
            current, connector = [], SEQ
        current.append(it)
    if current:
        _close(clauses, current, connector, optional, joined_by)
        connector = None
    if clauses:
        clauses[0].connector = None
    if len(clauses) >= 2:
        if leading_overlay:
            clauses[1].connector = OVERLAY
        if connector == OVERLAY:  # "wave and squat at the same time"
            clauses[-1].connector = OVERLAY
    return clauses


def _close(clauses: list[_Clause], items: list[Item], connector: str | None, optional: frozenset[str] = frozenset(),
           joined_by: str = "") -> None:
    """End a clause; after a bare comma, a part without an action word continues the last clause,
    and so does a part made only of manner words (``walks forward slowly and happily``) or of
    adverbs after ``and`` (``bows slowly and deeply``)."""
    manner_only = all(it.kind == ADV and (it.value in optional or joined_by in AND_WORDS) for it in items)
    if clauses and ((connector == PUNCTUATION and not any(it.kind in (TRIGGER, AGAIN, STOP) for it in items))
                    or (manner_only and connector != OVERLAY)):
        clauses[-1].items.extend(items)  # "walk forward, 2 meters" is one walk
    else:
        clauses.append(_Clause(connector, items, len(clauses)))


HOLDS = ("pick_up", "hand_over", "put_down", "push", "touch_object")  # what "lower it" would move: an object


def _stops(clauses: list[_Clause], uses: _Uses, normalized: str) -> list[_Clause]:
    """``stop`` / ``停下``: the end of the sequence, not a negation and not a step.

    A clause that is only a stop is dropped (the motion before it ends there; the robot stops
    between actions anyway) unless it is the whole instruction: then it means "stand still".
    A stop with slots (``stop for 2 seconds``, ``停三秒``) or with ``stand``/``rest`` is a stand.
    A stop before another action (``stop waving``, ``停止挥手``) asks to end something the plan
    never started: refused like a negation.
    """
    out: list[_Clause] = []
    stand_words = (("stand", None),)
    for clause in clauses:
        stops = [it for it in clause.items if it.kind == STOP]
        if not stops:
            out.append(clause)
            continue
        others = [it for it in clause.items if it.kind != STOP]
        actions = {a for it in others if it.kind == TRIGGER for a, _ in it.value}
        back = [it for it in stops if it.text.split()[-1] in ("it", "them")]  # "and then lowers it"
        if back:
            before = {a for c in out[-1:] for it in c.items if it.kind == TRIGGER for a, _ in it.value}
            if not before or others or any(a not in REGISTRY or REGISTRY[a].body != "upper" or a in HOLDS
                                           for a in before):
                raise UnsupportedInstruction(
                    f'"{back[0].text}" in "{clause.text(normalized)}": only an arm or head gesture said just before '
                    'it comes back down by itself; say what to move (e.g. "raise your arms")')
        if actions and "stand" not in actions:
            raise UnsupportedInstruction(
                f'"{clause.text(normalized)}": "{stops[0].text}" before an action asks to end something the '
                f"plan never started; say only what the robot should do (a final \"stop\" ends the sequence)"
            )
        if others or len(clauses) == 1:
            for it in stops:
                uses.add(it, "stop", "stand still", clause.index)
            if actions:  # "停下来休息": the stand word names the action
                clause.items = others
            else:  # "stop" alone, "stop for 2 seconds": stand
                clause.items = [Item(TRIGGER, stand_words, it.text, it.start, it.end) if it.kind == STOP else it
                                for it in clause.items]
            out.append(clause)
        else:
            last = clause is clauses[-1]
            for it in stops:
                uses.add(it, "stop", "end of the sequence" if last else "end of the motion before it")
    if out:
        out[0].connector = None
    return out


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
    ref = next((it for it in clause.items if it.kind == REF), None)
    if ref is not None:  # "go to the table": walk with an object is walk_to
        with_object = {lx.object_forms.get(n, n) for n in names}
        names = {n for n in with_object if lx.actions[n].object is not None}
        if not names:
            raise InvalidParameter(f'"{ref.text}" in "{clause.text(normalized)}": {", ".join(sorted(with_object))} '
                                   "takes no object")
    else:  # "walk to the left": walk_to's words without an object are a walk
        if any(n in lx.plain_forms for n in names) and all(
                it.kind in (TRIGGER, FILLER, SUBJECT, AUX, CLASSIFIER) for it in clause.items) and any(
                it.kind == TRIGGER and (it.text.startswith(COME_WORDS) or "过来" in it.text) for it in clause.items):
            said = clause.text(normalized)
            raise InvalidParameter(f'"{said}" names no object of the scene to go to: say which thing (e.g. "walk to '
                                   'the table", with --scene) or which way (e.g. "walk forward 1 meter")')
        names = {lx.plain_forms.get(n, n) for n in names}
    if len(names) == 1:
        return next(iter(names))
    raise AmbiguousInstruction(
        f'"{clause.text(normalized)}" names {len(names)} actions ({", ".join(sorted(names))}): '
        f'join them with "then" or "while", or use one of them'
    )


def _parse_clause(clause: _Clause, previous: list[ParsedAction], lx: Lexicon, normalized: str,
                  uses: _Uses | None = None) -> list[ParsedAction]:
    uses = uses if uses is not None else _Uses()
    ci = clause.index
    name = _resolve_action(clause, lx, normalized)
    if name is None:
        if all(it.kind in (AGAIN, CLASSIFIER) for it in clause.items):
            if not previous:
                raise NoAction(f'"{clause.text(normalized)}" repeats nothing: say the action first')
            for it in clause.items:
                uses.add(it, "again" if it.kind == AGAIN else "filler",
                         f"repeats {', '.join(p.action.name for p in previous)}" if it.kind == AGAIN else "measure word", ci)
            return list(previous)
        if not previous:
            raise NoAction(f'no action in "{clause.text(normalized)}": known actions are {known_actions()}')
        name = previous[-1].action.name  # "turn left, then right"
    said = name
    name = _in_place(name, clause, lx, normalized, uses)
    for it in clause.items:
        if it.kind == TRIGGER:
            uses.add(it, "action", name if name == said else f"{name} ({said} in place)", ci)
        elif it.kind == AGAIN:
            uses.add(it, "again", f"{name} once more", ci)
        elif it.kind == CLASSIFIER:
            uses.add(it, "filler", "measure word", ci)

    def note(it: Item, role: str, detail: str = "") -> None:
        uses.add(it, role, detail, ci)

    aw = lx.actions[name]
    sideways = any(it.kind == DIR and it.value in ("side", "sideways") for it in clause.items)
    if aw.bare_left_right == "side" and not aw.rotation_side and not sideways:
        way = next((it for it in clause.items if travel_direction(it, normalized)), None)
        if way is not None:  # "hop to the left" is no hop on the left foot
            raise InvalidParameter(f'"{way.text}" in "{clause.text(normalized)}" is a way to go, and {name} does '
                                   f'not travel sideways; to choose the {aw.side}, say e.g. "left {aw.side}"')
    params, copies, sources = read_slots(name, clause.items, clause.text(normalized), lx, normalized, note)
    if aw.ask is not None and aw.ask not in params:  # a bare "look" asks where
        where = clause.text(normalized)
        choices = ", ".join(REGISTRY[name].param(aw.ask).choices)
        raise InvalidParameter(f'"{where}" does not say the {aw.ask} ({choices}): e.g. "{where} left"')
    if aw.split is not None and aw.split in params:
        pieces = _split_value(name, aw.split, params, copies, sources, clause, normalized) // copies
        if pieces > 1:
            copies *= pieces
            for it in clause.items:
                n = uses.notes.get(id(it))
                if n is not None and n[1] == "parameter" and n[2].startswith(f"{aw.split}="):
                    uses.add(it, "parameter", f"{fmt(name, aw.split, params[aw.split])}, {pieces} x {name}", ci)
    try:
        action = Action(name=name, params=params)
    except TaskDefinitionError as e:
        words = next((w for p, w in sources.items() if str(e).startswith(f"{name} {p} ")), None)
        where = clause.text(normalized)
        quote = f'"{words}" in "{where}"' if words and words != where else f'"{where}"'
        raise InvalidParameter(f"{quote}: {e}") from None
    parsed = ParsedAction(action, frozenset(params))
    return [parsed] * copies


def _in_place(name: str, clause: _Clause, lx: Lexicon, normalized: str, uses: _Uses) -> str:
    """The action of a clause with ``in place`` / ``原地``: walk and step become march; others
    (turn, jump, squat, arm motions) stay in place anyway and keep their action."""
    marks = [it for it in clause.items if it.kind == IN_PLACE]
    if not marks:
        return name
    target = lx.actions[name].in_place
    if target is None:
        for it in marks:
            uses.add(it, "in place", f"{name} stays in place", clause.index)
        return name
    if target not in REGISTRY or target not in lx.actions:
        raise UnsupportedInstruction(
            f'"{clause.text(normalized)}": {name} "{marks[0].text}" means stepping on the spot (the {target} action), '
            f'which this wbmp does not have; say "{name}" to move, or "stand" to stay where you are'
        )
    for it in marks:
        uses.add(it, "in place", f"{name} in place is {target}", clause.index)
    return target


def _split_value(name: str, param: str, params: dict[str, Any], copies: int, sources: dict[str, str],
                 clause: _Clause, normalized: str) -> int:
    """A value beyond the registry range as equal copies (``turn 360 degrees``: 2 x 180)."""
    p = REGISTRY[name].param(param)
    value = params[param]
    limit = p.maximum if value > 0 else (-p.minimum if p.minimum is not None else None)
    if limit is None or limit <= 0 or abs(value) <= limit:
        return copies
    pieces = math.ceil(abs(value) / limit - 1e-9)
    if pieces * copies > MAX_COPIES:
        where = clause.text(normalized)
        words = sources.get(param, where)
        raise InvalidParameter(
            f'"{words}" in "{where}": {name} {param} {abs(value) * copies:g} {p.unit} is more than {MAX_COPIES} '
            f"{name}s of at most {limit:g} {p.unit}"
        )
    params[param] = value / pieces
    return copies * pieces


def _overlay(group: list[tuple[_Clause, list[ParsedAction]]], normalized: str) -> list[tuple[int, ParsedAction]]:
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
    clause_of = {id(parsed[0]): clause.index for clause, parsed in group}
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
    out = [(clause_of[id(base)], base)]
    for p in actions:
        if p is not base:
            out.append((clause_of[id(p)], ParsedAction(Action(name=p.action.name, params=_given_params(p), overlay=True), p.given)))
    return out


def _given_params(p: ParsedAction) -> dict[str, Any]:
    return {k: v for k, v in p.action.params.items() if k in p.given}


__all__ = ["ParsedAction", "known_actions", "parse_rules", "parse_rules_explained", "rules_plan"]
