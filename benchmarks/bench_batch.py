"""Throughput of ``wbmp batch``: items/min with 1 and 2 local workers, and Ray's overhead.

Run from the repository root (one command; tens of minutes with simulation on a 2-core machine)::

    .venv/bin/python benchmarks/bench_batch.py                 # 200 corpus sentences, with simulation
    .venv/bin/python benchmarks/bench_batch.py --items 20      # a quick check of the same thing
    .venv/bin/python benchmarks/bench_batch.py --items 16 --no-sim --out results.json

The items are a mix across task classes: the accepted sentences of the language corpora
(tests/language/corpus.txt and corpus_new_actions.txt) grouped by their first action (a
composition of several actions is its own class: ``walk+``), taken round-robin over the classes
(within a class, spread evenly over its sentences), each planned on talos. The same batch runs
as fresh ``wbmp batch`` processes into fresh folders, in ``--runs`` order (default: local pool
with 2 workers, Ray (a local instance started by the command) with 2 workers, local pool with 1
worker: the two compared for Ray's overhead run back to back, under the most similar load, and the
longest run comes last), always with ``--no-cache`` (every item is planned). Reported per run: wall time of the
whole command (process start, worker start-up, Ray start-up included), items/min, ok/failed
counts by exit code, median per-item times from the index, the load average before and after;
and Ray's overhead against the 2-worker local pool (wall time difference, absolute and
relative). Solvers are built in memory (``WBMP_COMPILE=0``) unless ``--compile``, so each run
starts equally cold.

Results: ``--out`` (default ``benchmarks/results/batch_<date>_<machine>_<N>items[-nosim].json``),
rewritten after each run (a stopped benchmark keeps the runs it finished), and a markdown table
beside it (``.md``). ``--work-dir`` keeps the batch folders (their ``index.jsonl`` shows the
progress of a run).
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
from datetime import date
from pathlib import Path

from wbmp.bench.machine import cpu_model, machine_tag

ROOT = Path(__file__).resolve().parents[1]
RUNS = {"local_1": ["--workers", "1"], "local_2": ["--workers", "2"], "ray_2": ["--workers", "2", "--ray"]}


def sentences(n: int) -> list[tuple[str, str]]:
    """``n`` distinct (class, sentence) pairs, round-robin over the task classes of the corpora."""
    sys.path.insert(0, str(ROOT))
    from tests.language.corpus import CORPUS_PATH, NEW_ACTIONS_PATH, load_corpus

    classes: dict[str, list[str]] = {}
    seen: set[str] = set()
    for path in (CORPUS_PATH, NEW_ACTIONS_PATH):
        for case in load_corpus(path):
            if case.expected is None or "\n" in case.text or case.text in seen:
                continue
            seen.add(case.text)
            name = case.expected[0]["action"] + ("+" if len(case.expected) > 1 else "")
            classes.setdefault(name, []).append(case.text)
    if n > len(seen):
        raise SystemExit(f"--items {n}: the corpora hold {len(seen)} distinct accepted sentences")
    # spread each class's sentences evenly (not its first ones: a corpus section starts with variants)
    spread = {k: [v[(i * 7) % len(v)] for i in range(len(v))] if len(v) % 7 else v for k, v in classes.items()}
    picked: list[tuple[str, str]] = []
    depth = 0
    while len(picked) < n:
        for name in sorted(spread):
            if depth < len(spread[name]) and len(picked) < n:
                picked.append((name, spread[name][depth]))
        depth += 1
    return picked


def _index_stats(folder: Path) -> dict:
    """Exit codes and median per-item times [s] from a run's index.jsonl."""
    from wbmp.batch.index import read_index

    path = folder / "index.jsonl"
    if not path.exists():
        return {}
    recs = list(read_index(path).values())
    codes: dict[str, int] = {}
    for r in recs:
        codes[str(r.get("exit_code"))] = codes.get(str(r.get("exit_code")), 0) + 1
    med = {}
    for key in ("spec", "plan", "simulate", "write", "total"):
        vals = [r["timings"][key] for r in recs if isinstance(r.get("timings"), dict) and key in r["timings"]]
        if vals:
            med[key] = round(statistics.median(vals), 3)
    return {"records": len(recs), "exit_codes": codes, "median_item_s": med,
            "sum_item_total_s": round(sum(r.get("timings", {}).get("total", 0.0) for r in recs), 1)}


