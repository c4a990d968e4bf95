"""``wbmp bench``: time every stage of the pipeline on each task class, optionally beside peers.

This module is the command line only (options, help, exit codes in the epilog); the harness is the
package :mod:`wbmp.bench`, whose docstring tells what is measured and how it exits.
"""

from __future__ import annotations

import argparse

from wbmp.bench.options import MAX_DT, MAX_ITERATIONS, MAX_REPEATS, MIN_DT
from wbmp.bench.tasks import QUICK_TASKS, TASKS


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "bench", help="time parse, spec, NLP build, solve, controller and simulation per task class",
        description="Benchmark every stage of the pipeline on each task class (medians over repeats),\n"
                    "optionally beside Crocoddyl and TSID (--peers, after `make bench-peers`).\n"
                    "Timings on a shared machine are noisy: the load average is recorded.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n"
               "  wbmp bench --quick\n"
               "  wbmp bench --json out.json --peers\n"
               "  wbmp bench --tasks squat --repeats 1 --no-sim --no-e2e --json smoke.json\n"
               "exit codes:\n"
               "  0      every task class that ran passed (n/a (not implemented) ones do not count)\n"
               "  3/4/5  a task class failed: the code of the first one, as `wbmp solve` gives it\n"
               "         (3 spec, 4 plan, 5 simulation check); the report is printed and\n"
               "         --json/--markdown are written anyway\n"
               "  2      a bad option (checked before any work); 130/143 Ctrl-C/SIGTERM",
    )
    p.add_argument("--quick", action="store_true",
                   help=f"every task class ({', '.join(QUICK_TASKS)}), 1 repeat, the user's solver cache, one "
                        "simulation, no first-ever builds, end-to-end runs or scaling study (< 2 min with the "
                        "solvers cached)")
    p.add_argument("--robot", default="talos", help="robot name (default: talos)")
    p.add_argument("--json", metavar="FILE", default=None, help="also write the results as JSON here")
    p.add_argument("--peers", action="store_true",
                   help="add Crocoddyl/TSID figures (benchmarks/results/peers/*.json) and ratios ours/peer")
    p.add_argument("--peers-dir", default=None, help="folder of the peer results (default: benchmarks/results/peers)")
    p.add_argument("--tasks", default=None, help=f"comma-separated task classes (default: all: {','.join(TASKS)})")
    p.add_argument("--repeats", type=int, default=None,
                   help=f"repeats per timing, 1 to {MAX_REPEATS} (default 3, quick 1)")
    p.add_argument("--dt", type=float, default=None,
                   help=f"override the knot spacing of every spec [s], {MIN_DT:g} to {MAX_DT:g} (smoke tests)")
    p.add_argument("--max-iterations", type=int, default=None, metavar="N",
                   help=f"IPOPT iteration limit of every plan, 1 to {MAX_ITERATIONS} (default: the planner's); "
                        "1 makes every plan fail (tests the failure path and the exit code)")
    p.add_argument("--no-compile", action="store_true",
                   help="build solvers in memory (CasADi SX) instead of compiling them with gcc (smoke tests)")
    p.add_argument("--no-sim", action="store_true", help="skip the controller/simulation stage")
    p.add_argument("--no-e2e", action="store_true", help="skip the end-to-end `wbmp solve` runs")
    p.add_argument("--no-first", action="store_true",
                   help="skip the first-ever build (use and fill the user's solver cache instead)")
    p.add_argument("--scaling", dest="scaling", action="store_true", default=None,
                   help="run the scaling study (default: on unless --quick)")
    p.add_argument("--no-scaling", dest="scaling", action="store_false")
    p.add_argument("--plot", metavar="PNG", default=None,
                   help="scaling plot file (default: next to --json, else bench_scaling.png)")
    p.add_argument("--from", dest="from_json", metavar="FILE", default=None,
                   help="do not run: re-read a result JSON (re-apply --peers, print, write --json/--markdown)")
    p.add_argument("--markdown", metavar="FILE", default=None, help="also write a short Markdown summary table")
    p.add_argument("--quiet", action="store_true", help="no progress messages on stderr")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from wbmp.bench.command import run_command

    return run_command(robot=args.robot, tasks=args.tasks, quick=args.quick, repeats=args.repeats, dt=args.dt,
                       max_iterations=args.max_iterations, no_compile=args.no_compile, no_sim=args.no_sim,
                       no_e2e=args.no_e2e, no_first=args.no_first, scaling=args.scaling, peers=args.peers,
                       peers_dir=args.peers_dir, json_path=args.json, markdown_path=args.markdown,
                       plot=args.plot, from_json=args.from_json, quiet=args.quiet)
