"""The dynamic layout: the centroidal implementation of the formulation protocol
(:class:`planner.trajopt.formulation.Formulation`), what :func:`planner.plan` uses for a spec with
``dynamic = True``."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Self

import numpy as np

from planner.trajopt.centroidal.checks import dynamic_plan_checks
from planner.trajopt.centroidal.data import DynamicData
from planner.trajopt.centroidal.diagnose import diagnose_dynamic
from planner.trajopt.centroidal.guess import forces_of, initial_guess
from planner.trajopt.centroidal.nlp import (
    dynamic_sizes,
    extend_bounds,
    extend_nlp,
    extend_parameters,
)
from planner.trajopt.centroidal.settings import CentroidalSettings
from planner.trajopt.centroidal.torque import TorqueMarginTerm, torque_margin_terms
from planner.trajopt.kinds import SupportPolygonTerm
from planner.trajopt.layout import Layout

if TYPE_CHECKING:
    from planner.results import Check, Plan
    from planner.trajopt.settings import PlannerSettings

DYNAMIC_FORMULATION = "lifted-com-3-momentum-affine-ankle-lifted-moment"  # part of a dynamic layout's structure (solver cache key)


@dataclass(frozen=True, eq=False)
class DynamicLayout(DynamicData, Layout):
    """A :class:`planner.trajopt.layout.Layout` with CoM dynamics and contact forces: the data
    (:class:`planner.trajopt.centroidal.data.DynamicData`) and the formulation protocol.

    Built by :func:`to_dynamic_layout`. Its :meth:`structure` adds the force pattern (contacts per
    knot, swinging sole corners), so the solver cache never confuses it with a kinematic
    layout or with another contact pattern.
    """

    def structure(self) -> tuple:
        """Kinematic structure + the dynamic one (with :data:`DYNAMIC_FORMULATION`, bumped when the
        dynamic NLP changes; the solver cache also hashes the centroidal sources)."""
        return (super().structure(), "dynamic", DYNAMIC_FORMULATION, self.pattern().structure,
                self.corner_rows(), self.centroidal_settings)

    # -- the formulation protocol (planner.trajopt.formulation.Formulation) ------------------

    def extra_sizes(self) -> tuple[int, int]:
        """(force + lifted CoM + lifted moment variables, dynamic constraint rows)."""
        return dynamic_sizes(self)

    def extend_nlp(self, nlp: dict, derivatives: dict) -> tuple[dict, dict]:
        """Forces, CoM dynamics and sole-corner rows added to the kinematic NLP."""
        return extend_nlp(self, nlp, derivatives)

    def extend_parameters(self, p: np.ndarray) -> np.ndarray:
        """The kinematic parameters, then the contact geometry."""
        return extend_parameters(self, p)

    def extend_bounds(self, lbx: np.ndarray, ubx: np.ndarray, lbg: np.ndarray,
                      ubg: np.ndarray) -> tuple[np.ndarray, ...]:
        """Bounds of the forces, the CoM dynamics and the swinging sole corners added."""
        return extend_bounds(self, lbx, ubx, lbg, ubg)

    def initial_guess(self, settings: PlannerSettings | None = None) -> np.ndarray:
        """Base along the feet's heading, weight on the corners (whatever ``settings.warm_start``)."""
        return initial_guess(self)

    def forces_of(self, x: np.ndarray) -> np.ndarray:
        """The force variables of a solution."""
        return forces_of(self, x)

    def plan_checks(self, q: np.ndarray, com: np.ndarray, forces: np.ndarray | None,
                    checks: list[Check], settings: PlannerSettings) -> list[Check]:
        """The kinematic checks with the dynamic ones (friction, CoP, CoM dynamics)."""
        return dynamic_plan_checks(self, q, com, forces, checks, settings)

    def plan_forces(self, forces: np.ndarray | None) -> tuple[dict, dict]:
        """(net force per contact frame, ``{"corner_forces": ...}``) of the force variables."""
        if forces is None:
            return {}, {}
        corner = self.pattern().corner_forces(forces)
        return {frame: f.sum(axis=1) for frame, f in corner.items()}, {"corner_forces": corner}

    def relinearized(self, dq: np.ndarray, x: np.ndarray, round_: int) -> Self | None:
        """This layout with the whole-body momentum rows linearized about the solution ``dq`` again
        (a copy; this one is not changed), when Euler's law with the exact :math:`A_g` is off by more
        than ``CentroidalSettings.momentum_tolerance``, for at most ``momentum_iterations`` rounds;
        and with the torque margin rows added or re-linearized when the solution's RNEA torques of
        ``torque_joints`` exceed ``torque_margin`` (:mod:`planner.trajopt.centroidal.torque`, at most
        ``torque_rounds`` rounds)."""
        s = self.centroidal_settings
        out = None
        # the torque rows move the motion after the momentum rows' own rounds: theirs come on top
        bounded = any(isinstance(t, TorqueMarginTerm) for t in self.terms)
        if s.whole_body_momentum and round_ < s.momentum_iterations + (s.torque_rounds if bounded else 0):
            from planner.trajopt.centroidal.momentum import euler_residual

            residual = euler_residual(self, dq, self.forces_of(x))
            if residual > s.momentum_tolerance:
                out = self.with_momentum_point(dq, residual)
        if round_ < s.torque_rounds:
            terms = torque_margin_terms(self, dq)
            if terms is not None:
                out = (out or self).with_terms(terms)
        return out

    def diagnose(self, failed: Plan, relaxed: Callable[[], str]) -> str:
        """The worst violated group of the failed plan (no relaxed solve)."""
        return diagnose_dynamic(self, failed)


def to_dynamic_layout(lay: Layout, settings: CentroidalSettings = CentroidalSettings()) -> DynamicLayout:
    """The dynamic version of a kinematic layout.

    The support-polygon rows on the CoM are dropped except at the last variable knot (the robot
    ends at rest there): with contact forces, balance is the centre of pressure inside the
    soles, which the corner forces guarantee at every knot.

    Args:
        lay: The layout of a spec (``planner.trajopt.layout.make_layout``).
        settings: Weights and options of the dynamic terms.

    Returns:
        The dynamic layout (a new object; ``lay`` is not changed).
    """
    import dataclasses

    fields = {f.name: getattr(lay, f.name) for f in dataclasses.fields(lay) if f.init}
    fields["terms"] = tuple(t for t in lay.terms if not isinstance(t, SupportPolygonTerm) or t.knot == lay.N - 1)
    return DynamicLayout(**fields, centroidal_settings=settings)
