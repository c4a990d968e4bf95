"""``wbmp solve --push FORCE@TIME``: every bad push is refused before planning, exit 2, one line.

The issue: ``--push 80@100`` on a 3 s motion never pushed and still certified PASS. Now a push
text is checked before any work (its syntax, then the force: above 0 N and at most
``sim.MAX_PUSH_FORCE``; the time: at least 0 s), and its time against the motion's length as
soon as the spec is built, before planning. ``sim.simulate`` refuses a late push too.
"""

from __future__ import annotations

import math
import re

import pytest
from hypothesis import given
from hypothesis import strategies as st

from sim import MAX_PUSH_FORCE, Push, PushParseError, check_push_time, parse_push
from tests.badinput.conftest import REPO, assert_refused, run_cli

SQ = REPO / "examples" / "specs" / "squat.json"
SENTENCE = "squat down 10 cm"
RAW_CONTROL = re.compile(r"[\x00-\x08\x0b-\x1f\x7f]")

# (push text, words the error line names): refused by the syntax check.
MALFORMED = [
    ("80@", ["'80@'", "FORCE@TIME"]),
    ("@1", ["'@1'", "FORCE@TIME"]),
    ("80@1@2", ["'80@1@2'", "FORCE@TIME"]),
    ("abc", ["'abc'", "FORCE@TIME"]),
    ("80", ["'80'", "FORCE@TIME"]),
    ("80@1ms", ["'80@1ms'", "FORCE@TIME"]),
    ("80N@1.5sec", ["FORCE@TIME"]),
    ("80,5@1", ["FORCE@TIME"]),
    ("0x50@1", ["FORCE@TIME"]),
    ("1_000@1", ["FORCE@TIME"]),
    ("\u0668\u0660@1", ["FORCE@TIME", "ASCII digits"]),  # Arabic-Indic 80
    ("\uff18\uff10@1", ["FORCE@TIME", "ASCII digits"]),  # full-width 80
    ("", ["''", "FORCE@TIME"]),
    ("   ", ["FORCE@TIME"]),
    ("80 @ 1 @", ["FORCE@TIME"]),
    ("80\x1b[31m@1", ["\\x1b", "FORCE@TIME"]),
    ("80@1\x00", ["\\x00", "FORCE@TIME"]),
    ("80@1\n2", ["\\n", "FORCE@TIME"]),
    ("9" * 100_000 + "@1", ["characters", "FORCE@TIME"]),
]

# Well-formed, but a value out of range.
OUT_OF_RANGE = [
    ("1e999@1", ["inf N", "5000 N"]),
    ("nan@1", ["nan N", "above 0 N"]),
    ("inf@1", ["inf N"]),
    ("-inf@1", ["-inf N"]),
    ("0@1", ["got 0 N", "above 0 N"]),
    ("0.0@1", ["got 0 N"]),
    ("-5@1", ["got -5 N", "above 0 N"]),
    ("5000.5@1", ["5000.5 N", "at most 5000 N"]),
    ("1e6@1", ["1e+06 N", "at most 5000 N"]),
    ("80@-1", ["got -1 s", "at least 0 s"]),
    ("80@-0.001", ["at least 0 s"]),
    ("80@nan", ["nan s"]),
    ("80@inf", ["inf s"]),
    ("80@1e999", ["inf s"]),
]


def _error_line(outcome) -> str:
    return next(ln for ln in outcome.err.splitlines() if ": error:" in ln)


@pytest.mark.parametrize(("text", "words"), MALFORMED + OUT_OF_RANGE, ids=lambda v: repr(v)[:30])
def test_bad_push_is_refused_before_any_work(text, words, capsys, tree):
    outcome = run_cli(["solve", SENTENCE, f"--push={text}", "--out", str(tree.root / "m.npz")], capsys)
    assert_refused(outcome, 2, "push", *words)
    line = _error_line(outcome)
    assert not RAW_CONTROL.search(line), line  # escaped, never raw to the terminal
    assert len(line) < 400
    assert "parsing the instruction" not in outcome.err  # refused before the sentence was read
    tree.assert_unchanged()


def _horizon() -> float:
    from tasks.serialize import load_spec

    return float(load_spec(SQ).horizon)


