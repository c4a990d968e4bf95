"""``wbmp solve``: sentence (or TaskSpec JSON) -> plan -> simulation check -> files.

Exit codes (docs/cli.md): 0 planned (and certified), 2 bad usage or an instruction that
could not be understood, 3 invalid spec (unknown frame, robot, bad value), 4 infeasible or solver
failure (the one-line diagnosis is printed), 5 planned but the simulation check failed.
"""

from __future__ import annotations

import argparse
import json
import os
import sys

from wbmp.commands.parse import timeout_seconds
from wbmp.errors import CliError, ExitCode


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "solve", help="plan a motion from a sentence or a task spec, check it in simulation, write files",
        description="Turn an English or Chinese instruction (or a TaskSpec JSON file) into a whole-body "
                    "motion: parse it into actions, compile them into a task spec, plan with the "
                    "CasADi/IPOPT trajectory optimizer, check the plan in MuJoCo with the whole-body "
                    "controller (unless --no-sim), print the solver statistics, the constraint report and "
                    "the certificate, and write the requested files.",
        epilog='examples: wbmp solve "wave your right hand twice, then squat" --html wave.html   '
               'wbmp solve "深蹲三次" --out squat.npz --plots plots/   '
               "wbmp solve --spec examples/specs/reach.json --no-sim --json   "
               'wbmp solve "reach forward 30 cm" --scene examples/scenes/table.json',
    )
    p.add_argument("instruction", nargs="*", help="the instruction, e.g. \"squat twice\" (or use --spec)")
    p.add_argument("--spec", metavar="FILE", help="TaskSpec JSON file instead of a sentence (docs/spec-format.md)")
    p.add_argument("--scene", metavar="FILE", default=None,
                   help="scene JSON file: a floor plus named objects the motion must keep clear of "
                        "(docs/scenes.md; replaces a spec's own scene)")
    p.add_argument("--robot", default=None,
                   help="robot name or profile file (default: talos, or the spec's robot)")
    p.add_argument("--out", metavar="FILE.npz", default=None,
                   help="write the motion file (.npz) here (an existing file is replaced; links, folders "
                        "and devices are refused)")
    p.add_argument("--html", metavar="FILE", default=None, help="write a standalone HTML replay here")
    p.add_argument("--plots", metavar="DIR", default=None,
                   help="write PNG plots into DIR (created if missing; its parent must exist)")
    p.add_argument("--view", action="store_true", help="open the live meshcat viewer (127.0.0.1) afterwards")
    p.add_argument("--no-sim", action="store_true", help="skip the MuJoCo simulation check")
    p.add_argument("--push", metavar="N@t", default=None,
                   help="push the base with N newtons at t seconds during the simulation, e.g. 80@1.5 "
                        "(0 < N <= 5000, 0 <= t < the motion's duration)")
    p.add_argument("--estop-at", metavar="SECONDS", type=_stop_time, default=None,
                   help="press the software E-stop at this time of the simulation: the robot freezes in the "
                        "plan's nearest double-support posture and holds it (or damps every joint when it "
                        "cannot); SIGUSR1 to the running command does the same at once (docs/safety.md)")
    p.add_argument("--estop-flag", metavar="FILE", default=None,
                   help="press the E-stop when FILE appears during the simulation (e.g. from a viewer)")
    p.add_argument("--faults", metavar="FILE", default=None,
                   help="put the simulation through the faults of this JSON file: pushes, friction and mass "
                        "errors, joint noise, control delay, a floor step (docs/safety.md)")
    p.add_argument("--no-cache", action="store_true",
                   help="neither read nor write the motion cache (a repeated request is answered from it "
                        "otherwise: docs/cli.md), and plan from the task's own guess, without the solution "
                        "library of earlier plans")
    p.add_argument("--parser", choices=("rules", "llm"), default="rules", help="instruction parser (default: rules)")
    p.add_argument("--llm-url", default=os.environ.get("WBMP_LLM_URL"),
                   help="OpenAI-compatible API base URL for --parser llm (env WBMP_LLM_URL)")
    p.add_argument("--llm-model", default=os.environ.get("WBMP_LLM_MODEL"), help="model name (env WBMP_LLM_MODEL)")
    p.add_argument("--llm-timeout", type=timeout_seconds, default=30.0, metavar="SECONDS",
                   help="limit for each whole request to the LLM server, connect to last byte "
                        "(default: 30, at most 3600)")
    p.add_argument("--motions", metavar="DIR", default=os.environ.get("WBMP_MOTIONS"),
                   help="a motion library: a folder of BVH clips with a clips.csv of labels; an instruction "
                        "that names no known action but a clip's label is that clip, retargeted "
                        "(docs/retarget.md; env WBMP_MOTIONS)")
    p.add_argument("--quiet", action="store_true", help="no progress display; print only the results")
    p.add_argument("--json", action="store_true", help="print the report as JSON (progress as JSON lines)")
    p.set_defaults(run=run)


