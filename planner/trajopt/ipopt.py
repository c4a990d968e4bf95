"""The IPOPT backend: nlpsol options (MUMPS, exact Hessian) and the map of IPOPT's return status."""

from __future__ import annotations

from planner.results import SolveStatus
from planner.trajopt.settings import PlannerSettings


def ipopt_options(settings: PlannerSettings) -> dict:
    """Options of CasADi's nlpsol for IPOPT + MUMPS with the exact Hessian."""
    return {
        "print_time": False,
        "ipopt": {
            "print_level": int(settings.solver.print_level),
            "sb": "yes",
            "max_iter": int(settings.solver.max_iterations),
            "tol": float(settings.solver.tolerance),
            "constr_viol_tol": float(settings.solver.constraint_tolerance),
            "linear_solver": "mumps",
            "mu_strategy": "adaptive",
            "obj_scaling_factor": float(settings.solver.objective_scaling),
            **dict(settings.solver.ipopt_extra),
        },
    }


_STATUS = {
    "Solve_Succeeded": SolveStatus.SOLVED,
    "Solved_To_Acceptable_Level": SolveStatus.SOLVED_INACCURATE,
    "Infeasible_Problem_Detected": SolveStatus.INFEASIBLE,
    "Restoration_Failed": SolveStatus.INFEASIBLE,
    "Maximum_Iterations_Exceeded": SolveStatus.MAX_ITERATIONS,
    "Maximum_CpuTime_Exceeded": SolveStatus.MAX_ITERATIONS,
    "Maximum_WallTime_Exceeded": SolveStatus.MAX_ITERATIONS,
}
