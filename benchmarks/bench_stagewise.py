"""The stage-wise transcription against the current one: IPOPT-current, IPOPT-stagewise, fatrop-stagewise.

Run from the repository root::

    PYTHONPATH=$PWD .venv/bin/python benchmarks/bench_stagewise.py                  # squat reach jump walk
    PYTHONPATH=$PWD .venv/bin/python benchmarks/bench_stagewise.py --tasks squat --repeat 3
    PYTHONPATH=$PWD .venv/bin/python benchmarks/bench_stagewise.py --json --out result.json

Each bench task (talos; the sentences of ``wbmp bench`` and the four-step walk) is planned with
:func:`planner.plan` under three settings: the current transcription (``transcription="knots"``,
IPOPT), the stage-wise one (``planner/trajopt/stagewise.py``) solved by IPOPT, and the stage-wise
one solved by fatrop. Every solver is built in memory (``compile=False``: the same CasADi virtual
machine evaluates every variant's functions; no gcc), every plan starts from the task's own guess
(no solution library). A variant is planned ``--repeat`` + 1 times in this process: the first run
builds its solver, the next runs reuse it ("cached").

Reported per task and variant: the first run's build time, the cached runs' median ``plan()`` CPU
time and IPOPT/fatrop solve time (wall), iterations, objective, whether every check of the plan's
constraint report passed (Pinocchio numerics, independent of the NLP: soles, CoM polygon, targets,
limits) and its worst check relative to its limit, the largest joint-angle difference from the
current transcription's plan, and, from the solver's own statistics of the last solve, the CPU time
of the function evaluations (Hessian, Jacobian, the rest): what is left is the solver's own
linear algebra (MUMPS for IPOPT, the Riccati recursion for fatrop).

Dynamic tasks (jump, walk) have no stage-wise transcription yet: their rows say so and only the
current transcription is measured. Timings depend on the machine and its load: the CPU time is the
figure to compare on a shared machine (the load average is printed).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TASKS = {
    "squat": "squat down 10 cm",
    "reach": "reach forward with your right hand 20 cm",
    "jump": "jump 5 cm",
    "walk": "walk forward four steps",
}
VARIANTS = {  # name -> (transcription, stage-wise solver)
    "ipopt-current": ("knots", "ipopt"),
    "ipopt-stagewise": ("stagewise", "ipopt"),
    "fatrop-stagewise": ("stagewise", "fatrop"),
}


def worst_check(result) -> tuple[str, float]:
    """(name, value / limit) of the plan's check nearest to (or furthest over) its limit."""
    best = ("", 0.0)
    for c in result.checks:
        if not c.upper or not c.limit:
            continue
        ratio = float(c.value) / float(c.limit)
        if ratio > best[1]:
            best = (c.name, ratio)
    return best


def evaluation_times(spec, robot, settings, variant: str) -> dict:
    """CPU time of the last solve's function evaluations [s], from the solver's own statistics (the
    solver of the structure :func:`planner.plan` solved first, from this process's cache)."""
    from planner.trajopt.api import _formulation, planned_layout

    lay = planned_layout(spec, robot, settings)
    if variant == "ipopt-current":
        from planner.trajopt.cache import get_solver

        _, used = _formulation(spec, robot, settings)  # a dynamic plan's own solver options
        stats = get_solver(lay, used).function.stats()
    else:
        from planner.trajopt.stagewise import get_stagewise_solver

        stats = get_stagewise_solver(lay, settings, VARIANTS[variant][1])[0].function.stats()
    return {k[len("t_proc_nlp_"):]: float(v) for k, v in stats.items() if k.startswith("t_proc_nlp_")}


def run_variant(robot, spec, variant: str, repeat: int, reference, fatrop_extra: tuple = ()) -> dict:
    """Plan ``spec`` ``repeat + 1`` times with one variant's settings."""
    from planner import CacheSettings, PlannerSettings, SolverSettings, plan

    transcription, solver = VARIANTS[variant]
    settings = PlannerSettings(cache=CacheSettings(compile=False, solution_library="off"),
                               solver=SolverSettings(transcription=transcription, stagewise_solver=solver, fatrop_extra=fatrop_extra))
    runs = []
    result = None
    for i in range(repeat + 1):
        w0, c0 = time.perf_counter(), time.process_time()
        result = plan(spec, robot, settings=settings, throw=False)
        runs.append({"wall": time.perf_counter() - w0, "cpu": time.process_time() - c0,
                     "build": result.stats.build_time, "solve": result.stats.solve_time,
                     "iterations": result.stats.iterations, "cache": result.stats.cache})
        print(f"  {variant:17s} run {i}: {runs[-1]['cpu']:.2f} s CPU, {result.stats.iterations} iterations, "
              f"{result.stats.backend}, ok={result.ok}", file=sys.stderr, flush=True)
    assert result is not None
    cached = runs[1:] or runs
    name, ratio = worst_check(result)
    try:
        evals = evaluation_times(spec, robot, settings, variant)
    except Exception as exc:  # noqa: BLE001 - a structure that changed in a collision round: no breakdown
        evals = {"error": str(exc)}
    diff = None if reference is None else float(abs(result.q - reference).max())
    return {
        "variant": variant, "backend": result.stats.backend, "ok": result.ok, "status": result.stats.status.name,
        "first_build_s": runs[0]["build"], "first_cpu_s": runs[0]["cpu"],
        "cpu_s": statistics.median(r["cpu"] for r in cached), "wall_s": statistics.median(r["wall"] for r in cached),
        "solve_s": statistics.median(r["solve"] for r in cached), "iterations": result.stats.iterations,
        "objective": result.stats.objective, "n_variables": result.stats.n_variables,
        "n_constraints": result.stats.n_constraints, "worst_check": name, "worst_check_ratio": ratio,
        "max_q_difference": diff, "evaluations_cpu_s": evals, "runs": runs, "q": result.q,
    }


