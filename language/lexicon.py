"""The lexicon: vocabulary phrases compiled into a longest-match table over atoms.

``vocabulary.json`` lists, per registry action, the words that name it and how the slots of a
sentence (side, direction, count, length, angle, duration, adverbs) map to its parameters,
plus the word classes shared by all actions (filler, sequencing, numbers' units...). This
module loads it once, checks it against :data:`tasks.actions.REGISTRY` (every action has
English and Chinese words; every parameter it names exists with the right kind), and builds
the phrase table that :meth:`Lexicon.segment` matches, longest phrase first, over the atoms of
:mod:`language.normalize`.
"""

from __future__ import annotations

import functools
import itertools
import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from language.exceptions import VocabularyError
from language.families import measure_variants, merge, thing_words, verb_forms
from language.normalize import CJK, PUNCT, Atom, phrase_key, read_number
from tasks import REGISTRY, ActionSchema

VOCABULARY_PATH = Path(__file__).with_name("vocabulary.json")
#: Issue 32's phrasing families (context words, return words, not_things...), merged into the
#: vocabulary by :func:`get_lexicon` (see :mod:`language.families`).
PHRASINGS_PATH = Path(__file__).with_name("phrasings.json")
LANGUAGES = ("en", "zh")

# Item kinds produced by the segmenter.
TRIGGER = "trigger"  # names an action; value: tuple of (action, required body or None)
FILLER = "filler"
SEQ = "seq"
OVERLAY = "overlay"
AGAIN = "again"
NEG = "negation"
TIMES = "times"
CLASSIFIER = "classifier"
LR = "lr"  # value: "left" | "right"
SIDE = "side"  # value: "both"
DIR = "dir"  # value: "forward" | "backward" | "up" | "down"
ROT = "rot"  # value: +1 (counter-clockwise) | -1 (clockwise)
BODY = "body"  # value: (name, plural)
ADV = "adv"  # value: adverb key
UNIT = "unit"  # value: unit name (key of Lexicon.units)
NUM = "num"  # value: int | float
NEARMISS = "nearmiss"  # value: suggested action or None
UNKNOWN = "unknown"
PUNCTUATION = "punct"
SUBJECT = "subject"  # "a person", "he", "这个人": who does it (caption style), not used
AUX = "aux"  # "is", "starts to", "正在": verb forms around the action word, not used
IN_PLACE = "in_place"  # "in place", "on the spot", "原地": changes walk/step into march
STOP = "stop"  # "stop", "停下": ends the sequence (a bare one alone means: stand still)
REF = "object"  # a reference to a scene object ("the red box"); value: its words (made by the rule parser)
DEST = "destination"  # a reference to where an object goes ("on the shelf"); value: its words (rule parser)
CARRIED = "carried"  # a reference to an object carried along ("with the cup"); value: its words (rule parser)

#: Possessive words that stand for each other inside a vocabulary phrase (see
#: :meth:`Lexicon._add_possessive_variants`).
POSSESSIVES = ("your", "his", "her", "their", "my")

SLOT_KEYS = ("side", "direction", "count", "length", "angle", "duration")
BARE_LEFT_RIGHT = ("side", "direction", "sign", None)


@dataclass(frozen=True, slots=True)
class Item:
    """One recognised word or phrase of an instruction.

    Attributes:
        kind: One of the item kinds of this module (``trigger``, ``num``, ``lr``...).
        value: Kind-specific value (action candidates, number, ``"left"``...).
        text: The words as written (normalized).
        start, end: Character span in the normalized text.
    """

    kind: str
    value: Any
    text: str
    start: int
    end: int


@dataclass(frozen=True, slots=True, kw_only=True)
class Unit:
    """A unit word's quantity (``length``, ``angle``, ``duration``) and factor to SI [m, rad, s]."""

    name: str
    quantity: str
    factor: float


