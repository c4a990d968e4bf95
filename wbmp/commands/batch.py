"""``wbmp batch``: a file of sentences or specs -> a motion library folder (docs/batch.md).

Exit codes: 0 every job succeeded (or was done before); 1 a job crashed (its worker died, or a
bug; recorded in the index); else the code ``wbmp solve`` gives for the first failed job in the
file's order (2 not understood, 3 invalid spec or robot, 4 infeasible, 5 simulation check
failed). Refused input (the file, a line of it, --robots, --workers, --out-dir) is one line
before any work, exit 2 (3 for an unknown robot). Ctrl-C 130, SIGTERM 143, with the index and
summary written.
"""

from __future__ import annotations

import argparse
import json
import os
import sys


def _workers(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--workers {text!r}: give a whole number of workers (1 or more)") from None
    if n < 1 or n > 1024:
        raise argparse.ArgumentTypeError(f"--workers {text!r}: give 1 to 1024 workers")
    return n


def default_workers() -> int:
    """One worker per CPU this process may use (at least 1)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "batch", help="plan many motions (a file of sentences, specs or JSONL) into a motion library folder",
        description="Plan every item of FILE on each robot (as `wbmp solve` does: parse, plan, simulate "
                    "unless --no-sim) and write a motion library into --out-dir: one motion file per item "
                    "and robot (<id>__<robot>.npz), index.jsonl (one record per item and robot: status, "
                    "exit code, certificate, timings, the failure message, the file and its sha256) and "
                    "summary.md. Rerunning the same command skips what is done (verified by hash). "
                    "FILE: one sentence per line, or a spec file path (*.json), or JSONL lines "
                    '{"instruction": ..., "robot": ..., "scene": ..., "id": ...} / {"spec": path-or-object, ...}; '
                    "blank lines and # comments are skipped. See docs/batch.md.",
        epilog="exit codes: 0 every item succeeded; 1 an item crashed (recorded); else the code of the first "
               "failed item in FILE's order, as `wbmp solve` gives it (2 not understood, 3 invalid spec, "
               "4 infeasible, 5 simulation check failed); bad input is one line before any work (2, or 3 "
               "for an unknown robot).  examples: wbmp batch sentences.txt --out-dir library --robots talos,g1  |  "
               "wbmp batch items.jsonl --out-dir lib --no-sim --workers 2  |  wbmp batch big.txt --out-dir lib --ray",
    )
    p.add_argument("file", metavar="FILE", help="the items: sentences, spec files or JSONL, one per line; or a folder of .bvh "
                        "motion-capture clips, each retargeted (docs/retarget.md)")
    p.add_argument("--out-dir", required=True, metavar="DIR",
                   help="the motion library folder (created if missing; its parent must exist)")
    p.add_argument("--robots", default=None, metavar="NAMES",
                   help="plan every item on each of these robots, e.g. talos,g1 (default: the item's robot, "
                        "the spec's, or talos); a JSONL line's own robot wins")
    p.add_argument("--workers", type=_workers, default=None, metavar="N",
                   help=f"parallel workers (default: one per CPU, here {default_workers()}); with --ray, the "
                        "number of tasks in flight (and the CPUs of a local Ray instance)")
    p.add_argument("--ray", nargs="?", const="", default=None, metavar="ADDRESS",
                   help="run on Ray: without ADDRESS a local instance is started on 127.0.0.1 and stopped; "
                        "with one (host:port, ray://host:port or auto) the cluster must answer within "
                        "5 s and have wbmp installed")
    p.add_argument("--no-sim", action="store_true", help="skip the MuJoCo simulation check")
    p.add_argument("--no-cache", action="store_true",
                   help="neither read nor write the motion cache (by default an item planned before, in any "
                        "folder, is answered from $WBMP_CACHE_DIR/motions, as `wbmp solve` does)")
    p.add_argument("--force", action="store_true",
                   help="run every item again, even those done before (from the motion cache when it holds "
                        "the item; with --no-cache, planned afresh)")
    p.add_argument("--retry-failed", action="store_true",
                   help="plan again the items that failed before (by default a failure the input decides, "
                        "exit 2 to 5, is kept; a crash is always retried)")
    p.add_argument("--quiet", action="store_true", help="no progress display")
    p.add_argument("--json", action="store_true", help="print the outcome as JSON (progress as JSON lines)")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from viz import make_progress
    from wbmp.batch.run import prepare, run_batch

    if args.ray:  # the form first (one line, exit 2); prepare() checks that it answers
        from wbmp.batch.raynet import parse_address

        parse_address(args.ray)
    plan = prepare(file=args.file, out_dir=args.out_dir, robots=args.robots,
                   workers=args.workers or default_workers(), simulate=not args.no_sim, force=args.force,
                   retry_failed=args.retry_failed, ray=args.ray is not None, ray_address=args.ray or None,
                   cache=not args.no_cache)
    progress = make_progress(quiet=args.quiet, json_lines=args.json)
    outcome = run_batch(plan, progress)
    c = outcome.counts
    if args.json:
        print(json.dumps({**c, "exit_code": outcome.exit_code, "wall_time": round(outcome.wall_time, 3),
                          "index": str(outcome.index_path), "summary": str(outcome.summary_path)}))
        return outcome.exit_code
    robots = len({r["robot"] for r in outcome.records}) or 1
    print(f"batch: {c['jobs']} jobs ({c['items']} items x {robots} robot{'s' if robots > 1 else ''}): "
          f"{c['ok']} ok, {c['failed']} failed; {c['ran']} planned now, {c['skipped']} done before "
          f"({outcome.wall_time:.1f} s)")
    for rec in outcome.records:
        if rec["status"] != "ok":
            print(f"failed: {rec['id']} on {rec['robot']} (line {rec['line']}), exit {rec['exit_code']}: "
                  f"{rec['message']}")
    print(f"wrote {outcome.index_path} and {outcome.summary_path}")
    sys.stdout.flush()
    return outcome.exit_code
