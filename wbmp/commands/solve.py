"""``wbmp solve --spec FILE``: plan a TaskSpec, check it in simulation, write the motion file.

Exit codes (DESIGN.md section 7): 0 planned (and certified), 2 bad usage, 3 invalid spec
(unknown frame, robot, bad value), 4 infeasible or solver failure (the one-line diagnosis is
printed), 5 planned but the simulation check failed.
"""

from __future__ import annotations

import argparse
import json
import sys

from wbmp.errors import CliError, ExitCode


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "solve", help="plan a motion from a task spec (JSON), simulate it, write the motion file",
        description="Plan a whole-body motion for a TaskSpec JSON file with the CasADi/IPOPT trajectory "
                    "optimizer, check it in MuJoCo with the whole-body controller (unless --no-sim), "
                    "print the solver statistics and the constraint report, and write the motion file.",
        epilog="examples: wbmp solve --spec examples/specs/squat.json --out squat.npz   "
               "wbmp solve --spec examples/specs/reach.json --robot talos --no-sim --json",
    )
    p.add_argument("instruction", nargs="?", default=None,
                   help="a sentence (not available yet in this command: use --spec)")
    p.add_argument("--spec", metavar="FILE", help="TaskSpec JSON file (see docs/spec-format.md)")
    p.add_argument("--robot", default=None, help="robot name or profile file (default: the spec's robot)")
    p.add_argument("--out", metavar="FILE", default=None, help="write the motion file (.npz) here")
    p.add_argument("--no-sim", action="store_true", help="skip the MuJoCo simulation check")
    p.add_argument("--quiet", action="store_true", help="no progress messages on stderr")
    p.add_argument("--json", action="store_true", help="print the report as JSON instead of tables")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from wbmp.pipeline import SolveRequest, solve, write_outputs

    if args.instruction is not None:
        raise CliError("sentence input not available yet, use --spec FILE", ExitCode.USAGE)
    if not args.spec:
        raise CliError("give a task spec: wbmp solve --spec FILE (see docs/spec-format.md)", ExitCode.USAGE)

    def progress(message: str) -> None:
        if not args.quiet:
            print(f"wbmp: {message}", file=sys.stderr, flush=True)

    request = SolveRequest(spec_path=args.spec, robot=args.robot, simulate=not args.no_sim)
    result = solve(request, progress)
    written = write_outputs(result, out=args.out, progress=progress)
    if args.json:
        report = result.report()
        report["files"] = written
        print(json.dumps(report, default=_json_default))
    else:
        print(result.plan.summary())
        if result.execution is not None:
            print(result.execution.certificate.summary())
        for kind, path in written.items():
            print(f"wrote {kind}: {path}")
    return int(result.exit_code)


def _json_default(obj):
    import numpy as np

    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    return str(obj)
