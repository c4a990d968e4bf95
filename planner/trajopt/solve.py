"""One solve of a layout: fetch or build its solver (:mod:`planner.trajopt.cache`), feed it the
layout's values, run IPOPT."""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from planner.results import SolverStats, SolveStatus
from planner.trajopt.cache import get_solver
from planner.trajopt.ipopt import _STATUS
from planner.trajopt.layout import Layout
from planner.trajopt.settings import PlannerSettings
from planner.trajopt.solver_output import SolverOutput
from planner.trajopt.transcription import NlpLayout, bounds, parameter_values


def solve_layout(lay: Layout, settings: PlannerSettings, progress: Callable[[str], None] | None = None,
                 x0: np.ndarray | None = None,
                 lam0: tuple[np.ndarray, np.ndarray] | None = None,
                 carry: tuple[Layout, SolverOutput] | None = None) -> tuple[np.ndarray, SolverStats, SolverOutput]:
    """Fetch/build the solver of a layout, solve, return (dq per knot (N+1, nv), stats, the solver's
    output :class:`SolverOutput`).

    ``lam0``: initial multipliers ``(lam_x, lam_g)`` of the same structure's previous solve (IPOPT
    uses them with its ``warm_start_init_point`` option, which dynamic plans set).
    ``carry``: (layout, output) of a solve of the same variables whose rows this layout extends
    (a collision round's): its multipliers, where the rows are the same terms', start this solve
    (:func:`carried_multipliers`; with ``lam0`` None).

    ``settings.transcription == "stagewise"`` solves a kinematic layout with the stage-wise
    transcription (:mod:`planner.trajopt.stagewise`, fatrop or IPOPT); a dynamic one keeps this one."""
    if settings.solver.transcription == "stagewise" and lay.extra_sizes() == (0, 0):
        from planner.trajopt.stagewise import solve_stagewise

        return solve_stagewise(lay, settings, progress, x0=x0)
    t0 = time.perf_counter()
    solver = get_solver(lay, settings, progress)
    build_time = time.perf_counter() - t0
    nl = solver.nlp_layout
    lbx, ubx, lbg, ubg = bounds(lay, nl)
    p = parameter_values(lay, nl)
    if x0 is None:
        x0 = lay.initial_guess()
    if progress:
        progress(f"solving ({nl.n_x} variables, {nl.n_g} constraints)")
    t1 = time.perf_counter()
    if lam0 is None and carry is not None and carry[1].x.size == nl.n_x:
        lam0 = carried_multipliers(carry[0], carry[1], lay, nl)
    warm = {} if lam0 is None else {"lam_x0": lam0[0], "lam_g0": lam0[1]}
    sol = solver.function(x0=x0, p=p, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg, **warm)
    solve_time = time.perf_counter() - t1
    st = solver.function.stats()
    raw = str(st.get("return_status", ""))
    status = _STATUS.get(raw, SolveStatus.NUMERICAL_ERROR if raw else SolveStatus.NOT_RUN)
    x = np.asarray(sol["x"], dtype=float).ravel()
    dq = np.zeros((lay.N + 1, lay.robot.nv))
    dq[2:lay.N] = x[: lay.robot.nv * (lay.N - 2)].reshape(lay.N - 2, lay.robot.nv)
    dq[lay.N] = dq[lay.N - 1]
    stats = SolverStats(
        status=status, iterations=int(st.get("iter_count", 0)), build_time=build_time,
        solve_time=solve_time, cache=solver.origin, objective=float(sol["f"]),
        n_variables=nl.n_x, n_constraints=nl.n_g, raw_status=raw,
    )
    return dq, stats, SolverOutput(x=x, lam_x=np.asarray(sol["lam_x"]), lam_g=np.asarray(sol["lam_g"]),
                                   g=np.asarray(sol["g"]), lbg=lbg, ubg=ubg, nlp_layout=nl)


def carried_multipliers(old: Layout, out: SolverOutput, new: Layout, nl: NlpLayout) -> tuple[np.ndarray, np.ndarray]:
    """Initial multipliers ``(lam_x, lam_g)`` for a solve of ``new`` (its NLP layout ``nl``) from the
    solve ``out`` of ``old``, which has the same variables and a subset of its terms (a collision
    round adds terms and replaces the changed pairs'): each term's rows get the multipliers they had,
    a new or changed term's rows zero, the rows after the terms' (velocities, dynamics) theirs."""
    def spans(lay: Layout, order: list[int]) -> tuple[dict[int, tuple[int, int]], int]:
        at, found = 0, {}
        for i in order:
            n = len(lay.terms[i].lower)
            found[id(lay.terms[i])] = (at, n)
            at += n
        return found, at

    before, old_end = spans(old, out.nlp_layout.row_order)
    after, new_end = spans(new, nl.row_order)
    src = np.asarray(out.lam_g, dtype=float).ravel()
    lam_g = np.zeros(nl.n_g)
    for key, (a, n) in after.items():
        hit = before.get(key)
        if hit is not None and hit[1] == n:
            lam_g[a:a + n] = src[hit[0]:hit[0] + n]
    if nl.n_g - new_end == src.size - old_end:
        lam_g[new_end:] = src[old_end:]
    return np.asarray(out.lam_x, dtype=float).ravel(), lam_g
