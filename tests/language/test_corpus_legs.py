"""The leg-motion corpus (``corpus_legs.txt``): every line parses as expected (required: 100 %).

Same format and checker as ``corpus.txt`` (:mod:`tests.language.corpus`); kept in its own file
so that the words of kick, march, walk_arc, hop, lunge, stomp and jog are tested together.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from tests.language import corpus

LEGS_PATH = Path(__file__).with_name("corpus_legs.txt")
LEG_ACTIONS = {"kick", "march", "walk_arc", "hop", "lunge", "stomp", "jog"}
CJK = re.compile(r"[\u3400-\u9fff]")

CASES = corpus.load_corpus(LEGS_PATH)


def test_corpus_legs_size():
    """About 60 lines, both languages, every leg action expected somewhere, a few refusals."""
    zh = [c for c in CASES if CJK.search(c.text)]
    expected = {a["action"] for c in CASES if c.expected for a in c.expected}
    assert len(CASES) >= 40 and len(zh) >= 15 and len(CASES) - len(zh) >= 25
    assert LEG_ACTIONS <= expected
    assert sum(c.expected is None for c in CASES) >= 2


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_corpus_legs_case(case):
    """One line of corpus_legs.txt (the id is its line number)."""
    assert corpus.check(case) is None, corpus.check(case)
