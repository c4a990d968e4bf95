"""Dynamic plans (steps, side steps, turn, jump) on Talos and G1: build, solve, iterations, before/after.

Run from the repository root::

    .venv/bin/python benchmarks/bench_dynamic.py                 # talos + g1, all tasks
    .venv/bin/python benchmarks/bench_dynamic.py --robots talos --tasks steps jump
    .venv/bin/python benchmarks/bench_dynamic.py --json          # machine-readable
    .venv/bin/python benchmarks/bench_dynamic.py --out benchmarks/results/dynamic_<date>.json

BLAS threads: the script sets ``OMP_NUM_THREADS`` and ``OPENBLAS_NUM_THREADS`` to ``--threads``
(default 1) before CasADi loads its bundled OpenBLAS, unless they are already set: with 2
threads the cached 4-step solve used twice the CPU for the same wall time.

Solvers of dynamic specs are built in memory by default (``PlannerSettings.compile_dynamic``);
``--compile-dynamic`` compiles them with gcc into the disk cache instead. Each task is compiled
from actions (``tasks.compose.compile_actions``, default ``dt``) and
planned ``--repeat`` + 1 times in this process with ``planner.trajopt.plan``: the first run
builds the solver (or loads a compiled one from the disk cache), the next runs reuse it from
memory ("cached"). Reported per task: the first run's
build time and cache origin, the cached runs' median solve time (wall and CPU), iterations,
problem size. Targets on this machine, cached: 4 steps <= 2 s, jump <= 1.5 s (build + solve
of a cached run). Timings are wall-clock on a shared machine; the CPU time is less sensitive
to other load.

Before / after (``--formulations``, default both): "centroidal" is the formulation before the
whole-body momentum rows (``CentroidalSettings(whole_body_momentum=False)``: the moment of the
contact forces only penalized), "whole-body" the default (Euler's law with Pinocchio's centroidal
momentum matrix, re-linearized once when needed). Each row also gives the plan's full-dynamics
ZMP excursion out of its support polygon (RNEA, the ``FULL_DYNAMICS_ZMP`` check) and whether
every check of the plan passed.

The solution library (``--library``, default both rows; ``planner/trajopt/library.py``): the
plain rows solve from the task's own guess (``solution_library="off"``: what any first request of
a structure pays). A ``+library`` row first plans the task's neighbours (``NEIGHBOURS``: the same
action with other values, e.g. 0.12 m and 0.18 m steps for the 0.15 m walk) into a new temporary
library, then plans the task ``--repeat`` + 1 times reading it only (``"read"``): the task's own
solution never seeds it, as for a user whose library holds other walks of the same structure.

For scale, Crocoddyl's FDDP (full dynamics, C++, single-threaded) plans one 2-step Talos walking
phase and a Talos jump in the same run, in its own environment (``.venv-crocoddyl``, made by
``bash benchmarks/peers/setup.sh crocoddyl``; ``--no-peers`` skips it), and the figures the issue
quotes for this machine (~0.3 s and ~0.4 s) are printed beside them.
"""

from __future__ import annotations

import argparse
import datetime
import json
import math
import os
import platform
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TASKS = {
    "steps": ("4 steps forward (0.15 m)", [{"action": "step", "params": {"direction": "forward", "length": 0.15, "count": 4}}]),
    "side": ("2 steps left (0.08 m)", [{"action": "step", "params": {"direction": "left", "length": 0.08, "count": 2}}]),
    "turn": ("turn 90 deg in place", [{"action": "turn", "params": {"angle": math.pi / 2}}]),
    "jump": ("jump 5 cm", [{"action": "jump", "params": {"height": 0.05}}]),
}
# The same action with other values: the solution library's neighbours of each task (--library).
# None for the jump: the heights whose solver structure is the 5 cm jump's (6 cm: the same flight
# knots) give the very same layout (the height sets the flight time, nothing else), so a "neighbour"
# would be the task itself.
NEIGHBOURS = {
    "steps": [{"length": 0.12}, {"length": 0.18}],
    "side": [{"length": 0.06}, {"length": 0.10}],
    "turn": [{"angle": math.radians(75)}, {"angle": math.radians(105)}],
}
TARGETS = {"steps": 2.0, "jump": 1.5}  # [s] cached build + solve
CROCODDYL_QUOTED = {"steps": ("one 2-step Talos walking phase", 0.3), "jump": ("Talos jump", 0.4)}  # [s], quoted
CROCODDYL_TASKS = {"steps": "walk", "jump": "jump"}  # our task -> crocoddyl_bench.py task


