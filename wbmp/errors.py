r"""Exit codes of the CLI (docs/cli.md), the table from every exception class of the layers
to them (:func:`exit_table`, :func:`classify`), and the one-line form of an error message.

Every message the CLI prints for a refused input goes through :func:`one_line`: control
characters (ANSI escapes, NUL, bells, newlines), bidirectional overrides and the lone surrogates
of a non-UTF-8 argument are shown escaped (``\x1b``, ``\u202e``, ``\udcff``), never sent raw to
the terminal, and a message longer than :data:`MAX_MESSAGE` characters (a 1 MB sentence quoted
back) keeps its start and end around a ``[... N characters cut ...]`` mark.
"""

from __future__ import annotations

import enum
import functools
import unicodedata
from typing import Literal, NamedTuple

from robots import WbmpError


class ExitCode(enum.IntEnum):
    """Process exit codes."""

    OK = 0
    INTERNAL = 1  # a bug
    USAGE = 2  # bad usage or unparseable instruction
    INVALID_SPEC = 3  # bad parameter, unknown frame or robot
    INFEASIBLE = 4  # infeasible or solver failure (with diagnosis)
    SIM_FAILED = 5  # plan found but the simulation check failed
    INTERRUPTED = 130  # SIGINT (Ctrl-C): 128 + 2, as shells report it
    TERMINATED = 143  # SIGTERM: 128 + 15


class Terminated(BaseException):
    """SIGTERM arrived (raised by the CLI's handler, like KeyboardInterrupt for SIGINT).

    A BaseException, so that ``except Exception`` blocks do not swallow it and every
    ``finally`` (temporary files, child processes, the live viewer) runs on the way out.
    """


# The signal the CLI received (SIGINT or SIGTERM), kept after its exception was raised: a C++
# library that polls for Ctrl-C (CasADi while IPOPT iterates) swallows the exception and carries
# on (IPOPT reports a failure, the planner diagnoses it for seconds). check_signals() raises
# it again at the next step boundary. Set by the CLI's handlers only.
_received: list[int] = []


def note_signal(signum: int) -> None:
    """Remember that ``signum`` arrived (called by the CLI's signal handlers)."""
    _received.append(int(signum))


def clear_signals() -> None:
    """Forget the signals noted (at the start of a CLI run)."""
    _received.clear()


def check_signals() -> None:
    """Raise KeyboardInterrupt (SIGINT) or :class:`Terminated` (SIGTERM) if one arrived.

    Called by the pipeline between steps and from its progress callback, so that an interrupt
    a library swallowed still stops the command at once.
    """
    if not _received:
        return
    import signal

    if signal.SIGTERM in _received:
        raise Terminated()
    raise KeyboardInterrupt()


class CliError(WbmpError):
    """An error with a one-line message and an exit code."""

    def __init__(self, message: str, code: ExitCode) -> None:
        self.code = code
        super().__init__(message)


class MotionFileError(CliError):
    """A motion file is missing, unreadable or lacks required keys (exit code 2), or its times
    lie beyond ``wbmp.motionfile.MAX_MOTION_SECONDS`` (exit code 3)."""

    def __init__(self, message: str, code: ExitCode = ExitCode.USAGE) -> None:
        super().__init__(message, code)


class CorrectionError(CliError, ValueError):
    """``wbmp serve``: a correction that cannot act on the last motion's actions (one line, for the
    page; exit code 2)."""

    def __init__(self, message: str) -> None:
        super().__init__(message, ExitCode.USAGE)


class Busy(CliError):  # noqa: N818 - a state, not a failure
    """``wbmp serve``: the queue is full (HTTP 429; exit code 2)."""

    def __init__(self, message: str) -> None:
        super().__init__(message, ExitCode.USAGE)


class Unavailable(CliError):  # noqa: N818
    """``wbmp serve``: the planning process cannot take jobs (HTTP 503; exit code 1)."""

    def __init__(self, message: str) -> None:
        super().__init__(message, ExitCode.INTERNAL)


#: Longest error message printed [characters]; longer ones are cut in the middle.
MAX_MESSAGE = 1000
_ESCAPES = {"\n": "\\n", "\r": "\\r", "\t": "\\t"}
#: Unicode categories shown escaped: controls, format characters (bidi overrides, zero-width
#: characters), surrogates (undecodable bytes of argv), line and paragraph separators.
_UNSAFE = ("Cc", "Cf", "Cs", "Zl", "Zp")


