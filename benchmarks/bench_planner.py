"""Planner speed on Talos: a 3 s squat and a hand reach, first-ever / cached cold / warm.

Run: ``.venv/bin/python benchmarks/bench_planner.py [--repeat 3] [--first 2] [--json out.json]``
or ``.venv/bin/python benchmarks/bench_planner.py --first-ever [--tasks squat walk] [--profile DIR]``

* first-ever: a new process with an empty cache directory (build + C code generation + gcc);
* cached cold: a new process whose cache directory holds the compiled solver;
* warm: the same process, solver already in memory.

Each plan's build time (solver construction or cache load) and solve time (IPOPT) are reported
separately, as medians over the repetitions, with the iteration count, the end-to-end time of
the ``plan()`` call, and the process start-up (imports + robot load) for the cold cases. This
is a report, not a test: timings depend on the machine and on its load.

``--first-ever``: every task class of ``wbmp bench`` (squat, wave, reach, bow, balance, walk, turn,
jump on talos), each planned once in a new process with an empty solver cache directory and the
default settings, as a user's first request runs (compiled or serialized entries are written in
the background: ``WBMP_COMPILE_BACKGROUND`` is removed from the child's environment unless
``--foreground``). Per task: the ``plan()`` call's wall and CPU time (the figure of the issue 18
target, <= 5 s), its solver build and IPOPT times, and then, after the plan, the background
writer's work: the child waits for it and reports its CPU time (gcc or the serializer, in the
other core of a 2-core machine) and how long after the plan the entry was in place. The tasks run
one after the other, so one task's background work never overlaps the next task's plan.
``--profile DIR`` writes a CPU-time cProfile of each ``plan()`` call to ``DIR/<task>.prof``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CASES = {"squat": ROOT / "examples" / "specs" / "squat.json", "reach": ROOT / "examples" / "specs" / "reach.json"}


def child(case: str, cache_dir: str, runs: int) -> None:
    """Plan ``case`` ``runs`` times in this process; print one JSON line per run."""
    t0 = time.perf_counter()
    from planner import plan
    from robots import load_robot
    from tasks.serialize import load_spec
    from wbmp.environment import planner_settings  # the WBMP_* switches, as the CLI reads them

    spec = load_spec(CASES[case])
    robot = load_robot(spec.robot)
    startup = time.perf_counter() - t0
    settings = planner_settings(cache={"cache_dir": cache_dir, "solution_library": "off"})
    for i in range(runs):
        t1 = time.perf_counter()
        result = plan(spec, robot, settings=settings)
        total = time.perf_counter() - t1
        s = result.stats
        print(json.dumps({"case": case, "run": i, "startup": startup if i == 0 else 0.0, "total": total,
                          "build": s.build_time, "solve": s.solve_time, "iterations": s.iterations,
                          "cache": s.cache, "ok": result.ok}), flush=True)


def first_ever_child(task: str, cache_dir: str, profile: str | None) -> None:
    """Plan the bench task ``task`` once in this new process (empty ``cache_dir``); print one JSON line."""
    import resource

    t0 = time.perf_counter()
    from planner import plan
    from planner.trajopt import cache
    from robots import load_robot
    from wbmp.bench.tasks import TASKS, spec_for
    from wbmp.environment import planner_settings  # the WBMP_* switches, as the CLI reads them

    robot = load_robot("talos")
    _, spec = spec_for(TASKS[task], robot, None)
    startup = time.perf_counter() - t0
    settings = planner_settings(cache={"cache_dir": cache_dir, "solution_library": "off"})
    profiler = None
    if profile:
        import cProfile

        profiler = cProfile.Profile(time.process_time)
    t1, c1 = time.perf_counter(), time.process_time()
    if profiler is not None:
        profiler.enable()
    result = plan(spec, robot, settings=settings, throw=False)
    if profiler is not None:
        profiler.disable()
    wall, cpu = time.perf_counter() - t1, time.process_time() - c1
    if profiler is not None and profile:
        profiler.dump_stats(str(Path(profile) / f"{task}.prof"))
    t2 = time.perf_counter()  # the background work this plan started: C code + gcc, or the serializer
    cache.wait_for_background()
    behind = time.perf_counter() - t2
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    s = result.stats
    entries = sorted(p.name for p in (Path(cache_dir) / "planner").glob("*") if not p.name.startswith("."))
    print(json.dumps({"task": task, "startup": startup, "plan_wall": wall, "plan_cpu": cpu, "build": s.build_time,
                      "solve": s.solve_time, "iterations": s.iterations, "cache": s.cache, "ok": bool(result.ok),
                      "background_cpu": children.ru_utime + children.ru_stime, "background_after_plan": behind,
                      "entries": len(entries)}), flush=True)


def first_ever(tasks: list[str], foreground: bool, profile: str | None) -> list[dict]:
    """One new process per task, each with its own empty cache directory; the rows they print."""
    import shutil

    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    env.pop("WBMP_COMPILE_BACKGROUND", None)
    if foreground:
        env["WBMP_COMPILE_BACKGROUND"] = "0"
    rows = []
    for task in tasks:
        d = tempfile.mkdtemp(prefix="wbmp_first_")
        try:
            cmd = [sys.executable, __file__, "--first-ever-child", task, "--cache-dir", d]
            if profile:
                cmd += ["--profile", profile]
            out = subprocess.run(cmd, capture_output=True, text=True, check=True, env=env)
        finally:
            shutil.rmtree(d, ignore_errors=True)
        row = next(json.loads(line) for line in out.stdout.splitlines() if line.startswith("{"))
        rows.append(row)
        print(f"{task:<8} plan() {row['plan_wall']:6.2f} s wall {row['plan_cpu']:6.2f} s CPU "
              f"(build {row['build']:5.2f}, IPOPT {row['solve']:5.2f}, {row['iterations']:3d} it, {row['cache']}); "
              f"{'<= 5 s' if row['plan_wall'] <= 5.0 else 'OVER 5 s'}; background {row['background_cpu']:5.2f} s CPU, "
              f"done {row['background_after_plan']:5.2f} s after the plan; start-up {row['startup']:.2f} s; "
              f"{'ok' if row['ok'] else 'NOT ok'}", flush=True)
    return rows


def run_child(case: str, cache_dir: str, runs: int) -> list[dict]:
    out = subprocess.run([sys.executable, __file__, "--child", case, "--cache-dir", cache_dir, "--runs", str(runs)],
                         capture_output=True, text=True, check=True, env={**os.environ, "PYTHONPATH": str(ROOT)})
    return [json.loads(line) for line in out.stdout.splitlines() if line.startswith("{")]


def machine() -> dict:
    from wbmp.bench.machine import cpu_model

    return {
        "cpu": cpu_model(), "cores": os.cpu_count(), "load_average": os.getloadavg(),
        "python": platform.python_version(),
        "threads": {k: os.environ.get(k, "unset") for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS")},
        "note": "IPOPT + MUMPS run single-threaded; gcc compiles in one process",
    }


def median(rows: list[dict], key: str) -> float:
    return statistics.median(r[key] for r in rows)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3, help="cached-cold processes and warm runs per case")
    ap.add_argument("--first", type=int, default=2, help="first-ever processes per case (each compiles)")
    ap.add_argument("--json", help="also write the results here")
    ap.add_argument("--first-ever", action="store_true",
                    help="the first-ever plan of every wbmp bench task (new process, empty cache) instead")
    ap.add_argument("--tasks", nargs="+", help="with --first-ever: these bench tasks only (default: all)")
    ap.add_argument("--foreground", action="store_true",
                    help="with --first-ever: write the cache entry in the foreground (WBMP_COMPILE_BACKGROUND=0)")
    ap.add_argument("--profile", help="with --first-ever: write a CPU-time profile of each plan() to DIR/<task>.prof")
    ap.add_argument("--first-ever-child", help=argparse.SUPPRESS)
    ap.add_argument("--child", help=argparse.SUPPRESS)
    ap.add_argument("--cache-dir", help=argparse.SUPPRESS)
    ap.add_argument("--runs", type=int, default=1, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(args.child, args.cache_dir, args.runs)
        return
    if args.first_ever_child:
        first_ever_child(args.first_ever_child, args.cache_dir, args.profile)
        return
    info = machine()
    print(f"machine: {info['cpu']}, {info['cores']} cores, load average {info['load_average']}, "
          f"threads {info['threads']} ({info['note']})")
    if args.first_ever:
        from wbmp.bench.tasks import TASKS

        rows = first_ever(args.tasks or list(TASKS), args.foreground, args.profile)
        info["load_average_after"] = os.getloadavg()
        over = [r["task"] for r in rows if r["plan_wall"] > 5.0]
        print(f"over 5 s: {', '.join(over) or 'none'}; load average after {info['load_average_after']}")
        if args.json:
            Path(args.json).write_text(json.dumps({"machine": info, "first_ever": rows}, indent=2))
        return
    results: dict[str, dict] = {}
    for case in CASES:
        first, cold = [], []
        keep = None
        for _ in range(args.first):
            d = tempfile.mkdtemp(prefix="wbmp_bench_")
            first += run_child(case, d, 1)
            keep = d
        for _ in range(args.repeat):
            cold += [run_child(case, keep, 1)[0]]
        warm = run_child(case, keep, args.repeat + 1)[1:]
        results[case] = {"first_ever": first, "cached_cold": cold, "warm": warm}
    print(f"\n{'case':<6} {'mode':<12} {'n':>2} {'build [s]':>10} {'solve [s]':>10} {'plan() [s]':>11} "
          f"{'startup [s]':>12} {'iters':>6} cache")
    for case, modes in results.items():
        for mode, rows in modes.items():
            print(f"{case:<6} {mode:<12} {len(rows):>2} {median(rows, 'build'):>10.3f} {median(rows, 'solve'):>10.3f} "
                  f"{median(rows, 'total'):>11.3f} {median(rows, 'startup'):>12.2f} "
                  f"{int(median(rows, 'iterations')):>6} {rows[0]['cache']}")
    if args.json:
        Path(args.json).write_text(json.dumps({"machine": info, "results": results}, indent=2))


if __name__ == "__main__":
    main()