def crocoddyl_peer(tasks: list[str], repeats: int) -> dict:
    """Crocoddyl's FDDP on the matching tasks, in its own environment, or why it cannot run."""
    names = [CROCODDYL_TASKS[t] for t in tasks if t in CROCODDYL_TASKS]
    if not names:
        return {"skipped": "no task with a Crocoddyl counterpart"}
    sys.path.insert(0, str(ROOT / "benchmarks" / "peers"))
    from run_peers import run_peer

    return run_peer("crocoddyl", ["--repeats", str(repeats), "--tasks", ",".join(names), "--no-legs"])

FORMULATIONS = {"centroidal": False, "whole-body": True}  # name -> CentroidalSettings.whole_body_momentum


def neighbour_library(robot, task: str, settings) -> tuple[str, list[str]]:
    """A new solution library (a temporary cache folder) holding the solutions of the task's
    neighbours (:data:`NEIGHBOURS`: the same action, other values); returns its folder and what
    was planned into it."""
    import tempfile
    from dataclasses import replace

    from planner import plan_with_library
    from tasks.compose import compile_actions

    folder = tempfile.mkdtemp(prefix="wbmp-bench-library-")
    planned = []
    _, actions = TASKS[task]
    for values in NEIGHBOURS[task]:
        neighbour = [{"action": actions[0]["action"], "params": {**actions[0]["params"], **values}}]
        p = plan_with_library(compile_actions(neighbour, robot), robot, throw=False,
                 settings=replace(settings,
                                  cache=replace(settings.cache, cache_dir=folder, solution_library="on")))
        planned.append(f"{values} ({'stored' if p.ok else 'failed'})")
    return folder, planned


def run_task(robot, actions, *, repeat: int, settings) -> dict:
    """Plan one task ``repeat + 1`` times; the first run builds or loads the solver (with the solution
    library the settings name: ``plan_with_library``; ``"off"``: ``plan`` itself)."""
    from planner import plan_with_library
    from tasks.compose import compile_actions

    spec = compile_actions(actions, robot)
    runs = []
    for _ in range(repeat + 1):
        t0, c0 = time.perf_counter(), time.process_time()
        p = plan_with_library(spec, robot, settings=settings, throw=False)
        runs.append({
            "wall_s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0,
            "build_s": p.stats.build_time, "solve_s": p.stats.solve_time, "cache": p.stats.cache,
            "iterations": p.stats.iterations, "ok": p.ok, "status": p.stats.status.value,
            "objective": p.stats.objective, "seed": p.stats.seed,
        })
    cached = runs[1:] or runs
    from planner.results import CheckKind

    zmp = [c.violation for c in p.checks if c.kind is CheckKind.FULL_DYNAMICS_ZMP]
    rise = None
    if any(not ph.contacts for ph in spec.phases):
        # the first knot of the flight phase is the take-off (the feet are still down there)
        k0 = next(k for k in range(len(p.t)) if not p.active_contacts(k))
        k1 = max(k for k in range(len(p.t)) if not p.active_contacts(k)) + 1
        rise = float(p.com[k0:k1 + 1, 2].max() - p.com[k0, 2])
    return {
        "knots": len(p.t), "horizon_s": float(p.t[-1]), "variables": p.stats.n_variables,
        "constraints": p.stats.n_constraints, "ok": all(r["ok"] for r in runs),
        "first": runs[0],
        "cached_build_s": statistics.median(r["build_s"] for r in cached),
        "cached_solve_s": statistics.median(r["solve_s"] for r in cached),
        "cached_total_s": statistics.median(r["build_s"] + r["solve_s"] for r in cached),
        "cached_plan_wall_s": statistics.median(r["wall_s"] for r in cached),
        "cached_cpu_s": statistics.median(r["cpu_s"] for r in cached),
        "iterations": cached[-1]["iterations"],
        "flight_rise_m": rise,
        "zmp_excursion_m": zmp[0] if zmp else None,
        "failed_status": [r["status"] for r in runs if not r["ok"]],
        "runs": runs,
    }


