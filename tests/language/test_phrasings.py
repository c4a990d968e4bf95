"""Issue 32: the phrasing corpus and the rules that make a silent misreading impossible.

``corpus/sentences.jsonl`` was written and labelled before the parser was changed for it. Every
sentence either becomes the motion it says or is refused with a one-line error; a plan that is
not what was said (a *silent misreading*) fails its own test case. The design rules are then
checked on words the corpus does not hold: every word of ``not_things`` after an object verb,
every travel direction with every side-taking action, and "back" against a dead-reckoning of the
plan (an independent reference: where the robot ends up, from the actions' distances and turns).
"""

from __future__ import annotations

import math

import pytest

from language import InvalidParameter, LanguageError, parse
from language.lexicon import get_lexicon
from tests.language import conftest
from tests.language.phrasings import load, score

SENTENCES = load()
MIN_ACCURACY = 0.90  # issue 32's target on in-scope sentences (the corpus is at ~99 %)
POSITION_TOL = 1e-6  # [m] dead-reckoning of exact decimal distances


def test_corpus_size_languages_and_labels():
    """>= 400 sentences, both languages, in-scope and out-of-scope ones, every label readable."""
    assert len(SENTENCES) >= 400, len(SENTENCES)
    assert sum(s.lang == "zh" for s in SENTENCES) >= 100
    assert sum(s.lang == "en" for s in SENTENCES) >= 200
    assert sum(not s.in_scope for s in SENTENCES) >= 50
    for s in SENTENCES:
        assert (s.expected is None) == (not s.in_scope) or s.expected is not None, s.text
        assert s.expected is not None or s.refuse, f"{s.text!r}: a refusal names the words it must quote"
    assert len({s.text.lower() for s in SENTENCES}) == len(SENTENCES), "duplicate sentences"


@pytest.mark.parametrize("sentence", SENTENCES, ids=[s.id for s in SENTENCES])
def test_no_silent_misreading(sentence):
    """A sentence is parsed as labelled or refused in one line; never a plan that differs."""
    from tests.language.phrasings import grade

    outcome, did = grade(sentence)
    assert outcome != "misread", f"{sentence.text!r} silently became: {did}"
    if outcome in ("refused", "unnamed"):
        assert "\n" not in did


def test_accuracy_on_in_scope_sentences():
    """In-scope accuracy at least the issue's 90 %, and no misreading (the summary line prints it)."""
    r = score(SENTENCES)
    conftest.CORPUS_SUMMARY.append(
        f"phrasing corpus: {r['in_scope_right']}/{r['in_scope']} in-scope right ({r['accuracy_in_scope']:.1%}), "
        f"{r['misread']} silent misreadings, {r['refused']} refusals of {r['sentences']}")
    assert r["misread"] == 0
    assert r["accuracy_in_scope"] >= MIN_ACCURACY, r["accuracy_in_scope"]


# -- an object is a thing --------------------------------------------------------------------

def _not_things(lang: str) -> list[tuple[str, str]]:
    lx = get_lexicon()
    cjk = lang == "zh"
    return [(w, c) for w, c in sorted(lx.not_things.items())
            if any("\u3400" <= ch <= "\u9fff" for ch in w) == cjk and " " not in w]


@pytest.mark.parametrize("verb", ["walk to the", "look at the", "point at the", "pick up the"])
def test_no_manner_path_place_body_or_exercise_word_is_an_object(verb):
    """Every English word of ``not_things`` after an object verb: refused, or a plan with no
    object holding it (``walk to the left`` may walk left; it never walks to "left")."""
    for word, cls in _not_things("en"):
        text = f"{verb} {word}"
        try:
            plan = parse(text)
        except LanguageError as e:
            assert "\n" not in str(e)
            continue
        for a in plan.actions:
            for k, v in a.params.items():
                assert not (isinstance(v, str) and word in v.split()), (text, cls, a.name, k, v)


def test_chinese_body_and_place_words_are_no_objects():
    """走到/摸/看着 + every Chinese ``not_things`` word: never an object holding it."""
    for word, cls in _not_things("zh"):
        for verb in ("走到", "摸", "看着"):
            text = verb + word
            try:
                plan = parse(text)
            except LanguageError:
                continue
            for a in plan.actions:
                assert not any(isinstance(v, str) and word in v for v in a.params.values()), (text, cls, a)


@pytest.mark.parametrize("text, words", [
    ("walk forward at a normal pace", None),
    ("walk in a zigzag", "zigzag"),
    ("walk up the ladder", "ladder"),  # "walk down the stairs" is step_down (issue 33)
    ("walk like a robot", None),
    ("touch your belly", "belly"),
    ("do ten push-ups", "push-ups"),
    ("go to sleep", "sleep"),
    ("come here", "come here"),
    ("摸肚子", "肚子"),
    ("walk away", "away"),
    ("keep walking", "keep"),
    ("move closer", "closer"),
    ("walk towards me", "me"),
    ("point at yourself", "yourself"),
    ("turn on the light", "light"),
    ("绕着桌子走", "绕"),
    ("看那边", "那"),
    ("走过来", "走过来"),
    ("把手放在头上", "手"),
])
def test_the_misreadings_of_the_issue(text, words):
    """The issue's examples: accepted without an object, or refused naming the words."""
    try:
        plan = parse(text)
    except LanguageError as e:
        assert words is not None and words in str(e), str(e)
        return
    assert words is None, plan.to_dict()
    assert all(a.name not in ("walk_to", "touch_object", "push") for a in plan.actions), plan.to_dict()


