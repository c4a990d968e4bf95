"""An ActionPlan converts exactly to its record (the motion cache keeps it beside a request) and
back: the actions with every parameter, the stated names, the text, the backend and the words,
for every accepted sentence of the language corpus (English and Chinese)."""

from __future__ import annotations

import json

import pytest

from language import ActionPlan, LanguageError, parse
from tests.language.corpus import load_corpus


def _accepted() -> list[str]:
    return [c.text for c in load_corpus() if c.expected is not None]


def test_every_corpus_plan_round_trips_through_json():
    texts = _accepted()
    assert len(texts) > 100
    for text in texts:
        plan = parse(text)
        back = ActionPlan.from_record(json.loads(json.dumps(plan.to_record())))
        assert back == plan, text
        assert back.words == plan.words and back.text == plan.text, text  # words take no part in ==
        assert back.describe() == plan.describe() and back.to_dict() == plan.to_dict(), text


@pytest.mark.parametrize("damage", [
    lambda r: r.pop("words"),
    lambda r: r.update(given=[["depth"]] * 5),
    lambda r: r.update(actions=[{"action": "fly", "params": {}}]),
    lambda r: r.update(actions="squat"),
    lambda r: r["words"].append({"role": "action"}),
], ids=["no words", "given per action", "unknown action", "not a list", "word without text"])
def test_a_damaged_record_is_a_language_error(damage):
    record = parse("squat 20 cm, then wave twice").to_record()
    damage(record)
    with pytest.raises(LanguageError, match="not an action plan record|action"):
        ActionPlan.from_record(record)
