"""From a solution to a :class:`~planner.results.Plan`: configurations, finite-difference velocities,
CoM, the constraint report and the formulation's forces."""

from __future__ import annotations

import numpy as np

from planner.results import Plan, SolverStats
from planner.trajopt.checks import check_plan, finite_differences
from planner.trajopt.layout import Layout
from planner.trajopt.settings import PlannerSettings
from planner.trajopt.symbolic import chart_to_configuration
from robots import Robot


def configurations(lay: Layout, dq: np.ndarray) -> np.ndarray:
    """Configurations (N+1, nq) from the chart displacements."""
    model = lay.robot.model
    return np.array([chart_to_configuration(model, lay.q_ref, d) for d in dq])


def make_plan(lay: Layout, dq: np.ndarray, stats: SolverStats, settings: PlannerSettings, *,
              diagnosis: str = "", checks=None, forces: np.ndarray | None = None) -> Plan:
    """The plan of chart displacements ``dq`` (N+1, nv), checked with Pinocchio numerics unless
    ``checks`` are given."""
    q = configurations(lay, dq)
    v, a = finite_differences(lay.robot.model, q, lay.dt)
    com = com_trajectory(lay.robot, q)
    if checks is None:
        checks = check_plan(lay, q, v, com, settings)
        checks = lay.plan_checks(q, com, forces, checks, settings)
    extras = {"frame_names": {fid: lay.robot.model.frames[fid].name for fid in lay.frame_ids}}
    plan_forces, more = lay.plan_forces(forces)
    extras.update(more)
    return Plan(robot=lay.robot.name, spec=lay.spec, t=lay.t.copy(), q=q, v=v, a=a, com=com, stats=stats,
                checks=tuple(checks), diagnosis=diagnosis, forces=plan_forces, extras=extras)


def com_trajectory(robot: Robot, q: np.ndarray) -> np.ndarray:
    """Centre of mass per configuration (T, 3) [m], Pinocchio numerics."""
    import pinocchio as pin

    data = robot.data()
    return np.array([np.array(pin.centerOfMass(robot.model, data, qk)) for qk in q])
