"""Examples are tests: each example script runs headless and reports success."""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def load_example(name: str):
    """Import an example script as a module (they are not a package)."""
    spec = importlib.util.spec_from_file_location(name, EXAMPLES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_reach_and_squat_example(capsys):
    """The hand-written spec example plans on talos and reaches its hand target within 1 cm."""
    assert load_example("talos_reach_and_squat").main([]) == 0
    out = capsys.readouterr().out
    error = float(re.search(r"right hand error at t = 1.5 s: ([0-9.]+) m", out).group(1))
    assert error <= 0.01 + 0.5e-4  # printed to 0.1 mm: the planner's 0.00995 m shows as 0.0100


def test_sentence_example_in_chinese(capsys):
    """The layer-by-layer example turns a Chinese sentence into a plan with two squat bottoms."""
    assert load_example("sentence_to_motion").main(["深蹲两次", "--no-sim"]) == 0
    out = capsys.readouterr().out
    assert "squat" in out and "plan: solved" in out
    assert out.count("squat bottom") == 2


@pytest.mark.parametrize("name", ["talos_reach_and_squat", "sentence_to_motion", "action_pictures"])
def test_examples_have_help(name, capsys):
    """Every example answers --help (argparse) without doing any work."""
    with pytest.raises(SystemExit) as exit_info:
        load_example(name).main(["--help"])
    assert exit_info.value.code == 0
    assert "usage" in capsys.readouterr().out


def test_action_pictures_draws_a_small_palette_strip(tmp_path, capsys):
    """The picture of a squat is a palette PNG of a few tens of KiB: five side and five front figures."""
    import numpy as np
    from PIL import Image

    assert load_example("action_pictures").main(["squat", "--out", str(tmp_path)]) == 0
    path = tmp_path / "squat.png"
    assert f"squat: {path}" in capsys.readouterr().out
    with Image.open(path) as img:
        assert img.mode == "P" and len(img.getcolors()) <= 48
        assert 500 <= img.width <= 1000 and img.height >= 300
        dark = int((np.asarray(img.convert("L")) < 100).sum())  # the stick figures' lines
    assert dark > 2000
    assert path.stat().st_size < 60 * 1024


def test_action_pictures_refuses_an_unknown_action(tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_info:
        load_example("action_pictures").main(["moonwalk", "--out", str(tmp_path)])
    assert exit_info.value.code == 2
    assert "unknown action(s) moonwalk" in capsys.readouterr().err
    assert not any(tmp_path.iterdir())


@pytest.mark.parametrize("name", ["table", "box_on_floor", "narrow_passage", "heightmap"])
def test_example_scenes_load(name):
    """Each example scene file loads, and its objects stand on the floor (none below z = 0)."""
    from tasks.scene import extent, load_scene

    scene = load_scene(EXAMPLES / "scenes" / f"{name}.json")
    assert scene.objects
    for obj in scene.objects:
        lower, _ = extent(obj)
        assert lower[2] == pytest.approx(0.0, abs=1e-9), obj.name


def test_narrow_passage_leaves_room_for_a_walk():
    """The two walls leave more than Talos's width (1.1 m apart, arms at y = +-0.44 m) along x."""
    from tasks.scene import extent, load_scene

    scene = load_scene(EXAMPLES / "scenes" / "narrow_passage.json")
    left, right = extent(scene.get("left wall")), extent(scene.get("right wall"))
    assert left[0][1] - right[1][1] == pytest.approx(1.1)
    assert left[0][0] > 0.1 and left[1][0] > 2.0  # from in front of the feet to 2 m ahead


def test_docs_pictures_exist_and_stay_small():
    """Every keyframe strip docs/primitives.md shows exists, each under 100 KB and all under 3 MB."""
    docs = Path(__file__).resolve().parents[1] / "docs"
    shown = re.findall(r"\]\((images/actions/[\w-]+\.png)\)", (docs / "primitives.md").read_text(encoding="utf-8"))
    assert len(shown) >= 10
    assert max((docs / p).stat().st_size for p in shown) < 100_000
    assert sum(f.stat().st_size for f in (docs / "images").rglob("*.png")) < 3_000_000
