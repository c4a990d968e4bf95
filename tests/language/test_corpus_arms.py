"""The arm, hand and head gestures' corpus (``corpus_arms.txt``): every line parses to its
expected actions or is rejected as it says, at 100 %."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from tests.language.corpus import check, load_corpus

CASES = load_corpus(Path(__file__).with_name("corpus_arms.txt"))
CJK = re.compile(r"[\u3400-\u9fff]")
GESTURES = {"punch", "clap", "touch", "hands_on_hips", "cross_arms", "arms_out", "point", "salute",
            "arm_circles", "shrug", "stretch", "nod", "shake_head"}


def test_corpus_covers_every_gesture_in_both_languages():
    """At least 60 lines; each gesture is expected in English and in Chinese lines."""
    assert len(CASES) >= 60, len(CASES)
    for lang, pick in (("en", lambda c: not CJK.search(c.text)), ("zh", lambda c: CJK.search(c.text))):
        named = {a["action"] for c in CASES if c.expected is not None and pick(c) for a in c.expected}
        assert GESTURES <= named, (lang, sorted(GESTURES - named))


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_corpus_arms_case(case):
    """One line (the id is its line number in corpus_arms.txt)."""
    assert check(case) is None, check(case)
