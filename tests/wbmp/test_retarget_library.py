"""``wbmp solve --motions DIR``: a sentence that names no known action but a clip's label is that
clip, retargeted; nothing matching: refused as without the library."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from wbmp.cli import main
from wbmp.motions import load_library, match

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "motions"


@pytest.fixture(autouse=True)
def _no_compilation(monkeypatch, tmp_path):
    monkeypatch.setenv("WBMP_COMPILE", "0")
    monkeypatch.setenv("WBMP_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.delenv("WBMP_MOTIONS", raising=False)


def test_the_example_library_matches_by_label_words():
    clips = load_library(EXAMPLES)
    assert len(clips) == 5
    assert match("do the chicken dance", clips).path.name == "18_15_dance.bvh"
    assert match("please do the chicken dance now", clips).path.name == "18_15_dance.bvh"
    assert match("direct traffic", clips).path.name == "13_26_wave.bvh"
    assert match("do the moonwalk", clips) is None and match("the", clips) is None


@pytest.fixture
def library(tmp_path):
    folder = tmp_path / "lib"
    folder.mkdir()
    shutil.copy(EXAMPLES / "13_29_squat.bvh", folder)
    (folder / "clips.csv").write_text("file,label,family,start,end\n13_29_squat.bvh,mocap dip,dip,0,1\n")
    return folder


def test_a_sentence_naming_a_clip_is_that_clip_retargeted(library, tmp_path, capsys):
    out = tmp_path / "dip.npz"
    code = main(["solve", "do the mocap dip", "--motions", str(library), "--no-sim", "--quiet", "--json",
                 "--out", str(out)])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    report = json.loads(captured.out)
    assert report["retarget"]["clip"].endswith("13_29_squat.bvh") and report["retarget"]["duration_s"] < 1.01
    assert report["retarget"]["plan"]["foot_skate_mm"] <= 2.0 and out.is_file()


def test_no_matching_clip_is_refused_as_before(library, capsys):
    code = main(["solve", "do the moonwalk", "--motions", str(library), "--no-sim", "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and 'could not understand "moonwalk"' in err


def test_a_bad_library_folder_exits_2(tmp_path, capsys):
    code = main(["solve", "do the mocap dip", "--motions", str(tmp_path / "none"), "--no-sim", "--quiet"])
    assert code == 2 and "no such folder" in capsys.readouterr().err