def _escape(ch: str) -> str:
    if ch in _ESCAPES:
        return _ESCAPES[ch]
    if unicodedata.category(ch) not in _UNSAFE:
        return ch
    o = ord(ch)
    return f"\\x{o:02x}" if o < 0x100 else f"\\u{o:04x}" if o < 0x10000 else f"\\U{o:08x}"


def one_line(message: str, limit: int = MAX_MESSAGE) -> str:
    """``message`` safe to print on one terminal line: unsafe characters escaped, cut to ``limit``."""
    text = "".join(_escape(ch) for ch in str(message))
    if len(text) <= limit:
        return text
    head, tail = (2 * limit) // 3, limit // 4
    return f"{text[:head]} [... {len(text) - head - tail:,} characters cut ...] {text[-tail:]}"


def require_text(value: str | None, what: str, hint: str) -> None:
    """Refuse an empty or blank argument (``--robot ""``) with exit 2: ``<what> is empty: <hint>``."""
    if value is not None and not value.strip():
        raise CliError(f"{what} is empty: {hint}", ExitCode.USAGE)


def require_instruction(text: str | None) -> None:
    """Refuse an instruction longer than ``tasks.limits.MAX_TEXT_LENGTH`` characters (exit 2):
    ``wbmp parse`` and ``wbmp solve`` read the same sentences."""
    from tasks import MAX_TEXT_LENGTH

    if text is not None and len(text) > MAX_TEXT_LENGTH:
        raise CliError(f"the instruction is {len(text):,} characters long; wbmp reads at most "
                       f"{MAX_TEXT_LENGTH:,} (one to a few sentences)", ExitCode.USAGE)


ROBOT_HINT = "give a robot name (talos, g1, icub, romeo; `wbmp robots` lists them) or a profile file"


#: The code of an exception that carries its own (:class:`CliError` and its subclasses: ``.code``).
OWN: Literal["own"] = "own"


class ExitRule(NamedTuple):
    """One row of :func:`exit_table`.

    Attributes:
        exception: The exception class.
        code: The exit code; :data:`OWN` for an exception that carries one; None for a class that
            must never reach the CLI (caught inside its layer, or a bug if it escapes): the CLI
            prints the traceback and exits 1 (``wbmp.cli.run``).
        why: What the exception means, in the words of docs/cli.md.
    """

    exception: type[BaseException]
    code: ExitCode | Literal["own"] | None
    why: str


_R = ExitRule  # the rows below, one per line


def _root_rows() -> tuple[ExitRule, ...]:
    """The root of the project's errors and the layers' bases without a code of their own."""
    from robots import WbmpError
    from viz import VizError

    return (
        _R(WbmpError, None, "the root of the project's errors: a class without a row of its own is a bug"),
        _R(VizError, None, "the viz layer's base: each of its errors has a row of its own"),
    )


def _cli_rows() -> tuple[ExitRule, ...]:
    """The CLI itself."""
    return (
        _R(CliError, OWN, "a refused input of the CLI, with the code it names"),
        _R(MotionFileError, OWN, "a missing or damaged motion file (exit 2; 3: times beyond 3600 s)"),
        _R(Terminated, ExitCode.TERMINATED, "SIGTERM"),
        _R(KeyboardInterrupt, ExitCode.INTERRUPTED, "Ctrl-C (SIGINT)"),
    )


