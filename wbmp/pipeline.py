"""The end-to-end job: sentence or spec -> actions -> TaskSpec -> Plan -> Execution -> files.

Only this package wires the layers together; each step is a function call into its layer, and
every step reports progress through a small callback so the CLI can show it (or stay quiet).
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from wbmp.errors import CliError, ExitCode

Progress = Callable[[str], None]


def _silent(_: str) -> None:
    pass


@dataclass(kw_only=True)
class SolveRequest:
    """What ``wbmp solve`` was asked to do.

    Attributes:
        instruction: A sentence (English or Chinese), or None when ``spec_path`` is given.
        spec_path: A TaskSpec JSON file, or None.
        robot: Robot name or profile file; None = the spec's robot (or talos for a sentence).
        parser: ``rules`` or ``llm``.
        llm_options: Options of the LLM backend (url, model, api_key, timeout).
        simulate: Run the controller in MuJoCo and certify the motion.
        push: ``"N@t"`` push on the base during simulation, or None: above 0 N, at most
            ``sim.MAX_PUSH_FORCE``, and a time within the motion (0 <= t < horizon).

    :meth:`check` (called by :func:`solve` first) refuses, with :class:`CliError` exit 2, what
    needs no work to see: an empty ``robot``, an instruction longer than
    ``tasks.limits.MAX_TEXT_LENGTH`` characters, a push without the simulation.
    """

    instruction: str | None = None
    spec_path: str | None = None
    robot: str | None = None
    parser: str = "rules"
    llm_options: dict[str, Any] = field(default_factory=dict)
    simulate: bool = True
    push: str | None = None

    def check(self) -> None:
        """Refuse contradictory or empty options before any work (:class:`CliError`, exit 2)."""
        from tasks.limits import MAX_TEXT_LENGTH
        from wbmp.errors import ROBOT_HINT, require_text

        require_text(self.robot, "--robot", ROBOT_HINT)
        if self.instruction is not None and len(self.instruction) > MAX_TEXT_LENGTH:
            raise CliError(f"the instruction is {len(self.instruction):,} characters long; wbmp reads at most "
                           f"{MAX_TEXT_LENGTH:,} (one to a few sentences)", ExitCode.USAGE)
        if self.push is not None and not self.simulate:
            raise CliError("--push needs the simulation: drop --no-sim", ExitCode.USAGE)


@dataclass(kw_only=True)
class SolveResult:
    """Everything the job produced."""

    robot: Any
    spec: Any
    plan: Any
    actions: Any = None
    execution: Any = None
    timings: dict[str, float] = field(default_factory=dict)

    @property
    def exit_code(self) -> ExitCode:
        """0 when planned (and certified when simulated), 5 when the simulation check failed."""
        if self.execution is not None and not self.execution.certificate.ok:
            return ExitCode.SIM_FAILED
        return ExitCode.OK

    def report(self) -> dict[str, Any]:
        """The JSON report stored in the motion file and printed by ``--json``."""
        s = self.plan.stats
        out: dict[str, Any] = {
            "robot": self.robot.name,
            "instruction": self.spec.description,
            "solver": {
                "status": s.status.name.lower(),
                "iterations": s.iterations,
                "build_time": s.build_time,
                "solve_time": s.solve_time,
                "cache": s.cache,
                "n_variables": s.n_variables,
                "n_constraints": s.n_constraints,
            },
            "constraints": [
                {"name": c.name, "violation": c.violation, "tolerance": c.tolerance, "unit": c.unit,
                 "time": c.time, "ok": c.ok}
                for c in self.plan.checks
            ],
            "timings": self.timings,
        }
        if self.actions is not None:
            out["actions"] = self.actions.to_dict()["actions"]
        if self.execution is not None:
            out["certificate"] = self.execution.certificate.to_dict()
        return out


def parse_instruction(request: SolveRequest):
    """Sentence -> ActionPlan with the requested backend."""
    from language import parse

    assert request.instruction is not None  # build_spec parses only a request with a sentence
    options = request.llm_options if request.parser == "llm" else {}
    return parse(request.instruction, backend=request.parser, **options)


def build_spec(request: SolveRequest, progress: Progress = _silent):
    """(robot, spec, actions) for a sentence or a spec file."""
    import dataclasses

    from robots import load_robot
    from tasks.robot_check import check_spec_for_robot
    from tasks.serialize import load_spec

    if request.spec_path is not None:
        spec = load_spec(request.spec_path)
        robot = load_robot(request.robot or spec.robot)
        if request.robot:
            spec = dataclasses.replace(spec, robot=robot.name)
        check_spec_for_robot(spec, robot)  # unknown joints, contacts off the ground: exit 3, before planning
        return robot, spec, None
    if not request.instruction or not request.instruction.strip():
        raise CliError("give an instruction in quotes, or --spec FILE", ExitCode.USAGE)
    progress("parsing the instruction")
    actions = parse_instruction(request)
    robot = load_robot(request.robot or "talos")
    from tasks.compose import compile_actions

    spec = compile_actions(actions.actions, robot)
    spec = dataclasses.replace(spec, robot=robot.name, description=request.instruction)
    check_spec_for_robot(spec, robot)
    return robot, spec, actions


def solve(request: SolveRequest, progress: Progress = _silent) -> SolveResult:
    """Run the whole job; raises the layers' exceptions (mapped to exit codes by the CLI).

    Ctrl-C or SIGTERM stops it at the next progress message or step, also when a library
    swallowed the interrupt (CasADi turns it into an IPOPT failure): see
    :func:`wbmp.errors.check_signals`.
    """
    from planner import plan as plan_motion
    from wbmp.errors import check_signals

    report = progress

    def checked_progress(message: str) -> None:
        check_signals()
        report(message)

    progress = checked_progress

    timings: dict[str, float] = {}
    request.check()
    push = None
    if request.simulate and request.push is not None:
        from sim import parse_push

        push = parse_push(request.push)  # before any work: a typo fails at once (exit 2)
    t0 = time.perf_counter()
    robot, spec, actions = build_spec(request, progress)
    timings["spec"] = time.perf_counter() - t0
    if push is not None:
        from sim import check_push_time

        check_push_time(push, spec.horizon)  # a push after the motion would never act (exit 2)
    progress(f"planning {spec.horizon:.1f} s of motion for {robot.name}")
    t0 = time.perf_counter()
    plan = plan_motion(spec, robot, progress=progress)
    check_signals()
    timings["plan"] = time.perf_counter() - t0
    execution = None
    if request.simulate:
        from sim import simulate

        progress("simulating in MuJoCo with the whole-body controller")
        t0 = time.perf_counter()
        execution = simulate(plan, robot, push=push, progress=progress)
        check_signals()
        timings["simulate"] = time.perf_counter() - t0
    return SolveResult(robot=robot, spec=spec, plan=plan, actions=actions, execution=execution, timings=timings)


@contextlib.contextmanager
def output_errors() -> Iterator[None]:
    """Turn :class:`viz.files.OutputError` (a refused path, a failed write) into exit 2."""
    from viz.files import OutputError

    try:
        yield
    except OutputError as e:
        raise CliError(str(e), ExitCode.USAGE) from None


@dataclass(frozen=True, kw_only=True)
class OutputPaths:
    """The files a command will write, checked before any work (:func:`check_outputs`)."""

    out: Path | None = None
    html: Path | None = None
    plots: Path | None = None


def check_outputs(*, out: str | None = None, html: str | None = None, plots: str | None = None,
                  inputs: dict[str, str | None] | None = None) -> OutputPaths:
    """Check every output path of ``solve``/``show``/``demo`` before any work.

    Refuses (:class:`CliError`, exit 2, one line naming the option, the path and why): an empty
    path, a directory, a symbolic link, a device or other non-regular file, a read-only file, a
    missing or unwritable folder, two outputs on one file, an output on an input file, and a
    motion file (``--out``) that does not end in ``.npz``. ``None`` means "not asked".
    See :mod:`viz.files` for the rules.
    """
    from viz.files import OutputPathError, check_distinct, check_output_dir, check_output_file

    with output_errors():
        paths = OutputPaths(
            out=None if out is None else check_output_file(out, "--out"),
            html=None if html is None else check_output_file(html, "--html"),
            plots=None if plots is None else check_output_dir(plots, "--plots", _plot_files()),
        )
        if paths.out is not None and paths.out.suffix.lower() != ".npz":
            raise OutputPathError(f"--out {out!r}: a motion file ends in .npz (for JSON or CSV, write the "
                                  ".npz and run `wbmp export`)")
        files = {k: v for k, v in (("--out", paths.out), ("--html", paths.html)) if v is not None}
        if paths.plots is not None:
            files.update({f"--plots ({name})": paths.plots / name for name in _plot_files()})
        check_distinct(files, {k: Path(v) for k, v in (inputs or {}).items() if v})
    return paths


def _plot_files() -> tuple[str, ...]:
    from viz.plots import PLOT_FILES

    return PLOT_FILES


def write_outputs(result: SolveResult, *, out: str | None = None, html: str | None = None,
                  plots: str | None = None, progress: Progress = _silent) -> dict[str, str]:
    """Write the requested files; returns {kind: path}.

    The paths are checked again (:func:`check_outputs`), every file is made in a temporary file
    beside its target, and all are renamed into place at the end: a failure (or Ctrl-C) while
    making them leaves the folders as they were.
    """
    from viz.files import Staging

    paths = check_outputs(out=out, html=html, plots=plots)
    written: dict[str, str] = {}
    with output_errors(), Staging() as staging:
        if paths.out is not None:
            from wbmp.motionfile import save_motion

            progress(f"writing {out}")
            save_motion(paths.out, result.plan, result.robot, execution=result.execution,
                        actions=result.actions.to_dict()["actions"] if result.actions is not None else None,
                        report=result.report(), staging=staging)
            written["motion"] = str(paths.out)
        if paths.html is not None:
            from viz import write_html

            progress(f"writing {html}")
            write_html(paths.html, result.robot, result.plan, execution=result.execution,
                       title=result.spec.description or result.spec.name, staging=staging)
            written["html"] = str(paths.html)
        if paths.plots is not None:
            from viz import write_plots

            progress(f"writing plots to {plots}")
            files = write_plots(paths.plots, result.robot, result.plan, execution=result.execution,
                                staging=staging)
            written["plots"] = ", ".join(str(p) for p in files)
        staging.commit()
    return written
