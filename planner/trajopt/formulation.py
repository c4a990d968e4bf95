"""The formulation protocol: what a formulation adds to the kinematic transcription.

The transcription (:mod:`planner.trajopt.transcription`) writes the NLP of a layout's chart
displacements ``dq``; the plan (:mod:`planner.trajopt.api`) starts, reads and reports a solve.
Both call the layout through this protocol and never ask which formulation it is:

* the kinematic formulation, :class:`planner.trajopt.layout.Layout`: nothing beyond the chart
  (CoM over the support polygon), warm start from the nominal motion, a relaxed re-solve to
  diagnose a failure;
* the centroidal formulation, :class:`planner.trajopt.centroidal.layout.DynamicLayout`: contact
  forces at the sole corners, a lifted CoM with its dynamics, sole-corner rows of swinging feet,
  force checks in the report (``spec.dynamic``, ``docs/dynamic.md``).

A new formulation (collision rows, object forces, ...) subclasses ``Layout`` and overrides these
methods; :meth:`structure` must then include whatever shapes its extra rows, since it keys the
solver cache.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Protocol, Self, runtime_checkable

if TYPE_CHECKING:
    import numpy as np

    from planner.results import Check, Plan
    from planner.trajopt.settings import PlannerSettings


@runtime_checkable
class Formulation(Protocol):
    """The hooks of a layout that the transcription and the plan call."""

    def structure(self) -> tuple:
        """Hashable structure of the NLP (no numeric values): the solver cache key."""
        ...

    def extra_sizes(self) -> tuple[int, int]:
        """(variables, constraint rows) added after the kinematic ones."""
        ...

    def extend_nlp(self, nlp: dict, derivatives: dict) -> tuple[dict, dict]:
        """The kinematic NLP ``{x, p, f, g}`` and its ``grad_f``/``jac_g`` functions, extended, with
        the formulation's ``hess_lag`` (returned without one, the kinematic one is built after)."""
        ...

    def extend_parameters(self, p: np.ndarray) -> np.ndarray:
        """The kinematic parameter vector, extended."""
        ...

    def extend_bounds(self, lbx: np.ndarray, ubx: np.ndarray, lbg: np.ndarray,
                      ubg: np.ndarray) -> tuple[np.ndarray, ...]:
        """The kinematic (lbx, ubx, lbg, ubg), extended."""
        ...

    def initial_guess(self, settings: PlannerSettings | None = None) -> np.ndarray:
        """The solver's starting point ``x0`` (all variables)."""
        ...

    def forces_of(self, x: np.ndarray) -> np.ndarray | None:
        """The contact-force variables of a solution (None: none modelled)."""
        ...

    def plan_checks(self, q: np.ndarray, com: np.ndarray, forces: np.ndarray | None,
                    checks: list[Check], settings: PlannerSettings) -> list[Check]:
        """The kinematic constraint report of a plan with this formulation's own checks."""
        ...

    def plan_forces(self, forces: np.ndarray | None) -> tuple[dict, dict]:
        """(net force per contact frame, extra :attr:`Plan.extras` entries) of the force variables."""
        ...

    def relinearized(self, dq: np.ndarray, x: np.ndarray, round_: int) -> Self | None:
        """The formulation re-linearized about a solution for solve ``round_ + 1`` (a new one: this
        one is not changed), or None: no need to solve again."""
        ...

    def diagnose(self, failed: Plan, relaxed: Callable[[], str]) -> str:
        """A failed plan in task terms; ``relaxed()`` gives the generic relaxed-solve diagnosis."""
        ...
