"""``wbmp export``: a motion file (.npz) as JSON or CSV, with the same content."""

from __future__ import annotations

import argparse
from pathlib import Path

from wbmp.errors import CliError, ExitCode

FORMATS = ("json", "csv")


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "export",
        help="convert a motion file (.npz) to JSON or CSV",
        description="Convert a motion file written by `wbmp solve --out motion.npz` to JSON (every key: "
                    "arrays as nested lists, the spec, actions and report as objects) or CSV (one row per "
                    "knot: t, q_*, v_*, com_*, after '#' lines with the robot, spec, actions and report; "
                    "a simulated execution goes to <name>.exec.csv).",
        epilog="examples: wbmp export motion.npz --format json  |  wbmp export motion.npz --format csv --out plan.csv",
    )
    p.add_argument("motion", help="motion file (.npz) written by wbmp solve --out")
    p.add_argument("--format", choices=FORMATS, default=None,
                   help="output format (default: from --out's suffix, else json)")
    p.add_argument("--out", metavar="FILE", default=None,
                   help="output file (default: the motion file's name with .json or .csv)")
    p.set_defaults(run=run)


def output_path(motion: str, out: str | None, fmt: str | None) -> tuple[Path, str]:
    """(path, format) from the arguments; raises CliError on a contradiction."""
    if out is not None:
        suffix = Path(out).suffix.lstrip(".").lower()
        if fmt is None:
            fmt = suffix if suffix in FORMATS else "json"
        elif suffix in FORMATS and suffix != fmt:
            raise CliError(f"--out {out!r} ends in .{suffix} but --format is {fmt}", ExitCode.USAGE)
        return Path(out), fmt
    fmt = fmt or "json"
    return Path(motion).with_suffix(f".{fmt}"), fmt


def run(args: argparse.Namespace) -> int:
    from wbmp.motionfile import export_motion, load_motion

    path, fmt = output_path(args.motion, args.out, args.format)
    if path.resolve() == Path(args.motion).resolve():
        raise CliError(f"--out {str(path)!r} would overwrite the motion file itself", ExitCode.USAGE)
    motion = load_motion(args.motion)
    for written in export_motion(motion, path, fmt):
        print(f"{fmt}: {written}")
    return ExitCode.OK