def machine() -> dict:
    """CPU model, cores, load, thread settings and the commit the numbers belong to."""
    from wbmp.bench.machine import cpu_model

    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True,
                                check=False).stdout.strip()
    except OSError:
        commit = ""
    return {
        "cpu": cpu_model(), "cores": os.cpu_count(), "load_average": list(os.getloadavg()),
        "python": platform.python_version(), "commit": commit,
        "date": datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC"),
        "threads": {k: os.environ.get(k, "unset") for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS")},
    }


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark and print a table (or JSON)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", nargs="+", default=["talos", "g1"])
    parser.add_argument("--tasks", nargs="+", default=list(TASKS), choices=list(TASKS))
    parser.add_argument("--repeat", type=int, default=2, help="cached runs after the first one")
    parser.add_argument("--formulations", nargs="+", default=list(FORMULATIONS), choices=list(FORMULATIONS),
                        help="centroidal (before the whole-body momentum rows) and/or whole-body (after)")
    parser.add_argument("--compile-dynamic", action="store_true",
                        help="compile the dynamic solvers with gcc and keep them on disk (minutes per task the first "
                             "time; by default they are built in memory)")
    parser.add_argument("--threads", type=int, default=1,
                        help="OMP_NUM_THREADS / OPENBLAS_NUM_THREADS for CasADi's bundled OpenBLAS when not set already")
    parser.add_argument("--json", action="store_true", help="print JSON instead of the table")
    parser.add_argument("--out", help="also write the JSON results (with machine, load and thread settings) here")
    parser.add_argument("--no-peers", action="store_true", help="do not run Crocoddyl (.venv-crocoddyl) beside ours")
    parser.add_argument("--library", choices=("off", "neighbours", "both"), default="both",
                        help="the solution library (planner/trajopt/library.py): off (every solve from the task's own "
                             "guess), neighbours (a library holding only the solutions of the same action with "
                             "other values, NEIGHBOURS, read-only: the task's own solution never seeds it), or both "
                             "rows (default)")
    args = parser.parse_args(argv)
    for key in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS"):  # before CasADi loads its OpenBLAS
        os.environ.setdefault(key, str(args.threads))
    sys.path.insert(0, str(ROOT))
    from planner.trajopt.centroidal import CentroidalSettings
    from robots import load_robot
    from wbmp.environment import planner_settings  # the WBMP_* switches, as the CLI reads them

    info = machine()
    results = {}
    for name in args.robots:
        robot = load_robot(name)
        for task in args.tasks:
            label, actions = TASKS[task]
            for form in args.formulations:
                settings = planner_settings(cache={"compile_dynamic": args.compile_dynamic, "solution_library": "off"},
                                            centroidal=CentroidalSettings(whole_body_momentum=FORMULATIONS[form]))
                key = f"{name}/{task}" + ("" if form == "whole-body" else f" ({form})")
                if args.library in ("off", "both"):
                    results[key] = {"label": label, "formulation": form, "library": "off",
                                    **run_task(robot, actions, repeat=args.repeat, settings=settings)}
                if args.library in ("neighbours", "both") and form == "whole-body" and task in NEIGHBOURS:
                    import shutil
                    from dataclasses import replace

                    folder, planned = neighbour_library(robot, task, settings)
                    try:
                        seeded = replace(settings,
                                         cache=replace(settings.cache, cache_dir=folder,
                                                       solution_library="read"))
                        results[key + " +library"] = {
                            "label": label, "formulation": form, "library": "neighbours", "neighbours": planned,
                            **run_task(robot, actions, repeat=args.repeat, settings=seeded)}
                    finally:
                        shutil.rmtree(folder, ignore_errors=True)
    info["load_average_after"] = list(os.getloadavg())
    talos_tasks = args.tasks if "talos" in args.robots else []
    croc = {"skipped": "--no-peers"} if args.no_peers else crocoddyl_peer(talos_tasks, max(1, args.repeat))
    document = {"machine": info, "repeat": args.repeat, "results": results, "targets_s": TARGETS,
                "crocoddyl_fddp_quoted_s": {k: v[1] for k, v in CROCODDYL_QUOTED.items()},
                "crocoddyl_fddp_measured": croc}
    if args.out:
        Path(args.out).write_text(json.dumps(document, indent=2) + "\n")
    if args.json:
        print(json.dumps(document, indent=2))
        return 0
    print(f"dynamic plans ({'compiled, disk cache' if args.compile_dynamic else 'in-memory solvers'}); times [s], "
          f"medians of {args.repeat} cached runs, wall clock (CPU time of the whole plan() call in brackets); "
          f"threads {info['threads']}, load average {info['load_average'][0]:.2f} -> "
          f"{info['load_average_after'][0]:.2f}")
    print(f"{'robot/task (formulation)':<31} {'what':<26} {'knots':>5} {'vars':>6} {'iter':>4}  {'first build':>14}  "
          f"{'cached build+solve':>22}  target   ok  ZMP out")
    for key, r in results.items():
        first = r["first"]
        task = key.split("/")[1].split(" ")[0]
        target = TARGETS.get(task)
        verdict = "" if target is None else ("met" if r["cached_total_s"] <= target else "MISSED")
        extra = f"  rise {r['flight_rise_m']:.3f} m" if r["flight_rise_m"] is not None else ""
        zmp = "" if r["zmp_excursion_m"] is None else f" {r['zmp_excursion_m']:.3f} m"
        seed = r["runs"][-1]["seed"]
        extra += f"  seed: {seed}" if seed else ("  (no neighbour of this structure)" if r.get("library") == "neighbours"
                                                 else "")
        print(f"{key:<31} {r['label']:<26} {r['knots']:>5} {r['variables']:>6} {r['iterations']:>4}  "
              f"{first['build_s']:8.2f} {first['cache']:<6}  {r['cached_build_s']:5.2f}+{r['cached_solve_s']:5.2f} "
              f"({r['cached_cpu_s']:5.2f} cpu)  {'' if target is None else f'<= {target:g}':<7} "
              f"{'yes' if r['ok'] else 'NO'} {verdict}{zmp}{extra}")
    measured = croc.get("tasks", {}) if isinstance(croc, dict) else {}
    print("\nFor scale: Crocoddyl FDDP (full dynamics, C++, single-threaded, on the full Talos), measured in this "
          "run in .venv-crocoddyl" + (f" (not run: {croc['skipped']})" if "skipped" in croc else "")
          + "; the issue's quoted figures in brackets:")
    for task, (what, seconds) in CROCODDYL_QUOTED.items():
        ours = [r["cached_total_s"] for k, r in results.items() if k == f"talos/{task}"]
        mine = f"ours (talos/{task}, cached): {ours[0]:.2f} s" if ours else "ours: not run"
        seeded = [r["cached_total_s"] for k, r in results.items() if k == f"talos/{task} +library" and r["runs"][-1]["seed"]]
        mine += f"; from a neighbour's solution: {seeded[0]:.2f} s" if seeded else ""
        m = measured.get(CROCODDYL_TASKS[task])
        theirs = (f"{m['build_s']['median'] + m['solve_s']['median']:.2f} s build + solve, "
                  f"{m.get('iterations', '?')} iterations" if m else "not measured")
        print(f"  {what}: Crocoddyl {theirs} [quoted ~{seconds} s]   |   {mine}")
    print("  (Crocoddyl plans one walking phase with a fixed contact sequence by DDP; ours is a whole-body NLP over "
          "the whole motion, with stand phases, CoM dynamics, friction and CoP constraints.)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
