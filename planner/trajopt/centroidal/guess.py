"""Initial guess of a dynamic plan: the base along the feet's heading (:mod:`.heading`; a tracked
motion: each knot's pose for its targets, :mod:`.tracking`), the weight on the corners."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from planner.trajopt.centroidal.data import DynamicData


def initial_guess(lay: DynamicData) -> np.ndarray:
    """Initial ``[x; u; c; l]``: the heading warm start for the chart, the weight shared by the
    corners, the CoM of the guessed configurations, and (lifted) the moment of those forces
    about that CoM (the moment rows hold at the guess)."""
    from planner.trajopt.centroidal.momentum import force_moments
    from planner.trajopt.centroidal.nlp import moment_rows
    from planner.trajopt.centroidal.stepping import stepping_guess
    from planner.trajopt.symbolic import chart_to_configuration

    stepped = stepping_guess(lay)  # a climb: every knot by inverse kinematics (None on a floor)
    dq = lay.guessed_chart() if stepped is None else stepped  # the tracking or the heading guess (memo)
    model, data = lay.robot.model, lay.robot.data()
    N = lay.N
    com = np.array([pin.centerOfMass(model, data, chart_to_configuration(model, lay.q_ref, dq[min(k, N - 1)]))
                    for k in range(N + 1)])
    pat = lay.pattern()
    moments = force_moments(pat, com, pat.initial).ravel() if moment_rows(lay) else np.zeros(0)
    return np.concatenate([dq[2:N].ravel(), pat.initial, com[2:N].ravel(), moments])


def forces_of(lay: DynamicData, x: np.ndarray) -> np.ndarray:
    """The force variables ``u`` from a solution ``x = [x_kin; u; c]`` of the extended NLP."""
    return np.asarray(x, dtype=float)[lay.n_kinematic:lay.n_kinematic + lay.pattern().n_variables]
