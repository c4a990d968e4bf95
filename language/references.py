"""References to scene objects in a sentence (the rule parser's object slots).

Split from :mod:`language.rules` (issue 31/32): :func:`nouns` reads an adverb word after
``the`` as a noun, :func:`around` turns the words around an object (``hand ... to me``) into
its action word, and :func:`references` merges the words of each reference (``the red box on
the table``, 桌子上的杯子) into one ``object`` item, after checking with
:func:`language.objects.not_a_thing` that they read as a thing; pronouns and borrowed
references (``walk over and point at the cup``) are resolved here too.
"""

from __future__ import annotations

from language.exceptions import InvalidParameter
from language.lexicon import (
    ADV,
    AUX,
    BODY,
    CARRIED,
    CLASSIFIER,
    DEST,
    DIR,
    FILLER,
    LR,
    NEARMISS,
    NUM,
    OVERLAY,
    PUNCTUATION,
    REF,
    SEQ,
    SUBJECT,
    TRIGGER,
    UNKNOWN,
    Item,
    Lexicon,
)
from language.normalize import phrase_key
from language.objects import not_a_thing
from tasks import strip_reference

REF_KINDS = (UNKNOWN, NEARMISS, FILLER, DIR, LR, CLASSIFIER, ADV)  # what the words of a reference can be
SIZE_ADVERBS = ("big", "small")  # the adverbs that can qualify an object ("the big box")
DETERMINERS = ("the", "that", "this", "a", "an")  # after one, an action word is a noun ("the box")
DEFINITE = ("the", "that", "this")  # "give me the box" is a hand-over, "give me a wave" a wave
POSSESSIVES = frozenset({"your", "my", "his", "her", "their", "你的", "我的", "他的", "她的"})
PRONOUNS = ("it", "them", "它", "它们")  # a reference to the object named before ("pick it up")
IMPLICIT_OBJECT = ("put_down", "hand_over")  # actions whose object, unsaid, is the one named before ("then put it
# down", 放下, "hand it to me")
PLACE_WORDS = ("on", "onto", "upon", "in", "into", "inside")  # "put the cup on the shelf": where the destination starts
PLACE_TRIGGER_ENDINGS = ("到", "在", "进")  # 放到, 放在: the reference after the action word is where it goes
PLACE_TRAILING = ("上面", "上边", "里面", "上", "里")  # 放到架子上: the shelf
HOLDING = ("pick_up",)  # actions whose object a hand then holds: what a put_down's "it" names


def nouns(items: list[Item]) -> list[Item]:
    """An adverb word after ``the``/``a`` at the end of a part is a noun, unknown to the parser
    (``turn on the light`` is no gentle turn)."""
    out = list(items)
    for k, it in enumerate(items):
        if (it.kind == ADV and not str(it.value).startswith("part_") and k > 0 and items[k - 1].kind == FILLER and items[k - 1].text in DETERMINERS
                and " " not in it.text and (k + 1 == len(items) or items[k + 1].kind in (SEQ, OVERLAY, PUNCTUATION))):
            out[k] = Item(UNKNOWN, None, it.text, it.start, it.end)
    return out


def _takes_object(trigger: Item, lx: Lexicon) -> bool:
    return any(lx.actions[a].object is not None or a in lx.object_forms for a, _ in trigger.value)


