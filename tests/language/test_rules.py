"""Rule parser pieces: normalization, numbers, the vocabulary against the registry, the plan."""

from __future__ import annotations

import copy
import json
import math

import pytest

from language import ActionPlan, InvalidParameter, LanguageError, UnknownWords, parse
from language.exceptions import VocabularyError
from language.lexicon import VOCABULARY_PATH, Lexicon, get_lexicon
from language.normalize import atomize, normalize, read_number
from language.rules import parse_rules
from tasks.actions import REGISTRY, Action


def number(text: str):
    atoms = atomize(normalize(text))
    got = read_number(atoms, 0)
    return None if got is None else got[0]


@pytest.mark.parametrize("text, value", [
    ("3", 3), ("0.3", 0.3), ("-90", -90), ("１２", 12),
    ("three", 3), ("twelve", 12), ("forty five", 45), ("forty-five", 45), ("ninety", 90),
    ("one hundred eighty", 180),
    ("三", 3), ("两", 2), ("十", 10), ("十二", 12), ("二十", 20), ("三十五", 35), ("九十", 90),
    ("一百八十", 180), ("一百零五", 105), ("零点三", 0.3), ("一点五", 1.5), ("半", 0.5),
])
def test_numbers(text, value):
    assert number(text) == pytest.approx(value, abs=1e-12)


@pytest.mark.parametrize("text", ["wave", "一点", "a"])
def test_not_numbers(text):
    """Words that are not numbers ("一点" alone means "a little")."""
    assert number(text) in (None, 1)  # "一点": the numeral 一 alone; the lexicon prefers "一点"
    if text == "一点":
        assert parse("前倾一点").to_dict()["actions"][0]["params"] == {"direction": "forward", "amount": 0.02}


def test_normalize_full_width_and_case():
    assert normalize("ＷＡＶＥ，Ｌｅｆｔ　３") == "wave,left 3"
    assert [a.text for a in atomize(normalize("Turn right 45°, then 3x"))] == ["turn", "right", "45", "°", ",", "then", "3", "x"]
    assert [a.text for a in atomize("挥手3次")] == ["挥", "手", "3", "次"]


def test_case_punctuation_whitespace_insensitive():
    """The same instruction in any case, punctuation and spacing gives the same plan."""
    base = parse("wave your right hand twice, then squat").to_dict()
    for variant in ("WAVE YOUR RIGHT HAND TWICE THEN SQUAT", "  wave   your right hand twice ;then squat!!! ",
                    "Wave your right hand twice... then squat?", "wave your right hand twice. Then squat."):
        assert parse(variant).to_dict() == base, variant


def test_every_registry_action_has_english_and_chinese_words():
    lx = get_lexicon()
    assert set(lx.action_words) == set(REGISTRY)
    for name, words in lx.action_words.items():
        assert words["en"] and words["zh"], name


@pytest.mark.parametrize("name", sorted(REGISTRY))
def test_every_action_parses_from_its_own_words(name):
    """Each action's first plain English and Chinese word parses to that action (with an object
    after it for the actions that take one: ``walk to`` alone is a walk)."""
    lx = get_lexicon()
    for lang in ("en", "zh"):
        plain = [w for w in lx.action_words[name][lang] if "(" not in w]
        if not plain:
            continue
        text = plain[0]
        if lx.actions[name].object is not None:
            text += " the cup" if lang == "en" else "杯子"
        if lx.actions[name].ask is not None:  # a bare "look" asks where (issue 32)
            text = f"{text} left" if lang == "en" else f"向左{text}"
        assert parse_rules(text)[0].action.name == name, (name, text)


def test_deeper_and_higher_than_plain():
    """Adverbs move parameters the right way: deep squat deeper, high jump higher, etc."""
    def p(text):
        return parse(text).actions[0].params

    assert p("Do a deep squat one time.")["depth"] > p("squat")["depth"]
    assert p("Jump up high.")["height"] > p("jump")["height"]
    assert p("squat a little")["depth"] < p("squat")["depth"]
    assert p("bow deeply")["angle"] > p("bow")["angle"] > p("bow slightly")["angle"]
    assert p("wave slowly")["duration"] > p("wave")["duration"] > p("wave quickly")["duration"]
    assert p("lean forward a lot")["amount"] > p("lean forward")["amount"] > p("lean forward a little")["amount"]


def test_turn_sign_follows_rep103():
    """Left / counter-clockwise is positive, right / clockwise negative, in radians."""
    angle = {t: parse(t).actions[0].params["angle"] for t in
             ("turn left 30 degrees", "turn right 30 degrees", "向左转30度", "向右转三十度", "turn clockwise 30 degrees",
              "turn counterclockwise 30 degrees")}
    assert angle["turn left 30 degrees"] == pytest.approx(math.radians(30), abs=1e-12)
    assert angle["turn right 30 degrees"] == pytest.approx(-math.radians(30), abs=1e-12)
    assert angle["向左转30度"] == angle["turn left 30 degrees"] == angle["turn counterclockwise 30 degrees"]
    assert angle["向右转三十度"] == angle["turn right 30 degrees"] == angle["turn clockwise 30 degrees"]


def test_units_convert_to_si():
    assert parse("walk 150 cm forward").actions[0].params["distance"] == 1.5
    assert parse("walk 500 mm forward").actions[0].params["distance"] == 0.5
    assert parse("stand still for half a second").actions[0].params["duration"] == 0.5
    assert parse("bow 0.5 rad").actions[0].params["angle"] == 0.5
    assert parse("向前走半米").actions[0].params["distance"] == 0.5


