"""The progress display: JSON lines, quiet, and plain lines on a non-terminal."""

from __future__ import annotations

import io
import json

import pytest

from viz.progress import Progress, make_progress


class FakeClock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def test_json_lines_report_stages_fractions_and_durations():
    out, clock = io.StringIO(), FakeClock()
    p = Progress("json", stream=out, clock=clock)
    with p.stage("planning"):
        clock.now += 0.5
        p.update(0.25, "iteration 5")
        clock.now += 1.0
    p("wrote motion.html")
    records = [json.loads(line) for line in out.getvalue().splitlines()]
    assert [r["event"] for r in records] == ["start", "progress", "end", "message"]
    assert records[1] == {"event": "progress", "stage": "planning", "elapsed": 0.5, "fraction": 0.25,
                          "message": "iteration 5"}
    assert records[2]["elapsed"] == pytest.approx(1.5) and records[2]["ok"] is True
    assert records[3]["message"] == "wrote motion.html"


def test_failed_stage_is_reported_and_the_error_propagates():
    out = io.StringIO()
    p = Progress("json", stream=out)
    with pytest.raises(RuntimeError), p.stage("simulating"):
        raise RuntimeError("fell")
    assert json.loads(out.getvalue().splitlines()[-1])["ok"] is False


def test_quiet_writes_nothing():
    out = io.StringIO()
    p = make_progress(quiet=True, json_lines=True, stream=out)
    with p.stage("x"):
        p.update(0.5, "half")
    p("hello")
    assert out.getvalue() == ""


def test_bar_on_a_non_terminal_writes_whole_lines_only():
    out, clock = io.StringIO(), FakeClock()
    p = Progress("bar", stream=out, clock=clock)
    assert not p.live
    with p.stage("building"):
        p.update(0.5)
        clock.now += 2.0
        with p.stage("quick step"):
            clock.now += 0.2  # under a second: nothing shown
    text = out.getvalue()
    assert "\r" not in text
    assert text == "done building (2.20 s)\n"


def test_live_line_shows_bar_and_message():
    clock = FakeClock()
    p = Progress("bar", stream=io.StringIO(), live=True, clock=clock)
    with p.stage("solving"):
        clock.now += 3.0
        p.update(0.5, "iteration 10")
        line = p.line()
    p.close()
    assert "solving" in line and "3.0 s" in line and "[##########..........]  50%" in line
    assert line.endswith("iteration 10")


def test_numbers_are_fractions_so_the_simulator_can_report():
    out = io.StringIO()
    p = Progress("json", stream=out)
    with p.stage("simulating"):
        p(0.3)
    assert json.loads(out.getvalue().splitlines()[1])["fraction"] == 0.3


def test_unknown_mode():
    with pytest.raises(ValueError, match="progress mode must be one of"):
        Progress("fancy")
