"""Exceptions raised by the planner layer."""

from __future__ import annotations

from typing import Any

from robots import WbmpError
from tasks import TaskDefinitionError


class PlannerError(WbmpError):
    """Base class of every planner error."""


class UnsupportedModel(PlannerError):
    """The Pinocchio model has a joint type the symbolic kinematics does not support."""


class SpecNotForRobot(PlannerError, TaskDefinitionError):
    """The spec names something the robot does not have (a joint, a frame): an invalid spec.

    It is a :class:`tasks.exceptions.TaskDefinitionError` too, so the CLI exits 3 (invalid spec),
    not 4 (infeasible): nothing was solved. :func:`tasks.robot_check.check_spec_for_robot`
    finds these before the planner is called; the planner raises this class when it meets one.
    """


class PlanningFailed(PlannerError):
    """The optimizer found no plan; ``diagnosis`` explains it in task terms.

    Attributes:
        plan: The (failed) Plan at the returned point, when there is one.
        diagnosis: e.g. "right_hand target 'reach' is 0.21 m beyond reach at t = 1.50 s".
        problem: The problem last solved (``planner.trajopt.api.Problem``: its layout with the rows
            the collision rounds added, and the settings its solves used), when there is one.
    """

    def __init__(self, diagnosis: str, plan: Any = None, *, problem: Any = None) -> None:
        self.diagnosis = diagnosis
        self.plan = plan
        self.problem = problem
        super().__init__(diagnosis)

    @property
    def stats(self) -> Any:
        """The solver's record (:class:`planner.results.SolverStats`: status, iterations, times, the
        warm start's origin), None without a plan."""
        return None if self.plan is None else self.plan.stats


class StagewiseUnsupported(PlannerError):
    """The layout has variables or rows the stage-wise transcription does not write (a dynamic
    formulation's contact forces, lifted CoM and momentum rows)."""


class ControllerError(PlannerError):
    """The whole-body controller was misconfigured (unknown backend, bad reference)."""