def test_grounding_of_every_object_word_is_shown():
    """``wbmp parse`` lists each object with why it reads as a thing (its head noun)."""
    plan = parse("walk to the red box on the table, then point at 桌子上的杯子")
    refs = [w for w in plan.words if w.role == "object"]
    assert [w.detail for w in refs] == [
        "object=the red box on the table (a thing: 'box'; the scene resolves it)",
        "object=桌子上的杯子 (a thing: '杯子'; the scene resolves it)",
    ]


# -- a travel direction is never a side ------------------------------------------------------

@pytest.mark.parametrize("action", ["hop", "kick", "stomp", "wave", "punch", "balance", "salute"])
@pytest.mark.parametrize("way", ["to the left", "to the right", "towards the left"])
def test_a_travel_direction_is_never_a_side(action, way):
    """``hop to the left`` is refused naming the words, never ``foot=left``."""
    with pytest.raises(LanguageError) as e:
        parse(f"{action} {way}")
    assert way.split()[-1] in str(e.value) and "\n" not in str(e.value)


def test_a_side_is_still_a_side():
    assert parse("hop on your left foot").to_dict()["actions"][0]["params"]["foot"] == "left"
    assert parse("side lunge to the right").to_dict()["actions"][0]["params"] == {"leg": "right", "direction": "side"}


# -- "back" after a walk is the way home: checked by dead reckoning ---------------------------

def _end_position(actions) -> tuple[float, float]:
    """Where the robot ends, from walk/step distances and turn angles (planar, start at 0)."""
    x = y = yaw = 0.0
    for a in actions:
        p = a.params
        if a.name == "turn":
            yaw += p["angle"]
        elif a.name in ("walk", "step"):
            dist = p["distance"] if a.name == "walk" else p["count"] * p["length"]
            heading = yaw + {"forward": 0.0, "backward": math.pi, "left": math.pi / 2, "right": -math.pi / 2}[
                p["direction"]]
            x += dist * math.cos(heading)
            y += dist * math.sin(heading)
    return x, y


@pytest.mark.parametrize("text", [
    "walk forward, turn around and walk back",
    "walk forward 2 meters, turn around and walk back",
    "a person walks forward 1.5 meters, turns around, and returns to the start",
    "walk backward 1 meter, then come back",
    "walk forward 3 meters and walk back to where you started",
    "take three steps forward, turn around and walk back",
    "往前走两米，转身，走回来",
    "向前走一米，然后回到原点",
    "walk forward 2 meters, turn left, turn left, and walk back",
    "a person walks to the right and then comes back",
    "walk left 1 meter, turn around, then walk back",
])
def test_back_means_back_to_the_start(text):
    """The robot ends where it started (dead reckoning of the parsed plan)."""
    x, y = _end_position(parse(text).actions)
    assert math.hypot(x, y) < POSITION_TOL, (text, x, y, parse(text).to_dict())


@pytest.mark.parametrize("text", ["go back to the start", "回到原点", "walk forward, turn left and go back to the start"])
def test_back_to_the_start_without_a_way_is_refused(text):
    with pytest.raises(InvalidParameter) as e:
        parse(text)
    assert "\n" not in str(e.value)


def test_plain_back_stays_backward():
    """Without a walk before it, "walk back" / "take a step back" is backward, as said."""
    assert parse("walk back").to_dict()["actions"] == [{"action": "walk", "params": {"direction": "backward"}}]
    assert parse("walk forward, then take a step back").to_dict()["actions"][1]["params"] == {
        "direction": "backward", "count": 1}


# -- a bare look asks where; families --------------------------------------------------------

@pytest.mark.parametrize("text", ["look", "看", "a person looks", "turn your head"])
def test_a_bare_look_asks_where(text):
    with pytest.raises(InvalidParameter) as e:
        parse(text)
    assert "direction" in str(e.value)


@pytest.mark.parametrize("variant, plain", [
    ("打个招呼", "打招呼"), ("鞠了一躬", "鞠躬"), ("敬个礼", "敬礼"), ("点了点头", "点头"),
    ("a person walks in a half circle to the right", "walk in a half circle to the right"),
    ("walking a quarter circle", "walk a quarter circle"),
    ("kick with the right leg, then the same with the left", "kick with the right leg, then kick with the left leg"),
    ("wave at the camera", "wave"), ("跟大家打个招呼", "挥手"), ("jog on the treadmill", "jog"),
    ("walk forward at medium speed", "walk forward"), ("复位", "stand"),
    ("a person raises their left arm and then lowers it", "raise your left arm"),
    ("wave, then bring it down", "wave"),
])
def test_a_family_member_reads_as_its_plain_phrase(variant, plain):
    assert parse(variant).to_dict()["actions"] == parse(plain).to_dict()["actions"]


@pytest.mark.parametrize("text", ["wave at the camera", "walk forward at a normal pace", "jog on the treadmill"])
def test_context_words_are_listed_not_used(text):
    roles = {w.text: (w.role, w.detail) for w in parse(text).words}
    assert any(role == "not used" and ("context" in d or "normal speed" in d) for role, d in roles.values()), roles