def request_from_args(args: argparse.Namespace):
    """A SolveRequest from parsed arguments (CliError on contradictory usage)."""
    from wbmp.commands.parse import llm_options
    from wbmp.pipeline import SolveRequest

    text = " ".join(args.instruction).strip() if args.instruction else ""
    if args.spec and text:
        raise CliError("give either an instruction or --spec FILE, not both", ExitCode.USAGE)
    if not args.spec and not text:
        raise CliError('give an instruction in quotes (wbmp solve "squat twice") or --spec FILE', ExitCode.USAGE)
    return SolveRequest(  # SolveRequest.check() (in solve()) refuses a push without the simulation
        instruction=text or None, spec_path=args.spec, scene_path=args.scene, robot=args.robot, simulate=not args.no_sim,
        push=args.push, parser=args.parser, llm_options=llm_options(args),
        estop_at=getattr(args, "estop_at", None), estop_flag=getattr(args, "estop_flag", None),
        faults_path=getattr(args, "faults", None),
    )


def _stop_time(text: str) -> float:
    """``--estop-at``: a finite time >= 0 [s] (argparse turns the ValueError into exit 2)."""
    import math

    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text[:40]!r} is not a time in seconds, e.g. 1.5") from None
    if not math.isfinite(value) or value < 0:
        raise argparse.ArgumentTypeError(f"{text[:40]!r}: give a time >= 0 s within the motion, e.g. 1.5")
    return value


def _stop_on_sigusr1(request) -> None:
    """SIGUSR1 presses the simulation's E-stop (the loop reacts on its next tick)."""
    import signal
    import threading

    if not hasattr(signal, "SIGUSR1") or threading.current_thread() is not threading.main_thread():
        return
    from sim import StopRequest

    stop = StopRequest()
    request.stop_request = stop
    signal.signal(signal.SIGUSR1, lambda signum, frame: stop.request("SIGUSR1 received"))


def run(args: argparse.Namespace) -> int:
    from viz import make_progress
    from wbmp.outputs import check_inputs_exist, check_outputs, write_outputs
    from wbmp.pipeline import solve

    request = request_from_args(args)
    check_inputs_exist(spec=args.spec, scene=args.scene)
    if request.simulate:
        _stop_on_sigusr1(request)
    # every output path before any work: a typo must not cost a whole solve (exit 2)
    check_outputs(out=args.out, html=args.html, plots=args.plots,
                  inputs={"--spec": args.spec, "--scene": args.scene, "--robot": args.robot if args.robot and os.path.isfile(args.robot)  # noqa: PTH113 - False on any OSError, where Path.is_file raises on EACCES
                          else None})
    progress = make_progress(quiet=args.quiet, json_lines=args.json)
    # --plots draws the simulation's contact forces, which the motion cache does not keep: solved
    # afresh (and stored), never read
    try:
        result = solve(request, progress, cache=not args.no_cache, cache_read=args.plots is None)
    except Exception as e:  # the language package only when it failed: a motion-cache hit never imports it
        from language import LanguageError

        if not isinstance(e, LanguageError) or not args.motions or not request.instruction:
            raise
        from wbmp.motions import retarget_from_library

        result = retarget_from_library(request.instruction, args.motions, robot=args.robot,
                                       simulate=not args.no_sim, progress=progress,
                                       cache=not args.no_cache and args.plots is None)
        if result is None:
            raise  # no clip of the library either: refused as without it
    written = write_outputs(result, out=args.out, html=args.html, plots=args.plots, progress=progress)
    if hasattr(result, "reference"):  # a clip of the motion library (wbmp.retarget.RetargetResult)
        from wbmp.commands.retarget import print_result as print_retarget

        print_retarget(result, written, as_json=args.json)
    else:
        print_result(result, written, as_json=args.json)
    if args.view:
        from viz import ViewerError, serve

        try:
            serve(result.model(), result.plan, execution=result.execution)
        except ViewerError as e:
            raise CliError(f"live viewer: {e}", ExitCode.INTERNAL) from None
    return int(result.exit_code)


def print_result(result, written: dict[str, str], *, as_json: bool) -> None:
    """The actions, the plan summary, the certificate and the files, as text or one JSON object."""
    if as_json:
        report = result.report()
        report["files"] = written
        from wbmp.motionfile import json_default

        print(json.dumps(report, default=json_default, ensure_ascii=False))
        return
    if result.actions is not None:
        print(result.actions.describe())
    print(result.plan.summary())
    if result.execution is not None and result.execution.certificate is not None:
        print(result.execution.certificate.summary())
    for kind, path in written.items():
        print(f"wrote {kind}: {path}")
    sys.stdout.flush()


