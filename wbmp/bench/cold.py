"""The cached-cold child process of ``wbmp bench``: ``python -m wbmp.bench.cold PAYLOAD`` plans
once in a new process, loading the compiled solver from the cache on disk, and prints the stats as
one JSON line (:func:`wbmp.bench.run.bench_task` starts it and reads that line)."""

from __future__ import annotations

import json
import sys

from wbmp.bench.tasks import planner_settings, spec_for


def child_main(payload: str) -> int:
    """Entry of the cached-cold child process: plan once, print the stats as one JSON line."""
    args = json.loads(payload)
    from planner import plan as plan_motion
    from robots import load_robot

    robot = load_robot(args["robot"])
    _, spec = spec_for(args["sentence"], robot, args.get("dt"))
    plan = plan_motion(spec, robot, settings=planner_settings(args["cache_dir"], args.get("max_iterations")), throw=False)
    s = plan.stats
    print(json.dumps({"build_time": s.build_time, "solve_time": s.solve_time, "cache": s.cache,
                      "iterations": s.iterations, "ok": bool(plan.ok)}))
    return 0



if __name__ == "__main__":
    sys.exit(child_main(sys.argv[1]))
