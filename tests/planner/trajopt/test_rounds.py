"""The solve loop's order of work (``planner.trajopt.api._solve_with_collisions``), with the solver
and the collision round replaced by stand-ins: a collision round's new layout is re-linearized
about the solution in the same step, so a dynamic plan whose round brings its momentum rows near
exact solves once after the round, not twice (the kitchen sentence: 118 -> 98 iterations). The
real plans: tests/planner/trajopt/test_library.py (talos walk and wave) and the kitchen profile in
docs/performance.md. Pure Python, no solve."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any, cast

import numpy as np
import pytest

from planner import CollisionSettings, PlannerSettings
from planner.results import SolverStats, SolveStatus
from planner.trajopt import api
from planner.trajopt.scene_collision import SceneRows
from planner.trajopt.solve import carried_multipliers
from planner.trajopt.solver_output import SolverOutput
from planner.trajopt.transcription import NlpLayout


class _Layout:
    """A stand-in layout: its name, and what a re-linearization about a solution gives."""

    def __init__(self, name: str, relinearizes_to: _Layout | None = None) -> None:
        self.name, self.relinearizes_to = name, relinearizes_to
        self.about: tuple[float, int] | None = None
        self.robot = None

    def relinearized(self, dq, x, round_):
        if self.relinearizes_to is None:
            return None
        out = self.relinearizes_to
        out.about = (float(dq[0, 0]), round_)
        return out


def _run(monkeypatch, first: _Layout, after_round: _Layout | None, warm_rounds: bool = False,
         carried: list | None = None) -> list[tuple[str, bool]]:
    """Solve ``first``; the first collision round gives ``after_round`` (None: no round adds
    rows). Returns (layout solved, started with multipliers) per solve; ``carried`` gets each
    solve's ``carry`` as (layout name, the x of the output) or None."""
    solved: list[tuple[str, bool]] = []

    def solve_layout(lay, settings, progress=None, x0=None, lam0=None, carry=None):
        solved.append((lay.name, lam0 is not None))
        if carried is not None:
            carried.append(None if carry is None else (carry[0].name, float(carry[1].x[0])))
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
    settings = PlannerSettings(collision=CollisionSettings(self_collision=False, scene_collision=True,
                                                           warm_rounds=warm_rounds))
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


@pytest.mark.parametrize("warm_rounds", [False, True])
def test_a_rounds_re_solve_carries_the_solved_layout_and_its_output_with_warm_rounds(monkeypatch, warm_rounds):
    """With ``warm_rounds`` the re-solve after a round is given the layout solved before it and that
    solve's output (whose multipliers it starts from); without, nothing, as before. A
    re-linearization's own solve gets the multipliers themselves (same rows), never a carry."""
    carried: list = []
    again = _Layout("round, linearized twice")
    after = _Layout("round", relinearizes_to=_Layout("round, linearized", relinearizes_to=again))
    solved = _run(monkeypatch, _Layout("first"), after, warm_rounds=warm_rounds, carried=carried)
    assert [name for name, _ in solved] == ["first", "round, linearized", "round, linearized twice",
                                            "returned round, linearized twice"]
    assert carried == [None, ("first", 1.0) if warm_rounds else None, None]


class _Term:
    def __init__(self, rows: int) -> None:
        self.lower = np.zeros(rows)


def test_carried_multipliers_keep_each_kept_terms_rows_and_start_new_ones_at_zero():
    """Rows of the terms both layouts share get their multipliers wherever the new row order puts
    them; a new term's rows (and a changed one, another object) zero; the rows after the terms'
    (velocities, dynamics) and the bound multipliers as they were."""
    a, b, c, new = _Term(2), _Term(1), _Term(3), _Term(2)
    old_lay = SimpleNamespace(terms=(a, b, c))
    old_nl = NlpLayout(n_x=4, n_g=8, row_order=[0, 1, 2], groups=[], velocity_joints=np.zeros(0))
    lam_g = np.arange(1.0, 9.0)  # a: 1 2, b: 3, c: 4 5 6, tail: 7 8
    out = SolverOutput(x=np.zeros(4), lam_x=np.array([0.5, -0.5, 0.0, 2.0]), lam_g=lam_g, g=np.zeros(8),
                       lbg=np.zeros(8), ubg=np.zeros(8), nlp_layout=old_nl)
    new_lay = SimpleNamespace(terms=(c, new, a, _Term(1)))  # b replaced by a changed term of one row
    nl = NlpLayout(n_x=4, n_g=10, row_order=[2, 1, 0, 3], groups=[], velocity_joints=np.zeros(0))
    lam_x, lam = carried_multipliers(cast(Any, old_lay), out, cast(Any, new_lay), nl)
    assert np.array_equal(lam_x, out.lam_x)
    assert np.array_equal(lam, [1.0, 2.0, 0.0, 0.0, 4.0, 5.0, 6.0, 0.0, 7.0, 8.0])