def progress_of(work_dir: Path) -> dict:
    """Figures of runs so far (also of a run still going, or stopped): records, exit codes, and
    items/min from the first to the last record's finish time (a lower bound of the run's rate,
    since the first record comes one item after the start)."""
    from datetime import datetime

    out = {}
    for name in RUNS:
        from wbmp.batch.index import read_index

        path = work_dir / name / "index.jsonl"
        if not path.exists():
            continue
        recs = list(read_index(path).values())
        stats = _index_stats(work_dir / name)
        times = sorted(datetime.fromisoformat(r["finished"]) for r in recs if r.get("finished"))
        span = (times[-1] - times[0]).total_seconds() if len(times) > 1 else 0.0
        stats["items_per_min_between_first_and_last"] = round(60.0 * (len(times) - 1) / span, 2) if span else None
        out[name] = stats
    return out


def run_batch(items: Path, out: Path, extra: list[str], env: dict[str, str]) -> dict:
    cmd = [sys.executable, "-c", "from wbmp.cli import run; run()", "batch", str(items), "--out-dir", str(out),
           "--quiet", "--json", *extra]
    load_before = os.getloadavg()
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
            **_index_stats(out),
            "load_before": [round(x, 2) for x in load_before],
            "load_after": [round(x, 2) for x in os.getloadavg()],
            **({"error": outcome["error"]} if "error" in outcome else {})}


