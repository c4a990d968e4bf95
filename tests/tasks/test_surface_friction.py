"""Friction per surface in the plan (issue 33): a sole on a surface less grippy than the robot's
soles carries that surface's friction coefficient, so the planner's friction cones (and the
controller's) are the surface's; on surfaces at least as grippy nothing changes; a surface too
slippery to stand on at its incline is refused in task terms (exit 4). The reference for which
surface a sole stands on is the placement's height (the example slope: the floor at z = 0, the ramp
and its landing above), not :func:`tasks.terrain.surface_at`; the incline's limit is Coulomb's,
``tan(10 deg)`` = 0.176. MuJoCo's side: ``tests/sim/test_surface_friction.py``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from language import parse
from tasks.compose import compile_actions
from tasks.exceptions import SceneConflict
from tasks.robot_check import check_spec_in_scene_for_robot
from tasks.scene import load_scene
from tests.badinput.conftest import run_cli

SLOPE = Path(__file__).resolve().parents[2] / "examples" / "scenes" / "slope.json"
SENTENCE = "walk up the slope"


def _scene(tmp_path: Path, *, slope_mu: float, floor_mu: float) -> Path:
    data = json.loads(SLOPE.read_text())
    data["slopes"][0]["friction"], data["floor_friction"] = slope_mu, floor_mu
    path = tmp_path / f"slope_{slope_mu}_{floor_mu}.json"
    path.write_text(json.dumps(data))
    return path


def _soles(spec):
    return [c for p in spec.phases for c in p.contacts if c.region is None]


def test_soles_on_a_surface_less_grippy_than_the_robots_carry_its_friction(talos, tmp_path):
    scene = load_scene(_scene(tmp_path, slope_mu=0.3, floor_mu=0.5))
    spec = compile_actions(list(parse(SENTENCE).actions), talos, scene=scene)
    on_floor = [c for c in _soles(spec) if abs(c.placement.position[2]) < 1e-9]
    on_slope = [c for c in _soles(spec) if c.placement.position[2] > 0.01]
    assert len(on_floor) >= 4 and len(on_slope) >= 4
    assert {c.friction_coefficient for c in on_floor} == {0.5}
    assert {c.friction_coefficient for c in on_slope} == {0.3}


def test_surfaces_at_least_as_grippy_as_the_soles_leave_the_plan_as_it_was(talos):
    spec = compile_actions(list(parse(SENTENCE).actions), talos, scene=load_scene(SLOPE))  # 0.8 over talos's 0.7
    assert talos.profile.friction_coefficient < 0.8
    assert {c.friction_coefficient for c in _soles(spec)} == {None}


def test_a_slope_too_slippery_to_stand_on_is_refused_in_task_terms(talos, tmp_path, capsys):
    need = math.tan(math.radians(10.0))
    path = _scene(tmp_path, slope_mu=round(need - 0.03, 2), floor_mu=0.8)
    with pytest.raises(SceneConflict) as e:
        compile_actions(list(parse(SENTENCE).actions), talos, scene=load_scene(path))
    assert e.value.object_name == "slope" and f"at least {need:.2f}" in str(e.value)
    outcome = run_cli(["solve", SENTENCE, "--scene", path, "--no-sim", "--quiet"], capsys)
    lines = outcome.err.strip().splitlines()
    assert outcome.code == 4 and len(lines) == 1 and "too slippery" in lines[0], outcome.err
    ok = _scene(tmp_path, slope_mu=round(need + 0.03, 2), floor_mu=0.8)  # just grippy enough: compiled
    assert _soles(compile_actions(list(parse(SENTENCE).actions), talos, scene=load_scene(ok)))


@pytest.mark.parametrize(("scene", "walk", "climb"), [
    ("stairs.json", "walk forward 0.5 m", "walk up the stairs"),
    ("slope.json", "walk forward 0.6 m", "walk up the slope"),
])
def test_a_walk_into_a_walkable_surface_is_refused_with_the_words_that_climb_it(talos, scene, walk, climb):
    """A plain walk keeps its soles on the floor: one that would put a sole into stairs or a slope is
    refused (exit 4) naming the sentence that climbs them, and that sentence compiles with every sole
    on the surface under it (heights by hand: above the floor where the walk's were inside)."""
    path = SLOPE.parent / scene
    spec = compile_actions(list(parse(walk).actions), talos, scene=load_scene(path))
    with pytest.raises(SceneConflict) as e:
        check_spec_in_scene_for_robot(spec, talos)
    assert f"'{climb}'" in str(e.value), e.value
    up = compile_actions(list(parse(climb).actions), talos, scene=load_scene(path))
    assert max(c.placement.position[2] for c in _soles(up)) > 0.08  # the stairs' second tread, the slope's landing
