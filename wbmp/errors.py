r"""Exit codes of the CLI (DESIGN.md section 7), the mapping from exceptions to them, and the
one-line form of an error message.

Every message the CLI prints for a refused input goes through :func:`one_line`: control
characters (ANSI escapes, NUL, bells, newlines), bidirectional overrides and the lone surrogates
of a non-UTF-8 argument are shown escaped (``\x1b``, ``\u202e``, ``\udcff``), never sent raw to
the terminal, and a message longer than :data:`MAX_MESSAGE` characters (a 1 MB sentence quoted
back) keeps its start and end around a ``[... N characters cut ...]`` mark.
"""

from __future__ import annotations

import enum
import unicodedata


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


class CliError(Exception):
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


ROBOT_HINT = "give a robot name (talos, g1, icub, romeo; `wbmp robots` lists them) or a profile file"


def classify(exc: BaseException) -> ExitCode | None:
    """Exit code for a known exception type of the layers, None for an unexpected one."""
    from planner.exceptions import PlannerError, UnsupportedModel
    from robots.exceptions import RobotError
    from tasks.exceptions import TaskError

    if isinstance(exc, CliError):
        return exc.code
    language_errors: tuple[type[Exception], ...] = ()
    try:
        from language.exceptions import LanguageError

        language_errors = (LanguageError,)
    except ImportError:  # pragma: no cover - language layer not installed
        pass
    if isinstance(exc, language_errors):
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
