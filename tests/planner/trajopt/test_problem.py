"""Build, then solve: a layout is frozen (its fields cannot be assigned, a changed layout is a new one,
and what it builds lazily neither shows as a field nor changes one); :func:`planner.formulate` builds
the frozen :class:`planner.Problem` of (spec, robot, settings), :func:`planner.solve` solves it from an
explicit warm start or its own guess, leaving it unchanged; :class:`planner.PlanningFailed` carries
the problem and the solver's record."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from planner import (
    CacheSettings,
    PlannerSettings,
    PlanningFailed,
    Problem,
    SolveStatus,
    formulate,
    plan,
    solve,
)
from planner.trajopt.centroidal.layout import to_dynamic_layout
from planner.trajopt.layout import make_layout, support_polygon
from tests.planner.planning_cases import reach_spec, squat_spec

SETTINGS = PlannerSettings(cache=CacheSettings(compile=False))


@pytest.fixture(scope="module")
def squat_layout(talos):
    return make_layout(squat_spec(talos, 0.1), talos)


@pytest.mark.parametrize("name", ["terms", "frame_ids", "N", "q_ref", "spec", "_memo", "something_new"])
def test_assigning_a_layouts_field_raises(squat_layout, name):
    """Every field (and any new attribute) of a kinematic and a dynamic layout refuses assignment."""
    dyn = to_dynamic_layout(squat_layout)
    for lay in (squat_layout, dyn):
        with pytest.raises(dataclasses.FrozenInstanceError):
            setattr(lay, name, [])
    with pytest.raises(dataclasses.FrozenInstanceError):
        dyn.linearized_about = np.zeros((dyn.N + 1, dyn.robot.nv))  # type: ignore[misc]


def test_with_terms_is_a_new_layout_sharing_what_was_built(squat_layout):
    """A layout's terms are a tuple (no append from outside); ``with_terms`` makes a new layout of the
    same class with the new terms, sharing the support polygon the original built (the same array,
    not rebuilt)."""
    assert isinstance(squat_layout.terms, tuple)
    structure = squat_layout.structure()
    hull = support_polygon(squat_layout, 3)
    assert hull.shape[0] >= 4  # both soles: a polygon
    half = squat_layout.with_terms(list(squat_layout.terms[: len(squat_layout.terms) // 2]))
    assert type(half) is type(squat_layout) and isinstance(half.terms, tuple)
    assert len(half.terms) == len(squat_layout.terms) // 2 and half.structure() != structure
    assert support_polygon(half, 3) is hull


def test_a_dynamic_layouts_momentum_point_is_a_field_of_a_new_layout(squat_layout):
    """The momentum point given to ``with_momentum_point`` is the copy's; the original keeps its
    initial guess's point (built once, the same array on every call)."""
    dyn = to_dynamic_layout(squat_layout)
    guess, pattern = dyn.momentum_point(), dyn.pattern()
    assert dyn.momentum_point() is guess and dyn.linearized_about is None
    point = np.full((dyn.N + 1, dyn.robot.nv), 0.01)
    moved = dyn.with_momentum_point(point, 0.02)
    np.testing.assert_array_equal(moved.momentum_point(), point)
    assert moved.momentum_residual == 0.02 and np.isnan(dyn.momentum_residual)
    assert dyn.momentum_point() is guess and moved.pattern() is pattern  # built before the copy: shared


@pytest.fixture(scope="module")
def squat_solved(talos):
    """A 10 cm squat's problem, its guess before the solve, and its solution from its own guess."""
    problem = formulate(squat_spec(talos, 0.1), talos, SETTINGS)
    guess = problem.guess.copy()
    return problem, guess, solve(problem)


def test_solve_is_plan_and_leaves_its_problem_unchanged(talos, squat_solved):
    """``solve(formulate(...))`` gives the plan ``plan()`` gives (the same bytes), and the problem it
    was given keeps its guess; a problem's fields cannot be assigned, nor its guess written."""
    problem, guess, solved = squat_solved
    assert isinstance(problem, Problem) and solved.plan.ok, solved.plan.summary()
    np.testing.assert_array_equal(problem.guess, guess)
    planned = plan(squat_spec(talos, 0.1), talos, settings=SETTINGS)
    assert planned.q.tobytes() == solved.plan.q.tobytes()
    with pytest.raises(dataclasses.FrozenInstanceError):
        problem.layout = solved.problem.layout  # type: ignore[misc]
    with pytest.raises(ValueError, match="read-only"):
        problem.guess[0] = 1.0


def test_a_previous_solution_as_warm_start_converges_to_it_sooner(squat_solved):
    """Solved again from its own solution (``Solution.warm_start()``), the squat stops in fewer
    iterations at the same motion (1e-4 rad), and the stats name the warm start."""
    problem, _, solved = squat_solved
    again = solve(problem, warm_start=solved.warm_start())
    assert again.plan.ok, again.plan.summary()
    assert again.stats.iterations < solved.stats.iterations
    assert again.stats.seed == "previous solution"
    assert np.max(np.abs(again.dq - solved.dq)) < 1e-4


def test_a_failure_carries_its_problem_and_the_solvers_record(talos):
    """A target before the robot can move is refused before any solve: the exception carries the
    problem (its layout has that target's spec) and the solver's record (not run)."""
    spec = reach_spec(talos, (0.1, 0.0, 0.0), time=0.0)
    with pytest.raises(PlanningFailed, match="comes before the robot") as failed:
        plan(spec, talos, settings=SETTINGS)
    assert isinstance(failed.value.problem, Problem) and failed.value.problem.layout.spec is spec
    assert failed.value.stats.status is SolveStatus.NOT_RUN and failed.value.stats is failed.value.plan.stats
