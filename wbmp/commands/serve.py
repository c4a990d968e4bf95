"""``wbmp serve``: a page on 127.0.0.1 to type instructions, watch the motions, correct them in words.

Runs until Ctrl-C (exit 130, the session's temporary folder removed) or SIGTERM (143). Bad
options are refused before anything starts: an unknown robot (3), a scene file that does not
load (3), a ``--motions`` folder that is not a clip library (2), an ``--out-dir`` folder that is not a writable folder or a port outside 0-65535 (2), a
port already in use (2).
"""

from __future__ import annotations

import argparse
import os
import sys

from wbmp.errors import CliError, ExitCode


def port_number(text: str) -> int:
    """``--port`` value: 0 (any free port) to 65535."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a port number from 0 to 65535, got {text[:40]!r}") from None
    if not 0 <= value <= 65535:
        raise argparse.ArgumentTypeError(f"expected a port number from 0 to 65535, got {value}")
    return value


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "serve", help="a local page to type instructions, watch the motions and correct them in words",
        description="Start a web page on 127.0.0.1: type an English or Chinese instruction, watch the planned "
                    "and simulated motion in 3D (the HTML replay's renderer; nothing is fetched from the "
                    "network), read the parsed actions, what each word did and the certificate, correct the "
                    "last motion in words (slower, faster, twice, lower, higher, bigger, with the left hand, "
                    "again, undo, 慢一点, 再低一点), continue it (then wave), stop a plan, and download each "
                    "motion (.npz, .html, .mcap). One plan runs at a time. Stop the server with Ctrl-C.",
        epilog="examples: wbmp serve   wbmp serve --robot g1 --port 8800   "
               "wbmp serve --scene examples/scenes/kitchen.json   wbmp serve --motions examples/motions   "
               "(docs/serve.md)",
    )
    p.add_argument("--robot", default=None, help="robot name or profile file (default: talos)")
    p.add_argument("--scene", metavar="FILE", default=None,
                   help="scene JSON file the motions are planned in (docs/scenes.md)")
    p.add_argument("--motions", metavar="DIR", default=os.environ.get("WBMP_MOTIONS"),
                   help="a motion library: a folder of BVH clips with a clips.csv of labels; a sentence that names "
                        "no known action but a clip's label is that clip, retargeted (as wbmp solve --motions; "
                        "default: $WBMP_MOTIONS)")
    p.add_argument("--out-dir", metavar="DIR", default=None,
                   help="keep the session's motion files in this existing folder (default: a temporary folder "
                        "removed when the server stops)")
    p.add_argument("--port", type=port_number, default=8765,
                   help="port on 127.0.0.1 (default: 8765; 0 picks a free one)")
    p.add_argument("--open", action="store_true", help="open the page in the web browser")
    p.set_defaults(run=run)


def check_options(args: argparse.Namespace) -> None:
    """Refuse a bad robot, scene or folder before the server starts (the CLI's exit codes)."""
    from wbmp.errors import ROBOT_HINT, require_text

    require_text(args.robot, "--robot", ROBOT_HINT)
    require_text(args.scene, "--scene", "give a scene JSON file (docs/scenes.md)")
    require_text(args.out_dir, "--out-dir", "give an existing folder")
    if args.robot is not None:
        from robots import available_robots, load_robot

        if args.robot not in available_robots():
            load_robot(args.robot)  # an unknown robot or a bad profile: exit 3 now, not at the first sentence
    if args.scene is not None:
        from tasks import load_scene

        load_scene(args.scene)
    if args.motions is not None:
        from wbmp.motions import load_library

        require_text(args.motions, "--motions", "give a folder of BVH clips with a clips.csv")
        if not load_library(args.motions):  # not a library: exit 2 now, not at the first sentence
            raise CliError(f"--motions {args.motions}: its clips.csv lists no clip (columns file, label)",
                           ExitCode.USAGE)
    if args.out_dir is not None:
        if not os.path.isdir(args.out_dir):  # noqa: PTH112 - False on any OSError
            raise CliError(f"--out-dir {args.out_dir!r}: not an existing folder; create it first", ExitCode.USAGE)
        if not os.access(args.out_dir, os.W_OK | os.X_OK):
            raise CliError(f"--out-dir {args.out_dir!r}: the folder is not writable", ExitCode.USAGE)


def run(args: argparse.Namespace) -> int:
    from wbmp.serve.server import ServeServer
    from wbmp.serve.session import Session

    check_options(args)
    session = Session(robot=args.robot, scene=os.path.abspath(args.scene) if args.scene else None,  # noqa: PTH100
                      folder=args.out_dir, start_worker=False,
                      library=os.path.abspath(args.motions) if args.motions else None)  # noqa: PTH100
    try:
        try:
            server = ServeServer(session, args.port)
        except OSError as e:
            raise CliError(f"--port {args.port}: cannot listen on 127.0.0.1:{args.port} ({e.strerror or e}); "
                           "give another port, or --port 0 for any free one", ExitCode.USAGE) from None
        session.start()  # the planning process, once the port is ours
        print(f"wbmp serve: open {server.url}  (Ctrl-C stops; the planner starts in the background)", flush=True)
        if args.open:
            import webbrowser

            webbrowser.open(server.url)
        try:
            server.serve_forever(poll_interval=0.2)
        finally:
            server.server_close()
    finally:
        session.close()
        sys.stdout.flush()
    return ExitCode.OK