def test_unstated_parameters_are_omitted_but_defaults_filled():
    plan = parse("squat")
    assert plan.to_dict() == {"actions": [{"action": "squat", "params": {}}], "backend": "rules"}
    assert plan.actions[0].params["depth"] == REGISTRY["squat"].param("depth").default


def test_plan_json_round_trip_and_overlay_flag():
    plan = parse("wave your left hand while squatting, then turn right 45 degrees")
    data = plan.to_dict()
    assert data["actions"][1] == {"action": "wave", "params": {"arm": "left"}, "overlay": True}
    again = ActionPlan.from_dict(json.loads(json.dumps(data)), text=plan.text)
    assert again == plan
    assert again.actions[1] == Action(name="wave", params={"arm": "left"}, overlay=True)
    with pytest.raises(LanguageError, match="actions\\[0\\]"):
        ActionPlan.from_dict({"actions": [{"action": "fly"}]})
    with pytest.raises(LanguageError):
        ActionPlan.from_dict({"actions": []})


def test_describe_lists_stated_and_default_parameters():
    text = parse("wave your right hand twice while squatting").describe()
    assert text.splitlines()[0].startswith("1. squat  (defaults: depth=0.15 m")
    assert "+ at the same time: wave  arm=right, repeat=2  (defaults: duration=0.8 s)" in text


def test_error_messages_are_one_line_and_suggest():
    with pytest.raises(UnknownWords) as info:
        parse("please fly")
    msg = str(info.value)
    assert msg.startswith('could not understand "fly": known actions are ')
    assert msg.endswith('did you mean "jump"?')
    assert info.value.words == ("fly",) and info.value.suggestions == ("jump",)
    with pytest.raises(UnknownWords, match='did you mean "squat"'):
        parse("sqaut twice")
    with pytest.raises(InvalidParameter) as info:
        parse("squat 5 meters")
    assert str(info.value) == '"5 meters" in "squat 5 meters": squat depth 5 m is above the maximum 0.6 m'


def test_vocabulary_drives_the_parser():
    """A new word needs vocabulary, not parser code: add one and it parses."""
    data = json.loads(VOCABULARY_PATH.read_text(encoding="utf-8"))
    with pytest.raises(UnknownWords):
        parse_rules("boogie twice")
    data["actions"]["squat"]["words"]["en"].append("boogie")
    data["values"]["adv"]["deep"]["en"].append("profoundly")
    lx = Lexicon(data)
    got = parse_rules("boogie profoundly twice", lexicon=lx)
    assert got[0].action.name == "squat" and dict(got[0].action.params)["repeat"] == 2
    assert got[0].action.params["depth"] == 0.3


@pytest.mark.parametrize("edit, fragment", [
    (lambda d: d["actions"].pop("bow"), "'bow' needs English and Chinese words"),
    (lambda d: (d["actions"]["bow"]["words"].update(zh=[]), d["actions"]["bow"].pop("with_body")),
     "'bow' needs English and Chinese words"),
    (lambda d: d["actions"].update(fly={"words": {"en": ["fly"]}}), "not in the registry"),
    (lambda d: d["actions"]["squat"].update(length="height"), "squat has no parameter 'height'"),
    (lambda d: d["actions"]["squat"]["adverbs"].update(deep={"height": 1}), "no parameter 'height'"),
    (lambda d: d["actions"]["squat"].update(side="depth"), "not a choice"),
    (lambda d: d["values"]["lr"]["left"]["en"].append("forward"), "'forward' already means"),
    (lambda d: d["actions"]["squat"].update(speed=1), "unknown key"),
    (lambda d: d["actions"]["turn"].update(split="height"), "'turn' split: turn has no parameter 'height'"),
])
def test_inconsistent_vocabulary_is_refused(edit, fragment):
    data = copy.deepcopy(json.loads(VOCABULARY_PATH.read_text(encoding="utf-8")))
    edit(data)
    with pytest.raises(VocabularyError, match=fragment):
        Lexicon(data)


def test_parse_is_well_under_a_millisecond():
    """Median parse time over the corpus sentences < 1 ms (benchmarks/bench_parse.py has the full table)."""
    import statistics
    import time

    from tests.language.corpus import load_corpus

    texts = [c.text for c in load_corpus() if c.expected is not None]
    for t in texts:
        parse(t)  # warm-up: the vocabulary loads once
    times = []  # CPU time of this thread: other processes on a loaded machine do not count
    for t in texts:
        t0 = time.thread_time()
        parse(t)
        times.append(time.thread_time() - t0)
    assert statistics.median(times) < 1e-3, f"median {statistics.median(times) * 1e6:.0f} us"


def test_random_vocabulary_sentences_never_crash():
    """Seeded random strings of vocabulary phrases: a plan or a one-line LanguageError, nothing else."""
    import random

    lx = get_lexicon()
    phrases = sorted(" ".join(k) if k[0].isascii() else "".join(k) for k in lx.phrases)
    phrases += ["3", "0.5", "-2", "两", "十二", ",", "。", "1e9", "999"]
    rng = random.Random(20261122)
    parsed = 0
    for _ in range(3000):
        text = " ".join(rng.choice(phrases) for _ in range(rng.randint(1, 6)))
        try:
            plan = parse(text)
        except LanguageError as e:
            assert "\n" not in str(e), text
            continue
        parsed += 1
        assert plan.actions and not plan.actions[0].overlay, text
    assert parsed > 100  # the generator does reach the accepting paths


from hypothesis import given  # noqa: E402
from hypothesis import strategies as st  # noqa: E402


@given(st.text(max_size=40))
def test_arbitrary_text_gives_a_plan_or_a_language_error(text):
    try:
        parse(text)
    except LanguageError as e:
        assert str(e) and "\n" not in str(e) and "\r" not in str(e)
