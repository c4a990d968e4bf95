"""Dynamic plans stop IPOPT's barrier parameter at 1e-9 (``mu_min`` in
``CentroidalSettings.ipopt_options``; IPOPT's default is 1e-11): the optimum is the one the
default reaches (objective and motion), in no more iterations. On the kitchen pick-up the
default spent 10-14 iterations a solve in short steps below 1e-9 at an objective already
converged to 8 digits (docs/performance.md, session 18); here a small G1 jump, both solves
from the same guess."""

from __future__ import annotations

import numpy as np
import pytest

from planner import CacheSettings, PlannerSettings, SolverSettings
from planner.trajopt.api import _formulation, planned_layout
from planner.trajopt.centroidal import CentroidalSettings
from planner.trajopt.ipopt import ipopt_options
from planner.trajopt.solve import solve_layout
from tasks.actions import Action
from tasks.compose import compile_actions


def test_a_dynamic_formulation_hands_ipopt_the_floor_and_a_kinematic_one_does_not(g1):
    """The fast twin of the test below (which solves twice: ~6 s): the option reaches IPOPT's
    options for a dynamic spec, and a setting of the caller's still overrides it."""
    jump = compile_actions([Action(name="jump", params={"height": 0.05})], g1, dt=0.075)
    squat = compile_actions([Action(name="squat", params={})], g1, dt=0.075)
    base = PlannerSettings(cache=CacheSettings(compile=False))
    assert ("mu_min", 1e-9) in CentroidalSettings().ipopt_options
    assert ipopt_options(_formulation(jump, g1, base)[1])["ipopt"]["mu_min"] == 1e-9
    assert "mu_min" not in ipopt_options(_formulation(squat, g1, base)[1])["ipopt"]
    mine = PlannerSettings(cache=base.cache, solver=SolverSettings(ipopt_extra=(("mu_min", 1e-11),)))
    assert ipopt_options(_formulation(jump, g1, mine)[1])["ipopt"]["mu_min"] == 1e-11


@pytest.mark.long
def test_dynamic_plans_floor_the_barrier_at_1e_9_and_reach_the_same_optimum(g1):
    spec = compile_actions([Action(name="jump", params={"height": 0.05})], g1, dt=0.075)
    runs = {}
    for name, extra in (("floored", ()), ("default", (("mu_min", 1e-11),))):
        settings = PlannerSettings(cache=CacheSettings(compile=False), solver=SolverSettings(ipopt_extra=extra))
        lay = planned_layout(spec, g1, settings)
        _, full = _formulation(spec, g1, settings)
        dq, stats, _ = solve_layout(lay, full, x0=lay.initial_guess(full))
        assert stats.status.ok, (name, stats.raw_status)
        runs[name] = (dq, stats)
    (dq_f, floored), (dq_d, default) = runs["floored"], runs["default"]
    assert floored.objective == pytest.approx(default.objective, rel=1e-6)
    np.testing.assert_allclose(dq_f, dq_d, atol=1e-4)
    assert floored.iterations <= default.iterations, (floored.iterations, default.iterations)
