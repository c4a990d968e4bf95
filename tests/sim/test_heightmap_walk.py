"""Talos walks up the gentle ramp of ``examples/scenes/heightmap.json``, a height map (a grid of
heights in a CSV file), certified in MuJoCo, where the ground is a height field (issue 33).

The foot placements are recomputed independently of the planner and of ``tasks.terrain``: Pinocchio
forward kinematics of the planned and of the executed configurations, every sole corner against the
example's ground by hand (4 cm over 0.4 m from x = 0.15, then 0.25 m flat; the floor around it). The fast
twins: ``tests/tasks/test_heightmap.py`` (the ground's height and normal, the compiled footsteps flat
on it) and ``tests/sim/test_heightfield.py`` (MuJoCo's height field under the grid).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from planner import PlannerSettings, plan
from sim import simulate
from tasks.actions import Action
from tasks.compose import compile_actions
from tasks.scene import load_scene
from tests.sim.soles import check_soles_on_the_ground

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "scenes" / "heightmap.json"
PLACEMENT_TARGET = 0.005  # [m] the target for the executed soles on the ground
TILTED_PLACEMENT = 0.008  # [m] an executed sole's origin from its placement on an incline (as on the slope)


def _ground(p: np.ndarray) -> float:
    """The example's ground under a point, by hand."""
    inside = 0.15 <= p[0] <= 0.80 and -0.5 <= p[1] <= 0.5
    return float(min(max(0.1 * (p[0] - 0.15), 0.0), 0.04)) if inside else 0.0


@pytest.mark.long  # minutes: a dynamic plan with scene rows, then ~9 s of MuJoCo and the certificate
def test_talos_walks_up_the_height_map_certified_with_the_soles_on_the_ground(talos):
    scene = load_scene(EXAMPLE)
    spec = compile_actions([Action(name="step_up", params={"object": "the ramp"})], talos, scene=scene)
    result = plan(spec, talos, settings=PlannerSettings())
    assert result.ok
    execution = simulate(result, talos)
    assert execution.certificate.ok, execution.certificate.reason

    soles = check_soles_on_the_ground(talos, spec, result, execution, _ground, executed=PLACEMENT_TARGET,
                                      tilted=TILTED_PLACEMENT)
    heights = {round(float(contact.placement.position[2]), 3) for contact, _ in soles}
    assert 0.0 in heights and 0.04 in heights and len(heights) >= 3  # the floor, the incline, the top
