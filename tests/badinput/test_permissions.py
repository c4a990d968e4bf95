"""Modes of written files: a new file gets 0o666 & ~umask, a replaced file keeps its mode.

wbmp used ``mkstemp`` (always 0600), so every output was private whatever the umask, and
overwriting a shared 0664 file made it 0600. Checked here in child processes started under
umask 022, 002 and 077, and in-process with the umask set and restored.
"""

from __future__ import annotations

import os
import shutil
import stat
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tests.badinput.conftest import REPO, run_cli, umask

UMASKS = (0o022, 0o002, 0o077)


def _mode(path: Path) -> int:
    return stat.S_IMODE(path.stat().st_mode)


@pytest.fixture
def sim_motion(tmp_path_factory, motion_file) -> Path:
    """M plus a short synthetic execution, so a CSV export writes two files."""
    with np.load(motion_file) as data:
        arrays = {k: data[k] for k in data.files}
    n = 20
    arrays.update(exec_t=np.arange(n) * 1e-3, exec_q=arrays["q"][:n], exec_v=arrays["v"][:n],
                  exec_tau=np.zeros((n, arrays["v"].shape[1] - 6)))
    path = tmp_path_factory.mktemp("sim") / "sim.npz"
    np.savez_compressed(path, **arrays)
    return path


@pytest.mark.parametrize("mask", UMASKS, ids=[f"umask{m:03o}" for m in UMASKS])
def test_new_files_follow_the_umask_in_a_child_process(mask, sim_motion, tmp_path):
    """`wbmp export` run as a process under the umask: both CSVs get 0o666 & ~umask."""
    out = tmp_path / "m.csv"
    proc = subprocess.run([sys.executable, "-c", "from wbmp.cli import run; run()", "export", str(sim_motion),
                           "--out", str(out)], capture_output=True, text=True, timeout=300,
                          preexec_fn=lambda: os.umask(mask))
    assert proc.returncode == 0, proc.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.csv", "m.exec.csv"]  # no temporary file left
    for p in tmp_path.iterdir():
        assert _mode(p) == 0o666 & ~mask, f"{p.name}: {_mode(p):o}"


def test_show_outputs_and_new_plot_folder_follow_the_umask(motion_file, tmp_path, capsys):
    """HTML and PNGs get 0o666 & ~umask, a new --plots folder 0o777 & ~umask (umask 027: one
    drawing run; the other umasks are covered by the cheaper export cases)."""
    mask = 0o027
    with umask(mask):
        outcome = run_cli(["show", motion_file, "--html", tmp_path / "m.html", "--plots", tmp_path / "plots",
                           "--quiet"], capsys)
    assert outcome.code == 0, outcome.err
    assert _mode(tmp_path / "m.html") == 0o666 & ~mask
    assert _mode(tmp_path / "plots") == 0o777 & ~mask
    pngs = sorted((tmp_path / "plots").iterdir())
    assert pngs and all(_mode(p) == 0o666 & ~mask for p in pngs)


@pytest.mark.parametrize("mask", UMASKS, ids=[f"umask{m:03o}" for m in UMASKS])
@pytest.mark.parametrize("existing", [0o664, 0o600, 0o640, 0o644, 0o755], ids=lambda m: f"was{m:03o}")
def test_replaced_file_keeps_its_mode(existing, mask, motion_file, tmp_path, capsys):
    """Overwriting an existing file keeps its permission bits whatever the umask; the content is new."""
    out = tmp_path / "m.json"
    out.write_text("old\n")
    out.chmod(existing)
    with umask(mask):
        outcome = run_cli(["export", motion_file, "--out", out], capsys)
    assert outcome.code == 0, outcome.err
    assert _mode(out) == existing
    assert out.read_text().startswith("{")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.json"]


def test_solve_outputs_follow_the_umask(tmp_path, capsys):
    """`wbmp solve --out --html` under umask 002: both group-writable, nothing else in the folder."""
    spec = REPO / "examples" / "specs" / "squat.json"
    (tmp_path / "h.html").write_text("old")
    (tmp_path / "h.html").chmod(0o640)
    with umask(0o002):
        outcome = run_cli(["solve", "--spec", spec, "--no-sim", "--quiet", "--out", tmp_path / "m.npz",
                           "--html", tmp_path / "h.html"], capsys)
    assert outcome.code == 0, outcome.err
    assert _mode(tmp_path / "m.npz") == 0o664
    assert _mode(tmp_path / "h.html") == 0o640  # replaced: kept
    assert sorted(p.name for p in tmp_path.iterdir()) == ["h.html", "m.npz"]


def test_export_of_a_motion_file_copy_keeps_input_untouched(motion_file, tmp_path, capsys):
    """Reading never changes the motion file's mode or content (read-only input is fine)."""
    src = tmp_path / "in.npz"
    shutil.copy(motion_file, src)
    src.chmod(0o444)
    before = src.read_bytes()
    outcome = run_cli(["export", src, "--out", tmp_path / "x.json"], capsys)
    assert outcome.code == 0, outcome.err
    assert _mode(src) == 0o444 and src.read_bytes() == before