def references(items: list[Item], lx: Lexicon, normalized: str) -> list[Item]:
    """Items with each reference to a scene object (``the red box on the table``, 桌子上的杯子)
    merged into one ``object`` item.

    In a part of the sentence (between sequencing words and punctuation) whose action word can
    take an object (walk, look, point...), the words right after it, or else right before it,
    that hold at least one word the vocabulary does not know (the object's name: the scene
    decides, not the parser) are the reference, up to a word that is a slot of its own (a number,
    a hand, a speed). Elsewhere unknown words stay unknown (and are refused).
    """
    out: list[Item] = []
    part: list[Item] = []

    def reference_run(run: list[Item]) -> list[Item]:
        return _reference_run(run, lx, normalized)

    def merge(run: list[Item], kind: str = REF) -> None:
        text = normalized[run[0].start:run[-1].end]
        if kind == DEST:
            text = _destination_text(text)
        ref = Item(kind, strip_reference(text), text, run[0].start, run[-1].end)
        first = part.index(run[0])
        part[first:first + len(run)] = [ref]

    def flush() -> None:
        t = next((k for k, it in enumerate(part) if it.kind == TRIGGER and _takes_object(it, lx)), None)
        if t is not None and _places(part[t], lx):
            after = part[t + 1:]
            dest: list[Item] = []
            obj: list[Item] = []
            if part[t].text.endswith(PLACE_TRIGGER_ENDINGS):  # 把杯子放到架子上
                dest = _trim_destination(reference_run(after))
            else:  # put the cup on the shelf
                for p in reversed(range(len(after))):
                    if after[p].text in PLACE_WORDS:
                        dest = _trim_destination(reference_run(after[p + 1:]))
                        if dest:
                            obj = reference_run(after[:p])
                            break
            if dest:
                if not obj:
                    obj = list(reversed(reference_run(list(reversed(part[:t])))))
                merge(dest, DEST)
                if obj:
                    merge(obj)
                out.extend(part)
                part.clear()
                return
        if t is not None and any(lx.actions[a].with_object is not None for a, _ in part[t].value):
            after = part[t + 1:]
            for p in reversed(range(len(after))):
                if after[p].text == "with":  # walk to the table with the cup
                    carried = reference_run(after[p + 1:])
                    obj = reference_run(after[:p])
                    if carried and obj:
                        merge(carried, CARRIED)
                        merge(obj)
                        out.extend(part)
                        part.clear()
                        return
        if t is not None:
            run = reference_run(part[t + 1:])
            if not run:
                run = list(reversed(reference_run(list(reversed(part[:t])))))
            if any(lx.actions[a].bare_left_right == "direction" and lx.actions[a].object for a, _ in part[t].value):
                run = _without_way(run)  # "push the box to the left", 把箱子往左推: the way is a slot of its own
            if run:
                text = normalized[run[0].start:run[-1].end]
                ref = Item(REF, strip_reference(text), text, run[0].start, run[-1].end)
                first = part.index(run[0])
                part[first:first + len(run)] = [ref]
        out.extend(part)
        part.clear()

    for it in items:
        if it.kind in (SEQ, OVERLAY, PUNCTUATION):
            flush()
            out.append(it)
        else:
            if part and _goes_then_acts(part[-1], it, lx):  # 走过去拿起杯子: two actions, one after the other
                flush()
                out.append(Item(SEQ, None, "", it.start, it.start))
            part.append(it)
    flush()
    return _pronouns(_borrow_references(out, lx))


TREAD_CLASSIFIERS = ("级",)  # 三级台阶: three treads of the stairs


def _reference_run(run: list[Item], lx: Lexicon, normalized: str) -> list[Item]:
    """The words of ``run`` (after an action word, or before it, reversed) that name an object:
    up to a word that is a slot of its own, with at least one word the vocabulary does not know
    (or an action word after a determiner), and reading as a thing (:func:`not_a_thing`)."""
    taken: list[Item] = []
    named = False  # a word the vocabulary does not know, or an action word after "the" ("the box")
    skip = 0
    while skip < len(run) and ((run[skip].kind == ADV and run[skip].value not in SIZE_ADVERBS)
                               or (run[skip].kind == FILLER and run[skip].text in ("一下", "下"))):
        skip += 1  # "walk slowly to the table": the adverb is a slot of its own
    if skip + 2 < len(run) and run[skip].kind == NUM and run[skip + 1].kind == CLASSIFIER \
            and run[skip + 1].text in TREAD_CLASSIFIERS:
        skip += 2  # 走上三级台阶: the treads' count is a slot of its own, the stairs the object
    run = run[skip:]
    for k, it in enumerate(run):
        if it.text in PRONOUNS and not taken:
            return [it]  # "pick it up": the pronoun alone
        nxt = run[k + 1] if k + 1 < len(run) else None
        noun = it.kind == TRIGGER and any(t.kind == FILLER and t.text in DETERMINERS for t in taken) \
            and not _takes_object(it, lx)
        if noun:
            named = True
        elif it.kind not in REF_KINDS or (it.kind == LR and nxt is not None and nxt.kind == BODY) \
                or (it.kind == ADV and it.value not in SIZE_ADVERBS):
            break
        named = named or it.kind in (UNKNOWN, NEARMISS)
        taken.append(it)
    while taken and taken[-1].kind in (FILLER, CLASSIFIER, DIR):
        taken.pop()  # "put the cup down": the direction is a word of its own
    if taken and taken[0].text in POSSESSIVES:
        return []  # "touch your nose": a part of the body, not an object of the scene
    span = normalized[min(x.start for x in taken):max(x.end for x in taken)] if taken else ""
    if named and not_a_thing(sorted(taken, key=lambda x: x.start), span, lx) is not None:
        return []  # "walk in a zigzag", "walk up the stairs": its words are refused, naming them
    return taken if named else []


