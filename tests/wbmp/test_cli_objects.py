"""``wbmp parse`` / ``wbmp solve`` with object references: the reference shown, one-line errors
with their exit codes, and walking to the kitchen table planned on talos (no simulation)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from tasks.primitives.objects import WALK_MARGIN
from tasks.scene import load_scene
from wbmp.cli import main

REPO = Path(__file__).resolve().parents[2]
KITCHEN = REPO / "examples" / "scenes" / "kitchen.json"
WAREHOUSE = REPO / "examples" / "scenes" / "warehouse.json"


@pytest.fixture(autouse=True)
def _no_compilation(monkeypatch, tmp_path):
    monkeypatch.setenv("WBMP_COMPILE", "0")
    monkeypatch.setenv("WBMP_CACHE_DIR", str(tmp_path / "cache"))


def test_parse_shows_the_reference(capsys):
    assert main(["parse", "walk to the table, then point at 桌子上的红色盒子", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["actions"] == [{"action": "walk_to", "params": {"object": "the table"}},
                              {"action": "point_at", "params": {"object": "桌子上的红色盒子"}}]
    assert {"text": "the table", "role": "object", "detail": "object=the table (a thing: 'table'; the scene resolves it)", "action": 1} in out["words"]
    assert main(["parse", "look at the box on the table"]) == 0
    assert "look_at  object=the box on the table" in capsys.readouterr().out


@pytest.mark.parametrize(("argv", "code", "message"), [
    (["walk to the table"], 2, 'wbmp solve: error: walk_to "the table" refers to an object, but there is no scene: '
                               "give one with --scene FILE"),
    (["point at the mug of tea", "--scene", str(KITCHEN)], 3,
     'wbmp solve: error: no object in the scene is called "the mug of tea"; its objects are table (desk, 桌子), cup'),
    (["look at the box", "--scene", str(KITCHEN)], 3,
     'wbmp solve: error: "the box" could be red box (red, at x 1.70, y -0.35, z 0.80 m) or blue box'),
    (["wave, then point at the box left of the table", "--scene", str(KITCHEN)], 3,
     'wbmp solve: error: action 2 (point_at): no box is left of the table'),
    (["走到绿色箱子", "--scene", str(WAREHOUSE)], 4,
     "wbmp solve: error: walk_to: the green box is enclosed by the tall crate, the wide crate, the back wall and the side wall"),
    (["看着那个杯子", "--scene", str(KITCHEN), "--robot", "g1"], 3, "wbmp solve: error: g1 has no neck joint to look at the cup"),
])
def test_object_errors_are_one_line_with_their_exit_code(capsys, argv, code, message):
    assert main(["solve", *argv, "--no-sim", "--quiet"]) == code
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(message), err


@pytest.mark.slow
def test_walk_to_the_kitchen_table_plans_on_talos():
    """"walk over to the table", parsed, grounded in kitchen.json and planned on talos (0.1 s knots,
    no simulation): the last configuration (Pinocchio) faces the table with the toes in front of
    the margin before its near face and the heels past where the toes started."""
    import planner
    from language import parse
    from robots import load_robot
    from tasks.compose import compile_actions

    robot = load_robot("talos")
    kitchen = load_scene(KITCHEN)
    spec = compile_actions(parse("walk over to the table").actions, robot, dt=0.1, scene=kitchen)
    plan = planner.plan(spec, robot,
                        settings=planner.PlannerSettings(cache=planner.CacheSettings(compile=False)),
                        throw=False)
    assert plan.ok, f"{plan.stats.status.value}: {plan.diagnosis}"
    data = robot.data()
    q = plan.q[-1]
    assert np.all(np.isfinite(plan.q))
    pin.framesForwardKinematics(robot.model, data, q)
    table = kitchen.get("table")
    front = table.position[0] - table.size[0] / 2
    toes = max(float(robot.sole_corners_in_world(q, s)[:, 0].max()) for s in ("left", "right"))
    heels = min(float(robot.sole_corners_in_world(q, s)[:, 0].min()) for s in ("left", "right"))
    start_toes = max(float(robot.sole_corners_in_world(robot.q_standing, s)[:, 0].max()) for s in ("left", "right"))
    assert start_toes < heels and toes < front - WALK_MARGIN, (heels, toes)
    yaw = pin.rpy.matrixToRpy(data.oMf[robot.frame_id("base")].rotation)[2]
    assert abs(yaw) < 0.05, yaw
