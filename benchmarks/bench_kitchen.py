"""The kitchen sentence's plan, step by step in CPU time: where loco-manipulation's first plan goes.

Run: ``.venv/bin/python benchmarks/bench_kitchen.py [--sentence 走过去拿起那个杯子]
[--scene examples/scenes/kitchen.json] [--json out.json] [--ipopt NAME=VALUE ...]``; the stairs climb (issue 33):
``--sentence "walk up the stairs" --scene examples/scenes/stairs.json``.

Builds the spec as ``wbmp solve`` does (parse, grounding, scene), then ``planner.formulate`` and
``planner.solve`` with the solver in memory (no gcc, no disk cache, no solution library: what a
new task structure pays the first time), and prints the wall and CPU time (``time.process_time``)
at each step the solve reports (builds, solves, collision rounds, re-linearizations), the
iterations, the sizes, the stage types of the first and the last layout solved (a build's
cost grows with them, not with the knots) and the sha256 of the plan's ``q`` (plans before/after a change compare by
it). On a shared machine compare the CPU column: the load slows wall time, not CPU time
(docs/performance.md "The kitchen sentence, profiled again"). ``--ipopt mu_min=1e-8`` (repeatable)
hands IPOPT an option after the planner's own (how session 18 tried its options: docs/performance.md
"The kitchen sentence's IPOPT iterations"). A report, not a test.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sentence", default="走过去拿起那个杯子")
    ap.add_argument("--scene", default=str(ROOT / "examples" / "scenes" / "kitchen.json"))
    ap.add_argument("--json", default=None, metavar="FILE", help="also write the steps here")
    ap.add_argument("--ipopt", action="append", default=[], metavar="NAME=VALUE",
                    help="an IPOPT option after the planner's own (repeatable), e.g. mu_min=1e-8")
    args = ap.parse_args(argv)
    try:
        extra = tuple(_option(text) for text in args.ipopt)
    except ValueError as e:
        print(f"bench_kitchen: {e}", file=sys.stderr)
        return 2

    import numpy as np

    from planner import CacheSettings, PlannerSettings, SolverSettings, formulate, solve
    from planner.trajopt.terms import stage_groups
    from wbmp.pipeline import SolveRequest, build_spec

    w0, c0 = time.perf_counter(), time.process_time()
    steps: list[dict] = []

    def step(what: str) -> None:
        steps.append({"what": what, "wall_s": time.perf_counter() - w0, "cpu_s": time.process_time() - c0})
        print(f"{steps[-1]['wall_s']:8.2f} s wall {steps[-1]['cpu_s']:8.2f} s CPU  {what}", flush=True)

    print(f"load average {os.getloadavg()[0]:.1f}", flush=True)
    robot, spec, _ = build_spec(SolveRequest(instruction=args.sentence, robot=None, scene_path=args.scene,
                                             simulate=False))
    step(f"spec ({spec.horizon:.1f} s of motion for {robot.name})")
    problem = formulate(spec, robot, PlannerSettings(cache=CacheSettings(compile=False),
                                                     solver=SolverSettings(ipopt_extra=extra)))
    step("formulated")
    solved = solve(problem, progress=step)
    step("solved")
    stats = solved.stats
    digest = hashlib.sha256(np.ascontiguousarray(solved.plan.q).tobytes()).hexdigest()[:16]
    summary = {"ok": solved.plan.ok, "iterations": stats.iterations, "n_variables": stats.n_variables,
               "n_constraints": stats.n_constraints, "stage_types": [len(stage_groups(problem.layout)),
                                                                     len(stage_groups(solved.problem.layout))],
               "q_sha256": digest, "load_after": os.getloadavg()[0]}
    print(json.dumps(summary), flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps({"steps": steps, **summary}, indent=1))
    return 0


def _option(text: str) -> tuple[str, int | float | str]:
    """``NAME=VALUE`` as an IPOPT option (the value an int, else a float, else the text)."""
    name, sep, value = text.partition("=")
    if not sep or not name:
        raise ValueError(f"--ipopt takes NAME=VALUE (e.g. mu_min=1e-8), got {text!r}")
    for kind in (int, float):
        try:
            return name, kind(value)
        except ValueError:
            pass
    return name, value


if __name__ == "__main__":
    sys.exit(main())
