"""Huge numbers and spans (issue 36): bounded where they enter, refused with one line.

* A motion file whose times span 1e7 s, or are shifted by 1e12 s, is refused where it is read
  (exit 3) by ``export --format tracker|mcap`` and ``show --html``: before, the tracker export
  ran out of memory and the mcap export died in ``struct.pack``.
* A tracker export whose rate and span give more samples than a tracker file holds is refused.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tests.badinput.conftest import Tree, assert_refused, run_cli
from wbmp.errors import ExitCode
from wbmp.motionfile import MAX_MOTION_SECONDS


def _rewrite(src: Path, dst: Path, change) -> Path:
    with np.load(src) as z:
        arrays = {k: z[k] for k in z.files}
    change(arrays)
    np.savez(dst, **arrays)
    return dst


def _span(arrays, seconds: float) -> None:
    t = arrays["t"]
    arrays["t"] = t / t[-1] * seconds


def _shift(arrays, seconds: float) -> None:
    arrays["t"] = arrays["t"] + seconds


TIMES = {
    "span 1e7 s": lambda a: _span(a, 1e7),
    "shifted 1e12 s": lambda a: _shift(a, 1e12),
    "shifted -1e12 s": lambda a: _shift(a, -1e12),
    "span just over the bound": lambda a: _span(a, MAX_MOTION_SECONDS * 1.001),
}
COMMANDS = {
    "tracker": lambda m, out: ["export", m, "--format", "tracker", "--out", out / "m.tracker.npz"],
    "mcap": lambda m, out: ["export", m, "--format", "mcap", "--out", out / "m.mcap"],
    "html": lambda m, out: ["show", m, "--html", out / "m.html"],
    "json": lambda m, out: ["export", m, "--format", "json", "--out", out / "m.json"],
}


@pytest.mark.parametrize("command", COMMANDS)
@pytest.mark.parametrize("times", TIMES)
def test_a_motion_of_huge_times_is_refused_where_it_is_read(motion_file, tmp_path, capsys, times, command):
    motion = _rewrite(motion_file, tmp_path / "m.npz", TIMES[times])
    out = tmp_path / "out"
    out.mkdir()
    tree = Tree(tmp_path)
    outcome = run_cli(COMMANDS[command](motion, out), capsys)
    assert_refused(outcome, ExitCode.INVALID_SPEC, "m.npz", "'t'", f"{MAX_MOTION_SECONDS:g} s")
    tree.assert_unchanged()


def test_a_motion_within_the_bound_is_exported(motion_file, tmp_path, capsys):
    """The bound is not in the way: a motion stretched to 20 min exports at 50 Hz (60,001 samples)."""
    motion = _rewrite(motion_file, tmp_path / "m.npz", lambda a: _span(a, 1200.0))
    outcome = run_cli(["export", motion, "--format", "tracker", "--out", tmp_path / "m.tracker.npz"], capsys)
    assert outcome.code == 0, outcome.err
    with np.load(tmp_path / "m.tracker.npz") as z:
        assert len(z["t"]) == 60_001
        assert z["t"][-1] == pytest.approx(1200.0)


def test_too_many_tracker_samples_are_refused(motion_file, tmp_path, capsys):
    from wbmp.export.tracker import MAX_SAMPLES

    motion = _rewrite(motion_file, tmp_path / "m.npz", lambda a: _span(a, 3000.0))
    tree = Tree(tmp_path)
    outcome = run_cli(["export", motion, "--format", "tracker", "--fps", "1000", "--out",
                       tmp_path / "m.tracker.npz"], capsys)
    assert_refused(outcome, ExitCode.USAGE, "fps", str(MAX_SAMPLES))
    tree.assert_unchanged()


DIGITS = "9" * 4400  # past Python's 4,300-digit limit of int(str)


@pytest.mark.parametrize("sentence", [f"wave {DIGITS} times", f"squat 0.{DIGITS} m", f"squat -{DIGITS} cm"],
                         ids=["count", "decimal", "negative"])
@pytest.mark.parametrize("command", ["parse", "solve"])
def test_a_number_of_thousands_of_digits_is_refused(tmp_path, capsys, monkeypatch, sentence, command):
    monkeypatch.setenv("WBMP_CACHE_DIR", str(tmp_path / "cache"))
    tree = Tree(tmp_path)
    argv = ["parse", sentence] if command == "parse" else ["solve", sentence, "--no-sim", "--quiet"]
    outcome = run_cli(argv, capsys)
    assert_refused(outcome, ExitCode.USAGE, "4,40", "at most 40 characters")
    tree.assert_unchanged()


def test_parse_and_solve_share_the_sentence_bound(tmp_path, capsys, monkeypatch):
    from tasks.limits import MAX_TEXT_LENGTH

    monkeypatch.setenv("WBMP_CACHE_DIR", str(tmp_path / "cache"))
    sentence = "wave " * (MAX_TEXT_LENGTH // 5 + 1)
    for argv in (["parse", sentence], ["solve", sentence, "--no-sim", "--quiet"]):
        assert_refused(run_cli(argv, capsys), ExitCode.USAGE, f"at most {MAX_TEXT_LENGTH:,}")
    assert run_cli(["parse", "wave twice"], capsys).code == 0


@pytest.mark.parametrize("value", ["9" * 400, "9" * 4400, "99999999999999999999T", "2000000T"])
def test_a_cache_cap_beyond_any_disk_is_refused_or_ignored(tmp_path, capsys, monkeypatch, value):
    """``wbmp cache`` refuses it (exit 2, one line); a store warns once and keeps the default cap."""
    from robots.store import DEFAULT_MAX_BYTES, max_cache_bytes

    monkeypatch.setenv("WBMP_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setenv("WBMP_CACHE_MAX_SIZE", value)
    assert_refused(run_cli(["cache"], capsys), ExitCode.USAGE, "WBMP_CACHE_MAX_SIZE", "EiB")
    assert max_cache_bytes() == DEFAULT_MAX_BYTES


def test_a_large_cache_cap_is_still_a_cap(monkeypatch):
    from robots.store import parse_size

    assert parse_size("1024T") == 1 << 50
    assert parse_size("1048576") == 1 << 20
