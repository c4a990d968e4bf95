"""Throughput of ``wbmp batch``: items/min with 1 and 2 local workers, and Ray's overhead.

Run from the repository root::

    .venv/bin/python benchmarks/bench_batch.py                 # 200 corpus sentences, with simulation
    .venv/bin/python benchmarks/bench_batch.py --items 20 --no-sim --out results.json

The items are the first N accepted sentences of the language corpus (tests/language/corpus.txt),
cycled when N is larger, each planned on talos. The same batch runs three times, each as a fresh
``wbmp batch`` process into a fresh folder: local pool with 1 worker, local pool with 2 workers,
Ray (a local instance started by the command) with 2 workers. Reported per run: wall time of the
whole command (process start, worker start-up, Ray start-up included), items/min, ok/failed
counts; and Ray's overhead against the 2-worker local pool (wall time difference, absolute and
relative). The results JSON holds the CPU model, the load average before and after, the CPU
count the process may use, and the BLAS thread variables. Solvers are built in memory
(``WBMP_COMPILE=0``) unless ``--compile``, so each run starts equally cold.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from wbmp.bench.machine import cpu_model

ROOT = Path(__file__).resolve().parents[1]


def sentences(n: int) -> list[str]:
    sys.path.insert(0, str(ROOT))
    from tests.language.corpus import load_corpus

    accepted = [c.text for c in load_corpus() if c.expected is not None and "\n" not in c.text]
    return [accepted[i % len(accepted)] + ("" if i < len(accepted) else f" ({i // len(accepted)})")
            for i in range(n)] if n > len(accepted) else accepted[:n]



def run_batch(items: Path, out: Path, extra: list[str], env: dict[str, str]) -> dict:
    cmd = [sys.executable, "-c", "from wbmp.cli import run; run()", "batch", str(items), "--out-dir", str(out),
           "--quiet", "--json", *extra]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=ROOT, check=False, timeout=6 * 3600)
    wall = time.perf_counter() - t0
    try:
        outcome = json.loads(proc.stdout.strip().splitlines()[-1])
    except (IndexError, ValueError):
        outcome = {"error": proc.stderr[-2000:]}
    n = outcome.get("ran", 0)
    return {"args": extra, "exit_code": proc.returncode, "wall_s": round(wall, 3),
            "items_per_min": round(60.0 * n / wall, 2) if wall > 0 else None,
            **{k: outcome.get(k) for k in ("jobs", "ok", "failed", "ran", "wall_time")},
            **({"error": outcome["error"]} if "error" in outcome else {})}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--items", type=int, default=200, help="number of sentences (default 200)")
    parser.add_argument("--no-sim", action="store_true", help="plan only (no MuJoCo check)")
    parser.add_argument("--compile", action="store_true", help="use the compiled solver cache (a temporary one)")
    parser.add_argument("--no-ray", action="store_true", help="skip the Ray run")
    parser.add_argument("--out", default=None, help="write the results JSON here")
    args = parser.parse_args()

    texts = sentences(args.items)
    extra = ["--no-sim"] if args.no_sim else []
    with tempfile.TemporaryDirectory(prefix="wbmp-bench-batch-") as tmp:
        folder = Path(tmp)
        items = folder / "items.txt"
        items.write_text("\n".join(texts) + "\n")
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
        env["WBMP_CACHE_DIR"] = str(folder / "cache")
        env["WBMP_COMPILE"] = "1" if args.compile else "0"
        load_before = os.getloadavg()
        runs = {}
        for name, opts in (("local_1", ["--workers", "1"]), ("local_2", ["--workers", "2"]),
                           *((("ray_2", ["--workers", "2", "--ray"]),) if not args.no_ray else ())):
            print(f"{name}: {len(texts)} items ...", file=sys.stderr, flush=True)
            runs[name] = run_batch(items, folder / name, opts + extra, env)
            print(f"  {runs[name]}", file=sys.stderr, flush=True)
        load_after = os.getloadavg()
    result = {
        "benchmark": "batch", "items": len(texts), "simulate": not args.no_sim, "compile": args.compile,
        "machine": {"cpu": cpu_model(), "cpu_count": os.cpu_count(),
                    "usable_cpus": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else None,
                    "load_before": [round(x, 2) for x in load_before],
                    "load_after": [round(x, 2) for x in load_after],
                    "threads": {k: os.environ.get(k, "1 (set by wbmp)") for k in
                                ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")},
                    "python": platform.python_version()},
        "runs": runs,
    }
    if "ray_2" in runs and runs["local_2"]["wall_s"]:
        diff = runs["ray_2"]["wall_s"] - runs["local_2"]["wall_s"]
        result["ray_overhead"] = {"wall_s": round(diff, 3), "relative": round(diff / runs["local_2"]["wall_s"], 3)}
    if runs["local_1"]["wall_s"] and runs["local_2"]["wall_s"]:
        result["speedup_2_workers"] = round(runs["local_1"]["wall_s"] / runs["local_2"]["wall_s"], 3)
    text = json.dumps(result, indent=2)
    print(text)
    if args.out:
        Path(args.out).write_text(text + "\n")
    return 0 if all(r["exit_code"] in (0, 2, 3, 4, 5) for r in runs.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
