"""Bad input of ``wbmp export --format mcap/tracker`` (and the options of each format): refused
with exit 2 and one line naming what is wrong, before any file is opened; the folder is left
exactly as it was."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from tests.badinput.conftest import Tree, assert_refused, run_cli


@pytest.fixture
def motion(motion_file: Path, tmp_path: Path) -> Path:
    """A copy of the planned squat (no simulation) in the test's folder."""
    return Path(shutil.copy(motion_file, tmp_path / "m.npz"))


CASES = [
    # (arguments after `export m.npz`, words of the error line)
    (["--format", "mcap", "--out", "x.csv"], ["ends in .csv", "--format is mcap"]),
    (["--format", "csv", "--out", "x.mcap"], ["ends in .mcap", "--format is csv"]),
    (["--format", "tracker", "--out", "x.json"], ["ends in .json", "--format is tracker"]),
    (["--format", "mcap", "--out", "x.npz"], ["not .npz", "--format tracker"]),
    (["--out", "x.npz"], ["not .npz", "--format tracker"]),
    (["--out", "x.bag"], ["unknown format", ".bag", ".mcap"]),
    (["--format", "mcap", "--out", "nodir/x.mcap"], ["--out", "nodir", "does not exist"]),
    (["--format", "mcap", "--out", "/proc/x.mcap"], ["--out", "/proc"]),
    (["--format", "tracker", "--out", "m.npz"], ["the same file as", "the motion file"]),
    (["--format", "mcap", "--fps", "30"], ["--fps applies to --format tracker", "not mcap"]),
    (["--format", "tracker", "--stamp", "5"], ["--stamp applies to --format mcap", "not tracker"]),
    (["--format", "csv", "--base-frame", "pelvis"], ["--base-frame applies to --format mcap or tracker"]),
    (["--format", "json", "--source", "plan"], ["--source applies to --format tracker"]),
    (["--format", "mcap", "--stamp", "-1"], ["--stamp", "from 0"]),
    (["--format", "mcap", "--stamp", "nan"], ["--stamp", "from 0"]),
    (["--format", "mcap", "--stamp", "1e12"], ["--stamp", "int32"]),
    (["--format", "mcap", "--stamp", "yesterday"], ["--stamp", "seconds since the unix epoch"]),
    (["--format", "tracker", "--fps", "0"], ["--fps", "above 0"]),
    (["--format", "tracker", "--fps", "inf"], ["--fps", "at most 1000"]),
    (["--format", "tracker", "--fps", "5000"], ["--fps", "at most 1000"]),
    (["--format", "tracker", "--fps", "0.05"], ["--fps", "one sample", "raise it"]),
    (["--format", "tracker", "--source", "execution"], ["no simulated execution", "--source plan"]),
    (["--format", "tracker", "--source", "simulated"], ["--source", "invalid choice"]),
    (["--format", "mcap", "--base-frame", ""], ["--base-frame", "give a frame name"]),
    (["--format", "mcap", "--base-frame", "base link"], ["--base-frame", "no spaces"]),
    (["--format", "rosbag"], ["--format", "invalid choice"]),
]


@pytest.mark.parametrize(("args", "words"), CASES, ids=[" ".join(a) or "none" for a, _ in CASES])
def test_export_format_refusals(args, words, motion, tmp_path, capsys, monkeypatch):
    """Each bad combination is one line and exit 2; nothing is written."""
    monkeypatch.chdir(tmp_path)
    tree = Tree(tmp_path)
    assert_refused(run_cli(["export", motion, *args], capsys), 2, *words)
    tree.assert_unchanged()


def test_a_file_without_joint_names_is_refused_for_mcap_and_tracker(motion, tmp_path, capsys):
    """ROS messages and tracker files name every joint: a motion file without ``joint_names`` is
    refused (and pointed to JSON/CSV, which do without)."""
    with np.load(motion) as f:
        arrays = {k: f[k] for k in f.files if k != "joint_names"}
    np.savez(tmp_path / "nonames.npz", **arrays)
    tree = Tree(tmp_path)
    for fmt in ("mcap", "tracker"):
        outcome = run_cli(["export", tmp_path / "nonames.npz", "--format", fmt], capsys)
        assert_refused(outcome, 2, "'joint_names' has 0 names", "--format json or csv")
    tree.assert_unchanged()
    assert run_cli(["export", tmp_path / "nonames.npz", "--format", "csv"], capsys).code == 0


def test_mcap_output_through_a_link_or_onto_a_read_only_file_is_refused(motion, tmp_path, capsys):
    """The output rules of every wbmp file hold for the bag and the tracker file."""
    (tmp_path / "real.mcap").write_bytes(b"keep me")
    (tmp_path / "link.mcap").symlink_to(tmp_path / "real.mcap")
    (tmp_path / "folder").mkdir()
    tree = Tree(tmp_path)
    assert_refused(run_cli(["export", motion, "--out", tmp_path / "link.mcap"], capsys), 2, "symbolic link")
    assert_refused(run_cli(["export", motion, "--format", "tracker", "--out", tmp_path / "folder"], capsys), 2,
                   "is a directory")
    tree.assert_unchanged()