@pytest.mark.parametrize("when", ["100", "{h}", "{h}0", "1e6", "{h}01"])
def test_push_after_the_motion_is_refused_before_planning(when, capsys, tree):
    """``--push 80@100`` on a 3 s spec: the spec is built, then refused; nothing is planned."""
    horizon = _horizon()
    text = "80@" + when.format(h=f"{horizon:.17g}")
    outcome = run_cli(["solve", "--spec", str(SQ), f"--push={text}", "--out", str(tree.root / "m.npz")], capsys)
    assert_refused(outcome, 2, "push", "outside the motion", f"{horizon:.3g} s")
    assert "planning" not in outcome.err
    tree.assert_unchanged()


def test_push_after_a_sentence_motion_is_refused_before_planning(capsys, tree):
    outcome = run_cli(["solve", SENTENCE, "--push", "80@100", "--html", str(tree.root / "m.html")], capsys)
    assert_refused(outcome, 2, "push 80@100", "outside the motion")
    assert "parsing the instruction" in outcome.err and "planning" not in outcome.err
    tree.assert_unchanged()


@pytest.mark.parametrize("push", ["80@1", "80@100", "", "nonsense"])
def test_push_without_the_simulation_is_refused(push, capsys, tree):
    outcome = run_cli(["solve", SENTENCE, f"--push={push}", "--no-sim", "--out", str(tree.root / "m.npz")], capsys)
    assert_refused(outcome, 2, "--push", "--no-sim")
    tree.assert_unchanged()


def test_simulate_refuses_a_push_after_the_plan(motion_file):
    """The library refuses it too (before building the MuJoCo model), whoever calls it."""
    from robots import load_robot
    from sim import simulate
    from wbmp.motionfile import load_motion

    plan = load_motion(motion_file).plan
    end = float(plan.t[-1])
    with pytest.raises(PushParseError, match="outside the motion"):
        simulate(plan, load_robot("talos"), push=Push(force=80.0, time=end))
    with pytest.raises(PushParseError, match="outside the motion"):
        simulate(plan, load_robot("talos"), push=Push(force=80.0, time=100.0))


def test_valid_pushes_are_accepted():
    """The positive control: the forms the help shows, units, the range's ends."""
    assert parse_push("80@1.5") == Push(80.0, 1.5)
    assert parse_push(" 120.5N @ 0.25s ") == Push(120.5, 0.25)
    assert parse_push("80@1s") == Push(80.0, 1.0)
    assert parse_push("5000@0") == Push(MAX_PUSH_FORCE, 0.0)
    assert parse_push("1e-3@2e-1") == Push(0.001, 0.2)
    check_push_time(parse_push("80@1.5"), 3.0)
    check_push_time(parse_push("80@0"), 3.0)
    with pytest.raises(PushParseError):
        check_push_time(parse_push("80@3"), 3.0)


@pytest.mark.parametrize("kwargs", [
    {"force": 80.0, "time": 1.0, "duration": 0.0},
    {"force": 80.0, "time": 1.0, "duration": float("nan")},
    {"force": 80.0, "time": 1.0, "duration": 1e9},
    {"force": 80.0, "time": 1.0, "direction": (0.0, 0.0, 0.0)},
    {"force": 80.0, "time": 1.0, "direction": (float("nan"), 0.0, 0.0)},
    {"force": 80.0, "time": 1.0, "direction": (1.0, 0.0)},
    {"force": True, "time": 1.0},
    {"force": "80", "time": 1.0},
])
def test_push_values_are_validated_on_construction(kwargs):
    with pytest.raises(PushParseError) as err:
        Push(**kwargs)
    assert "\n" not in str(err.value)


@given(st.text(max_size=40))
def test_any_text_is_a_push_in_range_or_one_escaped_line(text):
    try:
        push = parse_push(text)
    except PushParseError as e:
        message = str(e)
        assert "\n" not in message and not RAW_CONTROL.search(message)
        assert "FORCE@TIME" in message
        return
    assert 0.0 < push.force <= MAX_PUSH_FORCE and 0.0 <= push.time and math.isfinite(push.time)


@given(st.floats(allow_nan=True, allow_infinity=True), st.floats(allow_nan=True, allow_infinity=True))
def test_numbers_are_accepted_exactly_within_the_documented_range(force, time_):
    text = f"{force!r}@{time_!r}"
    in_range = 0.0 < force <= MAX_PUSH_FORCE and 0.0 <= time_ < math.inf
    try:
        push = parse_push(text)
    except PushParseError:
        assert not in_range, text
        return
    assert in_range and (push.force, push.time) == (force, time_)
