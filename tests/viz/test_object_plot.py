"""The held objects' height plot (viz/plots.py ``plot_objects``): drawn for a plan with a grasp and
the simulated object positions, absent without a grasp."""

from __future__ import annotations

import dataclasses

import numpy as np

from planner.results import Plan, SolverStats, SolveStatus
from tasks.actions import Action
from tasks.compose import compile_actions
from tasks.scene import Scene, SceneObject
from viz.plots import plot_objects

CUP = SceneObject(name="cup", shape="cylinder", size=(0.04, 0.1), position=(0.52, -0.2, 0.77), movable=True, mass=0.25)
TABLE = SceneObject(name="table", shape="box", size=(0.6, 1.0, 0.72), position=(0.75, 0.0, 0.36))


def test_object_height_plot(talos, tmp_path):
    """A PNG for the grasped cup; None for a spec without grasps."""
    spec = compile_actions([Action(name="pick_up", params={"object": "the cup"})], talos,
                           scene=Scene(objects=(TABLE, CUP)))
    t = np.linspace(0.0, spec.horizon, 50)
    q = np.tile(talos.q_standing, (len(t), 1))
    plan = Plan(robot="talos", spec=spec, t=t, q=q, v=np.zeros((len(t), talos.nv)), a=np.zeros((len(t), talos.nv)),
                com=np.zeros((len(t), 3)), stats=SolverStats(status=SolveStatus.NOT_RUN))
    z = np.where(t > spec.grasps[0].hold[0], 0.87, 0.77)
    cup = np.column_stack([np.full_like(t, 0.52), np.full_like(t, -0.2), z])
    path = plot_objects(tmp_path / "objects.png", talos, plan, t, {"cup": cup})
    assert path is not None and path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and path.stat().st_size > 10_000
    bare = dataclasses.replace(plan, spec=dataclasses.replace(spec, grasps=()))
    assert plot_objects(tmp_path / "none.png", talos, bare, t, {"cup": cup}) is None
    assert not (tmp_path / "none.png").exists()
