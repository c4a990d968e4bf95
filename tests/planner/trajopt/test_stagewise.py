"""The stage-wise transcription (planner/trajopt/stagewise.py): its plans meet their constraints
(Pinocchio numerics, tests/planner/planning_cases.py), agree with the current transcription's, and
every row and Hessian entry stays on one stage or two neighbours (the structure fatrop needs)."""

from __future__ import annotations

import dataclasses

import casadi as ca
import numpy as np
import pytest

from planner import CacheSettings, CollisionSettings, PlannerSettings, SolverSettings, plan
from planner.exceptions import PlannerError
from planner.results import SolveStatus
from planner.trajopt.centroidal.layout import to_dynamic_layout
from planner.trajopt.layout import make_layout
from planner.trajopt.stagewise import (
    StagewiseUnsupported,
    build_stagewise_nlp,
    chart_of,
    stage_layout,
    stagewise_parameters,
    to_stagewise,
)
from planner.trajopt.transcription import build_nlp
from tests.planner.planning_cases import assert_plan_meets_spec, squat_spec

# A short squat on the G1 (12 intervals): each solve takes well under a second. No collision rows:
# the transcriptions are compared, not the screening (whose first use builds the sphere model).
SETTINGS = PlannerSettings(cache=CacheSettings(compile=False),
                           collision=CollisionSettings(self_collision=False, scene_collision=False))
STAGEWISE = {solver: dataclasses.replace(SETTINGS,
                                         solver=dataclasses.replace(SETTINGS.solver,
                                                                    transcription="stagewise",
                                                                    stagewise_solver=solver))
             for solver in ("fatrop", "ipopt")}
# The two transcriptions are the same problem in other variables, each solved to IPOPT's (or
# fatrop's) tol 1e-6 on its own scaled KKT conditions: their optima agree to this in joint angle.
AGREEMENT_ATOL = 2e-3  # [rad, m]
OBJECTIVE_RTOL = 1e-3


def small_squat(robot):
    return squat_spec(robot, 0.05, duration=1.2, dt=0.1)


@pytest.fixture(scope="module")
def current_plan(g1):
    return plan(small_squat(g1), g1, settings=SETTINGS)


@pytest.mark.parametrize("solver", ["fatrop", "ipopt"])
def test_stagewise_plan_meets_its_constraints_and_agrees_with_the_current_one(g1, current_plan, solver):
    """The G1 squat planned stage-wise (fatrop, then IPOPT) holds the soles, the CoM in the shrunk
    polygon, the limits and the CoM target, checked with Pinocchio; its configurations are the
    current transcription's within AGREEMENT_ATOL and its cost within OBJECTIVE_RTOL."""
    spec = small_squat(g1)
    result = plan(spec, g1, settings=STAGEWISE[solver])
    assert result.ok, result.summary()
    assert result.stats.backend == f"{solver} (stage-wise)"
    assert_plan_meets_spec(result, g1, spec)
    assert current_plan.ok and current_plan.stats.backend == "ipopt"
    assert np.abs(result.q - current_plan.q).max() < AGREEMENT_ATOL
    assert result.stats.objective == pytest.approx(current_plan.stats.objective, rel=OBJECTIVE_RTOL)


@pytest.fixture(scope="module")
def built(g1):
    lay = make_layout(small_squat(g1), g1)
    nlp, derivatives, sl = build_stagewise_nlp(lay, symmetric_hessian=True)
    return lay, nlp, derivatives, sl


def test_every_row_touches_one_stage_or_two_neighbours(built):
    """Read off the Jacobian's sparsity: a path row only the columns of its own stage, a gap row
    its stage's states and controls and one state entry of the next stage (the -I of fatrop's
    ``x_{k+1} = f(x_k, u_k)``, coefficient +1 here); the Hessian is block diagonal by stage."""
    lay, nlp, derivatives, sl = built
    rng = np.random.default_rng(0)
    x = rng.standard_normal(sl.n_x)
    p = stagewise_parameters(lay)
    _, jac = derivatives["jac_g"](x, p)
    J = np.array(ca.DM(jac))
    pattern = np.zeros(J.shape, dtype=bool)  # structural nonzeros (a padded polygon row is 0 * com)
    rows, cols = jac.sparsity().get_triplet()
    pattern[rows, cols] = True
    stage_of_column = np.empty(sl.n_x, dtype=int)
    for s in range(sl.stages):
        stage_of_column[list(sl.stage_columns(s))] = s
    assert (np.diff(stage_of_column) >= 0).all()  # variables in stage order
    gap_seen = np.zeros(sl.stages, dtype=int)
    for r in range(sl.n_g):
        s = sl.row_stage[r]
        cols = np.flatnonzero(pattern[r])
        assert len(cols), f"row {r} touches no variable"
        own = cols[stage_of_column[cols] == s]
        other = cols[stage_of_column[cols] != s]
        if sl.gap_rows[r]:
            j = gap_seen[s]
            gap_seen[s] += 1
            nxt = sl.x_offset[s + 1] + j  # the j-th state of the next stage, coefficient 1
            assert other.tolist() == [nxt], f"gap row {r} of stage {s} touches {other}"
            assert J[r, nxt] == 1.0
            assert len(own) > 0
        else:
            assert len(other) == 0, f"path row {r} of stage {s} touches stages {set(stage_of_column[other])}"
    assert gap_seen.tolist() == [sl.nx[s + 1] for s in range(sl.stages - 1)] + [0]
    assert sum(sl.ng) + sum(sl.nx[1:]) == sl.n_g
    hess = derivatives["hess_lag"](x, p, 1.0, rng.standard_normal(sl.n_g))
    H = np.array(ca.DM(hess))
    rows, cols = (np.array(i) for i in hess.sparsity().get_triplet())
    assert (stage_of_column[rows] == stage_of_column[cols]).all(), "a Hessian entry couples two stages"
    assert np.allclose(H, H.T)


