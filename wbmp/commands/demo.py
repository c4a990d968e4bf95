"""``wbmp demo``: the main job on the default robot (what ``make demo`` runs).

Solves ``wave your right hand twice, then squat`` on talos end to end (parse, plan, simulate,
certify) and writes ``demo.npz`` and the offline replay ``demo.html``.

Exit codes are those of ``wbmp solve``: 0 certified, 2 bad usage (an empty sentence or
``--robot``, a bad output path: checked before any work), 3 unknown robot, 4 infeasible,
5 the simulation check failed.
"""

from __future__ import annotations

import argparse
from pathlib import Path

DEMO_SENTENCE = "wave your right hand twice, then squat"


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("demo", help="solve the demo sentence on the default robot and write demo.html",
                       description=f"Solve {DEMO_SENTENCE!r} end to end (parse, plan, simulate, certify) and "
                                   "write the motion file and a standalone HTML replay.")
    p.add_argument("sentence", nargs="?", default=DEMO_SENTENCE, help=f"instruction (default: {DEMO_SENTENCE!r})")
    p.add_argument("--robot", default="talos", help="robot name or profile file (default: talos)")
    p.add_argument("--scene", metavar="FILE", default=None,
                   help="scene JSON file: objects around the robot (docs/scenes.md)")
    p.add_argument("--html", default="demo.html", help="HTML replay to write (default: demo.html)")
    p.add_argument("--out", default="demo.npz", help="motion file to write (default: demo.npz)")
    p.add_argument("--no-sim", action="store_true", help="skip the MuJoCo simulation check")
    p.add_argument("--quiet", action="store_true", help="no progress display")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from viz import make_progress
    from wbmp.commands.solve import print_result
    from wbmp.errors import CliError, ExitCode, one_line
    from wbmp.outputs import check_inputs_exist, check_outputs, write_outputs
    from wbmp.pipeline import SolveRequest, solve

    if not args.sentence.strip():
        raise CliError(f"the sentence is empty: give an instruction in quotes, or none for {DEMO_SENTENCE!r}",
                       ExitCode.USAGE)
    request = SolveRequest(instruction=args.sentence, scene_path=args.scene, robot=args.robot,
                           simulate=not args.no_sim)
    request.check()
    check_inputs_exist(scene=args.scene)
    check_outputs(out=args.out, html=args.html, inputs={"--scene": args.scene})  # before any work
    print(f"wbmp demo: {one_line(repr(args.sentence), 200)} on {one_line(args.robot, 200)}")
    progress = make_progress(quiet=args.quiet)
    result = solve(request, progress)
    written = write_outputs(result, out=args.out, html=args.html, progress=progress)
    print_result(result, written, as_json=False)
    print(f"open {Path(args.html).resolve()} in a browser to replay the motion (works offline)")
    return int(result.exit_code)
