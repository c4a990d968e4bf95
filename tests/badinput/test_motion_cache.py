"""The motion cache of ``wbmp solve``: a repeat is the stored result, bit for bit; anything that
changes the result misses; a damaged entry is recomputed with one warning; ``--no-cache``
neither reads nor writes.

One simulated squat is solved for the module (``golden``), into a cache folder that tests copy
before touching; the other cases plan the example spec without simulation (about a second).
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import logging
import shutil
from pathlib import Path

import numpy as np
import pytest

from tests.badinput.conftest import Tree, run_cli, run_cli_process
from wbmp.motionfile import load_motion

REPO = Path(__file__).resolve().parents[2]
SPEC = REPO / "examples" / "specs" / "squat.json"
SENTENCE = "squat down 12 cm"


@pytest.fixture(autouse=True)
def _memory_solvers(monkeypatch):
    monkeypatch.setenv("WBMP_COMPILE", "0")  # solvers in memory (the solver cache has its own tests)


def entries(cache: Path) -> list[str]:
    folder = cache / "motions"
    return sorted(p.name for p in folder.glob("*.npz")) if folder.is_dir() else []


def arrays(path: Path) -> dict[str, np.ndarray]:
    with np.load(path) as z:
        return {k: z[k] for k in z.files}


@pytest.fixture(scope="module")
def golden(tmp_path_factory):
    """(cache folder, motion file, stdout) of one fresh simulated solve of SENTENCE."""
    root = tmp_path_factory.mktemp("golden")
    cache = root / "cache"
    out = root / "fresh.npz"
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("WBMP_CACHE_DIR", str(cache))
        mp.setenv("WBMP_COMPILE", "0")
        from wbmp.cli import main

        buf = io.StringIO()
        with contextlib.redirect_stdout(buf):
            code = main(["solve", SENTENCE, "--out", str(out), "--quiet"])
    assert code == 0, buf.getvalue()
    assert len(entries(cache)) == 1
    return cache, out, buf.getvalue()


def copy_cache(golden, tmp_path: Path, monkeypatch) -> Path:
    cache = tmp_path / "cache"
    shutil.copytree(golden[0], cache)
    monkeypatch.setenv("WBMP_CACHE_DIR", str(cache))
    return cache


def test_repeat_is_the_stored_motion_bit_for_bit(golden, tmp_path, monkeypatch, capsys):
    """Every array of the repeat's --out equals the fresh one exactly; the stored entry is that
    file's content; the printed lines are the fresh ones with the solver line saying cached."""
    cache = copy_cache(golden, tmp_path, monkeypatch)
    out = tmp_path / "again.npz"
    outcome = run_cli(["solve", SENTENCE, "--out", out, "--quiet"], capsys)
    assert outcome.code == 0, outcome.err
    fresh, again = arrays(golden[1]), arrays(out)
    stored = arrays(cache / "motions" / entries(cache)[0])
    assert set(fresh) == set(again) == set(stored)
    for key in fresh:
        if key != "report_json":
            assert np.array_equal(fresh[key], again[key]) and fresh[key].dtype == again[key].dtype, key
            assert np.array_equal(fresh[key], stored[key]), key
    report = json.loads(str(again["report_json"]))
    assert report["cached"] is True and report["solver"]["cache"] == "cached"
    assert json.loads(str(fresh["report_json"]))["cached"] is False
    assert load_motion(out).plan.ok and "exec_q" in again
    lines_fresh, lines_again = golden[2].splitlines(), outcome.out.splitlines()
    assert len(lines_fresh) == len(lines_again)
    differ = [(a, b) for a, b in zip(lines_fresh, lines_again, strict=True) if a != b]
    assert len(differ) == 2  # the solver line ([disk]/[built] -> [cached]) and "wrote motion: <path>"
    assert "[cached]" in differ[0][1] and differ[0][1].replace("[cached]", "") == \
        differ[0][0].replace("[memory]", "").replace("[built]", "").replace("[disk]", "")
    assert "certificate: PASS" in outcome.out