@dataclass(frozen=True, slots=True, kw_only=True)
class ActionWords:
    """How one action is named and how sentence slots map to its parameters.

    Attributes:
        name: Registry action name.
        body: Body words that may appear with it (``hand`` for wave).
        side: Parameter taking ``left``/``right``/``both`` from ``left hand``, ``双手`` (or None).
        direction: Choice parameter taking a direction word (or None).
        bare_left_right: Where a ``left``/``right`` not followed by a body word goes: ``side``,
            ``direction``, ``sign`` (sign of a signed angle, left positive) or None (not allowed).
        direction_params: Direction words that set parameters instead (``jump forward``).
        ignore_directions: Direction words that add nothing (``squat down``, ``jump up``).
        ignore_sides: Side words that add nothing (``jump with both feet``).
        count: Parameter taking ``N times`` (None: the action is repeated N times instead).
        length: Parameter taking a length [m]; ``length_by_direction`` overrides it per direction.
        angle: Parameter taking an angle [rad]; ``signed_angle``: left/counter-clockwise positive.
        rotation_side: ``counter-clockwise``/``clockwise`` set the side parameter to left/right
            (``walk in a counterclockwise circle``).
        duration: Parameter taking a duration [s].
        adverbs: Adverb key -> parameter values; a value is a number (SI) or ``{"scale": k}`` of
            the registry default.
        absorbs: Actions whose words this one takes over in the same clause (``walk 3 steps``).
        in_place: The action a clause with ``in place``/``原地`` becomes (``walk in place`` is
            ``march``); it may be missing from the registry (then the clause is refused). None:
            the action stays in place anyway and ``in place`` changes nothing.
        split: A numeric parameter whose value beyond its registry range is split into equal
            copies of the action (``turn 360 degrees`` is two turns of 180 degrees).
        object: Parameter taking a reference to a scene object (``the table``); an action with
            one is named by a clause that holds a reference.
        object_of: Actions whose words, with a reference to an object, name this one (``go`` is
            walk; ``go to the table`` is walk_to); this action's own words without a reference
            name the first of them (``walk to the left`` is walk).
        destination: Parameter taking a second reference, where the object goes (``put the cup
            on the shelf``, 把杯子放到架子上: ``on``).
        with_object: Parameter taking a second reference after ``with``, an object the robot
            carries (``walk to the table with the cup``: ``carrying``).
    """

    name: str
    body: tuple[str, ...] = ()
    side: str | None = None
    direction: str | None = None
    bare_left_right: str | None = None
    direction_params: Mapping[str, Mapping[str, float]] = field(default_factory=dict)
    ignore_directions: tuple[str, ...] = ()
    ignore_sides: tuple[str, ...] = ()
    count: str | None = None
    length: str | None = None
    length_by_direction: Mapping[str, str] = field(default_factory=dict)
    angle: str | None = None
    signed_angle: bool = False
    rotation_side: bool = False
    duration: str | None = None
    adverbs: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    absorbs: tuple[str, ...] = ()
    in_place: str | None = None
    split: str | None = None
    object: str | None = None
    object_of: tuple[str, ...] = ()
    destination: str | None = None
    with_object: str | None = None
    ask: str | None = None


