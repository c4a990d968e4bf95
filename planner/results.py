"""Planner results: the planned motion, solver statistics and the constraint report."""

from __future__ import annotations

import enum
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from tasks.specs import TaskSpec


class SolveStatus(enum.Enum):
    """Outcome of a trajectory optimization; the value is the human-readable message."""

    SOLVED = "solved"
    SOLVED_INACCURATE = "solved to acceptable (not full) accuracy"
    INFEASIBLE = "the requested task is infeasible"
    MAX_ITERATIONS = "iteration limit reached"
    NUMERICAL_ERROR = "the solver reported a numerical failure"
    NOT_RUN = "the solver was not run"

    @property
    def ok(self) -> bool:
        """True for SOLVED and SOLVED_INACCURATE."""
        return self in (SolveStatus.SOLVED, SolveStatus.SOLVED_INACCURATE)


@dataclass(frozen=True, slots=True, kw_only=True)
class SolverStats:
    """How the solve went.

    Attributes:
        status: Mapped solver outcome.
        iterations: IPOPT iterations.
        build_time: Time to build (or load from cache) the NLP and solver [s].
        solve_time: Time inside the solver [s].
        cache: ``"built"`` (first ever), ``"disk"`` (loaded compiled code), ``"memory"`` (warm).
        objective: Final cost value.
        n_variables, n_constraints: Problem size.
        backend: ``"ipopt"``.
        raw_status: The backend's own status string.
    """

    status: SolveStatus
    iterations: int = 0
    build_time: float = 0.0
    solve_time: float = 0.0
    cache: str = "built"
    objective: float = float("nan")
    n_variables: int = 0
    n_constraints: int = 0
    backend: str = "ipopt"
    raw_status: str = ""


@dataclass(frozen=True, slots=True, kw_only=True)
class ConstraintCheck:
    """Worst violation of one constraint group over the horizon.

    Attributes:
        name: Group name ("left_foot contact position", "CoM support polygon", "right hand target").
        violation: Worst violation, >= 0 (0 = satisfied) [unit].
        tolerance: Accepted violation [unit].
        unit: ``m``, ``rad``, ``rad/s``, ``N``...
        time: Time of the worst violation [s].
    """

    name: str
    violation: float
    tolerance: float
    unit: str
    time: float

    @property
    def ok(self) -> bool:
        """True when the violation is within tolerance."""
        return bool(self.violation <= self.tolerance)


@dataclass(frozen=True, eq=False, kw_only=True)
class Plan:
    """A planned whole-body motion on a uniform time grid.

    Attributes:
        robot: Robot name.
        spec: The TaskSpec it satisfies.
        t: Knot times (T,) [s].
        q: Configurations (T, nq), Pinocchio order, free-flyer quaternion (x, y, z, w).
        v: Velocities (T, nv) [m/s, rad/s], Pinocchio convention (base linear/angular in the
            base frame).
        a: Accelerations (T, nv).
        com: Centre of mass (T, 3) [m].
        forces: Contact force per contact frame (T, 3) in the world [N], for dynamic plans
            (zero while the contact is inactive); empty for kinematic plans.
        stats: Solver statistics.
        checks: Constraint report, one entry per group.
        diagnosis: Task-level explanation of a failure (empty when ok).
    """

    robot: str
    spec: TaskSpec
    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    com: np.ndarray
    forces: Mapping[str, np.ndarray] = field(default_factory=dict)
    stats: SolverStats
    checks: tuple[ConstraintCheck, ...] = ()
    diagnosis: str = ""
    extras: Mapping[str, Any] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        """Solver succeeded and every constraint group is within tolerance."""
        return self.stats.status.ok and all(c.ok for c in self.checks)

    @property
    def dt(self) -> float:
        """Knot spacing [s]."""
        return float(self.t[1] - self.t[0]) if len(self.t) > 1 else 0.0

    def active_contacts(self, k: int) -> tuple[str, ...]:
        """Contact frames active at knot ``k``."""
        return tuple(c.frame for c in self.spec.phases[self.spec.phase_at(float(self.t[k]))].contacts)

    def summary(self) -> str:
        """A short multi-line table of the solve and the constraint report."""
        s = self.stats
        lines = [
            f"plan: {s.status.value} in {s.iterations} iterations "
            f"(build {s.build_time:.2f} s [{s.cache}], solve {s.solve_time:.2f} s), "
            f"{len(self.t)} knots over {self.t[-1]:.2f} s, {s.n_variables} variables, {s.n_constraints} constraints",
        ]
        for c in self.checks:
            mark = "ok  " if c.ok else "FAIL"
            lines.append(f"  {mark} {c.name:<40} {c.violation:10.2e} {c.unit:<6} (tol {c.tolerance:.0e}, t = {c.time:.2f} s)")
        if self.diagnosis:
            lines.append(f"  diagnosis: {self.diagnosis}")
        return "\n".join(lines)