def table(result: dict) -> str:
    """The markdown table of a result."""
    lines = [f"`wbmp batch`, {result['items']} corpus sentences on talos "
             f"({'with' if result['simulate'] else 'without'} simulation, --no-cache), {result['machine']['cpu']}, "
             f"{result['date']}", "",
             "| backend | wall time | items/min | ok | failed (exit codes) | median item | load before → after |",
             "|---|---:|---:|---:|---|---:|---|"]
    names = {"local_1": "local, 1 worker", "local_2": "local, 2 workers", "ray_2": "Ray (local instance), 2 workers"}
    for key, run in result["runs"].items():
        codes = ", ".join(f"{c}: {k}" for c, k in sorted(run.get("exit_codes", {}).items()) if c != "0")
        med = run.get("median_item_s", {}).get("total")
        lines.append(f"| {names.get(key, key)} | {run['wall_s']:.1f} s | {run['items_per_min']} | {run.get('ok')} | "
                     f"{run.get('failed')} ({codes or '-'}) | {med if med is not None else '-'} s | "
                     f"{run['load_before'][0]} → {run['load_after'][0]} |")
    if "ray_overhead" in result:
        o = result["ray_overhead"]
        lines += ["", f"Ray's overhead against the 2-worker local pool: {o['wall_s']:+.1f} s ({100 * o['relative']:+.1f} %)."]
    if "speedup_2_workers" in result:
        lines.append(f"2 workers against 1: x{result['speedup_2_workers']}.")
    return "\n".join(lines) + "\n"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--items", type=int, default=200, help="number of sentences (default 200)")
    parser.add_argument("--no-sim", action="store_true", help="plan only (no MuJoCo check)")
    parser.add_argument("--compile", action="store_true", help="use the compiled solver cache (a temporary one)")
    parser.add_argument("--runs", default="local_2,ray_2,local_1",
                        help="which runs, in order (default local_2,ray_2,local_1)")
    parser.add_argument("--no-ray", action="store_true", help="skip the Ray run")
    parser.add_argument("--work-dir", default=None, help="keep the batch folders here (default: a temporary folder)")
    parser.add_argument("--out", default=None, help="write the results JSON here (default: benchmarks/results/...)")
    parser.add_argument("--progress", metavar="WORK_DIR", default=None,
                        help="print the figures so far of a benchmark run with --work-dir WORK_DIR, and exit")
    args = parser.parse_args()
    if args.progress:
        print(json.dumps(progress_of(Path(args.progress)), indent=2))
        return 0
    runs_wanted = [r.strip() for r in args.runs.split(",") if r.strip() and not (args.no_ray and r.strip() == "ray_2")]
    unknown = [r for r in runs_wanted if r not in RUNS]
    if unknown:
        parser.error(f"--runs: unknown {unknown}; choose from {sorted(RUNS)}")

    picked = sentences(args.items)
    extra = ["--no-cache"] + (["--no-sim"] if args.no_sim else [])
    cpu = cpu_model()
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    today = date.today().isoformat()
    out = Path(args.out) if args.out else (
        ROOT / "benchmarks" / "results"
        / f"batch_{today}_{machine_tag({'cpu_model': cpu, 'cores': cores})}_{args.items}items{'-nosim' if args.no_sim else ''}.json")
    folder = Path(args.work_dir) if args.work_dir else Path(tempfile.mkdtemp(prefix="wbmp-bench-batch-"))
    folder.mkdir(parents=True, exist_ok=True)
    try:
        items = folder / "items.txt"
        items.write_text("\n".join(text for _, text in picked) + "\n", encoding="utf-8")
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
        env["WBMP_CACHE_DIR"] = str(folder / "cache")
        env["WBMP_COMPILE"] = "1" if args.compile else "0"
        classes: dict[str, int] = {}
        for name, _ in picked:
            classes[name] = classes.get(name, 0) + 1
        result: dict = {
            "benchmark": "batch", "date": today, "items": len(picked), "simulate": not args.no_sim, "cache": False,
            "compile": args.compile, "robot": "talos", "classes": classes,
            "machine": {"cpu": cpu, "cpu_count": os.cpu_count(), "usable_cpus": cores,
                        "shared": "a shared machine: other users' jobs run at the same time (see the load averages)",
                        "threads": {k: os.environ.get(k, "1 (set by wbmp)") for k in
                                    ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")},
                        "python": platform.python_version()},
            "runs": {},
        }
        for name in runs_wanted:
            print(f"{name}: {len(picked)} items ... ({time.strftime('%H:%M:%S')})", file=sys.stderr, flush=True)
            shutil.rmtree(folder / name, ignore_errors=True)
            result["runs"][name] = run_batch(items, folder / name, RUNS[name] + extra, env)
            print(f"  {result['runs'][name]}", file=sys.stderr, flush=True)
            runs = result["runs"]
            if "ray_2" in runs and "local_2" in runs and runs["local_2"]["wall_s"]:
                diff = runs["ray_2"]["wall_s"] - runs["local_2"]["wall_s"]
                result["ray_overhead"] = {"wall_s": round(diff, 3),
                                          "relative": round(diff / runs["local_2"]["wall_s"], 3)}
            if "local_1" in runs and "local_2" in runs and runs["local_2"]["wall_s"]:
                result["speedup_2_workers"] = round(runs["local_1"]["wall_s"] / runs["local_2"]["wall_s"], 3)
            out.write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")  # kept if the benchmark stops
            out.with_suffix(".md").write_text(table(result), encoding="utf-8")
    finally:
        if not args.work_dir:
            shutil.rmtree(folder, ignore_errors=True)
    print(json.dumps(result, indent=2))
    print(table(result))
    print(f"wrote {out} and {out.with_suffix('.md')}", file=sys.stderr)
    return 0 if all(r["exit_code"] in (0, 2, 3, 4, 5) for r in result["runs"].values()) else 1


if __name__ == "__main__":
    sys.exit(main())
