"""Exit codes of the CLI (DESIGN.md section 7) and the mapping from exceptions to them."""

from __future__ import annotations

import enum


class ExitCode(enum.IntEnum):
    """Process exit codes."""

    OK = 0
    INTERNAL = 1  # a bug
    USAGE = 2  # bad usage or unparseable instruction
    INVALID_SPEC = 3  # bad parameter, unknown frame or robot
    INFEASIBLE = 4  # infeasible or solver failure (with diagnosis)
    SIM_FAILED = 5  # plan found but the simulation check failed


class CliError(Exception):
    """An error with a one-line message and an exit code."""

    def __init__(self, message: str, code: ExitCode) -> None:
        self.code = code
        super().__init__(message)


def classify(exc: BaseException) -> ExitCode | None:
    """Exit code for a known exception type of the layers, None for an unexpected one."""
    from planner.exceptions import PlannerError, UnsupportedModel
    from robots.exceptions import RobotError
    from tasks.exceptions import TaskError

    if isinstance(exc, CliError):
        return exc.code
    try:
        from language.exceptions import LanguageError
    except ImportError:  # pragma: no cover - language layer not installed
        LanguageError = ()  # type: ignore[assignment]  # noqa: N806
    if LanguageError and isinstance(exc, LanguageError):
        return ExitCode.USAGE
    if isinstance(exc, (RobotError, TaskError, UnsupportedModel)):
        return ExitCode.INVALID_SPEC
    if isinstance(exc, PlannerError):
        return ExitCode.INFEASIBLE
    from sim.exceptions import PushParseError, SimError

    if isinstance(exc, PushParseError):
        return ExitCode.USAGE
    if isinstance(exc, SimError):
        return ExitCode.SIM_FAILED
    return None
