"""``wbmp solve ... --scene FILE``: the scene reaches the plan, the motion file and the cache keys."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from tasks.scene import load_scene
from wbmp.cli import main
from wbmp.motionfile import load_motion

REPO = Path(__file__).resolve().parents[2]
TABLE = REPO / "examples" / "scenes" / "table.json"


@pytest.fixture(autouse=True)
def _no_compilation(monkeypatch, tmp_path):
    monkeypatch.setenv("WBMP_COMPILE", "0")
    monkeypatch.setenv("WBMP_CACHE_DIR", str(tmp_path / "cache"))


def test_reach_over_the_table_plans_and_the_motion_file_carries_the_scene(tmp_path, capsys):
    """Exit 0; the saved motion's spec holds the table (so `wbmp show`, HTML and plots draw it),
    and its hand target stays above the table top."""
    out = tmp_path / "reach.npz"
    code = main(["solve", "reach forward 30 cm with your right hand", "--scene", str(TABLE), "--no-sim",
                 "--quiet", "--out", str(out)])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    motion = load_motion(out)
    assert motion.plan.spec.scene == load_scene(TABLE)
    table = motion.plan.spec.scene.get("table")
    target = next(t for t in motion.plan.spec.targets if "reach point" in t.name)
    assert target.position[2] > table.position[2] + table.size[2] / 2 + 0.1


def test_cache_keys_follow_the_scene(tmp_path, talos):
    from tasks.actions import Action
    from tasks.compose import compile_actions
    from wbmp.motioncache import motion_key, request_key
    from wbmp.pipeline import SolveRequest

    spec = compile_actions([Action(name="squat")], talos)
    scene = load_scene(TABLE)
    with_table = dataclasses.replace(spec, scene=scene)
    moved = dataclasses.replace(scene, objects=(dataclasses.replace(scene.objects[0], position=(0.7, 0.0, 0.31)),))
    keys = {motion_key(s, "robot", simulate=False, push=None)
            for s in (spec, with_table, dataclasses.replace(spec, scene=moved))}
    assert len(keys) == 3
    assert motion_key(with_table, "robot", simulate=False, push=None) == \
        motion_key(dataclasses.replace(spec, scene=load_scene(TABLE)), "robot", simulate=False, push=None)

    a, b = tmp_path / "a.json", tmp_path / "b.json"
    a.write_text(TABLE.read_text(encoding="utf-8"), encoding="utf-8")
    data = json.loads(TABLE.read_text(encoding="utf-8"))
    data["objects"][0]["position"][0] = 0.7
    b.write_text(json.dumps(data), encoding="utf-8")
    rkeys = [request_key(SolveRequest(instruction="squat", scene_path=p)) for p in (None, str(a), str(b))]
    assert None not in rkeys and len(set(rkeys)) == 3
    data["objects"].append({"name": "cup", "shape": "mesh", "size": [1, 1, 1], "position": [0, 1, 1],
                            "mesh": "cup.stl"})
    b.write_text(json.dumps(data), encoding="utf-8")
    assert request_key(SolveRequest(instruction="squat", scene_path=str(b))) is None  # meshes: the slow path
