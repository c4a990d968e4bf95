"""``back`` as a way home (issue 32): "walk forward, turn around and walk back".

``back`` (``walk back``, ``comes back``, ``returns``, 走回来, 回到原点) after walking somewhere
means back to where the walk started, not "backward": after a half turn that is *forward*, the
distance (or the steps) of the walk before; without a turn it is backward by that distance.
Words that name the start (``to the start``, ``to where you started``, 原点, 起点) ask for it
explicitly: with nothing walked before, or after a turn that is not a half turn, the clause is
refused naming them instead of guessing a direction. A plain ``take a step back`` stays one
step backward. ``stands back up`` after a squat (bow, lunge) adds nothing: the squat ends standing.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from language.exceptions import InvalidParameter
from language.lexicon import DIR, TRIGGER, Item
from language.plan import ParsedAction
from tasks import Action

TRANSLATIONS = ("walk", "step")  # actions that take the robot somewhere along its heading
START_WORDS = ("start", "starting", "started", "beginning", "origin", "where", "原点", "起点", "原来")
RETURN_WORDS = ("return", "returns", "returning", "returned", "come back", "comes back", "coming back",
                "came back", "head back", "heads back", "回")
OPPOSITE = {"forward": "backward", "backward": "forward", "left": "right", "right": "left"}
HALF_TURN_TOL = 0.2  # [rad] a turn this close to pi (mod 2 pi) is a half turn


def marks(items: Sequence[Item]) -> tuple[list[Item], bool]:
    """The items of a clause that say ``back`` or name the start, and whether one names the start
    (or is a verb of returning)."""
    out, start = [], False
    for it in items:
        if it.kind not in (DIR, TRIGGER):
            continue
        words = it.text.split()
        names_start = any(w in it.text for w in START_WORDS) or any(
            it.text.startswith(w) or (not w.isascii() and w in it.text) for w in RETURN_WORDS)
        if names_start or "back" in words:
            out.append(it)
            start = start or names_start
    return out, start


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2 * math.pi) - math.pi


def go_back(parsed: list[ParsedAction], history: Sequence[ParsedAction], start: bool,
            where: str) -> tuple[list[ParsedAction], str]:
    """The clause's actions with ``back`` read as a way home, and the word reading's detail
    (empty if nothing changed). ``history``: the actions of the sentence before the clause."""
    if not parsed or parsed[0].action.name not in TRANSLATIONS:
        return parsed, ""
    last = next((k for k in range(len(history) - 1, -1, -1) if history[k].action.name in TRANSLATIONS
                 and history[k].action.params.get("direction") in OPPOSITE), None)
    if last is None:
        if not start and abs(abs(_wrap(sum(p.action.params["angle"] for p in history if p.action.name == "turn")))
                             - math.pi) < HALF_TURN_TOL and parsed[0].action.params.get("direction") == "backward":
            action = Action(name=parsed[0].action.name, params={**{k: parsed[0].action.params[k]
                                                                   for k in parsed[0].given}, "direction": "forward"})
            return [ParsedAction(action, parsed[0].given | {"direction"})] * len(parsed), \
                "back where it came from, facing it after the half turn: forward"
        if start:
            raise InvalidParameter(f'"{where}": nothing was walked before it to go back from; say the way '
                                   'and the distance, e.g. "walk backward 1 meter"')
        return parsed, ""
    before = history[last]
    turned = _wrap(sum(p.action.params["angle"] for p in history[last + 1:] if p.action.name == "turn"))
    half = abs(abs(turned) - math.pi) < HALF_TURN_TOL
    if not half and abs(turned) > HALF_TURN_TOL:
        if start:
            raise InvalidParameter(f'"{where}": after a turn of {math.degrees(turned):.0f} degrees the way back '
                                   'to the start is no straight walk; say the way, e.g. "turn around and walk back"')
        return parsed, ""
    if parsed[0].action.name == "step" and before.action.name != "step" and not start:
        return parsed, ""  # "walk forward, then take a step back": one step backward
    said = before.action.params["direction"]
    way = said if half else OPPOSITE[said]  # after a half turn the robot's own frame is turned too
    own = parsed[0].given - {"direction"}
    if own:  # "walk back 1 meter": the clause's own distance, the way home
        action = Action(name=parsed[0].action.name, params={**{k: parsed[0].action.params[k] for k in own},
                                                            "direction": way})
        given = own | {"direction"}
    else:  # the same walk (or steps) as before, the way home
        keep = before.given - {"direction"}
        action = Action(name=before.action.name, params={**{k: before.action.params[k] for k in keep},
                                                         "direction": way})
        given = keep | {"direction"}
    detail = f"back to the start: {action.name} {way}" + ("" if own else f", as far as {before.action.name} went")
    return [ParsedAction(action, frozenset(given))] * len(parsed), detail


ENDS_STANDING = ("squat", "bow", "lunge")  # actions that come back up by themselves
BACK_UP = ("back up", "up again")


def stands_back_up(parsed: Sequence[ParsedAction], history: Sequence[ParsedAction], items: Sequence[Item]) -> bool:
    """The clause only says to stand up again after an action that ends standing."""
    return (len(parsed) == 1 and parsed[0].action.name == "stand" and not parsed[0].given and bool(history)
            and history[-1].action.name in ENDS_STANDING
            and all(it.kind != TRIGGER or any(w in it.text for w in BACK_UP) for it in items))
