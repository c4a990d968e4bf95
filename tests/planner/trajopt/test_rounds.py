"""The solve loop's order of work (``planner.trajopt.api._solve_with_collisions``), with the solver
and the collision round replaced by stand-ins: a collision round's new layout is re-linearized
about the solution in the same step, so a dynamic plan whose round brings its momentum rows near
exact solves once after the round, not twice (the kitchen sentence: 118 -> 98 iterations), and the
round's solve starts from the solution's multipliers, the new rows' at zero (40 -> 31). The
real plans: tests/planner/trajopt/test_library.py (talos walk and wave) and the kitchen profile in
docs/performance.md. Pure Python, no solve."""

from __future__ import annotations

from typing import Any, cast

import numpy as np
import pytest

from planner import CollisionSettings, PlannerSettings
from planner.results import SolverStats, SolveStatus
from planner.trajopt import api
from planner.trajopt.scene_collision import SceneRows
from planner.trajopt.solver_output import SolverOutput, carried_multipliers
from planner.trajopt.transcription import NlpLayout


class _Layout:
    """A stand-in layout: its name, and what a re-linearization about a solution gives."""

    def __init__(self, name: str, relinearizes_to: _Layout | None = None) -> None:
        self.name, self.relinearizes_to = name, relinearizes_to
        self.about: tuple[float, int] | None = None
        self.robot = None
        self.terms: tuple = ()  # a re-linearization keeps the rows (the multipliers then warm-start it)

    def relinearized(self, dq, x, round_):
        if self.relinearizes_to is None:
            return None
        out = self.relinearizes_to
        out.about = (float(dq[0, 0]), round_)
        return out


def _run(monkeypatch, first: _Layout, after_round: _Layout | None) -> list[tuple[str, bool]]:
    """Solve ``first``; the first collision round gives ``after_round`` (None: no round adds
    rows). Returns (layout solved, started with multipliers) per solve."""
    solved: list[tuple[str, bool]] = []

    def solve_layout(lay, settings, progress=None, x0=None, lam0=None):
        solved.append((lay.name, lam0 is not None))
        n = len(solved)
        out = SolverOutput(x=np.full(3, float(n)), lam_x=np.zeros(3), lam_g=np.zeros(2), g=np.zeros(2),
                           lbg=np.zeros(2), ubg=np.zeros(2), nlp_layout=None)
        return np.full((4, 2), float(n)), SolverStats(status=SolveStatus.SOLVED, iterations=10 * n), out

    def collision_round(lay, settings, dq, sets, rows, scene_rows, deferred):
        if lay is first and after_round is not None:
            return api.CollisionRound(after_round, rows, scene_rows, deferred, (), (0,))
        return api.CollisionRound(lay, rows, scene_rows, deferred, (), ())

    monkeypatch.setattr(api, "solve_layout", solve_layout)
    monkeypatch.setattr(api, "collision_round", collision_round)
    monkeypatch.setattr(api, "scene_rows_of", lambda _lay: SceneRows())
    settings = PlannerSettings(collision=CollisionSettings(self_collision=False, scene_collision=True))
    lay, _, _, _ = api._solve_with_collisions(cast(Any, first), settings, None, np.zeros(3))
    solved.append((f"returned {lay.name}", False))
    return solved


def test_a_rounds_layout_is_relinearized_about_the_solution_in_the_same_step(monkeypatch):
    near = _Layout("round, linearized")  # its solution's momentum rows are within tolerance
    after = _Layout("round", relinearizes_to=near)
    first = _Layout("first", relinearizes_to=_Layout("first, linearized"))
    solved = _run(monkeypatch, first, after)
    assert solved == [("first", False), ("round, linearized", False), ("returned round, linearized", False)]
    assert near.about == (1.0, 0)  # about the first solution, not counted against momentum_iterations


def test_rows_still_off_after_the_round_get_their_own_relinearization(monkeypatch):
    again = _Layout("round, linearized twice")
    near = _Layout("round, linearized", relinearizes_to=again)  # still off: one more solve, warm
    after = _Layout("round", relinearizes_to=near)
    solved = _run(monkeypatch, _Layout("first"), after)
    assert solved == [("first", False), ("round, linearized", False), ("round, linearized twice", True),
                      ("returned round, linearized twice", False)]
    assert again.about == (2.0, 0)


@pytest.mark.parametrize("relinearizes", [False, True])
def test_without_a_round_the_relinearization_is_as_before(monkeypatch, relinearizes):
    first = _Layout("first", relinearizes_to=_Layout("first, linearized") if relinearizes else None)
    solved = _run(monkeypatch, first, None)
    expected = [("first", False), ("first, linearized", True)] if relinearizes else [("first", False)]
    assert solved == [*expected, (f"returned {expected[-1][0]}", False)]


