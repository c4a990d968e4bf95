"""``wbmp retarget``: a human motion-capture clip (BVH) -> a planned, simulated and certified robot motion.

Exit codes as ``wbmp solve``: 0 planned (and certified), 2 bad usage, 3 a clip that cannot be used
(damaged BVH, unknown skeleton, a window outside the clip or beyond 60 s), 4 no plan, 5 planned but
the simulation check failed.
"""

from __future__ import annotations

import argparse
import json
import math
import sys

from wbmp.errors import CliError, ExitCode


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "retarget", help="turn a human motion-capture clip (BVH) into a certified robot motion",
        description="Read a BVH clip (the CMU MotionBuilder and Daz skeletons are recognised; others need "
                    "--skeleton), label its foot contacts, scale it to the robot, and plan the whole motion "
                    "as one trajectory optimization that tracks the human's pelvis, torso, head, hands and "
                    "feet while the stance feet stay fixed (no slip) and nothing goes below the floor, with "
                    "the robot's limits and dynamics. The plan is then checked in MuJoCo (unless --no-sim), "
                    "and its figures printed: tracking error, foot skate, float, penetration, joint jerk "
                    "(docs/retarget.md).",
        epilog="examples: wbmp retarget examples/motions/13_29_squat.bvh --robot talos --start 0 --end 2 "
               "--out squat.npz   |   wbmp retarget walk.bvh --robot g1 --html walk.html",
    )
    p.add_argument("clip", help="the BVH motion-capture file")
    p.add_argument("--robot", default="talos", help="robot name or profile file (default: talos)")
    p.add_argument("--start", type=seconds, default=None, metavar="S", help="start of the window [s] (default: 0)")
    p.add_argument("--end", type=seconds, default=None, metavar="S",
                   help="end of the window [s] (default: the clip's end; a window lasts at most 58.2 s)")
    p.add_argument("--skeleton", metavar="FILE", default=None,
                   help="skeleton mapping (TOML: unit, up, forward and the keypoints' joints; docs/retarget.md) "
                        "for a skeleton wbmp does not recognise")
    p.add_argument("--out", metavar="FILE.npz", default=None, help="write the motion file (.npz) here")
    p.add_argument("--html", metavar="FILE", default=None, help="write a standalone HTML replay here")
    p.add_argument("--plot", metavar="PNG|DIR", default=None,
                   help="write a PNG of the source's (scaled) keypoints against the robot's (executed, or the "
                        "plan's with --no-sim) over time, per body, with the tracking error and the feet's "
                        "height over their labelled contacts (in a folder: CLIP_keypoints.png)")
    p.add_argument("--no-sim", action="store_true", help="skip the MuJoCo simulation check")
    p.add_argument("--no-cache", action="store_true",
                   help="neither read nor write the motion cache (by default a repeat of the same clip, window, "
                        "skeleton and robot is answered from $WBMP_CACHE_DIR/motions, as wbmp solve does)")
    p.add_argument("--quiet", action="store_true", help="no progress display; print only the results")
    p.add_argument("--json", action="store_true", help="print the report as JSON (progress as JSON lines)")
    p.set_defaults(run=run)


