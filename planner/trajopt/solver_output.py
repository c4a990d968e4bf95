"""What one solve returns beside the motion: a small read-only record (was a dict of seven string
keys)."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np


@dataclasses.dataclass(frozen=True, eq=False)
class SolverOutput:
    """What one solve returned beside the motion (:func:`solve_layout`), read-only: the variables
    and multipliers (the next solve's warm start, the solution library's seed), the constraint
    values and bounds, and the solver's variable layout.

    Attributes:
        x: All variables (the current transcription's: ``dq_2 .. dq_{N-1}`` first).
        lam_x: The variables' bound multipliers.
        lam_g: The constraint rows' multipliers.
        g: The constraint rows' values at ``x``.
        lbg: The rows' lower bounds.
        ubg: The rows' upper bounds.
        nlp_layout: The solver's variable and row layout (``NlpLayout``; the stage-wise one's
            ``StageLayout``).
        x_stagewise: The stage-wise transcription's own variables (None: solved by the current one).
    """

    x: np.ndarray
    lam_x: np.ndarray
    lam_g: np.ndarray
    g: np.ndarray
    lbg: np.ndarray
    ubg: np.ndarray
    nlp_layout: Any
    x_stagewise: np.ndarray | None = None

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if isinstance(value, np.ndarray):
                value = np.array(value, dtype=float).ravel()
                value.setflags(write=False)
                object.__setattr__(self, f.name, value)
