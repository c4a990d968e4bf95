"""End to end: process wall time of ``wbmp solve SENTENCE --out FILE.npz --html FILE.html``.

Run from the repository root::

    .venv/bin/python benchmarks/bench_e2e.py                       # squat and four steps, 5 repeats
    .venv/bin/python benchmarks/bench_e2e.py --repeat 3 --json
    .venv/bin/python benchmarks/bench_e2e.py --out benchmarks/results/e2e_<date>.json

Each case is a fresh ``python -m wbmp.cli`` process (start-up, parsing, robot loading,
planning, simulation and writing included), timed from outside:

* ``solver cached``: ``--no-cache`` (the motion cache is bypassed), with the compiled solver
  already in the solver cache (one warm-up run first builds it if needed);
* ``motion cached``: the same command without ``--no-cache``, after one run stored the motion:
  the repeat is answered from the motion cache (``wbmp/motioncache.py``).

Reported per case: the median, min and max of ``--repeat`` runs [s], the output sizes, and the
machine (CPU model, cores, load average before and after, BLAS threads). The solver cache and
the motion cache live in a temporary ``WBMP_CACHE_DIR`` unless ``--cache-dir`` is given.
Targets (issue 18): squat <= 3 s and four steps <= 6 s solver cached, <= 0.5 s motion cached.
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

from wbmp.bench.machine import cpu_model

REPO = Path(__file__).resolve().parents[1]
CASES = {"squat": "squat down 12 cm", "four steps": "walk forward four steps"}



def run_once(argv: list[str], env: dict[str, str], cwd: Path) -> float:
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "wbmp.cli", *argv], env=env, cwd=cwd,
                          capture_output=True, text=True, check=False)
    wall = time.perf_counter() - t0
    if proc.returncode not in (0, 5):
        raise SystemExit(f"wbmp {' '.join(argv)} failed (exit {proc.returncode}):\n{proc.stderr[-2000:]}")
    return wall


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--cases", nargs="*", default=list(CASES), choices=list(CASES))
    parser.add_argument("--threads", type=int, default=1, help="OMP/OpenBLAS threads (default 1)")
    parser.add_argument("--cache-dir", default=None, help="WBMP_CACHE_DIR (default: a temporary folder)")
    parser.add_argument("--json", action="store_true", help="print the results as JSON")
    parser.add_argument("--out", default=None, help="also write the JSON results here")
    args = parser.parse_args()

    work = Path(tempfile.mkdtemp(prefix="wbmp-e2e-"))
    env = dict(os.environ)
    env["PYTHONPATH"] = str(REPO) + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    env["WBMP_CACHE_DIR"] = args.cache_dir or str(work / "cache")
    env.setdefault("OMP_NUM_THREADS", str(args.threads))
    env.setdefault("OPENBLAS_NUM_THREADS", str(args.threads))
    env["WBMP_COMPILE_BACKGROUND"] = "0"  # the warm-up run leaves a compiled solver behind

    results: dict = {
        "date": time.strftime("%Y-%m-%d %H:%M:%S"),
        "cpu": cpu_model(), "cores": os.cpu_count(), "load_before": os.getloadavg(),
        "threads": {"OMP_NUM_THREADS": env["OMP_NUM_THREADS"], "OPENBLAS_NUM_THREADS": env["OPENBLAS_NUM_THREADS"]},
        "python": platform.python_version(), "repeat": args.repeat, "cases": {},
    }
    for name in args.cases:
        sentence = CASES[name]
        out, html = work / f"{name.replace(' ', '_')}.npz", work / f"{name.replace(' ', '_')}.html"
        base = ["solve", sentence, "--out", str(out), "--html", str(html), "--quiet"]
        warm = run_once([*base, "--no-cache"], env, work)  # builds/compiles the solver if needed
        solver = [run_once([*base, "--no-cache"], env, work) for _ in range(args.repeat)]
        run_once(base, env, work)  # stores the motion
        motion = [run_once(base, env, work) for _ in range(args.repeat)]
        results["cases"][name] = {
            "sentence": sentence, "warm_up": warm,
            "solver_cached": {"median": statistics.median(solver), "min": min(solver), "max": max(solver),
                              "runs": solver},
            "motion_cached": {"median": statistics.median(motion), "min": min(motion), "max": max(motion),
                              "runs": motion},
            "npz_bytes": out.stat().st_size, "html_bytes": html.stat().st_size,
        }
        if not args.json:
            r = results["cases"][name]
            print(f"{name:<11} solver cached {r['solver_cached']['median']:6.2f} s (min {r['solver_cached']['min']:.2f}, "
                  f"max {r['solver_cached']['max']:.2f})   motion cached {r['motion_cached']['median']:5.2f} s "
                  f"(min {r['motion_cached']['min']:.2f}, max {r['motion_cached']['max']:.2f})   "
                  f"html {r['html_bytes'] / 1e6:.2f} MB", flush=True)
    results["load_after"] = os.getloadavg()
    if args.json:
        print(json.dumps(results, indent=2))
    else:
        print(f"cpu: {results['cpu']}, {results['cores']} cores, load {results['load_before'][0]:.2f} -> "
              f"{results['load_after'][0]:.2f}, BLAS threads {env['OMP_NUM_THREADS']}, {args.repeat} repeats")
    if args.out:
        Path(args.out).write_text(json.dumps(results, indent=2) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
