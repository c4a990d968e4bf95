"""``wbmp batch FOLDER``: a folder of BVH clips, each clip one item retargeted as ``wbmp
retarget`` does, with the retarget's physical figures in the index; and the LAFAN1 export of
such a retargeted motion."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from wbmp.cli import main
from wbmp.motionfile import load_motion

ROOT = Path(__file__).resolve().parents[2]
DANCE = ROOT / "examples" / "motions" / "18_15_dance.bvh"
WINDOW_END = 0.8  # [s] of the dance: a short plan (a few seconds of CPU)


@pytest.fixture(scope="module")
def library(tmp_path_factory):
    """A folder with the dance (window 0-0.8 s from its clips.csv) and an empty clip, batched on
    talos without simulation."""
    clips = tmp_path_factory.mktemp("clips")
    shutil.copy(DANCE, clips / "18_15_dance.bvh")
    (clips / "empty.bvh").write_bytes(b"")
    (clips / "notes.txt").write_text("not a clip")
    (clips / "clips.csv").write_text(f"file,label,start,end\n18_15_dance.bvh,chicken dance,0,{WINDOW_END}\n")
    out = tmp_path_factory.mktemp("lib")
    code = main(["batch", str(clips), "--out-dir", str(out), "--no-sim", "--workers", "1", "--quiet"])
    records = [json.loads(line) for line in (out / "index.jsonl").read_text().splitlines()]
    return clips, out, code, records


def test_each_clip_is_an_item(library):
    clips, out, code, records = library
    assert code == 3  # the empty clip's exit code, as `wbmp retarget` gives it
    assert [(r["clip"], r["line"], r["status"]) for r in records] == [("18_15_dance.bvh", 1, "ok"),
                                                                      ("empty.bvh", 2, "failed")]
    dance, empty = records
    assert (dance["start"], dance["end"]) == (0.0, WINDOW_END) and "start" not in empty
    assert empty["exit_code"] == 3 and "empty" in empty["message"] and empty["motion"] is None
    m = load_motion(out / dance["motion"])
    assert m.robot_name == "talos"
    # the motion covers the window (the retarget may add a lead-in and slow the clip down)
    section = m.report["retarget"]
    assert section["duration_s"] == pytest.approx(WINDOW_END, abs=0.01)
    assert m.plan.t[-1] >= WINDOW_END - 1e-9


def test_the_index_holds_the_physical_figures(library):
    """The index's figures are the motion file's report (the same numbers), and they are
    physical: mean <= max tracking error, no skate, penetration or float in the plan (the stance
    feet are constraints)."""
    _, out, _, records = library
    dance = records[0]
    figures = dance["retarget"]["plan"]
    m = load_motion(out / dance["motion"])
    assert figures == m.report["retarget"]["plan"] and dance["retarget"]["execution"] is None
    assert 0.0 < figures["tracking_mean_m"] <= figures["tracking_max_m"] < 0.5
    assert figures["foot_skate_mm"] < 0.1 and figures["penetration_mm"] < 0.1 and figures["float_mm"] < 0.1
    assert records[1].get("retarget") is None


def test_a_rerun_skips_the_done_clips(library, capsys):
    clips, out, _, _ = library
    assert main(["batch", str(clips), "--out-dir", str(out), "--no-sim", "--workers", "1", "--quiet"]) == 3
    assert "0 planned now, 2 done before" in capsys.readouterr().out


def test_lafan_export_of_a_retargeted_motion(library, tmp_path):
    """The retargeted motion as the LAFAN1 CSV: one row per 1/30 s, the file's q at those times."""
    _, out, _, records = library
    path = out / records[0]["motion"]
    m = load_motion(path)
    csv_path = tmp_path / "dance.csv"
    assert main(["export", str(path), "--format", "lafan", "--out", str(csv_path)]) == 0
    rows = np.loadtxt(csv_path, delimiter=",", ndmin=2)
    t = m.plan.t
    frames = t[0] + np.arange(int(np.floor((t[-1] - t[0]) * 30.0 + 1e-9)) + 1) / 30.0
    assert rows.shape == (len(frames), m.plan.q.shape[1])
    for i in (0, 1, 2, *range(7, m.plan.q.shape[1])):
        np.testing.assert_allclose(rows[:, i], np.interp(frames, t, m.plan.q[:, i]), rtol=0, atol=1e-12)


def test_a_folder_without_clips_is_refused(tmp_path, capsys):
    (tmp_path / "clips").mkdir()
    code = main(["batch", str(tmp_path / "clips"), "--out-dir", str(tmp_path / "lib")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "without .bvh clips" in err
    assert not (tmp_path / "lib").exists()
