"""The language corpus: every instruction parses to the expected actions, or is rejected.

The corpus (``corpus.txt``) holds English and Chinese instructions: the tutorial sentences,
paraphrases, compositions, numbers and units, and rejections. Each line is its own test, and
``test_corpus_accuracy`` reports the accuracy over the whole corpus (required: 100 %).
"""

from __future__ import annotations

import re

import pytest

from tasks.actions import REGISTRY
from tests.language import conftest
from tests.language.corpus import NEW_ACTIONS_PATH, check, load_corpus

CASES = load_corpus()
NEW_CASES = load_corpus(NEW_ACTIONS_PATH)
NEW_ACTIONS = sorted({a["action"] for c in NEW_CASES if c.expected for a in c.expected} - set(REGISTRY))
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


def test_corpus_of_new_actions_is_well_formed():
    """corpus_new_actions.txt: >= 60 lines, both languages, every expected action is a registry
    action or one of the motions of issue 16 (the file is checked as soon as they are merged)."""
    issue16 = {"kick", "march", "walk_arc", "hop", "lunge", "stomp", "jog", "punch", "clap", "touch",
               "hands_on_hips", "cross_arms", "arms_out", "point", "salute", "arm_circles", "shrug",
               "stretch", "nod", "shake_head"}
    assert len(NEW_CASES) >= 60 and sum(bool(CJK.search(c.text)) for c in NEW_CASES) >= 20
    assert set(NEW_ACTIONS) <= issue16, set(NEW_ACTIONS) - issue16


@pytest.mark.parametrize("case", NEW_CASES, ids=[c.id for c in NEW_CASES])
def test_corpus_new_actions_case(case):
    """One line of corpus_new_actions.txt; runs once every action it names is in the registry."""
    missing = sorted({a["action"] for a in case.expected or ()} - set(REGISTRY))
    if missing:
        pytest.skip(f"needs {', '.join(missing)} (issue 16 motions, merged separately)")
    assert check(case, strict=False) is None, check(case, strict=False)
