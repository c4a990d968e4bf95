"""Faults and E-stops benchmark (a script, not a test): what each bench motion survives, and stops.

Three studies, each printed as a Markdown table (docs/safety.md holds the results):

* ``--stops N``: the demo sentence ("wave your right hand twice, then squat") on talos, stopped by
  a stop request at N random times (seeded); how many end standing (no fall after the stop), the
  response (stand or damp) and the joint speeds at the end. Target: >= 95 % standing.
* ``--target``: every bench motion (``wbmp bench``'s task classes) with a 20 N s push on the base at
  mid-motion and the floor friction times 0.7: PASS or FAIL of the certificate.
* ``--bisect``: for each bench motion on each ``--robots``, the largest push impulse at mid-motion
  (bisection, ``--steps`` steps between 0 and ``--max-impulse`` N s) whose certificate passes.

The plans come from the motion cache (``wbmp solve`` stores them) or are planned once, without
simulation; each simulation is a new :func:`sim.simulate` with its faults.

Usage::

    .venv/bin/python benchmarks/bench_faults.py --stops 40
    .venv/bin/python benchmarks/bench_faults.py --target --tasks squat,wave,reach,bow
    .venv/bin/python benchmarks/bench_faults.py --bisect --robots talos,g1 --tasks squat,wave --steps 5
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

from sim import simulate  # noqa: E402
from sim.estop import EStopSettings  # noqa: E402
from sim.faults import faults_from_dict  # noqa: E402
from wbmp.bench.tasks import TASKS  # noqa: E402
from wbmp.commands.demo import DEMO_SENTENCE  # noqa: E402
from wbmp.pipeline import SolveRequest, solve  # noqa: E402


def _plan(sentence: str, robot: str):
    """(robot, plan) of a sentence: from the motion cache, or planned once without simulation."""
    result = solve(SolveRequest(instruction=sentence, robot=robot, simulate=False), cache=True)
    robot_model = result.model()  # a cached result loads its robot here
    return robot_model, result.plan


def study_stops(n: int, seed: int, robot_name: str) -> dict:
    """The demo sentence stopped at ``n`` random times."""
    robot, plan = _plan(DEMO_SENTENCE, robot_name)
    rng = np.random.default_rng(seed)
    times = np.sort(rng.uniform(0.0, float(plan.t[-1]), n))
    rows = []
    for i, t in enumerate(times):
        t0 = time.perf_counter()
        ex = simulate(plan, robot, estop=EStopSettings(at=float(t)))
        stop = ex.stops[0]
        rows.append({"t": float(t), "response": stop.response, "stayed_up": stop.stayed_up,
                     "escalated": stop.escalated, "rest_speed": stop.rest_speed,
                     "posture_time": stop.posture_time, "wall_s": time.perf_counter() - t0})
        print(f"  stop {i + 1}/{n} at {t:.3f} s: {stop.response}, {'up' if stop.stayed_up else 'FELL'}"
              f" ({rows[-1]['wall_s']:.1f} s)", flush=True)
    up = sum(r["stayed_up"] for r in rows)
    print(f"\n{DEMO_SENTENCE!r} on {robot_name}, {n} stop requests (seed {seed}): {up}/{n} standing "
          f"({100 * up / n:.0f} %), {sum(r['response'] == 'stand' for r in rows)} stand, "
          f"{sum(r['response'] == 'damp' for r in rows)} damp; largest joint speed at the end "
          f"{max(r['rest_speed'] for r in rows):.3f} rad/s")
    return {"sentence": DEMO_SENTENCE, "robot": robot_name, "seed": seed, "rows": rows, "standing": up}


def _survives(robot, plan, impulse: float, friction: float = 1.0) -> tuple[bool, str]:
    faults = {"friction_scale": friction}
    if impulse > 0:
        faults["pushes"] = [{"t": 0.5 * float(plan.t[-1]), "impulse": impulse, "direction": [1, 0, 0]}]
    ex = simulate(plan, robot, faults=faults_from_dict(faults))
    return ex.ok, ex.certificate.reason


def study_target(tasks: list[str], robot_name: str) -> dict:
    """Each bench motion with 20 N s at mid-motion and friction x 0.7."""
    rows = []
    print(f"\n| motion ({robot_name}) | 20 N s at mid-motion, friction x 0.7 | reason |\n| --- | --- | --- |")
    for task in tasks:
        robot, plan = _plan(TASKS[task], robot_name)
        ok, reason = _survives(robot, plan, 20.0, 0.7)
        rows.append({"task": task, "ok": ok, "reason": reason})
        print(f"| {task} | {'PASS' if ok else 'FAIL'} | {reason[:90]} |", flush=True)
    return {"robot": robot_name, "rows": rows}


def study_bisect(tasks: list[str], robots: list[str], steps: int, top: float) -> dict:
    """The largest push at mid-motion each motion survives."""
    rows = []
    print("\n| motion | robot | largest push survived [N s] | first failure [N s] | its reason |\n"
          "| --- | --- | --- | --- | --- |")
    for robot_name in robots:
        for task in tasks:
            robot, plan = _plan(TASKS[task], robot_name)
            ok0, why0 = _survives(robot, plan, 0.0)
            if not ok0:
                rows.append({"task": task, "robot": robot_name, "survived": None, "failed": 0.0, "reason": why0})
                print(f"| {task} | {robot_name} | (fails without a push) | 0 | {why0[:80]} |", flush=True)
                continue
            lo, hi, why = 0.0, top, ""
            for _ in range(steps):
                mid = 0.5 * (lo + hi)
                ok, reason = _survives(robot, plan, mid)
                if ok:
                    lo = mid
                else:
                    hi, why = mid, reason
            rows.append({"task": task, "robot": robot_name, "survived": lo, "failed": hi, "reason": why})
            print(f"| {task} | {robot_name} | {lo:.1f} | {hi:.1f} | {why[:80]} |", flush=True)
    return {"rows": rows}


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--stops", type=int, default=0, metavar="N", help="stop the demo sentence at N random times")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--target", action="store_true", help="20 N s at mid-motion and friction x 0.7 on every motion")
    p.add_argument("--bisect", action="store_true", help="the largest push each motion survives")
    p.add_argument("--robots", default="talos", help="comma-separated robots (default talos)")
    p.add_argument("--tasks", default=",".join(TASKS), help=f"comma-separated task classes (default {','.join(TASKS)})")
    p.add_argument("--steps", type=int, default=5, help="bisection steps (default 5)")
    p.add_argument("--max-impulse", type=float, default=80.0, help="bisection upper bound [N s] (default 80)")
    p.add_argument("--json", metavar="FILE", help="write the results here")
    args = p.parse_args()
    tasks = [t for t in args.tasks.split(",") if t]
    unknown = [t for t in tasks if t not in TASKS]
    if unknown:
        p.error(f"unknown task {unknown[0]!r}; the tasks are {', '.join(TASKS)}")
    robots = [r for r in args.robots.split(",") if r]
    out: dict = {}
    if args.stops:
        out["stops"] = study_stops(args.stops, args.seed, robots[0])
    if args.target:
        out["target"] = study_target(tasks, robots[0])
    if args.bisect:
        out["bisect"] = study_bisect(tasks, robots, args.steps, args.max_impulse)
    if not out:
        p.error("choose a study: --stops N, --target or --bisect")
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
