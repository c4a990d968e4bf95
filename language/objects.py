"""Which words may name an object of the scene (issue 32: no silent misreadings).

An object slot (``walk_to``, ``look_at``, ``touch_object``...) takes only a noun phrase, and
without a scene a phrase is an object only if it reads as a thing: it does not start with a
direction or a path preposition (``forward at a normal pace``, ``up the stairs``, ``in a
zigzag``, ``over a beam``), and none of its words is a manner, path shape, place, body part or
exercise word (``not_things`` in ``phrasings.json``: ``pace``, ``circle``, ``here``,
``belly``, ``push-ups``, 肚子). Everything else stays words the parser does not know, so the
sentence is refused naming them, instead of a ``walk_to "forward at a normal pace"`` that a
scene might even match by accident.
"""

from __future__ import annotations

import re
from collections.abc import Sequence

from language.lexicon import DIR, LR, Item, Lexicon

#: Prepositions that start a path, a manner or a place, never an object after the action word.
PATH_PREPOSITIONS = frozenset({
    "in", "on", "at", "like", "over", "up", "down", "around", "across", "along", "through", "onto",
    "into", "for", "by", "past", "under", "with", "as", "upstairs", "downstairs", "inside", "outside",
})
#: Chinese words that start a path around or past a thing (绕着桌子走 walks around the table, not to it).
ZH_PATH_PREFIXES = ("绕着", "围着", "沿着", "顺着", "围绕", "绕", "穿过", "经过", "越过", "跨过", "跳过")
#: Words that start an English noun phrase naming a thing (after ``to``/``towards``).
EN_DETERMINERS = frozenset({"the", "a", "an", "that", "this", "those", "these", "my", "your", "his", "her",
                            "their", "our", "its", "some", "one", "two", "three", "another", "each", "any"})
#: Words that only point at the speaker or a place nobody named (``walk towards me``, 看这里).
DEICTIC = frozenset({"me", "us", "you", "yourself", "here", "there", "我", "我们", "这里", "那里", "这边", "那边",
                     "这儿", "那儿"})
#: Words after which such a word is where to go or aim (``towards me``, ``at yourself``, 走向我).
GOAL_ENDINGS = ("to", "towards", "toward", "at", "over", "向", "到", "朝", "往")
#: Chinese place words that end a reference without naming anything (走到桌子那里: the table).
DEICTIC_SUFFIXES = ("那里", "这里", "那儿", "这儿", "那边", "这边")
_EN_WORD = re.compile(r"[a-z][a-z'-]*")
_CJK = re.compile(r"[\u3400-\u9fff]")


def not_a_thing(run: Sequence[Item], text: str, lx: Lexicon) -> str | None:
    """Why the words ``run`` (spelling ``text``) are no object of the scene, or None if they
    read as a thing."""
    if not run:
        return "no words"
    chinese = bool(_CJK.search(text))
    first = run[0]
    if first.kind in (DIR, LR) and not (chinese and "的" in text):
        return f'"{first.text}" is a direction'  # "forward at a normal pace", 左边 (左边的箱子 is a thing)
    words = _EN_WORD.findall(text.lower())
    if words and not chinese and words[0] in PATH_PREPOSITIONS:
        return f'"{words[0]}" starts a path or a manner'  # "in a zigzag", "up the stairs"
    lead = [w for w in words if w not in ("to", "towards", "toward", "over", "top", "of")]
    if not chinese and lead and lead[0] not in EN_DETERMINERS:
        return f'"{lead[0]}" starts no noun phrase'  # "walk away", "keep walking", "move closer"
    if chinese and text.startswith(ZH_PATH_PREFIXES):
        return f'"{text[:2]}" is a path around or past a thing'  # 绕着桌子走
    for w in words:
        cls = lx.not_things.get(w)
        if cls is not None:
            return f'"{w}" is a {cls} word'
    if chinese:
        head = strip_deictic(text).rpartition("的")[2]
        for w, cls in lx.not_things.items():
            if _CJK.search(w) and (head == w or (head.endswith(w) and len(w) > 1)):
                return f'"{w}" is a {cls} word'
    return None


#: Words after which an English reference names another object (``the box on the table``).
RELATION_WORDS = frozenset({"on", "onto", "in", "inside", "near", "behind", "beside", "under", "below", "above",
                            "next", "left", "right", "of", "by", "at", "with", "from", "between", "in front of"})
DETERMINER_WORDS = frozenset({"the", "a", "an", "that", "this", "those", "these", "to", "towards", "toward"})


def head_noun(text: str) -> str:
    """The word a reference is about (``the red box on the table``: box; 桌子上的杯子: 杯子), as
    ``wbmp parse`` shows it; the scene, not the parser, decides which object that is."""
    if _CJK.search(text):
        head = strip_deictic(text).rpartition("的")[2]
        for det in ("那个", "这个", "那只", "这只", "那张", "这张", "那", "这"):
            if head.startswith(det) and len(head) > len(det):
                head = head[len(det):]
                break
        return head.rstrip("上里") or head
    words = _EN_WORD.findall(text.lower())
    out = ""
    for w in words:
        if out and w in RELATION_WORDS:
            break
        if w not in DETERMINER_WORDS:
            out = w
    return out or text


def strip_deictic(text: str) -> str:
    """A Chinese reference without a trailing 那里/这里 (走到桌子那里: 桌子)."""
    for suffix in DEICTIC_SUFFIXES:
        if text.endswith(suffix) and text[: -len(suffix)].strip():
            return text[: -len(suffix)].strip()
    return text


def travel_direction(it: Item, normalized: str) -> bool:
    """``it`` (left/right in the sentence ``normalized``) is a way to go (``to the left``, 向左,
    ``towards the right``), not the side of a limb."""
    if it.kind != LR:
        return False
    if it.text.startswith(("to ", "toward", "向", "往", "朝")) or it.text.endswith(("ward", "wards")):
        return True
    before = normalized[:it.start].split()
    while before and before[-1] in ("the", "your", "his", "her", "their", "my"):
        before.pop()
    return bool(before) and (before[-1] in ("to", "toward", "towards") or before[-1].endswith(("向", "往", "朝")))


def deictic_goal(part: Sequence[Item]) -> Item | None:
    """In the items of one part of a sentence, a word that only points at the speaker or an
    unnamed place where the motion should go or aim (``walk towards me``, ``point at
    yourself``, ``come to me``, 走向我), or None."""
    for k in range(1, len(part)):
        it, prev = part[k], part[k - 1]
        if it.text in DEICTIC and prev.text.split()[-1].endswith(GOAL_ENDINGS) and it.kind not in (DIR, LR):
            return it
    return None