def test_same_cost_and_rows_as_the_current_transcription(built, g1):
    """At a random chart trajectory (start at rest, end repeated), the stage-wise NLP's cost equals
    the current NLP's, its gap and start rows are zero, and its term rows are the current ones."""
    lay, nlp, _, sl = built
    rng = np.random.default_rng(1)
    N, nv = lay.N, g1.nv
    dq = np.zeros((N + 1, nv))
    dq[2:N] = 0.02 * rng.standard_normal((N - 2, nv))
    dq[N] = dq[N - 1]
    xs = to_stagewise(lay, sl, dq)
    assert np.array_equal(chart_of(lay, sl, xs), dq)
    p = stagewise_parameters(lay)
    f_s, g_s = (np.array(v).ravel() for v in ca.Function("sw", [nlp["x"], nlp["p"]], [nlp["f"], nlp["g"]])(xs, p))
    knlp, _, nl = build_nlp(lay)
    f_k, g_k = (np.array(v).ravel() for v in ca.Function("k", [knlp["x"], knlp["p"]], [knlp["f"], knlp["g"]])(
        dq[2:N].ravel(), p))
    assert f_s[0] == pytest.approx(f_k[0], rel=1e-12)
    assert np.abs(g_s[sl.gap_rows]).max() < 1e-12
    start = slice(sl.nx[1], sl.nx[1] + 2 * nv)  # stage 0: its gap rows, then dq_1 = 0, v_1 = 0
    assert np.abs(g_s[start]).max() < 1e-12
    terms_s = np.concatenate([g_s[(sl.row_stage == s) & ~sl.gap_rows][(2 * nv if s == 0 else 0):]
                              for s in range(sl.stages)])
    # the current NLP orders rows by stage group; compare each term's rows
    offset, by_term = 0, {}
    for i in nl.row_order:
        by_term[i] = g_k[offset: offset + lay.terms[i].n_rows]
        offset += lay.terms[i].n_rows
    expected = np.concatenate([by_term[i] for s in range(sl.stages) for i in sl.row_terms[s]])
    assert np.allclose(terms_s, expected, rtol=0, atol=1e-12)


def test_a_dynamic_layout_is_refused_and_plans_keep_the_current_transcription(g1):
    """The stage-wise bookkeeping refuses a dynamic layout (contact forces, CoM dynamics) in words."""
    lay = to_dynamic_layout(make_layout(small_squat(g1), g1), PlannerSettings().centroidal)
    with pytest.raises(StagewiseUnsupported, match="kinematic plans only"):
        stage_layout(lay)


@pytest.mark.parametrize("field, value", [("transcription", "fatrop"), ("stagewise_solver", "mumps")])
def test_settings_refuse_an_unknown_transcription_or_solver(field, value):
    with pytest.raises(PlannerError, match=field):
        SolverSettings(**{field: value})


def test_a_solver_that_raises_gives_a_failed_plan_not_a_traceback(g1):
    """fatrop raises (here: an option it does not know, set when the solve starts) instead of
    returning a status: the plan fails with a numerical-error status that names the reason."""
    settings = PlannerSettings(cache=CacheSettings(compile=False),
                               solver=SolverSettings(transcription="stagewise", fatrop_extra=(("no_such_option", 1),)),
                               diagnose=False,
                               collision=CollisionSettings(self_collision=False, scene_collision=False))
    result = plan(small_squat(g1), g1, settings=settings, throw=False)
    assert not result.ok
    assert result.stats.status is SolveStatus.NUMERICAL_ERROR
    assert "no_such_option" in result.stats.raw_status
