"""``wbmp bench`` from its options to its exit code: every option checked before any work, the run
(or a ``--from`` result re-read), the table printed, ``--json``/``--markdown`` written together,
and the one-line verdict on stderr when a task class failed."""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

from wbmp.bench.options import check_options, read_result
from wbmp.bench.peers import load_peers, peer_ratios
from wbmp.bench.report import exit_code, render, task_exit_code
from wbmp.bench.run import run_bench
from wbmp.errors import ExitCode, check_signals


def run_command(*, robot: str, tasks: str | None, quick: bool, repeats: int | None, dt: float | None,
                max_iterations: int | None, no_compile: bool, no_sim: bool, no_e2e: bool, no_first: bool,
                scaling: bool | None, peers: bool, peers_dir: str | None, json_path: str | None,
                markdown_path: str | None, plot: str | None, from_json: str | None, quiet: bool) -> int:
    """Run ``wbmp bench`` with the command line's options; returns the exit code.

    ``tasks`` is the comma-separated ``--tasks`` text; the other names are the options'.

    Raises:
        CliError: A bad option (exit 2), a bad ``--from`` file (exit 2).
        RobotError: An unknown robot (exit 3), before any work.
    """
    from viz import Staging
    from wbmp.errors import ROBOT_HINT, one_line, require_text
    from wbmp.outputs import check_distinct, check_output_file, output_errors

    def log(message: str) -> None:
        check_signals()  # a Ctrl-C that CasADi swallowed (a failed solve) stops the run here
        if not quiet:
            print(f"wbmp bench: {message}", file=sys.stderr, flush=True)

    # every option checked before any work -------------------------------------------------------
    names = [t.strip() for t in tasks.split(",") if t.strip()] if tasks is not None else None
    require_text(peers_dir, "--peers-dir", "give the folder of the peer results, or leave the option out")
    if not from_json:
        require_text(robot, "--robot", ROBOT_HINT)
        check_options(tasks=names, quick=quick, repeats=repeats, dt=dt, max_iterations=max_iterations)
    scaling = (not quick if scaling is None else scaling) and not from_json
    if plot is None and json_path:
        plot = str(Path(json_path).with_suffix("")) + "_scaling.png"
    elif plot is None and scaling:
        plot = "bench_scaling.png"
    with output_errors():
        outputs = {opt: check_output_file(path, opt) for opt, path in
                   (("--json", json_path), ("--markdown", markdown_path), ("--plot", plot if scaling else None))
                   if path is not None}
        check_distinct(outputs, {"--from": Path(from_json)} if from_json else None)

    if from_json:
        result = read_result(from_json)
        if peers:
            result["peers"] = load_peers(peers_dir)
            result["ratios"] = peer_ratios(result["tasks"], result["peers"])
    else:
        from robots import load_robot

        load_robot(robot)  # an unknown robot is exit 3 now, not eight failed tasks later
        if no_compile:  # read by planner_settings here and in the cached-cold child processes
            os.environ["WBMP_BENCH_COMPILE"] = "0"
        result = run_bench(robot=robot, tasks=names, quick=quick, repeats=repeats, dt=dt,
                           simulate=not no_sim, e2e=not no_e2e, first=not no_first,
                           scaling=scaling, peers=peers, peers_dir=peers_dir, plot=plot,
                           max_iterations=max_iterations, log=log)
    table, md = render(result, markdown=bool(markdown_path), source=from_json)
    print(table)
    with output_errors(), Staging() as staging:  # both files or neither
        if json_path:
            text = json.dumps(result, indent=2) + "\n"
            staging.add(outputs["--json"], lambda fh: fh.write(text.encode("utf-8")))
        if md is not None:
            staging.add(outputs["--markdown"], lambda fh: fh.write(md.encode("utf-8")))
        written = staging.commit()
    for path in written:
        print(f"wrote {path}")
    code = exit_code(result)
    if code != ExitCode.OK:
        failed = [name for name, rec in result["tasks"].items() if task_exit_code(rec) != ExitCode.OK]
        first = result["tasks"][failed[0]]
        status = first.get("status")
        if status == "ok":
            status = ("simulation check failed" if first.get("certified") is False
                      else f"`wbmp solve` exited {first.get('e2e_exit_code')}")
        why = first.get("certificate_reason") or first.get("message") or "-"
        print(f"wbmp bench: error: {len(failed)} of {len(result['tasks'])} task classes failed "
              f"({', '.join(failed)}); {failed[0]}: {status}: {one_line(str(why), 300)}",
              file=sys.stderr, flush=True)
    return int(code)
