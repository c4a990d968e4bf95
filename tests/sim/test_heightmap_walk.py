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
import pinocchio as pin
import pytest

from planner import PlannerSettings, plan
from sim import simulate
from tasks.actions import Action
from tasks.compose import compile_actions
from tasks.scene import load_scene

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

    model, data = talos.model, talos.data()
    t_exec = np.asarray(execution.t) - float(execution.t[0])
    t0, heights = 0.0, set()
    for phase in spec.phases:
        middle = t0 + 0.5 * phase.duration
        t0 += phase.duration
        k_plan = int(np.argmin(np.abs(result.t - middle)))
        k_exec = int(np.argmin(np.abs(t_exec - middle)))
        for contact in phase.contacts:
            side = "left" if contact.frame.startswith("left") else "right"
            tilted = abs(contact.placement.rpy[1]) > 1e-3
            for q, tolerance, along in ((result.q[k_plan], 1e-3, 1e-3),
                                        (execution.q[k_exec], PLACEMENT_TARGET,
                                         TILTED_PLACEMENT if tilted else PLACEMENT_TARGET)):
                pin.framesForwardKinematics(model, data, q)
                corners = talos.sole_corners_in_world(q, side)
                gaps = [float(c[2] - _ground(np.asarray(c))) for c in corners]
                assert max(abs(g) for g in gaps) < tolerance, f"{contact.frame} at t = {middle:.2f} s: {gaps}"
                M = data.oMf[talos.frame_id(contact.frame)]
                off = float(np.linalg.norm(M.translation - np.array(contact.placement.position)))
                assert off < along, f"{contact.frame} at t = {middle:.2f} s: {off * 1e3:.1f} mm from its placement"
            heights.add(round(float(contact.placement.position[2]), 3))
    assert 0.0 in heights and 0.04 in heights and len(heights) >= 3  # the floor, the incline, the top