def test_another_phrasing_shares_the_entry(golden, tmp_path, monkeypatch, capsys):
    """Same spec from another sentence: answered from the same entry, with its own wording."""
    cache = copy_cache(golden, tmp_path, monkeypatch)
    out = tmp_path / "other.npz"
    outcome = run_cli(["solve", "do a squat of 12 cm", "--out", out, "--json"], capsys)
    assert outcome.code == 0, outcome.err
    report = json.loads(outcome.out)
    assert report["cached"] is True and report["instruction"] == "do a squat of 12 cm"
    assert entries(cache) == entries(golden[0])
    assert load_motion(out).plan.spec.description == "do a squat of 12 cm"
    fresh, again = arrays(golden[1]), arrays(out)
    for key in ("q", "v", "a", "com", "exec_t", "exec_q", "exec_v", "exec_tau"):
        assert np.array_equal(fresh[key], again[key]), key


@pytest.mark.parametrize("change", ["no-sim", "push"])
def test_a_change_that_changes_the_result_misses(golden, tmp_path, monkeypatch, capsys, change):
    """Without simulation, or with a push: solved afresh and stored beside the first entry."""
    cache = copy_cache(golden, tmp_path, monkeypatch)
    argv = ["solve", SENTENCE, "--quiet", *(["--no-sim"] if change == "no-sim" else ["--push", "20@1.0"])]
    outcome = run_cli(argv, capsys)
    assert outcome.code == 0, outcome.err
    assert "[cached]" not in outcome.out
    assert len(entries(cache)) == 2
    again = run_cli(argv, capsys)  # and that new result is a hit in turn
    assert again.code == 0 and "[cached]" in again.out


