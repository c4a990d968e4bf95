"""The motion cache answers a repeated ``wbmp retarget`` (same clip, window, robot): the same
motion and figures without planning; another window or edited clip bytes are planned afresh;
``--no-cache`` neither reads nor writes."""

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


def retarget(clip: Path, out: Path, capsys, *extra: str) -> dict:
    code = main(["retarget", str(clip), "--robot", "talos", "--start", "0", "--end", "0.6", "--no-sim",
                 "--json", "--out", str(out), *extra])
    assert code == 0
    lines = capsys.readouterr().out.strip().splitlines()
    return json.loads(lines[-1])


@pytest.fixture()
def cache_dir(tmp_path, monkeypatch):
    folder = tmp_path / "cache"
    monkeypatch.setenv("WBMP_CACHE_DIR", str(folder))
    return folder


def test_a_repeat_is_answered_from_the_cache(tmp_path, cache_dir, capsys):
    clip = tmp_path / "dance.bvh"
    shutil.copy(DANCE, clip)
    first = retarget(clip, tmp_path / "a.npz", capsys)
    assert first["cached"] is False and "plan" in first["timings"]
    assert any((cache_dir / "motions").iterdir())
    second = retarget(clip, tmp_path / "b.npz", capsys)
    assert second["cached"] is True and "plan" not in second["timings"] and "cache" in second["timings"]
    a, b = load_motion(tmp_path / "a.npz"), load_motion(tmp_path / "b.npz")
    np.testing.assert_array_equal(a.plan.q, b.plan.q)
    np.testing.assert_array_equal(a.plan.t, b.plan.t)
    # the figures are computed again from the cached motion: the same numbers as the first run's
    assert b.report["retarget"]["plan"] == a.report["retarget"]["plan"] == second["retarget"]["plan"]
    assert b.report["retarget"]["clip"] == str(clip)


@pytest.mark.long
def test_no_cache_and_another_clip_are_planned(tmp_path, cache_dir, capsys):
    """--no-cache neither writes (the next run plans) nor reads; edited clip bytes that change the
    task are another motion. Three plans: about a minute on a loaded machine."""
    clip = tmp_path / "dance.bvh"
    shutil.copy(DANCE, clip)
    first = retarget(clip, tmp_path / "a.npz", capsys, "--no-cache")
    assert first["cached"] is False and not (cache_dir / "motions").exists()
    second = retarget(clip, tmp_path / "b.npz", capsys)
    assert second["cached"] is False and "plan" in second["timings"]
    np.testing.assert_array_equal(load_motion(tmp_path / "a.npz").plan.q, load_motion(tmp_path / "b.npz").plan.q)

    # another clip (the hips 0.5 units, 2.8 cm, lower in every frame: a slightly deeper stance):
    # another task, planned afresh
    lines = clip.read_text().splitlines()
    motion_at = next(i for i, line in enumerate(lines) if line.startswith("Frame Time")) + 1
    for k in range(motion_at, len(lines)):
        values = lines[k].split()
        values[1] = f"{float(values[1]) - 0.5:.6f}"  # Yposition of the hips (y is up in this skeleton)
        lines[k] = " ".join(values)
    clip.write_text("\n".join(lines) + "\n")
    third = retarget(clip, tmp_path / "c.npz", capsys)
    assert third["cached"] is False and "plan" in third["timings"]
