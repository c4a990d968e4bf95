"""The actions on scene objects' corpus (``corpus_objects.txt``): every line parses to its
expected actions, the reference's words handed over as said, or is rejected as it says, at 100 %."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from language import parse
from tests.language.corpus import check, load_corpus

CASES = load_corpus(Path(__file__).with_name("corpus_objects.txt"))
CJK = re.compile(r"[\u3400-\u9fff]")
OBJECT_ACTIONS = {"walk_to", "look_at", "point_at", "pick_up", "put_down"}


def test_corpus_covers_every_object_action_in_both_languages():
    """At least 50 lines; each object action is expected in English and in Chinese lines."""
    assert len(CASES) >= 50, len(CASES)
    for lang, pick in (("en", lambda c: not CJK.search(c.text)), ("zh", lambda c: CJK.search(c.text))):
        named = {a["action"] for c in CASES if c.expected is not None and pick(c) for a in c.expected}
        assert OBJECT_ACTIONS <= named, (lang, sorted(OBJECT_ACTIONS - named))


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_corpus_objects_case(case):
    """One line (the id is its line number in corpus_objects.txt)."""
    assert check(case) is None, check(case)


def test_the_reference_is_one_word_use_with_the_object_role():
    """``wbmp parse`` lists the reference as one phrase whose role is ``object``."""
    plan = parse("walk to the red box on the table, then point at 那个杯子 with your left hand")
    refs = [w for w in plan.words if w.role == "object"]
    assert [(w.text, w.detail, w.action) for w in refs] == [
        ("the red box on the table", "object=the red box on the table (a thing: 'box'; the scene resolves it)", 1),
        ("那个杯子", "object=那个杯子 (a thing: '杯子'; the scene resolves it)", 2),
    ]
    assert plan.to_dict()["actions"][1]["params"] == {"object": "那个杯子", "arm": "left"}


def test_object_actions_fit_the_backends_schema():
    """The reply schema every backend is checked against (the LLM's too) accepts the object actions."""
    from language.validate import validate
    from tasks.actions import actions_json_schema

    plan = parse("walk over to the red box, then point at 桌子上的杯子 with your left hand").to_dict()
    validate({"actions": plan["actions"]}, actions_json_schema())
    assert [a["action"] for a in plan["actions"]] == ["walk_to", "point_at"]