def seconds(text: str) -> float:
    """``--start``/``--end``: a finite number of seconds >= 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected seconds, e.g. 1.5, got {text[:40]!r}") from None
    if not (math.isfinite(value) and value >= 0.0):
        raise argparse.ArgumentTypeError(f"expected seconds >= 0, got {text[:40]!r}")
    return value


def run(args: argparse.Namespace) -> int:
    import os

    from viz import make_progress
    from wbmp.outputs import check_outputs, write_outputs
    from wbmp.retarget import RetargetRequest, plot_path, retarget, write_plot

    if args.start is not None and args.end is not None and args.end <= args.start:
        raise CliError(f"--end {args.end:g} s must be after --start {args.start:g} s", ExitCode.USAGE)
    check_outputs(out=args.out, html=args.html,
                  inputs={"clip": args.clip, "--skeleton": args.skeleton,
                          "--robot": args.robot if os.path.isfile(args.robot) else None})  # noqa: PTH113
    plot = None if args.plot is None else plot_path(
        args.plot, args.clip, {"clip": args.clip, "--skeleton": args.skeleton, "--out": args.out, "--html": args.html})
    progress = make_progress(quiet=args.quiet, json_lines=args.json)
    request = RetargetRequest(clip=args.clip, robot=args.robot, start=args.start, end=args.end,
                              skeleton=args.skeleton, simulate=not args.no_sim)
    result = retarget(request, progress, cache=not args.no_cache)
    written = write_outputs(result, out=args.out, html=args.html, progress=progress)
    if plot is not None:
        progress(f"writing {plot}")
        written["plot"] = str(write_plot(result, plot))
    print_result(result, written, as_json=args.json)
    return int(result.exit_code)




def print_result(result, written: dict[str, str], *, as_json: bool) -> None:
    """The plan, the figures and the certificate (tracking targets summed up by the figures)."""
    from wbmp.retarget import is_tracking

    if as_json:
        report = result.report()
        report["files"] = written
        from wbmp.motionfile import json_default

        print(json.dumps(report, default=json_default, ensure_ascii=False))
        return
    plan_lines = result.plan.summary().splitlines()
    print("\n".join(line for line in plan_lines if not is_tracking(line)))
    ref = result.reference
    print(f"retarget: {result.clip_info.get('clip')} ({result.skeleton}), {result.clip_info.get('duration_s', 0):.2f} s, "
          f"scale {ref.scale:.3f} (arms {ref.arm_scale:.3f}, travel {ref.stride_scale:.2f}), "
          f"{ref.time_scale:.2f} x slower than the human")
    if ref.raised_max() > 0:
        print(f"retarget: the body raised up to {ref.raised_max():.3f} m: the human goes lower than the robot's "
              "lowest base (0.6 of its standing height: deeper, its thighs meet its pelvis)")
    for side, moved in ref.arm_moved_max().items():
        if moved > 0.005:
            print(f"retarget: the {side} hand brought in sideways up to {moved:.3f} m: the human holds the "
                  "arm out further than the robot's shoulder can carry")
    if ref.grounded_s > 0:
        print(f"retarget: both feet kept down through the human's {ref.grounded_s:.2f} s of jumps: the robot is "
              "slowed for its steps, and a slowed flight is a far higher jump")
    if ref.stepped_s > 0:
        print(f"retarget: the human's {ref.stepped_s:.2f} s of travelling jumps made as steps (a foot always down): "
              "the robot is slowed for its steps, and a slowed flight is a far higher jump")
    for role, moved in ref.kept_out_max().items():
        if moved > 0.005:
            what = "out of its pelvis and thighs" if role.endswith("hand") else "apart from the other foot"
            print(f"retarget: the {role.replace('_', ' ')} moved {what} up to {moved:.3f} m: the human's "
                  "would pass through the robot's body")
    if ref.splay_turned > 0:
        print(f"retarget: a foot turned up to {math.degrees(ref.splay_turned):.0f} deg: the human stands with the feet "
              "turned further apart or together than the robot's hips turn")
    for gap in ref.gaps:  # each target's largest move from the human, and why, in body terms
        print(f"retarget: gap: {gap.text()}")
    print("planned: " + result.figures.summary().replace("\n", "\n         "))
    if result.execution is not None:
        cert = result.execution.certificate
        lines = cert.summary().splitlines()
        missed = [c for c in cert.checks if is_tracking(c.name) and not c.ok]
        print("\n".join(line for line in lines if not is_tracking(line)))
        if missed:
            print(f"  FAIL {len(missed)} tracking target(s) missed in the simulation beyond their tolerance")
        print("executed: " + result.exec_figures.summary().replace("\n", "\n          "))
    for kind, path in written.items():
        print(f"wrote {kind}: {path}")
    sys.stdout.flush()