class Lexicon:
    """Compiled vocabulary: phrase table, action slot maps, units, suggestions."""

    def __init__(self, data: Mapping[str, Any]) -> None:
        self.phrases: dict[tuple[str, ...], tuple[tuple[str, Any], ...]] = {}
        self.after_number: dict[tuple[str, ...], tuple[tuple[str, Any], ...]] = {}
        self.actions: dict[str, ActionWords] = {}
        #: (words before the object, words after it, action) of the actions' ``around`` phrases
        #: (``hand ... to me``: hand_over), longest first
        self.frames: list[tuple[tuple[str, ...], tuple[str, ...], str]] = []
        self.action_bodies: dict[str, set[str]] = {}
        self.action_words: dict[str, dict[str, list[str]]] = {}
        self.units: dict[str, Unit] = {}
        self.adverbs: set[str] = set(data["values"]["adv"])
        self.bodies: set[str] = set(data["values"]["body"])
        #: Adverb keys that an action without a mapping for them lists as "not used" instead of
        #: refusing (speed and mood words: "walk slowly", "wave happily").
        self.optional_adverbs: set[str] = set(data.get("optional_adverbs", ()))
        for name, spec in data["units"].items():
            self.units[name] = Unit(name=name, quantity=spec["quantity"], factor=float(spec["factor"]))
        self._load_actions(data["actions"])
        self.frames.sort(key=lambda f: -(len(f[0]) + len(f[1])))
        self._load_words(data)
        self._add_possessive_variants()
        self._add_families()
        #: word -> class of the words that never make a phrase an object (language.families)
        self.not_things: dict[str, str] = thing_words(data)
        self.max_len = max(len(k) for k in (*self.phrases, *self.after_number))
        self._check_registry()

    # -- loading -------------------------------------------------------------------------
    def _add(self, table: dict, phrase: str, entry: tuple[tuple[str, Any], ...], where: str) -> None:
        key = phrase_key(phrase)
        if not key:
            raise VocabularyError(f"vocabulary {where}: empty phrase {phrase!r}")
        old = table.get(key)
        if old is None:
            table[key] = entry
            return
        merged = _merge(old, entry)
        if merged is None:
            raise VocabularyError(f"vocabulary {where}: {phrase!r} already means {old}, cannot also mean {entry}")
        table[key] = merged

    def _load_actions(self, actions: Mapping[str, Any]) -> None:
        for name, spec in actions.items():
            if name not in REGISTRY:
                raise VocabularyError(f"vocabulary names action {name!r}, which is not in the registry ({', '.join(REGISTRY)})")
            unknown = set(spec) - {"words", "with_body", "phrases", "around", *(f.name for f in ActionWords.__dataclass_fields__.values())}
            if unknown:
                raise VocabularyError(f"vocabulary action {name!r}: unknown key(s) {sorted(unknown)}")
            words: dict[str, list[str]] = {lang: [] for lang in LANGUAGES}
            for lang, phrases in spec.get("words", {}).items():
                for phrase in phrases:
                    self._add(self.phrases, phrase, ((TRIGGER, ((name, None),)),), f"{name}.words")
                    words[lang].append(phrase)
            self.action_bodies[name] = set(spec.get("with_body", {}))
            for body, by_lang in spec.get("with_body", {}).items():
                if body not in self.bodies:
                    raise VocabularyError(f"vocabulary action {name!r}: unknown body word class {body!r}")
                for lang, phrases in by_lang.items():
                    for phrase in phrases:
                        self._add(self.phrases, phrase, ((TRIGGER, ((name, body),)),), f"{name}.with_body")
                        words[lang].append(f"{phrase} ({body})")
            for phrase, extras in spec.get("phrases", {}).items():
                entry = ((TRIGGER, ((name, None),)), *(_parse_item(x, f"{name}.phrases") for x in extras))
                self._add(self.phrases, phrase, entry, f"{name}.phrases")
                words["zh" if any("\u3400" <= ch <= "\u9fff" for ch in phrase) else "en"].append(phrase)
            for lang, frames in spec.get("around", {}).items():
                for frame in frames:
                    opener, dots, closer = frame.partition("...")
                    before, after = phrase_key(opener), phrase_key(closer)
                    if not dots or not (before or after) or spec.get("object") is None:
                        raise VocabularyError(f"vocabulary action {name!r}: around phrase {frame!r} needs '...' (where the "
                                              "object goes), words beside it, and an object parameter")
                    self.frames.append((before, after, name))
                    words[lang].append(frame)
            self.action_words[name] = words
            kwargs = {k: v for k, v in spec.items() if k not in ("words", "with_body", "phrases", "around")}
            for key in ("body", "ignore_directions", "ignore_sides", "absorbs", "object_of"):
                if key in kwargs:
                    kwargs[key] = tuple(kwargs[key])
            self.actions[name] = ActionWords(name=name, **kwargs)
        #: plain action -> its form with an object (walk -> walk_to), and back
        self.object_forms: dict[str, str] = {}
        self.plain_forms: dict[str, str] = {}
        for name, aw in self.actions.items():
            for plain in aw.object_of:
                self.object_forms.setdefault(plain, name)
            if aw.object_of:
                self.plain_forms[name] = aw.object_of[0]

    def _load_words(self, data: Mapping[str, Any]) -> None:
        words = data["words"]
        for kind in (FILLER, SEQ, OVERLAY, AGAIN, TIMES, CLASSIFIER, SUBJECT, AUX, IN_PLACE, STOP):
            for phrases in words[kind].values():
                for p in phrases:
                    self._add(self.phrases, p, ((kind, None),), f"words.{kind}")
        for phrases in words["negation"].values():
            for p in phrases:
                self._add(self.phrases, p, ((NEG, None),), "words.negation")
        for phrases in words["times_after_number"].values():
            for p in phrases:
                self._add(self.after_number, p, ((TIMES, None),), "words.times_after_number")
        values = data["values"]
        for kind in (LR, SIDE, DIR, ADV, UNIT):
            for value, by_lang in values[kind].items():
                if kind == UNIT and value not in self.units:
                    raise VocabularyError(f"vocabulary: unit word class {value!r} has no entry in 'units'")
                for phrases in by_lang.values():
                    for p in phrases:
                        self._add(self.phrases, p, ((kind, value),), f"values.{kind}.{value}")
        for value, by_lang in values[ROT].items():
            for phrases in by_lang.values():
                for p in phrases:
                    self._add(self.phrases, p, ((ROT, int(value)),), f"values.rot.{value}")
        for plural, group in ((False, values["body"]), (True, values["body_plural"])):
            for name, by_lang in group.items():
                for phrases in by_lang.values():
                    for p in phrases:
                        self._add(self.phrases, p, ((BODY, (name, plural)),), f"values.body.{name}")
        for phrase, items in data["compounds"].items():
            self._add(self.phrases, phrase, tuple(_parse_item(x, "compounds") for x in items), "compounds")
        self.near_misses: dict[str, str | None] = {}
        for by_word in data["near_misses"].values():
            for word, action in by_word.items():
                if action is not None and action not in REGISTRY:
                    raise VocabularyError(f"vocabulary near_misses: {word!r} suggests unknown action {action!r}")
                old = self.phrases.get(phrase_key(word))
                if old is not None and old[0][0] == TRIGGER:
                    continue  # an action's own word wins: "nod" is a near miss until nod is an action
                self._add(self.phrases, word, ((NEARMISS, action),), "near_misses")
                self.near_misses[word] = action
        self.suggestion_index: dict[str, str] = {}
        for with_body in (False, True):  # "turn" alone is turn; turn_head needs "head" with it
            for name, by_lang in self.action_words.items():
                for phrases in by_lang.values():
                    for p in phrases:
                        if p.endswith(")") == with_body:
                            self.suggestion_index.setdefault(p.split(" (")[0], name)
                self.suggestion_index.setdefault(name.replace("_", " "), name)

    def _add_possessive_variants(self) -> None:
        """Every multi-word phrase with a possessive also with the others: the vocabulary writes
        ``touch your head`` once, and ``touches their head``, ``hands on his hips`` read the same.

        A variant that is already a phrase keeps its own meaning (nothing is merged).
        """
        for key, entry in list(self.phrases.items()):
            slots = [i for i, w in enumerate(key) if w in POSSESSIVES]
            if not slots or len(key) < 2:
                continue
            for words in itertools.product(POSSESSIVES, repeat=len(slots)):
                variant = list(key)
                for i, w in zip(slots, words, strict=True):
                    variant[i] = w
                self.phrases.setdefault(tuple(variant), entry)

    def _check_registry(self) -> None:
        for name, schema in REGISTRY.items():
            words = self.action_words.get(name)
            if words is None or not all(words[lang] for lang in LANGUAGES):
                raise VocabularyError(f"vocabulary: action {name!r} needs English and Chinese words")
            aw = self.actions[name]
            for key in SLOT_KEYS:
                param = getattr(aw, key)
                if param is not None:
                    _check_param(schema, param, key)
            for direction, param in aw.length_by_direction.items():
                _check_param(schema, param, f"length_by_direction.{direction}")
            for direction, params in aw.direction_params.items():
                for p in params:
                    _check_param(schema, p, f"direction_params.{direction}")
            for adverb, params in aw.adverbs.items():
                if adverb not in self.adverbs:
                    raise VocabularyError(f"vocabulary action {name!r}: unknown adverb {adverb!r}")
                for p in params:
                    _check_param(schema, p, f"adverbs.{adverb}")
            if aw.bare_left_right not in BARE_LEFT_RIGHT:
                raise VocabularyError(f"vocabulary action {name!r}: bare_left_right must be one of {BARE_LEFT_RIGHT}")
            for body in aw.body:
                if body not in self.bodies:
                    raise VocabularyError(f"vocabulary action {name!r}: unknown body word class {body!r}")
            if aw.split is not None:
                _check_param(schema, aw.split, "split")
            if aw.object is not None:
                _check_param(schema, aw.object, "object")
                if schema.param(aw.object).kind != "object":
                    raise VocabularyError(f"vocabulary action {name!r}: object parameter {aw.object!r} is not an object reference")
            if aw.destination is not None:
                _check_param(schema, aw.destination, "destination")
                if schema.param(aw.destination).kind != "object" or aw.object is None:
                    raise VocabularyError(f"vocabulary action {name!r}: destination parameter {aw.destination!r} is not "
                                          "an object reference (or the action has no object)")
            if aw.with_object is not None:
                _check_param(schema, aw.with_object, "with_object")
                if schema.param(aw.with_object).kind != "object" or aw.object is None:
                    raise VocabularyError(f"vocabulary action {name!r}: with_object parameter {aw.with_object!r} is "
                                          "not an object reference (or the action has no object)")
            for plain in aw.object_of:
                if plain not in REGISTRY:
                    raise VocabularyError(f"vocabulary action {name!r}: object_of names unknown action {plain!r}")
            for other in aw.absorbs:
                if other not in REGISTRY:
                    raise VocabularyError(f"vocabulary action {name!r}: absorbs unknown action {other!r}")
            for key in ("side", "direction"):
                param = getattr(aw, key)
                if param is not None and schema.param(param).kind != "choice":
                    raise VocabularyError(f"vocabulary action {name!r}: {key} parameter {param!r} is not a choice")

    # -- use -----------------------------------------------------------------------------
    def _add_families(self) -> None:
        """Verb forms and Chinese measure words of every phrase (:mod:`language.families`); a
        variant that is already a phrase keeps its own meaning."""
        words = {k[0] for k, e in self.phrases.items() if len(k) == 1 and e[0][0] == TRIGGER}
        keys = [k for k, e in self.phrases.items() if e[0][0] == TRIGGER]
        for variant, key in (*verb_forms(keys, words).items(), *measure_variants(keys).items()):
            entry = self.phrases[key]
            if len(entry) == 1 and self.phrases.get(key[-1:], ((None,),))[0][0] == DIR:
                continue  # "stretch your arms up" says no direction: "stretches their arms" + "up" does
            if variant[:2] in self.phrases and variant[:2] != key[:2]:
                continue  # 高高举起: 高高 is a word of its own, not 高举 doubled
            self.phrases.setdefault(variant, entry)

    def _longest(self, table: Mapping, texts: list[str], i: int) -> tuple[int, tuple | None]:
        for n in range(min(self.max_len, len(texts) - i), 0, -1):
            entry = table.get(tuple(texts[i : i + n]))
            if entry is not None:
                return n, entry
        return 0, None

    def segment(self, atoms: list[Atom], normalized: str) -> list[Item]:
        """Items of an atomized instruction: longest known phrase (or longer number) first.

        Unknown atoms become ``unknown`` items (adjacent unknown Chinese characters merged).
        """
        texts = [a.text for a in atoms]
        items: list[Item] = []
        i = 0
        while i < len(atoms):
            atom = atoms[i]
            if atom.kind == PUNCT:
                items.append(Item(PUNCTUATION, None, atom.text, atom.start, atom.end))
                i += 1
                continue
            n, entry = 0, None
            if items and items[-1].kind == NUM:
                n, entry = self._longest(self.after_number, texts, i)
            if not n:
                n, entry = self._longest(self.phrases, texts, i)
            number = read_number(atoms, i)
            if number is not None and number[1] > n:
                value, n = number
                end = atoms[i + n - 1].end
                items.append(Item(NUM, value, normalized[atom.start : end], atom.start, end))
            elif n and entry is not None:  # _longest gives an entry with every n > 0
                end = atoms[i + n - 1].end
                text = normalized[atom.start : end]
                items.extend(Item(kind, value, text, atom.start, end) for kind, value in entry)
            else:
                n = 1
                prev = items[-1] if items else None
                if (atom.kind == CJK and prev is not None and prev.kind == UNKNOWN and prev.end == atom.start
                        and all("\u3400" <= ch <= "\u9fff" for ch in prev.text)):
                    items[-1] = Item(UNKNOWN, None, prev.text + atom.text, prev.start, atom.end)
                else:
                    items.append(Item(UNKNOWN, None, atom.text, atom.start, atom.end))
            i += n
        return items

    def suggest(self, word: str) -> str | None:
        """The known action an unknown word plausibly stands for, or None.

        First the near-miss list (``fly`` -> jump, ``坐下`` -> squat). Then, for English words of
        at least :data:`MIN_TYPO_LENGTH` letters, a typo of an action word: at most one edit
        (two for words of 8 letters or more), where an edit is a missing, extra or swapped
        letter or a letter replaced by a neighbouring key (``jumpp``, ``sqaut``, ``wqve``).
        ``boxing`` is not ``bowing`` and ``stops`` is not ``steps``: x/w and o/e are far apart
        on a keyboard. Chinese words get no spelling suggestion (a wrong character is another
        word, not a typo). A word the lexicon reads otherwise (``stops``: the end of a sequence) is
        never taken for a typo of an action word.
        """
        if word in self.near_misses:
            return self.near_misses[word]
        if phrase_key(word) in self.phrases:  # a word wbmp reads ("stops" ends a sequence) is no typo
            return None
        if not word.isascii() or not word.isalpha() or len(word) < MIN_TYPO_LENGTH:
            return None
        budget = 1 if len(word) < 8 else 2
        best: tuple[int, str] | None = None
        for known, name in self.suggestion_index.items():
            if abs(len(known) - len(word)) > budget or not known.isascii():
                continue
            d = typo_distance(word, known)
            if d <= budget and (best is None or d < best[0]):
                best = (d, name)
        return best[1] if best else None


