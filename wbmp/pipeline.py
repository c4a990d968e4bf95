"""The end-to-end job: sentence or spec -> actions -> TaskSpec -> Plan -> Execution -> files.

Only this package wires the layers together; each step is a function call into its layer, and
every step reports progress through a small callback so the CLI can show it (or stay quiet).
"""

from __future__ import annotations

import time
from collections.abc import Callable
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
        push: ``"N@t"`` push on the base during simulation, or None.
    """

    instruction: str | None = None
    spec_path: str | None = None
    robot: str | None = None
    parser: str = "rules"
    llm_options: dict[str, Any] = field(default_factory=dict)
    simulate: bool = True
    push: str | None = None


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

    options = request.llm_options if request.parser == "llm" else {}
    return parse(request.instruction, backend=request.parser, **options)


def build_spec(request: SolveRequest, progress: Progress = _silent):
    """(robot, spec, actions) for a sentence or a spec file."""
    import dataclasses

    from robots import load_robot
    from tasks.serialize import load_spec

    if request.spec_path is not None:
        spec = load_spec(request.spec_path)
        robot = load_robot(request.robot or spec.robot)
        if request.robot:
            spec = dataclasses.replace(spec, robot=robot.name)
        return robot, spec, None
    if not request.instruction or not request.instruction.strip():
        raise CliError("give an instruction in quotes, or --spec FILE", ExitCode.USAGE)
    progress("parsing the instruction")
    actions = parse_instruction(request)
    robot = load_robot(request.robot or "talos")
    from tasks.compose import compile_actions

    spec = compile_actions(actions.actions, robot)
    spec = dataclasses.replace(spec, robot=robot.name, description=request.instruction)
    return robot, spec, actions


def solve(request: SolveRequest, progress: Progress = _silent) -> SolveResult:
    """Run the whole job; raises the layers' exceptions (mapped to exit codes by the CLI)."""
    from planner import plan as plan_motion

    timings: dict[str, float] = {}
    push = None
    if request.simulate and request.push:
        from sim import parse_push

        push = parse_push(request.push)  # before any work: a typo fails at once (exit 2)
    t0 = time.perf_counter()
    robot, spec, actions = build_spec(request, progress)
    timings["spec"] = time.perf_counter() - t0
    progress(f"planning {spec.horizon:.1f} s of motion for {robot.name}")
    t0 = time.perf_counter()
    plan = plan_motion(spec, robot, progress=progress)
    timings["plan"] = time.perf_counter() - t0
    execution = None
    if request.simulate:
        from sim import simulate

        progress("simulating in MuJoCo with the whole-body controller")
        t0 = time.perf_counter()
        execution = simulate(plan, robot, push=push, progress=progress)
        timings["simulate"] = time.perf_counter() - t0
    return SolveResult(robot=robot, spec=spec, plan=plan, actions=actions, execution=execution, timings=timings)


def write_outputs(result: SolveResult, *, out: str | None = None, html: str | None = None,
                  plots: str | None = None, progress: Progress = _silent) -> dict[str, str]:
    """Write the requested files atomically; returns {kind: path}."""
    written: dict[str, str] = {}
    if out:
        from wbmp.motionfile import save_motion

        progress(f"writing {out}")
        save_motion(out, result.plan, result.robot, execution=result.execution,
                    actions=result.actions.to_dict()["actions"] if result.actions is not None else None,
                    report=result.report())
        written["motion"] = str(Path(out))
    if html:
        from viz import write_html

        progress(f"writing {html}")
        write_html(html, result.robot, result.plan, execution=result.execution,
                   title=result.spec.description or result.spec.name)
        written["html"] = str(Path(html))
    if plots:
        from viz import write_plots

        progress(f"writing plots to {plots}")
        paths = write_plots(plots, result.robot, result.plan, execution=result.execution)
        written["plots"] = ", ".join(str(p) for p in paths)
    return written