def test_a_relinearization_that_adds_rows_starts_without_the_multipliers(monkeypatch):
    """The torque margin's first round adds rows (planner/trajopt/centroidal/torque.py): the last
    solve's constraint multipliers no longer fit as they are: that solve does not take them whole (it
    starts as a round's does, from the carried ones, or cold: the stand-ins have no NlpLayout)."""
    more = _Layout("first, with torque rows")
    more.terms = ("a torque row",)
    first = _Layout("first", relinearizes_to=more)
    assert _run(monkeypatch, first, None) == [("first", False), ("first, with torque rows", False),
                                              ("returned first, with torque rows", False)]


class _Term:
    """A stand-in term: its row count (identity is the object's, as in a round's layout)."""

    def __init__(self, n_rows: int) -> None:
        self.n_rows = n_rows


def _nlp(terms: list[_Term], order: list[int], n_velocity: int, n_dynamic: int, n_x: int = 5) -> NlpLayout:
    n_kin = sum(terms[i].n_rows for i in order) + n_velocity
    return NlpLayout(n_x=n_x, n_g=n_kin + n_dynamic, row_order=order, groups=[],
                     velocity_joints=np.arange(n_velocity), n_x_kin=n_x, n_g_kin=n_kin)


def test_a_rounds_new_rows_start_at_zero_and_the_others_keep_their_multipliers():
    a, b, c, d, e = _Term(2), _Term(1), _Term(3), _Term(2), _Term(1)  # d, e: the round's new rows
    old = _nlp([a, b, c], [0, 2, 1], n_velocity=2, n_dynamic=3)  # g: a a c c c b | v v | f f f
    lam_g = np.array([1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0, 11.0])
    out = SolverOutput(x=np.zeros(5), lam_x=np.arange(5.0), lam_g=lam_g, g=lam_g, lbg=lam_g, ubg=lam_g,
                       nlp_layout=old)
    new_terms = [a, d, b, e, c]
    new = _nlp(new_terms, [1, 0, 4, 3, 2], n_velocity=2, n_dynamic=3)  # g: d d a a c c c e b | v v | f f f
    lam = carried_multipliers((a, b, c), out, tuple(new_terms), new)
    assert lam is not None
    np.testing.assert_array_equal(lam[0], np.arange(5.0))
    np.testing.assert_array_equal(lam[1], [0, 0, 1, 2, 3, 4, 5, 0, 6, 7, 8, 9, 10, 11])
    other_variables = _nlp(new_terms, [1, 0, 4, 3, 2], n_velocity=2, n_dynamic=3, n_x=6)
    assert carried_multipliers((a, b, c), out, tuple(new_terms), other_variables) is None
    other_dynamics = _nlp(new_terms, [1, 0, 4, 3, 2], n_velocity=2, n_dynamic=4)
    assert carried_multipliers((a, b, c), out, tuple(new_terms), other_dynamics) is None


def test_the_rounds_solve_starts_from_the_carried_multipliers(monkeypatch):
    """The loop hands the round's solve the solution's multipliers when the solve has an NlpLayout
    (the stand-ins above have none: their round starts cold)."""
    term, new_term = _Term(2), _Term(1)
    first, after = _Layout("first"), _Layout("round")
    first.terms, after.terms = (term,), (term, new_term)  # type: ignore[attr-defined]
    old, new = _nlp([term], [0], 0, 0), _nlp([term, new_term], [1, 0], 0, 0)
    monkeypatch.setattr(api, "make_nlp_layout", lambda lay: new if lay is after else old)
    started: list[np.ndarray | None] = []

    def solve_layout(lay, settings, progress=None, x0=None, lam0=None):
        started.append(None if lam0 is None else lam0[1])
        out = SolverOutput(x=np.zeros(5), lam_x=np.zeros(5), lam_g=np.array([4.0, 5.0]), g=np.zeros(2),
                           lbg=np.zeros(2), ubg=np.zeros(2), nlp_layout=old if lay is first else new)
        return np.zeros((4, 2)), SolverStats(status=SolveStatus.SOLVED, iterations=1), out

    def collision_round(lay, settings, dq, sets, rows, scene_rows, deferred):
        return api.CollisionRound(after if lay is first else lay, rows, scene_rows, deferred, (), (0,) if lay is first else ())

    monkeypatch.setattr(api, "solve_layout", solve_layout)
    monkeypatch.setattr(api, "collision_round", collision_round)
    monkeypatch.setattr(api, "scene_rows_of", lambda _lay: SceneRows())
    settings = PlannerSettings(collision=CollisionSettings(self_collision=False, scene_collision=True))
    api._solve_with_collisions(cast(Any, first), settings, None, np.zeros(5))
    assert started[0] is None and len(started) == 2
    np.testing.assert_array_equal(started[1], [0.0, 4.0, 5.0])
