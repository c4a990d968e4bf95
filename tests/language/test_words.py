"""Issue 16, language: caption style, manner and mood words, in place, stop, suggestions, and
the word-by-word reading that ``wbmp parse`` prints.

The reference of most tests is the plain instruction: a caption ("a person slowly walks
forward") must give exactly the plan of the command it describes ("walk forward"), and the
registry (not the parser) gives the default a speed word scales.
"""

from __future__ import annotations

import json
import math

import pytest

from language import InvalidParameter, UnknownWords, UnsupportedInstruction, parse
from language.lexicon import VOCABULARY_PATH, Lexicon, get_lexicon, typo_distance
from language.llm import system_prompt
from language.normalize import PUNCT, atomize, normalize
from language.plan import ROLES
from language.rules import parse_rules
from tasks.actions import REGISTRY, ActionSchema, Param, actions_json_schema
from tests.language.corpus import load_corpus


def plan(text: str) -> list[dict]:
    return parse(text).to_dict()["actions"]


@pytest.mark.parametrize("caption, command", [
    ("a person walks forward", "walk forward"),
    ("the man is walking backward 2 meters", "walk backward 2 meters"),
    ("someone walked to the left", "walk to the left"),
    ("she starts to wave her right hand twice", "wave your right hand twice"),
    ("he performs three squats", "do three squats"),
    ("the robot takes two steps forward", "take two steps forward"),
    ("a woman begins jumping", "jump"),
    ("they turned around", "turn around"),
    ("他正在向前走两米", "向前走两米"),
    ("她挥了挥手", "挥手"),
    ("这个人蹲下了", "蹲下"),
    ("机器人向左转", "向左转"),
])
def test_captions_read_like_the_command(caption, command):
    assert plan(caption) == plan(command)


@pytest.mark.parametrize("text, action, factor", [
    ("wave slowly", "wave", 2.0), ("wave quickly", "wave", 0.6), ("wave briskly", "wave", 0.6),
    ("squat slowly", "squat", 2.0), ("a man squats fast", "squat", 0.6), ("bow slowly", "bow", 2.0),
    ("慢慢地挥手", "wave", 2.0), ("快速地蹲下", "squat", 0.6), ("缓慢地鞠躬", "bow", 2.0),
])
def test_speed_words_scale_the_registry_duration(text, action, factor):
    (got,) = plan(text)
    assert got["action"] == action
    assert math.isclose(got["params"]["duration"], factor * REGISTRY[action].param("duration").default)


def _mood_words() -> list[str]:
    data = json.loads(VOCABULARY_PATH.read_text(encoding="utf-8"))
    return [w for words in data["values"]["adv"]["mood"].values() for w in words]


def test_every_mood_word_is_accepted_and_listed_as_not_used():
    """Each mood/style word of the vocabulary: the plan is the plain one, the word is 'not used'."""
    words = _mood_words()
    assert len(words) >= 40
    for w in words:
        text = f"{w}挥手" if not w.isascii() else f"wave {w}"
        p = parse(text)
        assert p.to_dict()["actions"] == [{"action": "wave", "params": {}}], text
        assert [(u.text, u.role) for u in p.words if u.role == "not used"] == [(w, "not used")], text


def test_speed_word_on_an_action_without_duration_is_not_used_not_refused():
    p = parse("a person walks forward quickly")
    assert p.to_dict()["actions"] == [{"action": "walk", "params": {"direction": "forward"}}]
    assert {u.text: u.role for u in p.words}["quickly"] == "not used"
    with pytest.raises(InvalidParameter, match='"deep"'):
        parse("walk deep")  # a magnitude word that does not fit is still an error


def test_every_word_of_the_corpus_is_accounted_for():
    """For every accepted corpus sentence, the words listed cover every atom that is not
    punctuation, in order, each with a known role; action numbers point into the plan."""
    for case in load_corpus():
        if case.expected is None:
            continue
        p = parse(case.text)
        atoms = [a.text for a in atomize(normalize(case.text)) if a.kind != PUNCT]
        listed = [a.text for w in p.words for a in atomize(w.text)]
        assert listed == atoms, case.text
        for w in p.words:
            assert w.role in ROLES, (case.text, w)
            assert w.action is None or 1 <= w.action <= len(p.actions), (case.text, w)


def test_walk_in_place_never_walks_away():
    """Before this issue "in place" was filler and "walk in place" walked 0.6 m."""
    for text in ("walk in place", "step in place", "a person walks on the spot", "原地走", "原地走路"):
        if "march" in REGISTRY:
            assert [a.name for a in parse(text).actions] == ["march"], text
        else:
            with pytest.raises(UnsupportedInstruction, match="march") as info:
                parse(text)
            assert "\n" not in str(info.value)
    for text in ("walk in place", "原地走"):
        try:
            actions = parse(text).actions
        except UnsupportedInstruction:
            continue
        assert all(a.name not in ("walk", "step") for a in actions)