MIN_TYPO_LENGTH = 4
_KEYBOARD_ROWS = ("1234567890", "qwertyuiop", "asdfghjkl", "zxcvbnm")


def _keyboard_neighbours() -> dict[str, set[str]]:
    pos = {ch: (r, c + 0.5 * r) for r, row in enumerate(_KEYBOARD_ROWS) for c, ch in enumerate(row)}
    return {a: {b for b, (r2, c2) in pos.items() if b != a and abs(r1 - r2) <= 1 and abs(c1 - c2) <= 1.0}
            for a, (r1, c1) in pos.items()}


KEYBOARD_NEIGHBOURS = _keyboard_neighbours()


def typo_distance(a: str, b: str) -> int:
    """Edit distance counting typing slips: a missing, extra or swapped letter, or a neighbouring
    key, costs 1; any other replaced letter costs 2 (it is a different word, not a slip)."""
    n, m = len(a), len(b)
    d = [[0] * (m + 1) for _ in range(n + 1)]
    for i in range(n + 1):
        d[i][0] = i
    for j in range(m + 1):
        d[0][j] = j
    for i in range(1, n + 1):
        for j in range(1, m + 1):
            if a[i - 1] == b[j - 1]:
                sub = 0
            else:
                sub = 1 if b[j - 1] in KEYBOARD_NEIGHBOURS.get(a[i - 1], ()) else 2
            d[i][j] = min(d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + sub)
            if i > 1 and j > 1 and a[i - 1] == b[j - 2] and a[i - 2] == b[j - 1]:
                d[i][j] = min(d[i][j], d[i - 2][j - 2] + 1)
    return d[n][m]


