"""``wbmp serve``'s "then <sentence>" and ``--motions`` with a real planning process.

The long test plans a turn, then "then squat": the squat alone is planned, and its motion file's
first knot is the turn's last knot (read back from the two motion files, not from the session);
"then" with a clip of the library is refused in words, and the clip as a new sentence is that
clip retargeted. The fast test calls the planning process's job function in this process: a
continuation that names a clip is refused before anything is planned.
"""

from __future__ import annotations

import shutil
import time
from pathlib import Path

import numpy as np
import pytest

from wbmp.errors import CliError
from wbmp.serve.session import Session
from wbmp.serve.worker import run_job

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "motions"
LIMIT = 900.0  # [s] for each plan on a busy machine: a bound, not a target


@pytest.fixture(scope="module")
def library(tmp_path_factory):
    folder = tmp_path_factory.mktemp("lib")
    shutil.copy(EXAMPLES / "13_29_squat.bvh", folder)
    (folder / "clips.csv").write_text("file,label,family,start,end\n13_29_squat.bvh,mocap dip,dip,0,1\n")
    return folder


def test_then_with_a_clip_is_refused_before_planning(library, tmp_path, talos):
    job = {"text": "do the mocap dip", "actions": None, "robot": None, "scene": None, "folder": str(tmp_path),
           "start": [float(x) for x in talos.q_standing], "motions": str(library)}
    t0 = time.perf_counter()
    with pytest.raises(CliError, match="motion-library clip 13_29_squat.bvh .* say it as a new sentence"):
        run_job(job, lambda _: None)
    assert time.perf_counter() - t0 < 60.0  # parsed and looked up, nothing planned (a bound, not a target)


def run(session: Session, text: str) -> dict:
    job = session.submit(text)
    deadline = time.monotonic() + LIMIT
    while session.job(job.id)["state"] in ("queued", "running"):
        assert time.monotonic() < deadline, session.job(job.id)
        time.sleep(0.1)
    return session.job(job.id)


@pytest.mark.long
def test_then_plans_from_where_the_last_motion_ended(library, tmp_path, monkeypatch):
    from wbmp.motionfile import load_motion

    monkeypatch.setenv("WBMP_COMPILE", "0")
    monkeypatch.setenv("WBMP_CACHE_DIR", str(tmp_path / "cache"))
    (tmp_path / "motions").mkdir()
    session = Session(folder=tmp_path / "motions", library=str(library))
    try:
        turn = run(session, "turn left 45 degrees")
        assert turn["state"] == "done" and turn["exit_code"] == 0, turn
        first = session.motion(turn["motion"])
        assert first.summary["end"]["kind"] == "start", first.summary["end"]

        squat = run(session, "then squat")
        assert squat["state"] == "done" and squat["exit_code"] == 0 and squat["kind"] == "continuation", squat
        second = session.motion(squat["motion"])
        assert [a["name"] for a in second.summary["actions"]] == ["squat"]  # only the new sentence
        assert second.parent == first.id and second.summary["start"] is not None
        before = load_motion(first.folder / "motion.npz").plan
        after = load_motion(second.folder / "motion.npz").plan
        np.testing.assert_allclose(after.q[0], before.q[-1], atol=1e-9)  # it starts where the turn ended
        turned = 2.0 * np.arctan2(before.q[-1][5], before.q[-1][6])
        assert turned == pytest.approx(np.radians(45.0), abs=np.radians(10.0))  # ... facing the new way

        refused = run(session, "then do the mocap dip")
        assert refused["state"] == "error" and refused["exit_code"] == 2
        assert "starts from its own first frame" in refused["error"], refused

        dip = run(session, "do the mocap dip")
        assert dip["state"] == "done", dip
        clip = session.motion(dip["motion"])
        assert "13_29_squat.bvh" in clip.summary["describe"]
        assert any("13_29_squat.bvh" in (w.get("detail") or "") for w in clip.summary["words"])
        assert clip.summary["certificate"] is not None
    finally:
        session.close()
