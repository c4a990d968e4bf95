"""Phrasing families (issue 32): rules that make one vocabulary phrase cover the ways people say it.

The vocabulary (``vocabulary.json``) writes each phrase once; the lexicon adds, for every phrase:

- **verb forms**: an English phrase written with a base verb (``walk in a half circle``) also
  with each inflection the vocabulary knows as a word of its own (``walks``, ``walking``,
  ``walked``: every single-word action word counts);
- **Chinese measure words and aspect**: a two- or three-character verb-object word (打招呼,
  鞠躬, 敬礼) also with 个, 了, 了个, 一, 一个, 了一, 了一个 after the verb (打个招呼, 鞠了一躬,
  敬个礼), and the verb doubled (摸摸头, 点点头), unless the object is a measure of its own
  (走一步 counts steps; 转一圈 counts turns) or the variant is a phrase already.

``phrasings.json`` is merged into the vocabulary (lists extended, mappings merged) before any of
this, so the families are data too. ``not_things`` there lists the words that never make a
phrase an object of the scene (see :func:`thing_words`).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

#: Chinese objects that are measures themselves: a number or 一 before them counts (走一步, 转一圈).
MEASURE_OBJECTS = frozenset("步圈次下遍回拳脚跳")
#: What may stand between a Chinese verb and its object (打个招呼, 鞠了一躬).
INSERTS = ("个", "了", "了个", "一", "一个", "了一", "了一个")


def merge(base: Any, extra: Any) -> Any:
    """``extra`` merged into ``base`` (new objects, ``base`` untouched): mappings key by key,
    lists extended with the items they lack, anything else from ``extra``."""
    if isinstance(base, Mapping) and isinstance(extra, Mapping):
        out = dict(base)
        for k, v in extra.items():
            out[k] = merge(base[k], v) if k in base else v
        return out
    if isinstance(base, list) and isinstance(extra, list):
        return [*base, *(x for x in extra if x not in base)]
    return extra


def verb_forms(keys: Iterable[tuple[str, ...]], words: set[str]) -> dict[tuple[str, ...], tuple[str, ...]]:
    """Variant key -> the key it stands for: the first word of a multi-word English phrase
    replaced by each of its inflections (``s``/``es``, ``ing``, ``ed``, with the final ``e``
    dropped or the last consonant doubled) that is in ``words`` (the single-word action words)."""
    out: dict[tuple[str, ...], tuple[str, ...]] = {}
    for key in keys:
        if len(key) < 2 or not key[0].isascii() or not key[0].isalpha():
            continue
        v = key[0]
        stem = v[:-1] if v.endswith("e") else v
        forms = {v + "s", v + "es", stem + "ing", stem + "ed", v + "ed", v + v[-1] + "ing", v + v[-1] + "ed"}
        for form in forms & words:
            out.setdefault((form, *key[1:]), key)
    return out


def measure_variants(keys: Iterable[tuple[str, ...]]) -> dict[tuple[str, ...], tuple[str, ...]]:
    """Variant key -> the key it stands for, for the two- and three-character Chinese words
    (keys of single characters, as the atomizer splits them)."""
    out: dict[tuple[str, ...], tuple[str, ...]] = {}
    for key in keys:
        if not 2 <= len(key) <= 3 or not all(len(c) == 1 and "\u3400" <= c <= "\u9fff" for c in key):
            continue
        verb, obj = key[0], key[1:]
        if obj[0] in MEASURE_OBJECTS or obj[0] in INSERTS[0] + "了一" or obj[0] == verb:
            continue
        for ins in INSERTS:
            out.setdefault((verb, *ins, *obj), key)
        out.setdefault((verb, verb, *obj), key)
    return out


def thing_words(data: Mapping[str, Any]) -> dict[str, str]:
    """Word -> its class (``manner``, ``path``, ``place``, ``body``, ``exercise``) for the words
    of ``not_things``: a phrase holding one is not an object of the scene."""
    out: dict[str, str] = {}
    for cls, by_lang in data.get("not_things", {}).items():
        for words in by_lang.values():
            for w in words:
                out.setdefault(w.lower(), cls)
    return out
