"""Talos walks up the three steps of ``examples/scenes/stairs.json`` (issue 33), certified in MuJoCo.

The foot placements are recomputed independently of the planner and of ``tasks.terrain``: Pinocchio
forward kinematics of the planned and of the executed configurations against the tread boxes, built
by hand from the flight's count, rise and run. The fast twins are in
``tests/planner/trajopt/test_terrain_rows.py`` (the rows and the guess of the same climb) and
``tests/tasks/test_terrain.py`` (the compiled footsteps).
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

STAIRS = Path(__file__).resolve().parents[2] / "examples" / "scenes" / "stairs.json"
PLACEMENT_TARGET = 0.005  # [m] the target for the executed soles on the treads


def _tread(flight, x: float) -> int:
    """The step (0: the floor) under a point at ``x`` of a flight climbing along +x, by hand."""
    return int(min(max(np.floor((x - flight.position[0]) / flight.run) + 1, 0), flight.count))


@pytest.mark.long  # minutes: a dynamic plan with scene and collision rounds, then ~8 s of MuJoCo
def test_talos_walks_up_the_stairs_certified_with_the_soles_on_the_treads(talos):
    scene = load_scene(STAIRS)
    flight = scene.stairs[0]
    spec = compile_actions([Action(name="step_up", params={"object": "the stairs"})], talos, scene=scene)
    result = plan(spec, talos, settings=PlannerSettings())
    assert result.ok
    execution = simulate(result, talos)
    assert execution.certificate.ok, execution.certificate.reason

    model, data = talos.model, talos.data()
    sole = talos.profile.sole
    corners = np.array([[x, y, 0.0] for x in (sole.x_min, sole.x_max) for y in (sole.y_min, sole.y_max)])
    t_exec = np.asarray(execution.t) - float(execution.t[0])
    start, heights = 0.0, set()
    for phase in spec.phases:
        middle = start + 0.5 * phase.duration
        start += phase.duration
        k_plan = int(np.argmin(np.abs(result.t - middle)))
        k_exec = int(np.argmin(np.abs(t_exec - middle)))
        for contact in phase.contacts:
            fid = talos.frame_id(contact.frame)
            for q, tolerance in ((result.q[k_plan], 1e-3), (execution.q[k_exec], PLACEMENT_TARGET)):
                pin.framesForwardKinematics(model, data, q)
                M = data.oMf[fid]
                world = corners @ M.rotation.T + M.translation
                steps = {_tread(flight, float(x)) for x in world[:, 0]}
                assert len(steps) == 1, f"{contact.frame} at t = {middle:.2f} s spans treads {steps}"
                top = flight.rise * steps.pop()
                assert np.abs(world[:, 2] - top).max() < tolerance  # flat on the tread's top face
                assert np.linalg.norm(M.translation - np.array(contact.placement.position)) < tolerance
                heights.add(round(top, 6))
    assert heights == {0.0, 0.1, 0.2, 0.3}