def _language_rows() -> tuple[ExitRule, ...]:
    """Language: a sentence that is not understood."""
    from language import (
        AmbiguousInstruction,
        BackendError,
        EmptyInstruction,
        InvalidParameter,
        LanguageError,
        LLMError,
        LLMReplyInvalid,
        LLMUnavailable,
        NoAction,
        SchemaViolation,
        UnknownWords,
        UnsupportedInstruction,
        UnsupportedSchema,
        VocabularyError,
    )

    return (
        _R(LanguageError, ExitCode.USAGE, "the instruction is not understood"),
        _R(EmptyInstruction, ExitCode.USAGE, "an empty instruction"),
        _R(UnknownWords, ExitCode.USAGE, "words the parser does not know"),
        _R(NoAction, ExitCode.USAGE, "no action in the instruction"),
        _R(AmbiguousInstruction, ExitCode.USAGE, "an instruction with two readings"),
        _R(UnsupportedInstruction, ExitCode.USAGE, "an action the robots cannot do"),
        _R(InvalidParameter, ExitCode.USAGE, "a parameter the sentence gives out of range"),
        _R(BackendError, ExitCode.USAGE, "the parser backend failed"),
        _R(LLMError, ExitCode.USAGE, "the LLM backend failed"),
        _R(LLMUnavailable, ExitCode.USAGE, "the LLM server cannot be reached or refused"),
        _R(LLMReplyInvalid, ExitCode.USAGE, "the LLM's reply is not an action plan"),
        _R(SchemaViolation, ExitCode.USAGE, "an action plan against the registry's schema"),
        _R(VocabularyError, None, "the shipped vocabulary is inconsistent: a bug"),
        _R(UnsupportedSchema, None, "a schema keyword the validator lacks: a bug"),
    )


def _spec_rows() -> tuple[ExitRule, ...]:
    """Robots and tasks: an invalid spec, parameter or robot."""
    from robots import FrameNotFound, ProfileError, RobotError, RobotNotFound
    from tasks import (
        BeyondCapability,
        ClipError,
        GroundingError,
        SceneConflict,
        TaskDefinitionError,
        TaskError,
        UnknownAction,
    )

    return (
        _R(RobotError, ExitCode.INVALID_SPEC, "a robot that cannot be loaded"),
        _R(RobotNotFound, ExitCode.INVALID_SPEC, "an unknown robot name"),
        _R(FrameNotFound, ExitCode.INVALID_SPEC, "a frame the robot does not have"),
        _R(ProfileError, ExitCode.INVALID_SPEC, "a bad robot profile file"),
        _R(TaskError, ExitCode.INVALID_SPEC, "an invalid task spec"),
        _R(TaskDefinitionError, ExitCode.INVALID_SPEC, "an invalid spec or parameter"),
        _R(UnknownAction, ExitCode.INVALID_SPEC, "an unknown primitive name"),
        _R(BeyondCapability, ExitCode.INFEASIBLE,
           "a motion beyond the robot's torques or beyond what is certified in simulation (hop, jog, a jump too high or too long)"),
        _R(SceneConflict, ExitCode.INFEASIBLE,
           "a hand target or a footstep inside a scene object, or an object walk_to cannot reach"),
        _R(ClipError, ExitCode.INVALID_SPEC,
           "a motion-capture clip that cannot be used (damaged BVH, unknown skeleton, a window outside it)"),
        _R(GroundingError, ExitCode.INVALID_SPEC, "an object reference that names no object of the scene, or several"),
    )


def _planner_rows() -> tuple[ExitRule, ...]:
    """Planner: infeasible, or the solver failed (with a diagnosis)."""
    from planner import (
        PlannerError,
        PlanningFailed,
        SpecNotForRobot,
        StagewiseUnsupported,
        UnsupportedModel,
    )

    return (
        _R(PlannerError, ExitCode.INFEASIBLE, "the planner failed"),
        _R(PlanningFailed, ExitCode.INFEASIBLE, "no plan: infeasible or the solver failed"),
        _R(StagewiseUnsupported, ExitCode.USAGE,
           "the stage-wise transcription asked for a dynamic plan (kinematic plans only)"),
        _R(UnsupportedModel, ExitCode.INVALID_SPEC, "a joint type the planner cannot model"),
        _R(SpecNotForRobot, ExitCode.INVALID_SPEC, "a joint or frame the robot does not have"),
    )


def _store_rows() -> tuple[ExitRule, ...]:
    """The stores and the file readers: caught inside the layer that raised them."""
    from robots import EntryDamaged, EntryStale, FileTooLarge, NotRegularFile, PathEscapes

    return (
        _R(EntryDamaged, None, "caught inside the solver, robot, MuJoCo and HTML mesh caches"),
        _R(EntryStale, None, "caught inside the robot and HTML mesh caches"),
        _R(NotRegularFile, None, "an OSError every reader catches (a FIFO, device or folder refused)"),
        _R(FileTooLarge, None, "an OSError every reader catches (a file over its kind's bound)"),
        _R(PathEscapes, None, "caught by the caches (a path read from a cache file that leads out)"),
    )


