"""``wbmp parse --scene``: every object word shown with the scene object it grounds to (issue 32),
and a reference the scene cannot resolve refused in one line with the exit code of ``wbmp solve``."""

from __future__ import annotations

import json
from pathlib import Path

from tasks.grounding import ground
from tasks.scene import load_scene
from wbmp.cli import main

KITCHEN = Path(__file__).resolve().parents[2] / "examples" / "scenes" / "kitchen.json"


def test_each_object_word_names_its_scene_object(capsys):
    text = "walk to the desk, then pick up the cup and put it on the table"
    assert main(["parse", text, "--scene", str(KITCHEN), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    scene = load_scene(KITCHEN)
    shown = [(w["text"], w["detail"]) for w in out["words"] if w["role"] in ("object", "destination")]
    # the reference: tasks.grounding on the same words
    want = [(said, f"{p}={v} -> scene object '{ground(v, scene).name}'")
            for said, p, v in (("the desk", "object", "the desk"), ("the cup", "object", "the cup"),
                               ("it", "object", "the cup"), ("the table", "on", "the table"))]
    assert shown == want


def test_an_ambiguous_reference_is_refused_like_solve(capsys):
    assert main(["parse", "look at the box", "--scene", str(KITCHEN)]) == 3
    err = capsys.readouterr().err.strip()
    assert err.startswith('wbmp parse: error: "the box" could be red box') and "\n" not in err
