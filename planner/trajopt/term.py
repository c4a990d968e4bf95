"""One constraint or cost at one knot (:class:`Term`), and the knots a timed item applies to.

A leaf of ``planner.trajopt``: the modules that add terms to a layout (self-collision, scene
objects) import these without importing :mod:`planner.trajopt.layout`, whose kinematic initial
guess imports the nominal motion, which screens against the collision model.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(eq=False)
class Term:
    """One constraint or cost at one knot.

    Attributes:
        kind: ``contact``, ``clearance``, ``polygon``, ``com_box``, ``frame_pos``, ``frame_rot``, ``collision``,
            ``com_pos``, ``joint``, ``frame_rel`` (two hands holding one object: a closed chain).
        knot: Knot index (0..N).
        structure: Hashable description of the expression (no numeric values).
        params: Numeric parameters fed to the NLP (flattened).
        lower, upper: Bounds of the constraint rows (empty for a cost term).
        label: What the report calls it ("left_foot contact", "target 'reach'").
        group: The report group it belongs to (several knots share a group).
        item: The spec item it comes from (for diagnoses).
        phase: Name of the phase at this knot.
        unit: Unit of the rows.
    """

    kind: str
    knot: int
    structure: tuple
    params: np.ndarray = field(default_factory=lambda: np.zeros(0))
    lower: np.ndarray = field(default_factory=lambda: np.zeros(0))
    upper: np.ndarray = field(default_factory=lambda: np.zeros(0))
    label: str = ""
    item: object = None
    phase: str = ""

    @property
    def is_cost(self) -> bool:
        """True when the term only adds to the cost."""
        return len(self.lower) == 0

    @property
    def n_rows(self) -> int:
        """Number of constraint rows."""
        return len(self.lower)


def knots_of(layout_t: np.ndarray, time: float | None, window, N: int) -> list[int]:
    """Knots where a timed item applies: nearest to ``time``, every knot in ``window``, or N."""
    dt = layout_t[1] - layout_t[0]
    if window is not None:
        ks = [k for k in range(N + 1) if window[0] - 1e-9 <= layout_t[k] <= window[1] + 1e-9]
        if not ks:
            ks = [int(round(0.5 * (window[0] + window[1]) / dt))]
        return ks
    if time is None:
        return [N]
    return [min(N, max(0, int(round(time / dt))))]
