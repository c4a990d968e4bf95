"""Faults and E-stops benchmark (a script, not a test): what each bench motion survives, and stops.

Three studies, each printed as a Markdown table (docs/safety.md holds the results):

* ``--stops N``: the demo sentence ("wave your right hand twice, then squat") on talos, stopped by
  a stop request at N random times (seeded); how many end standing (no fall after the stop), the
  response (stand or damp) and the joint speeds at the end. Target: >= 95 % standing.
* ``--target``: every bench motion (``wbmp bench``'s task classes) with a 20 N s push on the base at
  mid-motion and the floor friction times 0.7: PASS or FAIL of the certificate.
* ``--bisect``: for each bench motion on each ``--robots`` and each fault kind of ``--kinds``
  (:data:`KINDS`: a push at mid-motion forward, backward, left or right, 0-80 N s; the floor's
  friction, x 1 down to x 0.05; the base's mass, x 1 up to x 5; a control delay, 0-50 ticks; joint
  angle noise, 0-0.1 rad: the faults file's own limits, except the friction's 0.05 floor), the worst fault whose certificate passes: the range's worst end first,
  then ``--steps`` halvings (the delay: down to one tick).

The plans come from the motion cache (``wbmp solve`` stores them) or are planned once, without
simulation; each simulation is a new :func:`sim.simulate` with its faults.

Usage::

    .venv/bin/python benchmarks/bench_faults.py --stops 40
    .venv/bin/python benchmarks/bench_faults.py --target --tasks squat,wave,reach,bow
    .venv/bin/python benchmarks/bench_faults.py --bisect --robots talos,g1 --tasks squat,wave \
        --kinds push-forward,friction --steps 4 --log rows.jsonl
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

from sim import simulate  # noqa: E402
from sim.estop import EStopSettings  # noqa: E402
from sim.faults import MASS_RANGE, MAX_DELAY_TICKS, MAX_JOINT_NOISE, faults_from_dict  # noqa: E402
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


def _run(robot, plan, faults: dict) -> tuple[bool, str]:
    """(the certificate passed, its reason) of one simulation with ``faults`` (a faults file's dict)."""
    ex = simulate(plan, robot, faults=faults_from_dict(faults) if faults else None)
    return ex.ok, ex.certificate.reason if ex.certificate is not None else ""


def study_target(tasks: list[str], robot_name: str) -> dict:
    """Each bench motion with 20 N s at mid-motion and friction x 0.7: the certificate, the worst
    sole slip and CoM tracking error, the wall time."""
    rows = []
    print(f"\n| motion ({robot_name}) | 20 N s at mid-motion, friction x 0.7 | slip [mm] | CoM error [mm] | wall [s] | reason |"
          "\n| --- | --- | --- | --- | --- | --- |")
    for task in tasks:
        robot, plan = _plan(TASKS[task], robot_name)
        t0 = time.perf_counter()
        ex = simulate(plan, robot, faults=faults_from_dict({
            "friction_scale": 0.7,
            "pushes": [{"t": 0.5 * float(plan.t[-1]), "impulse": 20.0, "direction": [1, 0, 0]}]}))
        wall = time.perf_counter() - t0
        cert = ex.certificate
        assert cert is not None
        slip = max((c.value for c in cert.checks if c.name.endswith(" slip")), default=0.0)
        com = max((c.value for c in cert.checks if c.name == "CoM tracking error"), default=0.0)
        rows.append({"task": task, "ok": ex.ok, "reason": cert.reason, "slip": slip, "com_error": com, "wall_s": wall})
        print(f"| {task} | {'PASS' if ex.ok else 'FAIL'} | {1000 * slip:.1f} | {1000 * com:.1f} | {wall:.0f} | {cert.reason[:90]} |",
              flush=True)
    return {"robot": robot_name, "rows": rows}


@dataclass(frozen=True)
class Kind:
    """A fault kind the bisection searches: its faults at a severity, and the severity's range.

    ``severity`` runs from ``start`` (no fault, or the mildest) to ``stop`` (the worst tried); a
    motion that survives a severity is assumed to survive every milder one.
    """

    name: str
    unit: str
    start: float
    stop: float
    faults: Callable[[float, float], dict]  # (severity, mid-motion time) -> the faults file
    integer: bool = False
    fmt: str = "{:.1f}"


def _push(direction: tuple[float, float, float]) -> Callable[[float, float], dict]:
    def faults(impulse: float, t_mid: float) -> dict:
        return {"pushes": [{"t": t_mid, "impulse": impulse, "direction": list(direction)}]} if impulse > 0 else {}
    return faults


#: The fault kinds of ``--bisect`` (``--kinds``); push directions in the world, which is the robot's
#: frame at the start of every bench motion (it starts facing +x).
KINDS: dict[str, Kind] = {k.name: k for k in (
    Kind("push-forward", "N s", 0.0, 80.0, _push((1.0, 0.0, 0.0))),
    Kind("push-backward", "N s", 0.0, 80.0, _push((-1.0, 0.0, 0.0))),
    Kind("push-left", "N s", 0.0, 80.0, _push((0.0, 1.0, 0.0))),
    Kind("push-right", "N s", 0.0, 80.0, _push((0.0, -1.0, 0.0))),
    Kind("friction", "x mu", 1.0, 0.05, lambda f, _t: {"friction_scale": f}, fmt="{:.2f}"),
    Kind("base-mass", "x mass", 1.0, MASS_RANGE[1], lambda m, _t: {"mass_scale": {"base": m}}, fmt="{:.2f}"),
    Kind("delay", "ticks", 0.0, float(MAX_DELAY_TICKS), lambda d, _t: {"delay_ticks": int(d)}, integer=True, fmt="{:.0f}"),
    Kind("joint-noise", "rad", 0.0, MAX_JOINT_NOISE, lambda s, _t: {"joint_noise": s}, fmt="{:.4f}"),
)}


def _bisect(kind: Kind, steps: int, passes: Callable[[float], tuple[bool, str]]) -> tuple[float, float | None, str]:
    """(the worst severity that passed, the mildest that failed or None, its reason), in ``steps``
    halvings of [start, stop] (integer kinds: until the two are neighbours)."""
    ok, why = passes(kind.stop)
    if ok:
        return kind.stop, None, ""
    good, bad = kind.start, kind.stop
    for _ in range(steps if not kind.integer else 64):
        if kind.integer and abs(bad - good) <= 1:
            break
        mid = 0.5 * (good + bad)
        if kind.integer:
            mid = float(round(mid))
        ok, reason = passes(mid)
        if ok:
            good = mid
        else:
            bad, why = mid, reason
    return good, bad, why


def _run_kind(robot, plan, kind: Kind, t_mid: float, severity: float) -> tuple[bool, str]:
    return _run(robot, plan, kind.faults(severity, t_mid))


def study_bisect(tasks: list[str], robots: list[str], kinds: list[str], steps: int, log: Path | None) -> dict:
    """For each motion, robot and fault kind, the worst fault whose certificate passes (the worst
    of the range is tried first: a motion that survives it needs no bisection)."""
    rows: list[dict] = []
    print("\n| motion | robot | fault | survives | fails | unit | its reason |\n| --- | --- | --- | --- | --- | --- | --- |")
    for robot_name in robots:
        for task in tasks:
            robot, plan = _plan(TASKS[task], robot_name)
            t_mid = 0.5 * float(plan.t[-1])
            ok0, why0 = _run(robot, plan, {})
            if not ok0:
                rows.append({"task": task, "robot": robot_name, "kind": None, "survived": None, "failed": None,
                             "reason": why0})
                print(f"| {task} | {robot_name} | (fails without a fault) | | | | {why0[:80]} |", flush=True)
                continue
            for name in kinds:
                kind = KINDS[name]
                t0 = time.perf_counter()
                good, bad, why = _bisect(kind, steps, partial(_run_kind, robot, plan, kind, t_mid))
                row = {"task": task, "robot": robot_name, "kind": name, "unit": kind.unit, "survived": good,
                       "failed": bad, "reason": why, "wall_s": time.perf_counter() - t0}
                rows.append(row)
                shown = kind.fmt.format(good) + ("" if bad is not None else " (the range's end)")
                print(f"| {task} | {robot_name} | {name} | {shown} | "
                      f"{'-' if bad is None else kind.fmt.format(bad)} | {kind.unit} | {why[:80]} |", flush=True)
                if log is not None:
                    with log.open("a") as fh:
                        fh.write(json.dumps(row) + "\n")
    return {"rows": rows}


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--stops", type=int, default=0, metavar="N", help="stop the demo sentence at N random times")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--target", action="store_true", help="20 N s at mid-motion and friction x 0.7 on every motion")
    p.add_argument("--bisect", action="store_true", help="the largest push each motion survives")
    p.add_argument("--robots", default="talos", help="comma-separated robots (default talos)")
    p.add_argument("--tasks", default=",".join(TASKS), help=f"comma-separated task classes (default {','.join(TASKS)})")
    p.add_argument("--kinds", default=",".join(KINDS), help=f"comma-separated fault kinds of --bisect (default {','.join(KINDS)})")
    p.add_argument("--steps", type=int, default=4, help="bisection steps (default 4)")
    p.add_argument("--log", metavar="FILE", help="append each --bisect row to this JSON-lines file as it is found")
    p.add_argument("--json", metavar="FILE", help="write the results here")
    args = p.parse_args()
    tasks = [t for t in args.tasks.split(",") if t]
    unknown = [t for t in tasks if t not in TASKS]
    if unknown:
        p.error(f"unknown task {unknown[0]!r}; the tasks are {', '.join(TASKS)}")
    robots = [r for r in args.robots.split(",") if r]
    kinds = [k for k in args.kinds.split(",") if k]
    bad_kinds = [k for k in kinds if k not in KINDS]
    if bad_kinds:
        p.error(f"unknown fault kind {bad_kinds[0]!r}; the kinds are {', '.join(KINDS)}")
    out: dict = {}
    if args.stops:
        out["stops"] = study_stops(args.stops, args.seed, robots[0])
    if args.target:
        out["target"] = study_target(tasks, robots[0])
    if args.bisect:
        out["bisect"] = study_bisect(tasks, robots, kinds, args.steps, Path(args.log) if args.log else None)
    if not out:
        p.error("choose a study: --stops N, --target or --bisect")
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
