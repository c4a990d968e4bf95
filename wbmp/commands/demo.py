"""``wbmp demo``: the main job on the default robot (what ``make demo`` runs)."""

from __future__ import annotations

import argparse

from wbmp.errors import ExitCode


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("demo", help="run the demo on the default robot",
                       description="Show the default robot and what wbmp can do with it.")
    p.add_argument("--robot", default="talos", help="robot name or profile file (default: talos)")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from wbmp.commands import robots

    robots.run(argparse.Namespace(robot=[args.robot], json=False))
    return ExitCode.OK