def table(rows: list[dict]) -> str:
    """The results as a Markdown table."""
    head = ("| task | variant | ok | iterations | cached plan() CPU [s] | solve wall [s] | evaluations CPU "
            "(Hessian / Jacobian) [s] | first build [s] | variables / rows | worst check / limit | "
            "max abs q diff vs current |")
    lines = [head, "|" + " --- |" * 11]
    for r in rows:
        if r.get("skipped"):
            lines.append(f"| {r['task']} | {r['variant']} | {r['skipped']} |" + " |" * 8)
            continue
        ev = r["evaluations_cpu_s"]
        evs = "n/a" if "error" in ev else (f"{sum(ev.values()):.2f} "
                                           f"({ev.get('hess_l', 0):.2f} / {ev.get('jac_g', 0):.2f})")
        diff = "-" if r["max_q_difference"] is None else f"{r['max_q_difference']:.1e}"
        lines.append(
            f"| {r['task']} | {r['variant']} | {'yes' if r['ok'] else 'NO ' + r['status']} | {r['iterations']} | "
            f"{r['cpu_s']:.2f} | {r['solve_s']:.2f} | {evs} | {r['first_build_s']:.2f} | "
            f"{r['n_variables']} / {r['n_constraints']} | {r['worst_check_ratio']:.2f} ({r['worst_check']}) | {diff} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark; print a table (or JSON)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tasks", nargs="+", default=list(TASKS), choices=list(TASKS))
    parser.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=list(VARIANTS))
    parser.add_argument("--repeat", type=int, default=2, help="cached runs after the first one (default 2)")
    parser.add_argument("--robot", default="talos")
    parser.add_argument("--fatrop-option", action="append", default=[], metavar="NAME=VALUE",
                        help="a fatrop option for the fatrop-stagewise rows (a number), e.g. mu_init=1e-4")
    parser.add_argument("--json", action="store_true", help="print JSON instead of the table")
    parser.add_argument("--out", help="also write the JSON results here")
    args = parser.parse_args(argv)
    if args.repeat < 0:
        parser.error(f"--repeat must be >= 0, got {args.repeat}")
    fatrop_extra = []
    for item in args.fatrop_option:
        name, _, value = item.partition("=")
        try:
            fatrop_extra.append((name, int(value) if value.lstrip("-").isdigit() else float(value)))
        except ValueError:
            parser.error(f"--fatrop-option: expected NAME=NUMBER, got {item!r}")
    for key in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS"):  # before CasADi loads its OpenBLAS
        os.environ.setdefault(key, "1")
    sys.path.insert(0, str(ROOT))
    from robots import load_robot
    from wbmp.bench.machine import machine_info
    from wbmp.bench.tasks import spec_for

    robot = load_robot(args.robot)
    rows = []
    for task in args.tasks:
        _, spec = spec_for(TASKS[task], robot, None)
        print(f"{task}: {TASKS[task]!r} ({'dynamic' if spec.dynamic else 'kinematic'})", file=sys.stderr, flush=True)
        reference = None
        for variant in args.variants:
            if spec.dynamic and VARIANTS[variant][0] == "stagewise":
                rows.append({"task": task, "variant": variant,
                             "skipped": "not built: the stage-wise transcription is kinematic only"})
                continue
            row = run_variant(robot, spec, variant, args.repeat, reference, tuple(fatrop_extra))
            if variant == "ipopt-current":
                reference = row["q"]
            rows.append({"task": task, **row})
    for r in rows:
        r.pop("q", None)
    info = machine_info()
    report = {"machine": info, "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), "repeat": args.repeat,
              "fatrop_options": dict(fatrop_extra), "rows": rows}
    if args.out:
        Path(args.out).write_text(json.dumps(report, indent=1) + "\n")
    if args.json:
        print(json.dumps(report, indent=1))
    else:
        print(f"{info['cpu_model']}, {info['cores']} cores, load average {info['loadavg']} "
              f"(threads: OMP {os.environ.get('OMP_NUM_THREADS')}), {report['date']}")
        print(table(rows))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
