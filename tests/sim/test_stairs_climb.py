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


def _tread(flight, x: float) -> tuple[int, float, float]:
    """The step under a point at ``x`` of a flight climbing along +x (0: the floor), by hand, and its
    top face's extent along x [m]."""
    i = int(min(max(np.floor((x - flight.position[0]) / flight.run) + 1, 0), flight.count))
    x0 = -np.inf if i == 0 else flight.position[0] + (i - 1) * flight.run
    x1 = flight.position[0] if i == 0 else x0 + flight.run
    return i, x0, x1


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
                step, x0, x1 = _tread(flight, float(M.translation[0]))  # the tread under the sole's centre
                # every corner over that tread (the primitive puts talos's heel on the nosing: a corner
                # may sit on the edge, within the tolerance)
                assert (world[:, 0] >= x0 - tolerance).all() and (world[:, 0] <= x1 + tolerance).all(), \
                    f"{contact.frame} at t = {middle:.2f} s: corners x {world[:, 0]} off step {step} ({x0}..{x1})"
                top = flight.rise * step
                assert np.abs(world[:, 2] - top).max() < tolerance  # flat on the tread's top face
                assert np.linalg.norm(M.translation - np.array(contact.placement.position)) < tolerance
                heights.add(round(top, 6))
    assert heights == {0.0, 0.1, 0.2, 0.3}
