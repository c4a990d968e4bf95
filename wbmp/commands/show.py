"""``wbmp show``: replay a saved motion file in the live viewer, or write its HTML/plots."""

from __future__ import annotations

import argparse
from pathlib import Path

from wbmp.errors import CliError, ExitCode


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "show",
        help="replay a motion file (.npz) in the live 3D viewer, or write HTML/plots from it",
        description="Replay a motion file written by `wbmp solve --out motion.npz`. By default a live "
                    "meshcat viewer starts on 127.0.0.1 and loops the motion until Ctrl-C. With --html "
                    "or --plots, the files are written instead (add --view to also start the viewer).",
        epilog="examples: wbmp show motion.npz  |  wbmp show motion.npz --html motion.html  |  "
               "wbmp show motion.npz --plots plots/",
    )
    p.add_argument("motion", help="motion file (.npz) written by wbmp solve --out")
    p.add_argument("--html", metavar="FILE", help="write a standalone HTML replay (no server, works offline)")
    p.add_argument("--plots", metavar="DIR", help="write PNG plots into DIR")
    p.add_argument("--view", action="store_true", help="start the live viewer even with --html/--plots")
    p.add_argument("--port", type=int, default=None,
                   help="web port of the live viewer (default: first free port from 7000)")
    p.add_argument("--open", action="store_true", help="open the live viewer in the default browser")
    p.add_argument("--collisions", action="store_true",
                   help="live viewer: also draw the robot's collision capsules (docs/collisions.md)")
    p.add_argument("--quiet", action="store_true", help="no progress display")
    p.add_argument("--json", action="store_true", help="progress as JSON lines on stderr")
    p.set_defaults(run=run)


def load(path: str):
    """(robot, plan, execution or None) of a motion file, with one-line errors.

    A damaged file is exit 2 (:func:`wbmp.motionfile.load_motion` names the key); a robot name
    in the file that this install does not know is exit 3, as an unknown robot is for ``solve``.
    """
    from robots import RobotError, load_robot
    from wbmp.motionfile import check_robot, load_motion

    motion = load_motion(path)
    try:
        robot = load_robot(motion.robot_name)
    except RobotError as e:
        raise CliError(f"motion file {path!r}: key 'robot': {e}", ExitCode.INVALID_SPEC) from None
    check_robot(motion, robot, path)
    return robot, motion.plan, motion.execution


def run(args: argparse.Namespace) -> int:
    from viz import Staging, VizInputError, make_progress
    from wbmp.motionfile import check_motion_exists
    from wbmp.outputs import check_outputs, output_errors

    if args.port is not None and not 1 <= args.port <= 65535:
        raise CliError(f"--port must be in 1..65535, got {args.port}", ExitCode.USAGE)
    check_motion_exists(args.motion)  # a missing input is named as such, before the outputs
    outputs = check_outputs(html=args.html, plots=args.plots, inputs={"motion file": args.motion})
    progress = make_progress(quiet=args.quiet, json_lines=args.json)
    with progress.stage("loading the motion"):
        robot, plan, execution = load(args.motion)
    written: list[str] = []
    try:
        with output_errors(), Staging() as staging:
            if outputs.html is not None:
                from viz import write_html

                with progress.stage(f"writing {args.html}"):
                    out = write_html(outputs.html, robot, plan, execution=execution, staging=staging,
                                     title=plan.spec.description or plan.spec.name or Path(args.motion).stem)
                written.append(f"html: {out}")
            if outputs.plots is not None:
                from viz import write_plots

                with progress.stage(f"writing plots to {args.plots}"):
                    paths = write_plots(outputs.plots, robot, plan, execution=execution, staging=staging)
                written += [f"plot: {p}" for p in paths]
            staging.commit()
    except VizInputError as e:  # load() checked the shapes; this is a last line of defence
        raise CliError(f"motion file {args.motion!r}: {e}", ExitCode.USAGE) from None
    for line in written:
        print(line)
    if (outputs.html or outputs.plots) and not args.view:
        return ExitCode.OK
    from viz import ViewerError, serve

    try:
        serve(robot, plan, execution=execution, port=args.port, open_browser=args.open, collisions=args.collisions)
    except ViewerError as e:
        raise CliError(f"live viewer: {e}", ExitCode.INTERNAL) from None
    return ExitCode.OK
