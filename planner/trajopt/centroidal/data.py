"""The data of a dynamic layout: a layout's data with its dynamic parts (the force pattern, the
sole-corner rows, the centroidal function, the momentum linearization point).

The centroidal modules (``nlp``, ``guess``, ``momentum``, ``checks``, ``zmp``, ``diagnose``) take a
:class:`DynamicData`; the formulation, :class:`planner.trajopt.centroidal.layout.DynamicLayout`,
adds the formulation protocol on top and imports them, never the other way round. The parts are
built on first use from the layout's data alone (``contacts``, ``pattern``, ``heading``) and kept in
the layout's memo (:meth:`planner.trajopt.layout_data.LayoutData.memo`): a dynamic layout is frozen
like every layout.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Self

import numpy as np

from planner.trajopt.centroidal.contacts import layout_contacts
from planner.trajopt.centroidal.heading import heading_guess
from planner.trajopt.centroidal.pattern import (
    CentroidalFunction,
    CentroidalPattern,
    centroidal_function,
    centroidal_pattern,
    swinging_corners,
)
from planner.trajopt.centroidal.settings import CentroidalSettings
from planner.trajopt.layout_data import LayoutData


def chart_guess(lay: DynamicData) -> np.ndarray:
    """The initial guess's chart displacements (N+1, nv) on a floor: each knot's pose for its soft
    targets when the settings ask for it and the spec tracks a motion
    (:func:`planner.trajopt.centroidal.tracking.tracking_guess`), else the heading guess."""
    if lay.centroidal_settings.tracking_guess:
        from planner.trajopt.centroidal.tracking import tracking_guess

        tracked = tracking_guess(lay)
        if tracked is not None:
            return tracked
    return heading_guess(lay)


@dataclass(frozen=True, eq=False)
class DynamicData(LayoutData):
    """A :class:`planner.trajopt.layout_data.LayoutData` with the parts of its CoM dynamics.

    Attributes:
        centroidal_settings: Weights and options of the dynamic terms.
        linearized_about: Chart displacements (N+1, nv) given to :meth:`with_momentum_point` (None:
            the initial guess's, :meth:`momentum_point`).
        momentum_residual: Euler's law / (m g) [m] at the solution the momentum rows were last
            re-linearized about (nan before).
    """

    centroidal_settings: CentroidalSettings = CentroidalSettings()
    linearized_about: np.ndarray | None = None
    momentum_residual: float = float("nan")  # Euler's law at the momentum point / (m g) [m]

    def momentum_point(self) -> np.ndarray:
        """Chart displacements (N+1, nv) the whole-body momentum rows are linearized about: the
        solution given to :meth:`with_momentum_point`, else the initial guess's."""
        if self.linearized_about is not None:
            return self.linearized_about
        return self.guessed_chart()

    def guessed_chart(self) -> np.ndarray:
        """The initial guess's chart displacements (N+1, nv) on a floor (:func:`chart_guess`; built once)."""
        return self.memo("guess", lambda: chart_guess(self))

    def with_momentum_point(self, dq: np.ndarray, residual: float = float("nan")) -> Self:
        """A copy of this layout whose whole-body momentum rows are linearized about ``dq`` (N+1, nv)
        (``residual``: Euler's law there, for the record); this one is not changed."""
        return self._changed(linearized_about=np.array(dq, dtype=float), momentum_residual=residual)

    def centroidal(self) -> CentroidalFunction:
        """The centroidal function of this layout (CasADi; built once, only to build a solver)."""
        return self.memo("centroidal", lambda: centroidal_function(self, settings=self.centroidal_settings))

    def pattern(self) -> CentroidalPattern:
        """The numbers of the centroidal terms (no CasADi; what a cached solver needs)."""
        def build() -> CentroidalPattern:
            contacts = layout_contacts(self, cop_margin=self.centroidal_settings.cop_margin)
            return centroidal_pattern(contacts, self.robot.mass, settings=self.centroidal_settings)

        return self.memo("pattern", build)

    def corner_rows(self) -> tuple[tuple[int, int, int], ...]:
        """(knot, foot frame id, corner) of the sole-corner rows (feet not in contact)."""
        return swinging_corners(self)

    @property
    def n_kinematic(self) -> int:
        """Number of chart variables (the force variables come after them)."""
        return self.robot.nv * (self.N - 2)
