"""What collision avoidance costs: solve time with and without the self-collision rows, on every
task of ``wbmp bench`` (wbmp/bench/tasks.py), Talos by default; then with scene objects.

Run: ``.venv/bin/python benchmarks/bench_collision.py [--robot talos] [--repeat 3] [--tasks squat,reach]
[--scenes far,table] [--scene-tasks reach] [--json out.json]``

For each task the spec is planned warm (solver already in memory: the first plan of each variant
builds it and is not timed) ``--repeat`` times with ``self_collision`` off and on, interleaved (off,
on, off, on, ...: a change in the machine's load hits both alike). The report gives the median
IPOPT solve time and the median ``plan()`` time (screening, re-solves and the report included) of
each variant, their ratio, the median CPU time of ``plan()`` (``time.process_time``: on a shared
machine the load slows wall time more than CPU time) and its ratio, the IPOPT iterations, the
collision rows the plan carried, whether a pair is *active* (the
closest pair ends within 0.5 mm of the margin: its rows bind) and the closest pair, and the load
average before and after. Target (issue 15): at most 20 % more where no pair is active.

Scenes (``--scenes``): each ``--scene-tasks`` task is planned warm without a scene, then with
``far`` (examples/scenes/table.json's table moved 5 m away: screening only, no row, the same
solver; target: no extra cost) and ``table`` (examples/scenes/table.json as it is); the report gives
the median plan time, its ratio to the scene-free plan, and the scene rows. This is a report, not a
test: timings depend on the machine and on its load.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def measure(task: str, sentence: str, robot, repeat: int, cache_dir: str) -> dict:
    from planner import CacheSettings, CollisionSettings, PlannerSettings, plan
    from wbmp.bench.tasks import spec_for

    _, spec = spec_for(sentence, robot, None)
    row: dict = {"task": task, "sentence": sentence}
    variants = {label: PlannerSettings(cache=CacheSettings(cache_dir=cache_dir, compile=False, solution_library="off"),
                                       collision=CollisionSettings(self_collision=on))
                for label, on in (("off", False), ("on", True))}
    results = {label: plan(spec, robot, settings=s, throw=False)  # builds the solver(s): not timed
               for label, s in variants.items()}
    solves: dict[str, list[float]] = {label: [] for label in variants}
    totals: dict[str, list[float]] = {label: [] for label in variants}
    cpus: dict[str, list[float]] = {label: [] for label in variants}
    for _ in range(repeat):
        for label, settings in variants.items():  # interleaved
            t0, c0 = time.perf_counter(), time.process_time()
            results[label] = plan(spec, robot, settings=settings, throw=False)
            totals[label].append(time.perf_counter() - t0)
            cpus[label].append(time.process_time() - c0)
            solves[label].append(results[label].stats.solve_time)
    for label, result in results.items():
        row[f"solve_{label}_s"] = statistics.median(solves[label])
        row[f"plan_{label}_s"] = statistics.median(totals[label])
        row[f"cpu_{label}_s"] = statistics.median(cpus[label])
        row[f"iterations_{label}"] = result.stats.iterations
        row[f"ok_{label}"] = bool(result.ok)
        row[f"n_constraints_{label}"] = result.stats.n_constraints
    closest = closest_pair(robot, results["on"])
    row["closest"] = f"{closest[1][0]} / {closest[1][1]} {closest[0] * 1000:.1f} mm"
    row["active"] = bool(closest[0] < variants["on"].collision.margin + ACTIVE_TOLERANCE)
    row["solve_ratio"] = row["solve_on_s"] / max(row["solve_off_s"], 1e-9)
    row["plan_ratio"] = row["plan_on_s"] / max(row["plan_off_s"], 1e-9)
    row["cpu_ratio"] = row["cpu_on_s"] / max(row["cpu_off_s"], 1e-9)
    row["collision_rows"] = row["n_constraints_on"] - row["n_constraints_off"]
    return row


ACTIVE_TOLERANCE = 5e-4  # [m] a pair this close to the margin at the end of a solve is held there by its rows


def closest_pair(robot, result) -> tuple[float, tuple[str, str]]:
    """(sphere-set distance [m], link pair) of the closest checked pair over a planned motion."""
    import numpy as np

    from planner.trajopt.collision import pair_distances, sphere_sets

    sets = sphere_sets(robot)
    d = pair_distances(robot, sets, np.asarray(result.q)).min(axis=0)
    pi = int(np.argmin(d))
    return float(d[pi]), sets.pair_names[pi]


def _scene(kind: str):
    import dataclasses

    from tasks.scene import load_scene

    table = load_scene(ROOT / "examples" / "scenes" / "table.json")
    if kind == "table":
        return table
    if kind == "far":
        obj = table.objects[0]
        return dataclasses.replace(table,
                                   objects=(dataclasses.replace(obj, position=(5.0, 0.0, obj.position[2])),))
    raise SystemExit(f"bench_collision.py: error: unknown scene {kind!r}; the scenes are far, table")


def measure_scenes(task: str, sentence: str, robot, scenes: list[str], repeat: int, cache_dir: str) -> dict:
    """Median plan time of one task without a scene and with each of ``scenes`` (warm solvers)."""
    import dataclasses

    from planner import CacheSettings, PlannerSettings, plan
    from wbmp.bench.tasks import spec_for

    _, spec = spec_for(sentence, robot, None)
    settings = PlannerSettings(cache=CacheSettings(cache_dir=cache_dir, compile=False, solution_library="off"))
    row: dict = {"task": task, "sentence": sentence}
    for kind in ["none", *scenes]:
        variant = spec if kind == "none" else dataclasses.replace(spec, scene=_scene(kind))
        result = plan(variant, robot, settings=settings, throw=False)  # builds the solver(s): not timed
        totals = []
        for _ in range(repeat):
            t0 = time.perf_counter()
            result = plan(variant, robot, settings=settings, throw=False)
            totals.append(time.perf_counter() - t0)
        row[f"plan_{kind}_s"] = statistics.median(totals)
        row[f"ok_{kind}"] = bool(result.ok)
        row[f"n_constraints_{kind}"] = result.stats.n_constraints
        check = next((c for c in result.checks if c.kind.value == "scene_collision"), None)
        row[f"closest_{kind}"] = check.name if check else ""
    for kind in scenes:
        row[f"ratio_{kind}"] = row[f"plan_{kind}_s"] / max(row["plan_none_s"], 1e-9)
        row[f"rows_{kind}"] = row[f"n_constraints_{kind}"] - row["n_constraints_none"]
    return row


def main(argv: list[str] | None = None) -> int:
    from robots import load_robot
    from wbmp.bench.tasks import TASKS

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robot", default="talos")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--tasks", default=",".join(TASKS), help="comma-separated task classes of wbmp bench")
    ap.add_argument("--scenes", default="far,table", help="scenes to plan with: far, table (empty: none)")
    ap.add_argument("--scene-tasks", default="reach", help="comma-separated tasks planned with the scenes")
    ap.add_argument("--json", metavar="FILE")
    args = ap.parse_args(argv)
    robot = load_robot(args.robot)
    load0 = os.getloadavg()[0]
    names = [t.strip() for t in args.tasks.split(",") if t.strip()]
    unknown = [t for t in names if t not in TASKS]
    if unknown:
        ap.error(f"unknown task {unknown[0]!r}; the tasks are {', '.join(TASKS)}")
    rows = []
    with tempfile.TemporaryDirectory(prefix="wbmp-bench-collision-") as cache_dir:
        print(f"load average {load0:.2f}; {args.repeat} interleaved repeats; {args.robot}")
        print(f"{'task':8s} {'solve off':>10s} {'solve on':>10s} {'ratio':>6s} {'plan off':>9s} {'plan on':>9s} "
              f"{'ratio':>6s} {'cpu off':>8s} {'cpu on':>8s} {'ratio':>6s} {'iter':>7s} {'rows':>6s} {'active':>6s}  closest pair")
        for task in names:
            row = measure(task, TASKS[task], robot, args.repeat, cache_dir)
            rows.append(row)
            print(f"{task:8s} {row['solve_off_s']:10.3f} {row['solve_on_s']:10.3f} {row['solve_ratio']:6.2f} "
                  f"{row['plan_off_s']:9.3f} {row['plan_on_s']:9.3f} {row['plan_ratio']:6.2f} "
                  f"{row['cpu_off_s']:8.3f} {row['cpu_on_s']:8.3f} {row['cpu_ratio']:6.2f} "
                  f"{row['iterations_off']:3d}/{row['iterations_on']:<3d} "
                  f"{row['collision_rows']:6d} {'yes' if row['active'] else 'no':>6s}  {row['closest']}", flush=True)
    ratios = [r["solve_ratio"] for r in rows if not r["active"]]
    cpu_ratios = [r["cpu_ratio"] for r in rows if not r["active"]]
    if ratios:
        print(f"where no pair is active: median solve-time ratio {statistics.median(ratios):.2f}, largest "
              f"{max(ratios):.2f}; plan CPU ratio median {statistics.median(cpu_ratios):.2f}, largest "
              f"{max(cpu_ratios):.2f} (target <= 1.20); load average {load0:.2f} -> {os.getloadavg()[0]:.2f}")
    scenes = [s.strip() for s in args.scenes.split(",") if s.strip()]
    scene_tasks = [t.strip() for t in args.scene_tasks.split(",") if t.strip()]
    scene_rows = []
    if scenes:
        unknown = [t for t in scene_tasks if t not in TASKS]
        if unknown:
            ap.error(f"unknown task {unknown[0]!r}; the tasks are {', '.join(TASKS)}")
        with tempfile.TemporaryDirectory(prefix="wbmp-bench-scene-") as cache_dir:
            print(f"\n{'task':8s} {'scene':6s} {'plan':>8s} {'ratio':>6s} {'rows':>6s}  closest")
            for task in scene_tasks:
                row = measure_scenes(task, TASKS[task], robot, scenes, args.repeat, cache_dir)
                scene_rows.append(row)
                print(f"{task:8s} {'none':6s} {row['plan_none_s']:8.3f} {1.0:6.2f} {0:6d}", flush=True)
                for kind in scenes:
                    print(f"{task:8s} {kind:6s} {row[f'plan_{kind}_s']:8.3f} {row[f'ratio_{kind}']:6.2f} "
                          f"{row[f'rows_{kind}']:6d}  {row[f'closest_{kind}']}", flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps({"robot": args.robot, "repeat": args.repeat, "load": load0,
                                               "load_end": os.getloadavg()[0], "tasks": rows,
                                               "scenes": scene_rows}, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
