"""Central finite differences of a stage function's rows, for the derivative tests."""

from __future__ import annotations

import numpy as np


def stage_rows_jacobian(fn, dq: np.ndarray, q_ref: np.ndarray, p, step: float) -> np.ndarray:
    """d g / d dq of ``fn(dq, q_ref, p)[0]`` by central differences with ``step`` on each coordinate."""
    fd = []
    for i in range(len(dq)):
        e = np.zeros(len(dq))
        e[i] = step
        fd.append((np.asarray(fn(dq + e, q_ref, p)[0]).ravel() - np.asarray(fn(dq - e, q_ref, p)[0]).ravel())
                  / (2 * step))
    return np.array(fd).T