def around(items: list[Item], lx: Lexicon, normalized: str) -> list[Item]:
    """Items with the words of an action's ``around`` phrase (``hand ... to me``, ``give me ...``,
    ``... 给我``: hand_over) made its action word, where they stand around an object.

    Only in a part of the sentence (between sequencing words and punctuation) that has no action
    word of its own, and whose words in the ``...`` place (an object: fillers, directions... and at
    least one word the vocabulary does not know, or a pronoun) would otherwise be refused: the words
    before the object become the action word (the words after it, when none stand before), the
    others fillers. Before the phrase only fillers, subjects and auxiliaries (``please``,
    ``can you``); after it anything (``with your left hand``). ``give me a wave`` keeps its wave.
    """
    out: list[Item] = []
    part: list[Item] = []
    for it in [*items, None]:
        if it is None or it.kind in (SEQ, OVERLAY, PUNCTUATION):
            out.extend(_around_part(part, lx, normalized))
            part.clear()
            if it is not None:
                out.append(it)
        else:
            part.append(it)
    return out


def _around_part(part: list[Item], lx: Lexicon, normalized: str) -> list[Item]:
    def noun(j: int, determiners: tuple[str, ...]) -> bool:
        """An action word after one of ``determiners`` names an object (``the red box``), as in a reference."""
        if part[j].kind != TRIGGER or _takes_object(part[j], lx):
            return False
        i = j - 1
        while i >= 0 and part[i].kind in REF_KINDS and part[i].text not in determiners:
            i -= 1
        return i >= 0 and part[i].kind == FILLER and part[i].text in determiners

    nouns = {j for j in range(len(part)) if noun(j, DETERMINERS)}
    definite = {j for j in nouns if noun(j, DEFINITE)}
    if not lx.frames or any(it.kind == TRIGGER and j not in nouns for j, it in enumerate(part)):
        return part
    keys = [phrase_key(it.text) for it in part]

    def spell(words: tuple[str, ...], k: int) -> int:
        """How many items from ``k`` spell ``words`` exactly (0: they do not)."""
        got: tuple[str, ...] = ()
        n = 0
        while len(got) < len(words) and k + n < len(part):
            got += keys[k + n]
            n += 1
        return n if words and got == words else 0

    def word(j: int) -> bool:
        """``part[j]`` can be a word of an object."""
        return part[j].kind in REF_KINDS or part[j].text in PRONOUNS or j in nouns

    def names_object(a: int, b: int, closed: bool) -> bool:
        """Items ``a`` to ``b`` name an object: with words the vocabulary does not know, a pronoun, or
        an action word as a noun, after ``the`` (``this``, ``that``) when the phrase has no words
        after the object: ``give me the box``, ``give the box to me``, but ``give me a wave`` is a wave."""
        return b > a and all(word(j) for j in range(a, b)) and any(
            part[j].kind in (UNKNOWN, NEARMISS) or part[j].text in PRONOUNS or j in (nouns if closed else definite)
            for j in range(a, b)) and (any(part[j].text in PRONOUNS for j in range(a, b))
                                       or not_a_thing(part[a:b], normalized[part[a].start:part[b - 1].end], lx) is None)

    lead = 0
    while lead < len(part) and part[lead].kind in (FILLER, SUBJECT, AUX):
        lead += 1
    for opener, closer, action in lx.frames:
        for k in range(lead + 1):
            n = spell(opener, k) if opener else 0
            if opener and not n:
                continue
            first = k + n
            if closer:
                m = next((m for m in range(first + 1, len(part)) if spell(closer, m)), None)
                if m is None or not names_object(first, m, True):
                    continue
                closing = part[m:m + spell(closer, m)]
            else:
                end = first
                while end < len(part) and word(end):
                    end += 1
                if not names_object(first, end, False):
                    continue
                closing = []
            said = part[k:first] if opener else closing
            trigger = Item(TRIGGER, ((action, None),), normalized[said[0].start:said[-1].end], said[0].start, said[-1].end)
            rest = [Item(FILLER, None, it.text, it.start, it.end) if opener and it in closing else it for it in part]
            at = part.index(said[0])
            return [*rest[:at], trigger, *rest[at + len(said):]]
    return part


def _without_way(run: list[Item]) -> list[Item]:
    """A reference without the way words that end it (``the box to the left``, 箱子往左), for an action
    that takes left and right as its direction; nothing if no word of the object is left."""
    out = list(run)
    while out and out[-1].kind in (LR, DIR, FILLER, CLASSIFIER):
        out.pop()
    return out if any(it.kind not in (FILLER, CLASSIFIER) for it in out) else []


def _places(trigger: Item, lx: Lexicon) -> bool:
    """The action word can say where its object goes (put_down: ``put the cup on the shelf``)."""
    return any(lx.actions[a].destination is not None for a, _ in trigger.value)


def _trim_destination(run: list[Item]) -> list[Item]:
    """A destination without a trailing direction word (放到架子上: 上 is a word of its own)."""
    while len(run) > 1 and run[-1].kind == DIR:
        run = run[:-1]
    return run