def _merge(old: tuple, new: tuple) -> tuple | None:
    """Union of two entries that differ only in their trigger candidates (None if they clash)."""
    if len(old) != len(new):
        return None
    out = []
    for (k1, v1), (k2, v2) in zip(old, new, strict=True):
        if k1 != k2:
            return None
        if k1 == TRIGGER:
            out.append((k1, tuple(dict.fromkeys((*v1, *v2)))))
        elif v1 != v2:
            return None
        else:
            out.append((k1, v1))
    return tuple(out)


def _parse_item(spec: str, where: str) -> tuple[str, Any]:
    kind, _, value = spec.partition(":")
    if kind == NUM:
        number = float(value)
        return NUM, int(number) if number.is_integer() else number
    if kind == BODY:
        return BODY, (value.rstrip("+"), value.endswith("+"))
    if kind in (TIMES,):
        return TIMES, None
    if kind in (ADV, DIR, LR, SIDE, UNIT):
        return kind, value
    raise VocabularyError(f"vocabulary {where}: cannot read item {spec!r}")


def _check_param(schema: ActionSchema, param: str, where: str) -> None:
    try:
        schema.param(param)
    except Exception as e:  # noqa: BLE001 - any schema error names the vocabulary item
        raise VocabularyError(f"vocabulary action {schema.name!r} {where}: {e}") from None


@functools.cache
def get_lexicon() -> Lexicon:
    """The lexicon of the packaged vocabulary, loaded once."""
    with VOCABULARY_PATH.open(encoding="utf-8") as f, PHRASINGS_PATH.open(encoding="utf-8") as g:
        extra = json.load(g)
        extra.pop("about", None)
        return Lexicon(merge(json.load(f), extra))
