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
from planner.trajopt.transcription import bounds, parameter_values


def solve_layout(lay: Layout, settings: PlannerSettings, progress: Callable[[str], None] | None = None,
                 x0: np.ndarray | None = None,
                 lam0: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[np.ndarray, SolverStats, SolverOutput]:
    """Fetch/build the solver of a layout, solve, return (dq per knot (N+1, nv), stats, the solver's
    output :class:`SolverOutput`).

    ``lam0``: initial multipliers ``(lam_x, lam_g)`` of the same structure's previous solve (IPOPT
    uses them with its ``warm_start_init_point`` option, which dynamic plans set; a collision
    round's are carried by :func:`planner.trajopt.solver_output.carried_multipliers`).

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