def test_in_place_turns_walk_into_march_when_the_registry_has_it(monkeypatch):
    """The rule follows the registry: add a march action (as the legs branch does) and the
    same sentences become march, its slots filled from march's own vocabulary entry."""
    data = json.loads(VOCABULARY_PATH.read_text(encoding="utf-8"))
    if "march" not in REGISTRY:
        monkeypatch.setitem(REGISTRY, "march", ActionSchema(
            name="march", summary="Step in place.", body="lower", dynamic=True,
            params=(Param(name="count", kind="int", unit="count", default=4, minimum=1, maximum=40),)))
        data["actions"]["march"] = {"words": {"en": ["march", "marches"], "zh": ["踏步"]}, "count": "count"}
    lx = Lexicon(data)
    for text in ("walk in place", "a person is walking in place", "step in place", "原地踏步", "在原地走"):
        (got,) = parse_rules(text, lexicon=lx)
        assert got.action.name == "march", text
    if "count" in REGISTRY["march"].resolve({}):
        (got,) = parse_rules("step in place 6 times", lexicon=lx)
        assert got.action.name == "march" and got.action.params["count"] == 6
    (turn,) = parse_rules("turn left in place", lexicon=lx)
    assert turn.action.name == "turn" and turn.action.params["angle"] == pytest.approx(math.pi / 2)
    # "march" was a near miss (-> step); the action's own word wins over it, no vocabulary clash
    assert lx.phrases[("march",)][0][0] == "trigger" and "march" not in lx.near_misses


def test_in_place_is_never_filler():
    p = parse("turn around on the spot")
    assert {u.text: u.role for u in p.words}["on the spot"] == "in place"
    data = json.loads(VOCABULARY_PATH.read_text(encoding="utf-8"))
    filler = {w for words in data["words"]["filler"].values() for w in words}
    assert not filler & {"in place", "on the spot", "原地"}


@pytest.mark.parametrize("with_stop, without", [
    ("walk forward and stop", "walk forward"),
    ("a person walks forward, then stops.", "walk forward"),
    ("wave twice, then come to a stop", "wave twice"),
    ("向前走然后停下", "向前走"),
    ("挥手两次，停", "挥手两次"),
    ("walk forward, stop, then turn left", "walk forward, then turn left"),
])
def test_a_final_stop_ends_the_sequence(with_stop, without):
    assert plan(with_stop) == plan(without)
    assert "stop" in {u.role for u in parse(with_stop).words}


def test_stop_alone_stands_and_stop_before_an_action_is_refused():
    assert plan("stop") == plan("停") == [{"action": "stand", "params": {}}]
    assert plan("stop for 2 seconds") == [{"action": "stand", "params": {"duration": 2.0}}]
    for text in ("stop waving", "停止挥手"):
        with pytest.raises(UnsupportedInstruction):
            parse(text)


def test_turns_beyond_half_a_turn_are_split_into_equal_turns():
    for text, total in (("turn 360 degrees", 2 * math.pi), ("转两圈", 4 * math.pi), ("turn right 270 degrees", -1.5 * math.pi),
                        ("转圈", 2 * math.pi)):
        angles = [a.params["angle"] for a in parse(text).actions]
        assert math.isclose(sum(angles), total) and all(abs(x) <= math.pi + 1e-12 for x in angles), text
        assert len(set(angles)) == 1, text
    with pytest.raises(InvalidParameter, match="3600 degrees"):
        parse("turn 3600 degrees")


@pytest.mark.parametrize("word, expected", [
    ("jumpp", "jump"), ("sqaut", "squat"), ("wvae", "wave"), ("steo", "step"), ("turb", "turn"),
    ("stnad", "stand"), ("baalnce", "balance"), ("wavr", "wave"),
    ("boxing", None), ("stops", None), ("tune", None), ("bake", None), ("jab", None), ("dab", None),
    ("出拳", None), ("摸头", None), ("踏出来", None),
])
def test_suggestions_only_when_plausible(word, expected):
    assert get_lexicon().suggest(word) == expected


def test_typo_distance_counts_slips_not_other_words():
    assert typo_distance("jump", "jump") == 0
    assert typo_distance("jumpp", "jump") == 1          # extra letter
    assert typo_distance("sqaut", "squat") == 1         # swapped letters
    assert typo_distance("wavr", "wave") == 1           # r is next to e
    assert typo_distance("boxing", "bowing") == 2       # x and w are far apart
    assert typo_distance("stops", "steps") == 2


def test_unknown_word_message_suggests_only_plausible_actions():
    with pytest.raises(UnknownWords) as info:
        parse("a person is juggling")
    assert info.value.suggestions == () and "did you mean" not in str(info.value)
    with pytest.raises(UnknownWords) as info:
        parse("jumpp twice")
    assert info.value.suggestions == ("jump",)


def test_llm_schema_and_prompt_list_every_registry_action(monkeypatch):
    """The LLM backend offers every registry action, new ones included, with no code change."""
    def offered() -> set[str]:
        branches = actions_json_schema()["properties"]["actions"]["items"]["oneOf"]
        return {b["properties"]["action"]["const"] for b in branches}

    assert offered() == set(REGISTRY)
    prompt = system_prompt()
    assert all(f"- {name}: " in prompt for name in REGISTRY)
    monkeypatch.setitem(REGISTRY, "zz_test_motion", ActionSchema(name="zz_test_motion", summary="A test motion.", body="upper"))
    assert "zz_test_motion" in offered() and "- zz_test_motion: A test motion." in system_prompt()
