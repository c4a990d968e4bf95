"""``wbmp export``: a motion file (.npz) as JSON, CSV, a ROS 2 bag (MCAP) or a tracker file."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from wbmp.errors import CliError, ExitCode

FORMATS = ("json", "csv", "mcap", "tracker", "lafan")
#: the suffix each format's file gets when --out is not given
DEFAULT_SUFFIX = {"json": ".json", "csv": ".csv", "mcap": ".mcap", "tracker": ".tracker.npz",
                  "lafan": ".lafan.csv"}
#: --out's suffix -> the format it implies (.npz: only with --format tracker)
SUFFIX_FORMAT = {"json": "json", "csv": "csv", "mcap": "mcap"}
#: formats that --out's suffix may hold besides the one it implies (the LAFAN1 file is a .csv)
SUFFIX_ALSO = {"csv": ("lafan",)}
#: options that belong to one format
FORMAT_OPTIONS = {"stamp": ("--stamp", "mcap"), "base_frame": ("--base-frame", "mcap or tracker"),
                  "fps": ("--fps", "tracker or lafan"), "source": ("--source", "tracker or lafan")}


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "export",
        help="convert a motion file (.npz) to JSON, CSV, a ROS 2 bag (MCAP), a tracker file or the "
             "LAFAN1 CSV of RL motion trackers",
        description="Convert a motion file written by `wbmp solve --out motion.npz`: JSON (every key: arrays "
                    "as nested lists, the spec, actions and report as objects), CSV (one row per knot: t, q_*, "
                    "v_*, com_*, after '#' lines with the robot, spec, actions and report; a simulated "
                    "execution goes to <name>.exec.csv), mcap (a ROS 2 bag: JointTrajectory, /joint_states, "
                    "/tf and the report; no ROS installation needed) or tracker (an .npz resampled at --fps "
                    "for motion trackers) or lafan (the Unitree/LAFAN1 retargeting CSV that BeyondMimic reads: no header, "
                    "one row per frame at --fps, default 30: root x y z, root quaternion x y z w, then the "
                    "joint positions in the robot's joint order). docs/export.md states every format's frames, "
                    "units and orders.",
        epilog="examples: wbmp export motion.npz --format csv --out plan.csv  |  "
               "wbmp export motion.npz --out motion.mcap  |  wbmp export motion.npz --format tracker --fps 30  |  "
               "wbmp export motion.npz --format lafan --fps 50 --out motion_g1.csv",
    )
    p.add_argument("motion", help="motion file (.npz) written by wbmp solve --out")
    p.add_argument("--format", choices=FORMATS, default=None,
                   help="output format (default: from --out's suffix .json, .csv or .mcap; without --out, json)")
    p.add_argument("--out", metavar="FILE", default=None,
                   help="output file (default: the motion file's name with .json, .csv, .mcap, "
                        ".tracker.npz or .lafan.csv); an existing file is replaced, links, folders and devices are refused")
    p.add_argument("--stamp", type=stamp_seconds, default=None, metavar="SECONDS",
                   help="mcap: ROS time of the motion's t = 0, in seconds since the Unix epoch (default: 0)")
    p.add_argument("--base-frame", default=None, metavar="NAME",
                   help="mcap and tracker: the base's frame name (default: the robot profile's base frame, "
                        "its URDF root link: base_link for talos, pelvis for g1)")
    p.add_argument("--fps", type=frames_per_second, default=None, metavar="HZ",
                   help="tracker and lafan: sample rate (default: 50 for tracker, 30 for lafan)")
    p.add_argument("--source", choices=("plan", "execution"), default=None,
                   help="tracker and lafan: resample the plan (default) or the simulated execution")
    p.set_defaults(run=run)


def stamp_seconds(text: str) -> float:
    """``--stamp`` value: a finite number of seconds >= 0 that a ROS time (int32 seconds) holds."""
    from wbmp.export.rosbag import MAX_STAMP

    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected seconds since the Unix epoch, e.g. 0 or 1700000000, got "
                                         f"{text[:40]!r}") from None
    if not (math.isfinite(value) and 0.0 <= value <= MAX_STAMP - 86400):
        raise argparse.ArgumentTypeError(f"expected seconds from 0 to {MAX_STAMP - 86400} (a ROS time is an "
                                         f"int32 of seconds), got {text[:40]!r}")
    return value


def frames_per_second(text: str) -> float:
    """``--fps`` value: a rate in (0, 1000] Hz."""
    from wbmp.export.tracker import check_fps

    try:
        value = float(text)
        check_fps(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a rate in Hz above 0 and at most 1000, e.g. 30 or 50, got "
                                         f"{text[:40]!r}") from None
    return value


def output_path(motion: str, out: str | None, fmt: str | None) -> tuple[Path, str]:
    """(path, format) from the arguments; raises CliError on a contradiction.

    Without ``--out`` the file is the motion file's name with ``.json``, ``.csv``, ``.mcap`` or
    ``.tracker.npz``. With it, the suffix gives the format (``.json``, ``.csv``, ``.mcap``);
    ``--format`` must agree with such a suffix, is required for any other suffix, and ``.npz`` is
    refused unless the format is ``tracker`` (the motion file already is one).
    """
    if out is None:
        fmt = "json" if fmt is None else fmt
        return Path(motion).with_suffix(DEFAULT_SUFFIX[fmt]), fmt
    if not out.strip():
        raise CliError("--out: empty path", ExitCode.USAGE)
    suffix = Path(out).suffix.lstrip(".").lower()
    if suffix == "npz" and fmt != "tracker":
        raise CliError(f"--out {out!r}: export writes JSON, CSV or MCAP, not .npz (the motion file already is one; "
                       "copy it to duplicate it); for a tracker file give --format tracker", ExitCode.USAGE)
    if fmt is None:
        if suffix not in SUFFIX_FORMAT:
            shown = f".{suffix}" if suffix else "no suffix"
            raise CliError(f"--out {out!r}: unknown format ({shown}); name it .json, .csv or .mcap, or give "
                           "--format", ExitCode.USAGE)
        fmt = SUFFIX_FORMAT[suffix]
    elif suffix in SUFFIX_FORMAT and SUFFIX_FORMAT[suffix] != fmt and fmt not in SUFFIX_ALSO.get(suffix, ()):
        raise CliError(f"--out {out!r} ends in .{suffix} but --format is {fmt}", ExitCode.USAGE)
    return Path(out), fmt


def check_options(args: argparse.Namespace, fmt: str) -> None:
    """Refuse an option of another format (``--fps`` with ``--format mcap``...)."""
    for attr, (option, formats) in FORMAT_OPTIONS.items():
        if getattr(args, attr) is not None and fmt not in formats.split(" or "):
            raise CliError(f"{option} applies to --format {formats}, not {fmt}", ExitCode.USAGE)
    if args.base_frame is not None:
        name = args.base_frame
        if not name.strip() or any(c.isspace() or not c.isprintable() for c in name) or len(name) > 256:
            raise CliError(f"--base-frame {name[:80]!r}: give a frame name (no spaces, at most 256 characters), "
                           "e.g. base_link", ExitCode.USAGE)


def _check_rate(args: argparse.Namespace, motion) -> None:
    """Refuse an --fps that gives fewer than two samples of the motion (exit 2)."""
    from wbmp.export.lafan import LAFAN_FPS
    from wbmp.export.tracker import DEFAULT_FPS, check_fps

    ex = motion.execution
    t = ex.t if args.source == "execution" and ex is not None else motion.plan.t
    default = LAFAN_FPS if args.format == "lafan" else DEFAULT_FPS
    try:
        check_fps(default if args.fps is None else args.fps, float(t[-1] - t[0]))
    except ValueError as e:
        raise CliError(f"--fps: {e}", ExitCode.USAGE) from None


def run(args: argparse.Namespace) -> int:
    from viz import Staging
    from wbmp.export.files import exec_csv_path, export_motion
    from wbmp.motionfile import check_motion_exists, load_motion
    from wbmp.outputs import check_distinct, check_output_file, output_errors

    check_motion_exists(args.motion)  # a missing input is named as such, before the outputs
    path, fmt = output_path(args.motion, args.out, args.format)
    check_options(args, fmt)
    option = "--out" if args.out is not None else "the output"
    with output_errors():
        check_output_file(path if args.out is None else args.out, option)
        check_distinct({option: path}, {"the motion file": Path(args.motion)})
    motion = load_motion(args.motion)
    if fmt == "csv" and motion.execution is not None:
        exec_path = exec_csv_path(path)
        with output_errors():
            check_output_file(exec_path, f"{option} (the execution's {exec_path.name})")
            check_distinct({option: path, "the execution CSV": exec_path}, {"the motion file": Path(args.motion)})
    if fmt in ("tracker", "lafan"):
        _check_rate(args, motion)
    with output_errors(), Staging() as staging:
        written = export_motion(motion, path, fmt, staging=staging, stamp=args.stamp or 0.0,
                                base_frame=args.base_frame, fps=args.fps, source=args.source or "plan")
        staging.commit()
    for p in written:
        print(f"{fmt}: {p}")
    if fmt == "lafan":
        _print_lafan_layout(motion, args.fps)
    return ExitCode.OK


def _print_lafan_layout(motion, fps: float | None) -> None:
    """The rate and column order of a LAFAN1 CSV (the file itself states neither)."""
    from wbmp.export.columns import joint_names
    from wbmp.export.lafan import LAFAN_FPS

    names = joint_names(motion)
    print(f"lafan: {LAFAN_FPS if fps is None else fps:g} frames/s; columns: root x y z [m], root quaternion "
          f"x y z w, then {len(names)} joint positions [rad]: {' '.join(names)}")
