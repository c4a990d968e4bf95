"""The solve loop's order of work (``planner.trajopt.api._solve_with_collisions``), with the solver
and the collision round replaced by stand-ins: a collision round's new layout is re-linearized
about the solution in the same step, so a dynamic plan whose round brings its momentum rows near
exact solves once after the round, not twice (the kitchen sentence: 118 -> 98 iterations). The
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
from planner.trajopt.solver_output import SolverOutput


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
    solve's constraint multipliers no longer fit, so that solve starts from the solution alone."""
    more = _Layout("first, with torque rows")
    more.terms = ("a torque row",)
    first = _Layout("first", relinearizes_to=more)
    assert _run(monkeypatch, first, None) == [("first", False), ("first, with torque rows", False),
                                              ("returned first, with torque rows", False)]
