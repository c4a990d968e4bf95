"""Central finite differences of a stage function's rows, and the check the derivative tests share."""

from __future__ import annotations

from collections.abc import Callable

import casadi as ca
import numpy as np

from planner.trajopt.symbolic import chart_to_configuration
from tests.tolerances import FD_STEP

FD_TOLERANCE = 2e-5  # relative to the Jacobian's scale: central differences at 1e-6 on O(1) rows


def stage_rows_jacobian(fn, dq: np.ndarray, q_ref: np.ndarray, p, step: float) -> np.ndarray:
    """d g / d dq of ``fn(dq, q_ref, p)[0]`` by central differences with ``step`` on each coordinate."""
    fd = []
    for i in range(len(dq)):
        e = np.zeros(len(dq))
        e[i] = step
        fd.append((np.asarray(fn(dq + e, q_ref, p)[0]).ravel() - np.asarray(fn(dq - e, q_ref, p)[0]).ravel())
                  / (2 * step))
    return np.array(fd).T


def check_stage_rows(fn, robot, p, reference: Callable[[np.ndarray], np.ndarray], *, seed: int, atol: float,
                     rtol: float = 0.0, draws: int = 2, scale: float = 0.2) -> list[np.ndarray]:
    """At ``draws`` random chart points ``dq`` (normal, ``scale``) around the robot's standing
    posture, the rows ``fn(dq, q_standing, p)[0]`` equal ``reference(q)`` (an independent
    computation on the configuration ``q``, e.g. Pinocchio's) within ``rtol``/``atol``, and CasADi's
    Jacobian of them equals central differences within :data:`FD_TOLERANCE` of its scale (at least 1).
    Returns each draw's Jacobian, for the caller's own checks."""
    q_ref = robot.q_standing
    dqs = ca.SX.sym("dq", robot.nv)
    jac = ca.Function("j", [dqs], [ca.jacobian(fn(dqs, q_ref, p)[0], dqs)])
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(draws):
        dq = rng.normal(scale=scale, size=robot.nv)
        g = np.asarray(fn(dq, q_ref, p)[0]).ravel()
        want = np.asarray(reference(chart_to_configuration(robot.model, q_ref, dq)), dtype=float)
        assert g.shape == want.shape, (g.shape, want.shape)
        np.testing.assert_allclose(g, want, rtol=rtol, atol=atol)
        J = np.asarray(jac(dq))
        fd = stage_rows_jacobian(fn, dq, q_ref, p, FD_STEP)
        assert np.abs(J - fd).max() <= FD_TOLERANCE * max(1.0, np.abs(J).max())
        out.append(J)
    return out
