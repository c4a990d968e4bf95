"""Planner speed on Talos: a 3 s squat and a hand reach, first-ever / cached cold / warm.

Run: ``.venv/bin/python benchmarks/bench_planner.py [--repeat 3] [--first 2] [--json out.json]``

* first-ever: a new process with an empty cache directory (build + C code generation + gcc);
* cached cold: a new process whose cache directory holds the compiled solver;
* warm: the same process, solver already in memory.

Each plan's build time (solver construction or cache load) and solve time (IPOPT) are reported
separately, as medians over the repetitions, with the iteration count, the end-to-end time of
the ``plan()`` call, and the process start-up (imports + robot load) for the cold cases. This
is a report, not a test: timings depend on the machine and on its load.
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
    from planner import PlannerSettings, plan
    from robots import load_robot
    from tasks.serialize import load_spec

    spec = load_spec(CASES[case])
    robot = load_robot(spec.robot)
    startup = time.perf_counter() - t0
    settings = PlannerSettings(cache_dir=cache_dir)
    for i in range(runs):
        t1 = time.perf_counter()
        result = plan(spec, robot, settings=settings)
        total = time.perf_counter() - t1
        s = result.stats
        print(json.dumps({"case": case, "run": i, "startup": startup if i == 0 else 0.0, "total": total,
                          "build": s.build_time, "solve": s.solve_time, "iterations": s.iterations,
                          "cache": s.cache, "ok": result.ok}), flush=True)


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
    ap.add_argument("--child", help=argparse.SUPPRESS)
    ap.add_argument("--cache-dir", help=argparse.SUPPRESS)
    ap.add_argument("--runs", type=int, default=1, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(args.child, args.cache_dir, args.runs)
        return
    info = machine()
    print(f"machine: {info['cpu']}, {info['cores']} cores, load average {info['load_average']}, "
          f"threads {info['threads']} ({info['note']})")
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
