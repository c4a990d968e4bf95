"""End to end: process wall time of ``wbmp solve SENTENCE --out FILE.npz --html FILE.html``.

Run from the repository root::

    .venv/bin/python benchmarks/bench_e2e.py                       # squat and four steps, 5 repeats
    .venv/bin/python benchmarks/bench_e2e.py --repeat 3 --json
    .venv/bin/python benchmarks/bench_e2e.py --out benchmarks/results/e2e_<date>.json
    .venv/bin/python benchmarks/bench_e2e.py --repeat 3 --baseline /tmp/main-tree   # before/after, interleaved
    .venv/bin/python benchmarks/bench_e2e.py --cases squat --first-run               # also a first request

Each case is a fresh ``python -m wbmp.cli`` process (start-up, parsing, robot loading,
planning, simulation and writing included), timed from outside:

* ``solver cached``: ``--no-cache`` (the motion cache is bypassed), with the compiled solver
  already in the solver cache (one warm-up run first builds it if needed);
* ``motion cached``: the same command without ``--no-cache``, after one run stored the motion:
  the repeat is answered from the motion cache (``wbmp/motioncache.py``);
* ``first run`` (``--first-run``): the same command without ``--no-cache`` with the motion cache
  emptied before each run: what a user's first request costs (the solve, plus hashing the
  robot's files and storing the motion), the solver still cached.

Reported per case: the median, min and max of ``--repeat`` runs [s] of wall time and of the
process's CPU time (user + sys: steadier than the wall time on a loaded machine), the median of
each stage the command reports (``--json``: ``spec``, ``plan``, ``simulate``, ``npz``, ``html``;
``other`` is the rest: Python start-up, imports, printing), the output sizes, and the machine
(CPU model, cores, load average before and after, BLAS threads). The solver cache and the motion
cache live in a temporary ``WBMP_CACHE_DIR`` unless ``--cache-dir`` is given. Python's bytecode
goes to a temporary ``PYTHONPYCACHEPREFIX`` (``PYTHONDONTWRITEBYTECODE`` is dropped: an
installed wbmp has its bytecode, and recompiling every module costs ~0.5 s a process).

``--baseline TREE`` runs every command also with ``PYTHONPATH=TREE`` (another source tree, e.g.
``git archive main | tar -x -C /tmp/main-tree``), alternating run by run with this tree, so
both see the same load; its caches are separate entries of the same cache folder, and its
results go to ``baseline`` beside ``cases`` in the JSON.
Targets (issue 18): squat <= 3 s and four steps <= 6 s solver cached, <= 0.5 s motion cached.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from wbmp.bench.machine import cpu_model

REPO = Path(__file__).resolve().parents[1]
CASES = {"squat": "squat down 12 cm", "four steps": "walk forward four steps"}
STAGES = ("spec", "plan", "simulate", "npz", "html")


def run_once(argv: list[str], env: dict[str, str], cwd: Path) -> dict:
    """One process: wall and CPU time [s] and the stage timings of its ``--json`` report."""
    before = os.times()
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "wbmp.cli", *argv, "--json"], env=env, cwd=cwd,
                          capture_output=True, text=True, check=False)
    wall = time.perf_counter() - t0
    after = os.times()
    if proc.returncode not in (0, 5):
        raise SystemExit(f"wbmp {' '.join(argv)} failed (exit {proc.returncode}):\n{proc.stderr[-2000:]}")
    try:
        timings = json.loads(proc.stdout.strip().splitlines()[-1]).get("timings", {})
    except (ValueError, IndexError, AttributeError):
        timings = {}
    cpu = (after.children_user - before.children_user) + (after.children_system - before.children_system)
    return {"wall": wall, "cpu": cpu, "timings": {k: float(v) for k, v in timings.items()}}


def summary(runs: list[dict]) -> dict:
    walls, cpus = [r["wall"] for r in runs], [r["cpu"] for r in runs]
    stages = {}
    for name in {k for r in runs for k in r["timings"]}:
        stages[name] = statistics.median(r["timings"].get(name, 0.0) for r in runs)
    stages["other"] = statistics.median(r["wall"] - sum(r["timings"].values()) for r in runs)
    return {"median": statistics.median(walls), "min": min(walls), "max": max(walls), "runs": walls,
            "cpu_median": statistics.median(cpus), "cpu_runs": cpus, "stages": stages}


def _line(label: str, r: dict) -> str:
    s = r["solver_cached"]
    stages = "  ".join(f"{k} {s['stages'][k]:.2f}" for k in (*STAGES, "cache", "other") if k in s["stages"])
    return (f"{label:<20} solver cached {s['median']:6.2f} s (min {s['min']:.2f}, max {s['max']:.2f}; "
            f"CPU {s['cpu_median']:.2f})  [{stages}]   motion cached {r['motion_cached']['median']:5.2f} s   "
            f"html {r['html_bytes'] / 1e6:.2f} MB"
            + (f"   first run {r['first_run']['median']:5.2f} s (CPU {r['first_run']['cpu_median']:.2f})"
               if "first_run" in r else ""))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--cases", nargs="*", default=list(CASES), choices=list(CASES))
    parser.add_argument("--threads", type=int, default=1, help="OMP/OpenBLAS threads (default 1)")
    parser.add_argument("--cache-dir", default=None, help="WBMP_CACHE_DIR (default: a temporary folder)")
    parser.add_argument("--baseline", default=None, metavar="TREE",
                        help="another source tree to run alternately with this one (before/after)")
    parser.add_argument("--first-run", action="store_true",
                        help="also time the command with the motion cache on and emptied before each run")
    parser.add_argument("--json", action="store_true", help="print the results as JSON")
    parser.add_argument("--out", default=None, help="also write the JSON results here")
    args = parser.parse_args()

    work = Path(tempfile.mkdtemp(prefix="wbmp-e2e-"))
    env = dict(os.environ)
    env["WBMP_CACHE_DIR"] = args.cache_dir or str(work / "cache")
    env.setdefault("OMP_NUM_THREADS", str(args.threads))
    env.setdefault("OPENBLAS_NUM_THREADS", str(args.threads))
    env["WBMP_COMPILE_BACKGROUND"] = "0"  # the warm-up run leaves a compiled solver behind
    env["WBMP_SOLUTION_LIBRARY"] = "off"  # a first run's plan from its own guess, not from the warm-up's solution
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    env["PYTHONPYCACHEPREFIX"] = str(work / "pycache")
    trees = {"this tree": REPO}
    if args.baseline:
        trees["baseline"] = Path(args.baseline).resolve()
    envs = {}
    for label, tree in trees.items():
        e = dict(env)
        e["PYTHONPATH"] = str(tree) + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
        envs[label] = e

    results: dict = {
        "date": time.strftime("%Y-%m-%d %H:%M:%S"),
        "cpu": cpu_model(), "cores": os.cpu_count(), "load_before": os.getloadavg(),
        "threads": {"OMP_NUM_THREADS": env["OMP_NUM_THREADS"], "OPENBLAS_NUM_THREADS": env["OPENBLAS_NUM_THREADS"]},
        "python": platform.python_version(), "repeat": args.repeat, "trees": {k: str(v) for k, v in trees.items()},
        "cases": {},
    }
    for name in args.cases:
        sentence = CASES[name]
        per_tree: dict[str, dict] = {}
        outs = {}
        for label in trees:
            stem = f"{name.replace(' ', '_')}_{label.replace(' ', '_')}"
            out, html = work / f"{stem}.npz", work / f"{stem}.html"
            outs[label] = (out, html, ["solve", sentence, "--out", str(out), "--html", str(html)])
            warm = run_once([*outs[label][2], "--no-cache"], envs[label], work)  # builds the solver if needed
            per_tree[label] = {"warm_up": warm["wall"], "solver": [], "motion": [], "first": []}
        for _ in range(args.repeat):  # interleaved: each tree sees the same load
            for label in trees:
                per_tree[label]["solver"].append(run_once([*outs[label][2], "--no-cache"], envs[label], work))
        if args.first_run:
            for _ in range(args.repeat):
                for label in trees:
                    shutil.rmtree(Path(envs[label]["WBMP_CACHE_DIR"]) / "motions", ignore_errors=True)
                    per_tree[label]["first"].append(run_once(outs[label][2], envs[label], work))
        for label in trees:
            run_once(outs[label][2], envs[label], work)  # stores the motion
        for _ in range(args.repeat):
            for label in trees:
                per_tree[label]["motion"].append(run_once(outs[label][2], envs[label], work))
        for label in trees:
            out, html, _ = outs[label]
            r = {"sentence": sentence, "warm_up": per_tree[label]["warm_up"],
                 "solver_cached": summary(per_tree[label]["solver"]),
                 "motion_cached": summary(per_tree[label]["motion"]),
                 "npz_bytes": out.stat().st_size, "html_bytes": html.stat().st_size}
            if per_tree[label]["first"]:
                r["first_run"] = summary(per_tree[label]["first"])
            # this tree's results where they always were; the baseline's beside them
            results.setdefault("cases" if label == "this tree" else "baseline", {})[name] = r
            if not args.json:
                print(_line(f"{name} ({label})" if args.baseline else name, r), flush=True)
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
