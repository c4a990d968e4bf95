"""Trajectory optimization (CasADi + IPOPT) and whole-body control for TaskSpecs."""

from planner.exceptions import PlannerError, PlanningFailed, UnsupportedModel
from planner.plan import ConstraintCheck, Plan, SolverStats, SolveStatus

__all__ = [
    "ConstraintCheck",
    "Plan",
    "PlannerError",
    "PlanningFailed",
    "SolveStatus",
    "SolverStats",
    "UnsupportedModel",
]
