"""``wbmp retarget``: bad clips and options refused in one line with their exit code, nothing written."""

from __future__ import annotations

from pathlib import Path

import pytest

from wbmp.cli import main

MOCAP = Path("/work/shared/mocap")
HEAD = ("HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation "
        "Xrotation\n End Site\n {\n  OFFSET 0 1 0\n }\n}\nMOTION\n")


@pytest.fixture(autouse=True)
def _no_compilation(monkeypatch, tmp_path):
    monkeypatch.setenv("WBMP_COMPILE", "0")
    monkeypatch.setenv("WBMP_CACHE_DIR", str(tmp_path / "cache"))


def _walk_lines(frames: int) -> str:
    text = (MOCAP / "12_01_walk.bvh").read_text()
    head, _, motion = text.partition("MOTION\n")
    rows = motion.splitlines()[2:]
    return head + f"MOTION\nFrames: {frames}\nFrame Time: 0.0083333\n" + "\n".join(rows[:frames]) + "\n"


CASES = {
    "empty": (b"", "empty"),
    "binary": (bytes(range(256)) * 4, "binary"),
    "truncated": (HEAD.encode()[:50], "truncated"),
    "nan": ((HEAD + "Frames: 3\nFrame Time: 0.01\n" + "0 0 nan 0 0 0\n" * 3).encode(), "finite numbers"),
    "channels": ((HEAD + "Frames: 3\nFrame Time: 0.01\n" + "0 0 0 0 0 0 0\n" * 3).encode(), "7 values"),
    "frame count": ((HEAD + "Frames: 9\nFrame Time: 0.01\n" + "0 0 0 0 0 0\n" * 3).encode(), "says 9 frames"),
    "10^7 frames": ((HEAD + "Frames: 10000000\nFrame Time: 0.01\n" + "0 0 0 0 0 0\n").encode(), "10,000,000 frames"),
    "unknown skeleton": ((HEAD + "Frames: 3\nFrame Time: 0.01\n" + "0 0 0 0 0 0\n" * 3).encode(), "unknown skeleton"),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_a_bad_clip_exits_3_in_one_line_and_writes_nothing(case, tmp_path, capsys):
    raw, message = CASES[case]
    clip = tmp_path / "clip.bvh"
    clip.write_bytes(raw)
    out, html = tmp_path / "m.npz", tmp_path / "m.html"
    code = main(["retarget", str(clip), "--out", str(out), "--html", str(html), "--no-sim", "--quiet"])
    err = capsys.readouterr().err
    assert code == 3, err
    assert err.count("\n") == 1 and message in err and "Traceback" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cache", "clip.bvh"] or not out.exists()
    assert not out.exists() and not html.exists()


@pytest.mark.skipif(not MOCAP.is_dir(), reason="the shared CMU clips are not on this machine")
@pytest.mark.parametrize(("args", "code", "message"), [
    (["--start", "9"], 3, "--start 9 s is at or after the end of the clip"),
    (["--start", "2", "--end", "1"], 2, "--end 1 s must be after --start 2 s"),
    (["--start", "-1"], 2, "expected seconds >= 0"),
    (["--robot", "nao"], 3, "nao"),
])
def test_bad_windows_and_robots(args, code, message, tmp_path, capsys):
    out = tmp_path / "m.npz"
    try:
        got = main(["retarget", str(MOCAP / "13_29_squat.bvh"), *args, "--out", str(out), "--no-sim", "--quiet"])
    except SystemExit as e:  # argparse's own refusal of a malformed value
        got = e.code
    err = capsys.readouterr().err
    assert got == code, err
    assert message in err and not out.exists()


@pytest.mark.skipif(not MOCAP.is_dir(), reason="the shared CMU clips are not on this machine")
def test_a_window_over_the_work_bound_exits_3(tmp_path, capsys):
    """A 70 s clip (the walk's frames repeated) is refused before any planning: over 60 s of work."""
    text = (MOCAP / "12_01_walk.bvh").read_text()
    head, _, motion = text.partition("MOTION\n")
    rows = motion.splitlines()[2:]
    many = (rows * 17)[:8400]
    clip = tmp_path / "long.bvh"
    clip.write_text(head + f"MOTION\nFrames: {len(many)}\nFrame Time: 0.0083333\n" + "\n".join(many) + "\n")
    code = main(["retarget", str(clip), "--no-sim", "--quiet", "--out", str(tmp_path / "m.npz")])
    err = capsys.readouterr().err
    assert code == 3 and "wbmp retargets at most 58.2 s" in err and "cut it with --start/--end" in err
    assert not (tmp_path / "m.npz").exists()


def test_a_skeleton_mapping_that_names_missing_joints_exits_3(tmp_path, capsys):
    mapping = tmp_path / "mine.toml"
    mapping.write_text("unit = 0.01\n[joints]\n" + "".join(
        f"{k} = 'X{k}'\n" for k in ("pelvis", "torso", "head", "left_shoulder", "right_shoulder", "left_hand",
                                    "right_hand", "left_hip", "right_hip", "left_ankle", "right_ankle",
                                    "left_toe", "right_toe")))
    clip = tmp_path / "clip.bvh"
    clip.write_text(HEAD + "Frames: 3\nFrame Time: 0.01\n" + "0 0 0 0 0 0\n" * 3)
    code = main(["retarget", str(clip), "--skeleton", str(mapping), "--no-sim", "--quiet"])
    err = capsys.readouterr().err
    assert code == 3 and "names joints the clip does not have: Xhead" in err


def test_help_names_the_options(capsys):
    with pytest.raises(SystemExit) as info:
        main(["retarget", "--help"])
    out = capsys.readouterr().out
    assert info.value.code == 0
    for option in ("--robot", "--start", "--end", "--skeleton", "--out", "--html", "--no-sim"):
        assert option in out