def test_an_edited_robot_profile_misses(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("WBMP_CACHE_DIR", str(tmp_path / "cache"))
    text = (REPO / "robots" / "profiles" / "talos.toml").read_text(encoding="utf-8")
    text = text.replace('name = "talos"', 'name = "my_talos"')
    profile = tmp_path / "my_talos.toml"
    profile.write_text(text, encoding="utf-8")
    argv = ["solve", SENTENCE, "--robot", profile, "--no-sim", "--quiet"]
    assert "[cached]" not in run_cli(argv, capsys).out
    assert "[cached]" in run_cli(argv, capsys).out
    profile.write_text(text.replace("friction_coefficient = 0.7", "friction_coefficient = 0.8"), encoding="utf-8")
    outcome = run_cli(argv, capsys)
    assert outcome.code == 0 and "[cached]" not in outcome.out, outcome.err
    assert len(entries(tmp_path / "cache")) == 2


def test_an_edited_spec_file_misses(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("WBMP_CACHE_DIR", str(tmp_path / "cache"))
    spec = tmp_path / "squat.json"
    shutil.copy(SPEC, spec)
    argv = ["solve", "--spec", spec, "--no-sim", "--quiet"]
    assert "[cached]" not in run_cli(argv, capsys).out
    assert "[cached]" in run_cli(argv, capsys).out
    data = json.loads(spec.read_text(encoding="utf-8"))
    data["phases"][0]["duration"] = 3.5
    spec.write_text(json.dumps(data), encoding="utf-8")
    outcome = run_cli(argv, capsys)
    assert outcome.code == 0 and "[cached]" not in outcome.out
    assert len(entries(tmp_path / "cache")) == 2


def test_no_cache_neither_reads_nor_writes(golden, tmp_path, monkeypatch, capsys):
    cache = copy_cache(golden, tmp_path, monkeypatch)
    tree = Tree(cache)
    outcome = run_cli(["solve", SENTENCE, "--no-cache", "--no-sim", "--quiet"], capsys)
    assert outcome.code == 0 and "[cached]" not in outcome.out
    outcome = run_cli(["solve", SENTENCE, "--no-cache", "--quiet"], capsys)  # would be a hit
    assert outcome.code == 0 and "[cached]" not in outcome.out
    tree.assert_unchanged()
    empty = tmp_path / "empty"
    empty.mkdir()
    monkeypatch.setenv("WBMP_CACHE_DIR", str(empty))
    assert run_cli(["solve", "--spec", SPEC, "--no-sim", "--no-cache", "--quiet"], capsys).code == 0
    assert list(empty.rglob("*")) == []


def _flip_byte(path: Path) -> None:
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0xFF
    path.write_bytes(bytes(data))


def _forge(path: Path) -> None:
    """A different valid-looking file with a manifest that matches it (sha256 passes)."""
    path.write_bytes(b"PK\x03\x04 not really an archive")
    manifest = path.with_suffix(".json")
    meta = json.loads(manifest.read_text(encoding="utf-8"))
    meta["size"] = path.stat().st_size
    meta["sha256"] = hashlib.sha256(path.read_bytes()).hexdigest()
    manifest.write_text(json.dumps(meta), encoding="utf-8")


def _bad_manifest(path: Path) -> None:
    path.with_suffix(".json").write_text("{not json", encoding="utf-8")


def _truncate(path: Path) -> None:
    path.write_bytes(path.read_bytes()[:1000])


@pytest.mark.parametrize("damage", [_flip_byte, _truncate, _forge, _bad_manifest],
                         ids=["flipped byte", "truncated", "forged with matching sha256", "bad manifest"])
def test_a_damaged_entry_is_recomputed_with_one_warning(golden, tmp_path, monkeypatch, capsys, caplog, damage):
    cache = copy_cache(golden, tmp_path, monkeypatch)
    entry = cache / "motions" / entries(cache)[0]
    damage(entry)
    out = tmp_path / "m.npz"
    with caplog.at_level(logging.WARNING, logger="wbmp.motioncache"):
        outcome = run_cli(["solve", SENTENCE, "--out", out, "--quiet"], capsys)
    assert outcome.code == 0, outcome.err
    warnings = [r.getMessage() for r in caplog.records if r.name == "wbmp.motioncache"]
    assert len(warnings) == 1 and "damaged" in warnings[0] and "computed again" in warnings[0], warnings
    assert "[cached]" not in outcome.out  # solved afresh...
    fresh, again = arrays(golden[1]), arrays(out)
    for key in ("q", "exec_q"):  # ...to the same motion (same solver, same start)
        np.testing.assert_allclose(again[key], fresh[key], rtol=0, atol=1e-6)
    assert entries(cache) == entries(golden[0])  # and stored again, healthy
    assert "[cached]" in run_cli(["solve", SENTENCE, "--quiet"], capsys).out


def test_a_damaged_entry_warns_on_one_stderr_line(golden, tmp_path, monkeypatch, capsys):
    """What a user sees, in a process of its own: one ``wbmp: warning:`` line, exit 0, no
    traceback. The damaged entry is a ``--no-sim`` one (another key: its own entry, stored here in
    about a second), so the process plans again rather than simulating again."""
    cache = copy_cache(golden, tmp_path, monkeypatch)
    first = run_cli(["solve", SENTENCE, "--quiet", "--no-sim"], capsys)
    assert first.code == 0 and not first.err.strip(), first.err  # nothing damaged was read
    (name,) = set(entries(cache)) - set(entries(golden[0]))
    _flip_byte(cache / "motions" / name)
    outcome = run_cli_process(["solve", SENTENCE, "--quiet", "--no-sim"],
                              env={"WBMP_CACHE_DIR": str(cache), "WBMP_COMPILE": "0", "PYTHONPATH": str(REPO)})
    lines = [ln for ln in outcome.err.splitlines() if ln.strip()]
    assert outcome.code == 0 and "Traceback" not in outcome.err, outcome.err
    assert len(lines) == 1 and lines[0].startswith("wbmp: warning: motion cache entry"), lines


def test_plots_are_drawn_from_a_fresh_solve(golden, tmp_path, monkeypatch, capsys):
    """--plots needs the simulated contact forces, which the cache does not keep: not read."""
    copy_cache(golden, tmp_path, monkeypatch)
    plots = tmp_path / "plots"
    outcome = run_cli(["solve", SENTENCE, "--plots", plots, "--quiet"], capsys)
    assert outcome.code == 0 and "[cached]" not in outcome.out, outcome.err
    assert (plots / "contact_forces.png").is_file()
