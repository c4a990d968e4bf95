r"""Exit codes of the CLI (docs/cli.md), the table from every exception class of the layers
to them (:data:`EXIT_TABLE`, :func:`classify`), and the one-line form of an error message.

Every message the CLI prints for a refused input goes through :func:`one_line`: control
characters (ANSI escapes, NUL, bells, newlines), bidirectional overrides and the lone surrogates
of a non-UTF-8 argument are shown escaped (``\x1b``, ``\u202e``, ``\udcff``), never sent raw to
the terminal, and a message longer than :data:`MAX_MESSAGE` characters (a 1 MB sentence quoted
back) keeps its start and end around a ``[... N characters cut ...]`` mark.
"""

from __future__ import annotations

import enum
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
    """One row of :data:`EXIT_TABLE`.

    Attributes:
        exception: Full name of the class, ``module.Class``, the module being where it is defined.
        code: The exit code; :data:`OWN` for an exception that carries one; None for a class that
            must never reach the CLI (caught inside its layer, or a bug if it escapes): the CLI
            prints the traceback and exits 1 (``wbmp.cli.run``).
        why: What the exception means, in the words of docs/cli.md.
    """

    exception: str
    code: ExitCode | Literal["own"] | None
    why: str


_R = ExitRule
#: Every exception class of every layer and its exit code (docs/cli.md holds the same table, and
#: tests/wbmp/test_errors.py checks that each class defined in the packages has its row). A class
#: decides by its own row; :func:`classify` walks the exception's classes most specific first
#: (``type(exc).__mro__``), so an exception from outside the project that subclasses one of these
#: gets its nearest ancestor's code.
EXIT_TABLE: tuple[ExitRule, ...] = (
    # the root of the project's errors and the layers' bases without a code of their own
    _R("robots.exceptions.WbmpError", None, "the root of the project's errors: a class without a row of its own is a bug"),
    _R("viz.exceptions.VizError", None, "the viz layer's base: each of its errors has a row of its own"),
    # the CLI itself
    _R("wbmp.errors.CliError", OWN, "a refused input of the CLI, with the code it names"),
    _R("wbmp.motionfile.MotionFileError", OWN, "a missing or damaged motion file (exit 2; 3: times beyond 3600 s)"),
    _R("wbmp.errors.Terminated", ExitCode.TERMINATED, "SIGTERM"),
    _R("builtins.KeyboardInterrupt", ExitCode.INTERRUPTED, "Ctrl-C (SIGINT)"),
    # language: a sentence that is not understood
    _R("language.exceptions.LanguageError", ExitCode.USAGE, "the instruction is not understood"),
    _R("language.exceptions.EmptyInstruction", ExitCode.USAGE, "an empty instruction"),
    _R("language.exceptions.UnknownWords", ExitCode.USAGE, "words the parser does not know"),
    _R("language.exceptions.NoAction", ExitCode.USAGE, "no action in the instruction"),
    _R("language.exceptions.AmbiguousInstruction", ExitCode.USAGE, "an instruction with two readings"),
    _R("language.exceptions.UnsupportedInstruction", ExitCode.USAGE, "an action the robots cannot do"),
    _R("language.exceptions.InvalidParameter", ExitCode.USAGE, "a parameter the sentence gives out of range"),
    _R("language.exceptions.BackendError", ExitCode.USAGE, "the parser backend failed"),
    _R("language.exceptions.LLMError", ExitCode.USAGE, "the LLM backend failed"),
    _R("language.exceptions.LLMUnavailable", ExitCode.USAGE, "the LLM server cannot be reached or refused"),
    _R("language.exceptions.LLMReplyInvalid", ExitCode.USAGE, "the LLM's reply is not an action plan"),
    _R("language.validate.SchemaViolation", ExitCode.USAGE, "an action plan against the registry's schema"),
    _R("language.llm._ReplyError", ExitCode.USAGE, "an invalid LLM reply (caught: it triggers the retry)"),
    _R("language.exceptions.VocabularyError", None, "the shipped vocabulary is inconsistent: a bug"),
    _R("language.validate.UnsupportedSchema", None, "a schema keyword the validator lacks: a bug"),
    _R("language.llm._BadNumber", None, "caught inside language.llm"),
    _R("language.llm._Deadline", None, "caught inside language.llm"),
    _R("language.llm._TooLarge", None, "caught inside language.llm"),
    _R("language.llm._BadEncoding", None, "caught inside language.llm"),
    # robots and tasks: an invalid spec, parameter or robot
    _R("robots.exceptions.RobotError", ExitCode.INVALID_SPEC, "a robot that cannot be loaded"),
    _R("robots.exceptions.RobotNotFound", ExitCode.INVALID_SPEC, "an unknown robot name"),
    _R("robots.exceptions.FrameNotFound", ExitCode.INVALID_SPEC, "a frame the robot does not have"),
    _R("robots.exceptions.ProfileError", ExitCode.INVALID_SPEC, "a bad robot profile file"),
    _R("tasks.exceptions.TaskError", ExitCode.INVALID_SPEC, "an invalid task spec"),
    _R("tasks.exceptions.TaskDefinitionError", ExitCode.INVALID_SPEC, "an invalid spec or parameter"),
    _R("tasks.exceptions.UnknownAction", ExitCode.INVALID_SPEC, "an unknown primitive name"),
    _R("tasks.exceptions.BeyondCapability", ExitCode.INFEASIBLE,
       "a motion beyond the robot's torques or beyond what is certified in simulation (hop, jog, a jump too high or too long)"),
    _R("tasks.exceptions.SceneConflict", ExitCode.INFEASIBLE,
       "a hand target or a footstep inside a scene object, or an object walk_to cannot reach"),
    _R("tasks.mocap.exceptions.ClipError", ExitCode.INVALID_SPEC,
       "a motion-capture clip that cannot be used (damaged BVH, unknown skeleton, a window outside it)"),
    _R("tasks.grounding.GroundingError", ExitCode.INVALID_SPEC, "an object reference that names no object of the scene, or several"),
    _R("tasks.jsonio._Refused", None, "caught inside tasks.jsonio"),
    # planner: infeasible, or the solver failed (with a diagnosis)
    _R("planner.exceptions.PlannerError", ExitCode.INFEASIBLE, "the planner failed"),
    _R("planner.exceptions.PlanningFailed", ExitCode.INFEASIBLE, "no plan: infeasible or the solver failed"),
    _R("planner.trajopt.stagewise.StagewiseUnsupported", ExitCode.USAGE,
       "the stage-wise transcription asked for a dynamic plan (kinematic plans only)"),
    _R("planner.exceptions.UnsupportedModel", ExitCode.INVALID_SPEC, "a joint type the planner cannot model"),
    _R("planner.exceptions.SpecNotForRobot", ExitCode.INVALID_SPEC, "a joint or frame the robot does not have"),
    _R("robots.store.EntryDamaged", None, "caught inside the solver, robot, MuJoCo and HTML mesh caches"),
    _R("robots.store.EntryStale", None, "caught inside the robot and HTML mesh caches"),
    _R("robots.safeio.NotRegularFile", None, "an OSError every reader catches (a FIFO, device or folder refused)"),
    _R("robots.safeio.FileTooLarge", None, "an OSError every reader catches (a file over its kind's bound)"),
    _R("robots.safeio.PathEscapes", None, "caught by the caches (a path read from a cache file that leads out)"),
    _R("wbmp.batch.items._NonFinite", None, "caught by the batch reader (a JSONL number with no finite value)"),
    # simulation: planned, but the closed-loop check failed or could not run
    _R("planner.wbc.settings.ControllerError", ExitCode.SIM_FAILED,
       "the whole-body controller cannot be set up (settings, QP backend): no simulation check"),
    _R("sim.exceptions.SimError", ExitCode.SIM_FAILED, "the simulation check failed or could not run"),
    _R("sim.exceptions.SimModelError", ExitCode.SIM_FAILED, "the robot cannot be built in MuJoCo"),
    _R("sim.exceptions.PushParseError", ExitCode.USAGE, "a bad --push"),
    _R("sim.exceptions.FaultsError", ExitCode.INVALID_SPEC, "a bad --faults file (docs/safety.md)"),
    # outputs and viewers
    _R("viz.files.OutputError", ExitCode.USAGE, "an output file refused or not written"),
    _R("viz.files.OutputPathError", ExitCode.USAGE, "a bad output path"),
    _R("viz.files.OutputWriteError", ExitCode.USAGE, "an output that could not be written (nothing was)"),
    _R("viz.motion.VizInputError", None,
       "arrays that do not match the robot: a bug (`wbmp show` names the motion file, exit 2)"),
    _R("viz.live.ViewerError", ExitCode.INTERNAL, "the meshcat server did not start or died (one line)"),
    # wbmp serve: shown on the page as one line with this code (HTTP 400, 429, 503)
    _R("wbmp.serve.corrections.CorrectionError", ExitCode.USAGE, "a correction that changes nothing of the last motion"),
    _R("wbmp.serve.session.Busy", ExitCode.USAGE, "wbmp serve's queue is full (HTTP 429)"),
    _R("wbmp.serve.session.Unavailable", ExitCode.INTERNAL, "wbmp serve's planning process is not running (HTTP 503)"),
)
del _R
_RULES = {rule.exception: rule for rule in EXIT_TABLE}


def full_name(cls: type) -> str:
    """``module.Class`` of a class: its key in :data:`EXIT_TABLE`."""
    return f"{cls.__module__}.{cls.__qualname__}"


def classify(exc: BaseException) -> ExitCode | None:
    """Exit code of an exception by :data:`EXIT_TABLE`; None for an unexpected one (a bug).

    The most specific class with a row decides (the exception's own class, then its bases in
    method resolution order); a row without a code (None) means a bug: the traceback is shown.
    """
    for cls in type(exc).__mro__:
        rule = _RULES.get(full_name(cls))
        if rule is not None:
            if rule.code == "own":  # CliError and its subclasses carry their code
                return ExitCode(exc.code)  # type: ignore[attr-defined]
            return rule.code
    return None
