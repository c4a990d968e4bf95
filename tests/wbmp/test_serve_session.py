"""The session's reading of a job (wbmp.serve.session): correction, continuation, undo, sentence.

No plan is made: the last motion is one whose summary holds the actions of a parsed sentence,
as the planning process reports them (wbmp.serve.worker.describe_actions).
"""

from __future__ import annotations

import pytest

from language import parse
from wbmp.serve import corrections
from wbmp.serve.session import Job, Motion, Session
from wbmp.serve.worker import describe_actions


@pytest.fixture
def session(tmp_path):
    s = Session(folder=tmp_path, start_worker=False)
    yield s
    s.close()


def add_motion(session, text, *, parent=None, ident="a" * 12, step_duration=0.8):
    plan = parse(text)
    motion = Motion(id=ident, text=text, kind="sentence", folder=session.folder, parent=parent,
                    summary={"actions": describe_actions(plan), "step_duration": step_duration})
    session.motions[motion.id] = motion
    session.history.append(motion.id)
    session.last = motion.id
    return motion


def test_a_sentence_is_planned_from_its_words(session):
    request, parent = session._interpret(Job(id="j", text="squat twice"))
    assert request == {"text": "squat twice", "actions": None} and parent is None


def test_a_correction_sends_the_changed_actions(session):
    last = add_motion(session, "wave your left hand")
    job = Job(id="j", text="慢一点")
    request, parent = session._interpret(job)
    assert parent == last.id and job.kind == "correction"
    (wave,) = request["actions"]
    assert wave["name"] == "wave" and wave["params"]["arm"] == "left"
    assert wave["params"]["duration"] == pytest.approx(1.5 * last.summary["actions"][0]["params"]["duration"])
    assert set(wave["given"]) == {"arm", "duration"}
    assert job.changes[0]["param"] == "duration" and "x1.5" in job.changes[0]["text"]
    assert request["text"] == "wave your left hand (慢一点)"


def test_a_correction_needs_a_motion(session):
    with pytest.raises(corrections.CorrectionError, match="there is none yet"):
        session._interpret(Job(id="j", text="slower"))


def test_then_continues_the_last_actions(session):
    add_motion(session, "squat")
    job = Job(id="j", text="then wave your right hand twice")
    request, parent = session._interpret(job)
    assert job.kind == "continuation" and parent == "a" * 12
    assert [a["name"] for a in request["actions"]] == ["squat", "wave"]
    assert request["actions"][1]["params"] == {"arm": "right", "repeat": 2}
    assert request["text"] == "squat, then wave your right hand twice"
    job = Job(id="k", text="然后鞠躬")
    request, _ = session._interpret(job)
    assert [a["name"] for a in request["actions"]] == ["squat", "bow"]


def test_then_without_a_motion_is_a_sentence(session):
    request, parent = session._interpret(Job(id="j", text="then squat"))
    assert request["actions"] is None and parent is None


def test_undo_goes_back_to_the_parent(session):
    first = add_motion(session, "squat", ident="a" * 12)
    add_motion(session, "squat (slower)", parent=first.id, ident="b" * 12)
    job = Job(id="j", text="undo")
    assert session._interpret(job) is None
    assert session.last == first.id and job.state == "done" and job.motion == first.id
    with pytest.raises(corrections.CorrectionError, match="nothing to undo"):
        session._interpret(Job(id="k", text="撤销"))


def test_slower_walk_sends_the_pace_and_then_keeps_it(session):
    add_motion(session, "walk forward 1 m", step_duration=0.8)
    job = Job(id="j", text="slower")
    request, _ = session._interpret(job)
    assert request["step_duration"] == pytest.approx(1.2)
    assert request["actions"] == [{"name": "walk", "overlay": False, "given": ["direction", "distance"],
                                   "params": {"direction": "forward", "distance": 1.0}}]
    assert [ch["param"] for ch in job.changes] == ["step_duration"]
    add_motion(session, "walk forward 1 m (slower)", ident="b" * 12, step_duration=1.2)
    request, _ = session._interpret(Job(id="k", text="then squat"))
    assert request["step_duration"] == 1.2  # a continuation keeps the pace
    request, _ = session._interpret(Job(id="l", text="walk forward"))
    assert "step_duration" not in request  # a new sentence: the robot's own pace


def test_then_starts_where_the_last_motion_ended(session):
    end_q = [0.3, 0.1, 1.0, 0.0, 0.0, 0.0, 1.0, 0.2]
    last = add_motion(session, "turn left")
    last.summary["end"] = {"kind": "start", "q": end_q, "reason": ""}
    job = Job(id="j", text="then wave your right hand")
    request, parent = session._interpret(job)
    assert job.kind == "continuation" and parent == last.id
    # only the new sentence is planned, from the last knot of the last motion, at its pace
    assert request == {"text": "wave your right hand", "actions": None, "start": end_q, "step_duration": 0.8}
    assert "starting where 'turn left' ended" in job.progress[-1]


def test_a_correction_of_a_continuation_keeps_its_start(session):
    last = add_motion(session, "squat")
    last.summary["start"] = [0.3, 0.1, 1.0, 0.0, 0.0, 0.0, 1.0, 0.2]
    request, _ = session._interpret(Job(id="j", text="slower"))
    assert request["start"] == last.summary["start"]


def test_then_where_no_motion_can_start_is_refused_in_words(session):
    last = add_motion(session, "squat")
    last.summary["end"] = {"kind": "refused", "q": None, "reason": "the last motion ends with the left foot off the "
                           "ground (its last phase is not standing on both feet)"}
    with pytest.raises(corrections.CorrectionError,
                       match="no motion can start there: the last motion ends with the left foot off the ground"):
        session._interpret(Job(id="j", text="then squat"))


def test_then_after_holding_an_object_plans_both_from_the_last_start(session):
    last = add_motion(session, "squat")
    last.summary["end"] = {"kind": "together", "q": None, "reason": "the robot ends holding the cup"}
    last.summary["start"] = [0.3, 0.1, 1.0, 0.0, 0.0, 0.0, 1.0, 0.2]
    job = Job(id="j", text="then bow")
    request, _ = session._interpret(job)
    assert [a["name"] for a in request["actions"]] == ["squat", "bow"]
    assert request["start"] == last.summary["start"] and "holding the cup" in job.progress[-1]


def test_a_continuation_that_does_not_parse_is_the_cli_line(session):
    last = add_motion(session, "squat")
    last.summary["end"] = {"kind": "together", "q": None, "reason": "the robot ends holding the cup"}
    job = session.submit("then frobnicate the garlic")
    session._queue.clear()
    session._run(job)
    assert job.state == "error" and job.exit_code == 2 and "frobnicate" in job.error, job
