"""The page's stop button during the simulation is the simulation's E-stop (issue 35 with issue
34's stop): a real planning process plans and simulates a squat; stop pressed once it simulates
ends the job with the motion, whose certificate names the stop and says the robot stayed up."""

from __future__ import annotations

import time

import pytest

from wbmp.serve.session import Session

LIMIT = 600.0  # [s] generous: a squat plans and simulates in well under a minute on a quiet machine


@pytest.fixture
def session(tmp_path, monkeypatch):
    monkeypatch.setenv("WBMP_COMPILE", "0")
    monkeypatch.setenv("WBMP_CACHE_DIR", str(tmp_path / "cache"))
    (tmp_path / "motions").mkdir()
    s = Session(folder=tmp_path / "motions")
    yield s
    s.close()


def test_stop_while_simulating_is_an_estop_that_keeps_the_motion(session):
    job = session.submit("squat down 10 cm")
    deadline = time.monotonic() + LIMIT
    while not any(line.startswith("simulating") for line in session.job(job.id)["progress"]):
        assert time.monotonic() < deadline, session.job(job.id)
        assert session.job(job.id)["state"] in ("queued", "running"), session.job(job.id)
        time.sleep(0.05)
    time.sleep(0.5)  # into the motion (the loop runs at about real time or faster)
    assert session.stop() == 1
    while session.job(job.id)["state"] in ("queued", "running"):
        assert time.monotonic() < deadline
        time.sleep(0.1)
    done = session.job(job.id)
    assert done["state"] == "done" and done["exit_code"] == 5, done
    assert any("E-stop" in line for line in done["progress"])
    certificate = session.motion(done["motion"]).summary["certificate"]
    assert certificate["ok"] is False
    (line,) = [c for c in certificate["checks"] if c["name"] == "e-stop"]
    assert "the page's stop button" in line["message"] and "stayed up" in line["message"], line
