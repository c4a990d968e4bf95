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


def carried_multipliers(old_terms: tuple, output: SolverOutput, new_terms: tuple,
                        new_layout: Any) -> tuple[np.ndarray, np.ndarray] | None:
    """The multipliers of a solve (``output``, of a layout whose terms were ``old_terms``) carried to
    a layout of the same variables with other rows (``new_terms``, its ``NlpLayout``
    ``new_layout``; a collision round adds rows): each term of both (the same object) keeps its
    rows' multipliers, the velocity rows and the dynamic rows after them keep theirs (the same
    count in both), a new term's rows start at zero. None when the variables or the rows after the
    terms differ (then there is nothing to carry)."""
    old = output.nlp_layout
    if (getattr(old, "n_g_kin", -1) < 0 or getattr(new_layout, "n_g_kin", -1) < 0 or old.n_x != new_layout.n_x
            or old.n_g - old.n_g_kin != new_layout.n_g - new_layout.n_g_kin
            or len(old.velocity_joints) != len(new_layout.velocity_joints)):
        return None
    start: dict[int, int] = {}
    r = 0
    for i in old.row_order:
        start[id(old_terms[i])] = r
        r += old_terms[i].n_rows
    lam = np.zeros(new_layout.n_g)
    r_new = 0
    for i in new_layout.row_order:
        term = new_terms[i]
        r_old = start.get(id(term))
        if r_old is not None:
            lam[r_new: r_new + term.n_rows] = output.lam_g[r_old: r_old + term.n_rows]
        r_new += term.n_rows
    tail = old.n_g - r  # the velocity rows, then the dynamic rows
    lam[r_new:] = output.lam_g[r: r + tail]
    return np.array(output.lam_x, dtype=float), lam