def _destination_text(text: str) -> str:
    """Where an object goes, without ``top of`` and a trailing 上 (``on top of the shelf``, 架子上面)."""
    out = text.strip()
    if out.startswith("top of "):
        out = out[len("top of "):]
    for word in PLACE_TRAILING:
        if out.endswith(word) and out[: -len(word)].strip() and "的" not in out[-len(word) - 1:]:
            return out[: -len(word)].strip()
    return out


def _goes_then_acts(prev: Item, it: Item, lx: Lexicon) -> bool:
    """``prev`` only means going to an object (走过去, walk over) and ``it`` is another action word
    that takes one, right after it (走过去拿起那个杯子): a sequence without a sequencing word."""
    return (prev.kind == TRIGGER and it.kind == TRIGGER and prev.end == it.start
            and all(lx.actions[a].object is not None for a, _ in prev.value)
            and _takes_object(it, lx) and not any(a in {b for b, _ in prev.value} for a, _ in it.value))


def _pronouns(items: list[Item]) -> list[Item]:
    """A pronoun reference (``pick it up``, 把它放下) names the reference before it in the sentence,
    and so does an action of :data:`IMPLICIT_OBJECT` said without one (``then put it down``, 放下)."""
    out: list[Item] = []
    last = None  # the object named last
    held = None  # the object picked up last: what a put_down's "it" names ("walk to the shelf and put it on it")
    verb: Item | None = None  # the action word of this part of the sentence

    def placing() -> bool:
        return verb is not None and any(a in IMPLICIT_OBJECT for a, _ in verb.value)

    for k, it in enumerate(items):
        if it.kind in (SEQ, OVERLAY, PUNCTUATION):
            verb = None
        elif it.kind == TRIGGER:
            verb = it
            if any(a in HOLDING for a, _ in it.value) and out and out[-1].kind == REF and out[-1].end <= it.start:
                held = out[-1]  # 把杯子拿起来: the object before the action word
        if it.kind in (REF, DEST, CARRIED) and it.value in PRONOUNS:
            from_hand = held is not None and (it.kind == CARRIED or (it.kind == REF and (placing() or _places_next(items, k))))
            known = held if from_hand else last
            if known is None:
                raise InvalidParameter(f'"{it.text}": no object was named before it; say which object (e.g. "the cup")')
            out.append(Item(it.kind, known.value, it.text, it.start, it.end))
            if not from_hand:  # "put it on it": the second "it" is the object named before, not the held one
                last = out[-1]
            if it.kind == REF and verb is not None and any(a in HOLDING for a, _ in verb.value):
                held = out[-1]  # "walk to the cup and pick it up"
            continue
        if it.kind in (REF, DEST):
            last = it
            if it.kind == REF and verb is not None and any(a in HOLDING for a, _ in verb.value):
                held = it
        out.append(it)
        if it.kind == TRIGGER and last is not None and all(a in IMPLICIT_OBJECT for a, _ in it.value):
            end = next((j for j in range(k + 1, len(items)) if items[j].kind in (SEQ, OVERLAY, PUNCTUATION)), len(items))
            if not any(x.kind == REF for x in items[k + 1:end]) and not (out[-2:-1] and out[-2].kind == REF):
                out.append(Item(REF, (held or last).value, "", it.end, it.end))
    return out


def _places_next(items: list[Item], k: int) -> bool:
    """The reference ``items[k]`` is the object of a put_down said after it (把它放到架子上)."""
    for x in items[k + 1:]:
        if x.kind in (SEQ, OVERLAY, PUNCTUATION):
            return False
        if x.kind == TRIGGER:
            return any(a in IMPLICIT_OBJECT for a, _ in x.value)
    return False


def _borrow_references(items: list[Item], lx: Lexicon) -> list[Item]:
    """``walk over and point at the cup``: words that only mean going to an object (``walk over``,
    ``approach``, 走过去) without a reference of their own take the next reference of the sentence
    (an ``object`` item of no words, placed after the action word)."""
    out = list(items)
    for k, it in enumerate(items):
        if it.kind != TRIGGER or not all(lx.actions[a].object is not None for a, _ in it.value):
            continue
        end = next((j for j in range(k + 1, len(items)) if items[j].kind in (SEQ, OVERLAY, PUNCTUATION)), len(items))
        if any(x.kind == REF for x in items[k + 1:end]) or any(x.kind == REF for x in items[:k] if x.end == it.start):
            continue
        ref = next((x for x in items[end:] if x.kind == REF), None)
        if ref is not None:
            out.insert(out.index(it) + 1, Item(REF, ref.value, "", it.end, it.end))
    return out
