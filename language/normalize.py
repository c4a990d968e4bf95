"""Normalization and tokenization of English and Chinese instructions.

An instruction is first normalized (Unicode NFKC, so full-width ``３`` and ``，`` become ``3``
and ``,``; lower case; typographic quotes made plain), then cut into *atoms*: an English
word, a number written with digits, one Chinese character, a run of punctuation, or another
symbol. Chinese has no spaces, so words are only formed later, when the lexicon matches the
longest known phrase over the atoms (:mod:`language.lexicon`). The same function cuts the
vocabulary phrases, so ``"wave hello"`` and ``"挥手"`` become atom tuples the same way.

Numbers are read from atoms by :func:`read_number`: digits (``3``, ``0.3``, ``-90``), English
number words (``three``, ``forty five``, ``one hundred eighty``) and Chinese numerals
(``三``, ``两``, ``十二``, ``九十``, ``一百八十``, ``零点三``, ``半``).
"""

from __future__ import annotations

import re
import unicodedata
from dataclasses import dataclass

#: Atom kinds.
WORD, CJK, NUM, PUNCT, SYM = "word", "cjk", "num", "punct", "sym"

_ATOM_RE = re.compile(
    r"(?P<num>-?\d+(?:\.\d+)?)"
    r"|(?P<word>[a-z]+(?:'[a-z]+)?)"
    r"|(?P<cjk>[\u3400-\u4dbf\u4e00-\u9fff\u3007])"
    r"|(?P<punct>[,.;:!?\u3001\u3002\u2026\n]+)"
    r"|(?P<space>(?:[\s_/()\[\]{}\"'`~*#]|-(?!\d))+)"
    r"|(?P<sym>\S)"
)
MAX_NUMBER_CHARS = 40  # digits (with sign and decimal point) of one number in an instruction
_PLAIN = str.maketrans({"\u2018": "'", "\u2019": "'", "\u201c": '"', "\u201d": '"', "\u2212": "-", "\u2013": "-", "\u2014": "-"})

EN_ONES = {
    "zero": 0, "one": 1, "two": 2, "three": 3, "four": 4, "five": 5, "six": 6, "seven": 7,
    "eight": 8, "nine": 9, "ten": 10, "eleven": 11, "twelve": 12, "thirteen": 13, "fourteen": 14,
    "fifteen": 15, "sixteen": 16, "seventeen": 17, "eighteen": 18, "nineteen": 19,
}
EN_TENS = {"twenty": 20, "thirty": 30, "forty": 40, "fifty": 50, "sixty": 60, "seventy": 70, "eighty": 80, "ninety": 90}
ZH_DIGITS = {"零": 0, "〇": 0, "一": 1, "二": 2, "两": 2, "三": 3, "四": 4, "五": 5, "六": 6, "七": 7, "八": 8, "九": 9}
ZH_MULTIPLIERS = {"十": 10, "百": 100}


@dataclass(frozen=True, slots=True)
class Atom:
    """The smallest unit of an instruction.

    Attributes:
        text: The atom as written (normalized).
        kind: ``word``, ``cjk``, ``num``, ``punct`` or ``sym``.
        start, end: Character span in the normalized text.
    """

    text: str
    kind: str
    start: int
    end: int


def normalize(text: str) -> str:
    """NFKC, lower case, plain quotes and dashes; ``"Ｗａｖｅ，"`` -> ``"wave,"``."""
    return unicodedata.normalize("NFKC", text).translate(_PLAIN).lower()


def atomize(normalized: str) -> list[Atom]:
    """Cut a normalized text into atoms (blanks, hyphens and brackets are dropped)."""
    atoms = []
    for m in _ATOM_RE.finditer(normalized):
        kind = m.lastgroup
        assert kind is not None  # every alternative of _ATOM_RE is a named group
        if kind == "space":
            continue
        atoms.append(Atom(m.group(), kind, m.start(), m.end()))
    return atoms


def phrase_key(text: str) -> tuple[str, ...]:
    """The atom tuple of a vocabulary phrase, as the lexicon stores it."""
    return tuple(a.text for a in atomize(normalize(text)))


def read_number(atoms: list[Atom], i: int) -> tuple[float | int, int] | None:
    """The number that starts at ``atoms[i]``, as ``(value, atoms used)``; None if none does.

    Digits give an ``int`` when written without a decimal point.
    """
    a = atoms[i]
    if a.kind == NUM:
        if len(a.text) > MAX_NUMBER_CHARS:  # int() refuses 4,301 digits and is slow long before
            from language.exceptions import InvalidParameter

            raise InvalidParameter(f"the number {a.text[:12]}... is {len(a.text):,} characters long; a number in "
                                   f"an instruction has at most {MAX_NUMBER_CHARS} characters")
        return (float(a.text) if "." in a.text else int(a.text)), 1
    if a.kind == WORD:
        return _read_english(atoms, i)
    if a.kind == CJK:
        return _read_chinese(atoms, i)
    return None


def _word(atoms: list[Atom], j: int) -> str:
    return atoms[j].text if j < len(atoms) and atoms[j].kind == WORD else ""


def _read_english_below_100(atoms: list[Atom], j: int) -> tuple[int, int] | None:
    w = _word(atoms, j)
    if w in EN_ONES:
        return EN_ONES[w], 1
    if w in EN_TENS:
        nxt = _word(atoms, j + 1)
        if nxt in EN_ONES and 1 <= EN_ONES[nxt] <= 9:
            return EN_TENS[w] + EN_ONES[nxt], 2
        return EN_TENS[w], 1
    return None


def _read_english(atoms: list[Atom], i: int) -> tuple[int, int] | None:
    first = _read_english_below_100(atoms, i)
    if first is None:
        return None
    value, n = first
    if _word(atoms, i + n) == "hundred" and 1 <= value <= 9:
        value, n = value * 100, n + 1
        rest = _read_english_below_100(atoms, i + n)
        if rest is not None:
            value, n = value + rest[0], n + rest[1]
    return value, n


def _cjk(atoms: list[Atom], j: int) -> str:
    return atoms[j].text if j < len(atoms) and atoms[j].kind == CJK else ""


def _read_chinese(atoms: list[Atom], i: int) -> tuple[float | int, int] | None:
    if _cjk(atoms, i) == "半":
        return 0.5, 1
    total, digit, j, last_was_digit = 0, None, i, False
    while True:
        ch = _cjk(atoms, j)
        if ch in ZH_DIGITS:
            if last_was_digit and digit != 0:  # "一二" is no number; "一百零五" is
                break
            digit, last_was_digit = ZH_DIGITS[ch], True
        elif ch in ZH_MULTIPLIERS:
            if ch == "百" and digit is None:
                break
            total += (1 if digit is None else digit) * ZH_MULTIPLIERS[ch]
            digit, last_was_digit = None, False
        else:
            break
        j += 1
    if j == i:
        return None
    value: float | int = total + (digit or 0)
    # decimal part: 点 followed by digits (一点五 = 1.5); a bare 一点 means "a little"
    if _cjk(atoms, j) == "点" and _cjk(atoms, j + 1) in ZH_DIGITS:
        k, frac = j + 1, ""
        while _cjk(atoms, k) in ZH_DIGITS:
            frac += str(ZH_DIGITS[_cjk(atoms, k)])
            k += 1
        value, j = float(f"{value}.{frac}"), k
    return value, j - i