def _sim_rows() -> tuple[ExitRule, ...]:
    """Simulation: planned, but the closed-loop check failed or could not run."""
    from planner import ControllerError
    from sim import FaultsError, PushParseError, SimError, SimModelError

    return (
        _R(ControllerError, ExitCode.SIM_FAILED,
           "the whole-body controller cannot be set up (settings, QP backend): no simulation check"),
        _R(SimError, ExitCode.SIM_FAILED, "the simulation check failed or could not run"),
        _R(SimModelError, ExitCode.SIM_FAILED, "the robot cannot be built in MuJoCo"),
        _R(PushParseError, ExitCode.USAGE, "a bad --push"),
        _R(FaultsError, ExitCode.INVALID_SPEC, "a bad --faults file (docs/safety.md)"),
    )


def _output_rows() -> tuple[ExitRule, ...]:
    """Outputs and viewers."""
    from viz import OutputError, OutputPathError, OutputWriteError, ViewerError, VizInputError

    return (
        _R(OutputError, ExitCode.USAGE, "an output file refused or not written"),
        _R(OutputPathError, ExitCode.USAGE, "a bad output path"),
        _R(OutputWriteError, ExitCode.USAGE, "an output that could not be written (nothing was)"),
        _R(VizInputError, None,
           "arrays that do not match the robot: a bug (`wbmp show` names the motion file, exit 2)"),
        _R(ViewerError, ExitCode.INTERNAL, "the meshcat server did not start or died (one line)"),
    )


def _serve_rows() -> tuple[ExitRule, ...]:
    """``wbmp serve``: shown on the page as one line with this code (HTTP 400, 429, 503)."""
    return (
        _R(CorrectionError, ExitCode.USAGE, "a correction that changes nothing of the last motion"),
        _R(Busy, ExitCode.USAGE, "wbmp serve's queue is full (HTTP 429)"),
        _R(Unavailable, ExitCode.INTERNAL, "wbmp serve's planning process is not running (HTTP 503)"),
    )


@functools.cache
def exit_table() -> tuple[ExitRule, ...]:
    """Every exception class of every layer and its exit code, keyed by the class.

    docs/cli.md holds the same table, and tests/wbmp/test_errors.py checks that each public
    exception class defined in the packages has its row. A class decides by its own row;
    :func:`classify` walks the exception's classes most specific first (``type(exc).__mro__``), so
    an exception from outside the project that subclasses one of these gets its nearest
    ancestor's code; a private class (``_Refused``), caught inside its module, has no row.

    Every class lives in its layer's exception module (``robots.exceptions``, ``tasks.exceptions``,
    ``language.exceptions``, ``planner.exceptions``, ``sim.exceptions``, ``viz.exceptions``, this
    module; the stores' and readers' ``OSError`` kinds in ``robots.store`` and ``robots.safeio``):
    building the table imports those light modules only, never a layer's heavy code (CasADi, MuJoCo,
    the server). It is built on the first error classified, not when the CLI starts.
    """
    return (_root_rows() + _cli_rows() + _language_rows() + _spec_rows() + _planner_rows() + _store_rows()
            + _sim_rows() + _output_rows() + _serve_rows())


def full_name(cls: type) -> str:
    """``module.Class`` of a class, as docs/cli.md names it."""
    return f"{cls.__module__}.{cls.__qualname__}"


@functools.cache
def _rules() -> dict[type[BaseException], ExitRule]:
    return {rule.exception: rule for rule in exit_table()}


def classify(exc: BaseException) -> ExitCode | None:
    """Exit code of an exception by :func:`exit_table`; None for an unexpected one (a bug).

    The most specific class with a row decides (the exception's own class, then its bases in
    method resolution order); a row without a code (None) means a bug: the traceback is shown.
    """
    for cls in type(exc).__mro__:
        rule = _rules().get(cls)
        if rule is not None:
            if rule.code == "own":  # CliError and its subclasses carry their code
                return ExitCode(exc.code)  # type: ignore[attr-defined]
            return rule.code
    return None
