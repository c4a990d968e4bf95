"""The language corpus: every instruction parses to the expected actions, or is rejected.

The corpus (``corpus.txt``) holds English and Chinese instructions: the tutorial sentences,
paraphrases, compositions, numbers and units, and rejections. Each line is its own test, and
``test_corpus_accuracy`` reports the accuracy over the whole corpus (required: 100 %).
"""

from __future__ import annotations

import re

import pytest

from tests.language import conftest
from tests.language.corpus import check, load_corpus

CASES = load_corpus()
CJK = re.compile(r"[\u3400-\u9fff]")


def test_corpus_size():
    """The corpus has >= 150 instructions, both languages, >= 30 rejections."""
    accepted = [c for c in CASES if c.expected is not None]
    rejected = [c for c in CASES if c.expected is None]
    zh = [c for c in CASES if CJK.search(c.text)]
    composed = [c for c in accepted if len(c.expected) > 1]
    assert len(CASES) >= 150, len(CASES)
    assert len(rejected) >= 30, len(rejected)
    assert len(zh) >= 60, len(zh)
    assert len(CASES) - len(zh) >= 60
    assert len(composed) >= 25, len(composed)


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_corpus_case(case):
    """One corpus line (the id is its line number in corpus.txt)."""
    assert check(case) is None, check(case)


def test_corpus_accuracy():
    """Accuracy over the whole corpus, reported in the summary; it must be 100 %."""
    failures = [r for r in map(check, CASES) if r is not None]
    accepted = sum(c.expected is not None for c in CASES)
    accuracy = 1.0 - len(failures) / len(CASES)
    conftest.CORPUS_SUMMARY.append(
        f"language corpus: {len(CASES) - len(failures)}/{len(CASES)} correct ({accuracy:.1%}); "
        f"{accepted} to parse, {len(CASES) - accepted} to reject"
    )
    assert not failures, f"corpus accuracy {accuracy:.1%}:\n" + "\n".join(failures)
