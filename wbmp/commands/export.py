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
                   help="output format (default: from --out's suffix .json or .csv; without --out, json)")
    p.add_argument("--out", metavar="FILE", default=None,
                   help="output file (default: the motion file's name with .json or .csv); an existing "
                        "file is replaced, links, folders and devices are refused")
    p.set_defaults(run=run)


def output_path(motion: str, out: str | None, fmt: str | None) -> tuple[Path, str]:
    """(path, format) from the arguments; raises CliError on a contradiction.

    Without ``--out`` the file is the motion file's name with ``.json`` or ``.csv``. With it, the
    suffix gives the format (``.json``, ``.csv``); ``--format`` must agree with a ``.json``/``.csv``
    suffix, is required for any other suffix, and ``.npz`` is refused (the motion file is one).
    """
    if out is None:
        fmt = "json" if fmt is None else fmt
        return Path(motion).with_suffix(f".{fmt}"), fmt
    if not out.strip():
        raise CliError("--out: empty path", ExitCode.USAGE)
    suffix = Path(out).suffix.lstrip(".").lower()
    if suffix == "npz":
        raise CliError(f"--out {out!r}: export writes JSON or CSV, not .npz (the motion file already is one; "
                       "copy it to duplicate it)", ExitCode.USAGE)
    if fmt is None:
        if suffix not in FORMATS:
            shown = f".{suffix}" if suffix else "no suffix"
            raise CliError(f"--out {out!r}: unknown format ({shown}); name it .json or .csv, or give --format",
                           ExitCode.USAGE)
        fmt = suffix
    elif suffix in FORMATS and suffix != fmt:
        raise CliError(f"--out {out!r} ends in .{suffix} but --format is {fmt}", ExitCode.USAGE)
    return Path(out), fmt


def run(args: argparse.Namespace) -> int:
    from viz.files import Staging, check_distinct, check_output_file
    from wbmp.motionfile import exec_csv_path, export_motion, load_motion
    from wbmp.pipeline import output_errors

    path, fmt = output_path(args.motion, args.out, args.format)
    option = "--out" if args.out is not None else "the output"
    with output_errors():
        check_output_file(path if args.out is None else args.out, option)
        check_distinct({option: path}, {"the motion file": Path(args.motion)})
    motion = load_motion(args.motion)
    if fmt == "csv" and motion.execution_arrays:
        exec_path = exec_csv_path(path)
        with output_errors():
            check_output_file(exec_path, f"{option} (the execution's {exec_path.name})")
            check_distinct({option: path, "the execution CSV": exec_path}, {"the motion file": Path(args.motion)})
    with output_errors(), Staging() as staging:
        written = export_motion(motion, path, fmt, staging=staging)
        staging.commit()
    for p in written:
        print(f"{fmt}: {p}")
    return ExitCode.OK
