"""The task classes of ``wbmp bench``: their sentences, the JSON keys of a task record, and how a
sentence becomes the spec and the planner settings a benchmark plans with."""

from __future__ import annotations

import dataclasses
import os

SCHEMA = "wbmp-bench/1"

#: Task class -> sentence given to the parser (and to ``wbmp solve``).
TASKS: dict[str, str] = {
    "squat": "squat down 10 cm",
    "wave": "wave your right hand",
    "reach": "reach forward with your right hand 20 cm",
    "bow": "bow",
    "balance": "stand on your left foot",
    "walk": "take two steps forward",
    "turn": "turn left 90 degrees",
    "jump": "jump 5 cm",
}
#: ``--quick`` covers every task class (one repeat, one simulation, no first-ever builds).
QUICK_TASKS = tuple(TASKS)
SCALING_N = (20, 40, 80, 120, 160)
SCALING_ROBOTS = ("g1", "talos", "romeo")
#: Which peer figure each of our task classes is compared with.
PEER_TASKS = {"squat": "squat", "reach": "reach", "walk": "walk", "jump": "jump"}
NOT_IMPLEMENTED = "n/a (not implemented)"
#: Per-task keys of the JSON (documented in benchmarks/README.md).
TASK_KEYS = (
    "sentence", "status", "message", "actions", "horizon_s", "knots", "parse_s", "spec_s",
    "nlp_build_s", "solve_first_s", "first_total_s", "cache_first", "nlp_load_cold_s", "solve_cold_s",
    "cold_total_s", "cold_process_s", "cache_cold", "solve_warm_s", "warm_total_s", "cache_warm",
    "iterations", "solver_status", "n_variables", "n_constraints", "max_violation", "max_violation_unit",
    "max_violation_check", "checks_ok", "tick_median_us", "tick_p99_us", "realtime_factor", "sim_wall_s",
    "certified", "certificate_reason", "e2e_s", "e2e_mode", "e2e_exit_code",
)


def planner_settings(cache_dir: str, max_iterations: int | None = None):
    """PlannerSettings of a benchmark plan: solver cache in ``cache_dir``, compiled unless
    ``WBMP_BENCH_COMPILE=0`` (``--no-compile``, inherited by the child processes); every plan
    from the task's own guess (no solution library: a repeat would start from its own solution);
    the rest of the user's switches (:func:`wbmp.environment.planner_settings`)."""
    from wbmp.environment import planner_settings as from_environment

    compile_ = os.environ.get("WBMP_BENCH_COMPILE", "1") != "0"
    settings = from_environment(cache={"cache_dir": cache_dir, "compile": compile_, "solution_library": "off"})
    if max_iterations is not None:
        settings = dataclasses.replace(settings, solver=dataclasses.replace(settings.solver,
                                                                            max_iterations=max_iterations))
    return settings


def spec_for(sentence: str, robot, dt: float | None):
    """(actions, spec) of a task sentence on ``robot``, the knot spacing replaced by ``dt`` if given."""
    from language import parse
    from tasks import compile_actions

    actions = parse(sentence)
    spec = compile_actions(actions.actions, robot)
    spec = dataclasses.replace(spec, robot=robot.name, description=sentence)
    if dt is not None:
        spec = dataclasses.replace(spec, dt=dt)
    return actions, spec

