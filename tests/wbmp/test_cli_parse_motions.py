"""``wbmp parse TEXT --motions DIR``: a sentence that names no known action but a clip of the
motion library shows that clip and its words (as ``wbmp solve --motions`` picks it); none is
refused exactly as without the library."""

from __future__ import annotations

import csv
import json
from pathlib import Path

from wbmp.cli import main

ROOT = Path(__file__).resolve().parents[2]
LIBRARY = ROOT / "examples" / "motions"


def test_chicken_dance_shows_the_clip(capsys):
    """The example library's clips.csv (read here with csv) labels 18_15_dance.bvh 'chicken
    dance ...': the text output names that file and label, 'chicken dance' is its action word."""
    text = (LIBRARY / "clips.csv").read_text(encoding="utf-8")
    rows = {r["file"]: r for r in csv.DictReader(text.splitlines())}
    assert main(["parse", "do the chicken dance", "--motions", str(LIBRARY)]) == 0
    out = capsys.readouterr().out
    first, words = out.splitlines()[0], out.splitlines()[2:]
    assert "18_15_dance.bvh" in first and rows["18_15_dance.bvh"]["label"] in first and "the whole clip" in first
    assert [w.split()[0] for w in words] == ["do", "the", "chicken"]
    assert "filler" in words[0] and "filler" in words[1]
    assert "action: motion-library clip 18_15_dance.bvh" in words[2] and words[2].endswith("[action 1]")

    assert main(["parse", "do the chicken dance", "--motions", str(LIBRARY), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["actions"] == [] and doc["backend"] == "rules"
    assert doc["clip"] == {"file": "18_15_dance.bvh", "label": rows["18_15_dance.bvh"]["label"],
                           "family": "dance", "start": None, "end": None}
    assert doc["words"][2] == {"text": "chicken dance", "role": "action", "action": 1,
                               "detail": f"motion-library clip 18_15_dance.bvh ({rows['18_15_dance.bvh']['label']})"}


def test_the_best_fitting_clip_and_its_window(tmp_path, capsys):
    """Of two clips whose words hold the sentence's, the one with fewer extra words; a window of
    clips.csv is shown."""
    (tmp_path / "clips.csv").write_text("file,label,family,start,end\n"
                                        "a.bvh,salsa dance with a turn,dance,,\n"
                                        "b.bvh,salsa,dance,1.5,3\n", encoding="utf-8")
    assert main(["parse", "please dance the salsa", "--motions", str(tmp_path), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["clip"]["file"] == "b.bvh" and (doc["clip"]["start"], doc["clip"]["end"]) == (1.5, 3.0)
    assert [w["role"] for w in doc["words"]] == ["filler", "action", "filler", "action"]
    assert main(["parse", "salsa dance with a turn", "--motions", str(tmp_path)]) == 0
    assert "clip a.bvh" in capsys.readouterr().out
    assert main(["parse", "please dance the salsa", "--motions", str(tmp_path)]) == 0
    assert "1.5 s to 3 s" in capsys.readouterr().out


def test_no_clip_is_refused_as_without_the_library(capsys):
    assert main(["parse", "do the robot dance"]) == 2
    without = capsys.readouterr().err
    assert main(["parse", "do the robot dance", "--motions", str(LIBRARY)]) == 2
    assert capsys.readouterr().err == without and "dance" in without
    # a known action is parsed as always: the library is not read
    assert main(["parse", "squat twice", "--motions", str(LIBRARY / "missing")]) == 0
    assert "squat" in capsys.readouterr().out
    assert main(["parse", "do the robot dance", "--motions", str(LIBRARY / "missing")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "no such folder" in err
