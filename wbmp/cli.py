"""The ``wbmp`` command line.

Each subcommand lives in ``wbmp/commands/<name>.py`` with ``add_parser(subparsers)`` and
``run(args) -> int``; this module only assembles them and turns known errors into a
one-line message and the exit code of :class:`wbmp.errors.ExitCode`.

What every subcommand shares:

- a refused input is one line ``wbmp <command>: error: <message>`` on stderr, the message
  escaped and bounded by :func:`wbmp.errors.one_line` (no raw ANSI escapes, NUL or newlines
  from the user's text reach the terminal); argparse's own usage errors (an unknown option,
  a missing argument, a bad number) print the command's usage block, then such a line, exit 2;
- Ctrl-C (SIGINT) stops with ``wbmp: interrupted``, exit 130; SIGTERM with
  ``wbmp: terminated``, exit 143; both unwind every ``finally``, so no temporary file is left
  and nothing is half-written; a second SIGTERM during that cleanup is ignored;
- a reader that goes away (``wbmp robots | head -1``) ends the command quietly (exit 0).
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import signal
import sys
import threading
import warnings
from collections.abc import Iterator
from typing import NoReturn

from wbmp import __version__
from wbmp.errors import (
    ExitCode,
    Terminated,
    check_signals,
    classify,
    clear_signals,
    note_signal,
    one_line,
)

COMMANDS = ("solve", "retarget", "parse", "show", "export", "bench", "robots", "actions", "demo", "batch", "cache",
            "serve")

ISSUES_HINT = "this is a bug in wbmp; please report it with the command line and the traceback above"


class _Parser(argparse.ArgumentParser):
    """argparse with its usage errors on one escaped line (exit 2), after the usage block."""

    subcommands: dict[str, argparse.ArgumentParser]

    def error(self, message: str) -> NoReturn:
        self.print_usage(sys.stderr)
        self.exit(ExitCode.USAGE, f"{self.prog}: error: {one_line(message)}\n")


def build_parser() -> _Parser:
    """The argument parser with every available subcommand."""
    parser = _Parser(
        prog="wbmp",
        description="Whole-body motion planning for humanoid robots from a sentence.",
        epilog='example: wbmp solve "wave your right hand twice, then squat" --html wave.html',
    )
    parser.add_argument("--version", action="version", version=f"wbmp {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS:
        try:
            module = importlib.import_module(f"wbmp.commands.{name}")
        except ModuleNotFoundError as e:
            if e.name == f"wbmp.commands.{name}":
                continue  # not built yet
            raise
        module.add_parser(sub)
    parser.subcommands = dict(sub.choices)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the console script; returns the exit code."""
    with _signal_handlers():
        try:
            return _main(argv)
        except KeyboardInterrupt:
            _quiet_print("wbmp: interrupted")
            return ExitCode.INTERRUPTED
        except Terminated:
            _quiet_print("wbmp: terminated")
            return ExitCode.TERMINATED


def _escape_unencodable() -> None:
    """A character the terminal's encoding cannot show (a Chinese sentence with
    ``PYTHONIOENCODING=ascii`` or a C locale) is written escaped (``\u6325``), never a traceback."""
    for stream in (sys.stdout, sys.stderr):
        reconfigure = getattr(stream, "reconfigure", None)
        if reconfigure is not None and getattr(stream, "errors", "strict") == "strict":
            try:
                reconfigure(errors="backslashreplace")
            except (ValueError, OSError):  # pragma: no cover - a stream that cannot change
                pass


def _main(argv: list[str] | None) -> int:
    warnings.filterwarnings("ignore", category=DeprecationWarning, module="zmq")
    _escape_unencodable()
    parser = build_parser()
    args, extras = parser.parse_known_args(argv)
    command = getattr(args, "command", None)
    if not command:
        parser.error(f"give a command: {', '.join(parser.subcommands)} (wbmp COMMAND --help tells more)")
    if extras:
        parser.subcommands[command].error(f"unrecognized arguments: {' '.join(extras)}")
    debug = getattr(args, "debug", False)
    try:
        # A command that returns normally had its interrupt handled on purpose (Ctrl-C stops the
        # live viewer, exit 0); one swallowed by a library is re-raised by the pipeline's checks.
        code = int(args.run(args))
        sys.stdout.flush()  # a closed pipe shows up here, not at exit
        return code
    except BrokenPipeError:
        # The reader went away (`wbmp robots | head`): stop quietly, as Unix tools do.
        _stdout_to_devnull()
        return ExitCode.OK
    except Exception as exc:  # the CLI boundary
        check_signals()  # a library turned the interrupt into its own error (CasADi, IPOPT)
        exit_code = classify(exc)
        if exit_code is None or debug:
            raise
        _quiet_print(f"wbmp {command}: error: {one_line(str(exc))}")
        return exit_code


def _quiet_print(line: str) -> None:
    """Print one line on stderr; a closed stderr is not a reason for a traceback."""
    with contextlib.suppress(OSError, ValueError):
        print(line, file=sys.stderr, flush=True)


def _stdout_to_devnull() -> None:
    """Point fd 1 at /dev/null so that the interpreter's last flush does not fail again."""
    with contextlib.suppress(OSError, ValueError, AttributeError):
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())


def _on_signal(signum, frame) -> None:  # noqa: ARG001 - the signal-handler signature
    note_signal(signum)  # kept: check_signals() raises it again if a library swallows the exception
    if signum == signal.SIGTERM:
        signal.signal(signal.SIGTERM, signal.SIG_IGN)  # a second SIGTERM must not cut the cleanup short
        raise Terminated()
    raise KeyboardInterrupt()


@contextlib.contextmanager
def _signal_handlers() -> Iterator[None]:
    """While the command runs (main thread only): SIGTERM raises :class:`Terminated`, SIGINT
    KeyboardInterrupt, and both are noted for :func:`wbmp.errors.check_signals`. A signal the
    process started with ignored stays ignored; a handler someone else installed is kept."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    clear_signals()
    previous = {}
    for sig, default in ((signal.SIGTERM, signal.SIG_DFL), (signal.SIGINT, signal.default_int_handler)):
        current = signal.getsignal(sig)
        if current in (default, None):
            previous[sig] = current
            signal.signal(sig, _on_signal)
    try:
        yield
    finally:
        clear_signals()
        for sig, handler in previous.items():
            signal.signal(sig, handler if handler is not None else signal.SIG_DFL)


# BLAS/OpenMP threads for the console script, unless the user set them: IPOPT's MUMPS and the
# controller's small matrices gain nothing from a second thread here (the 4-step plan used twice
# the CPU for the same wall time). Set before numpy or CasADi load their BLAS.
_THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS")


def run() -> None:
    """Console-script wrapper: map uncaught exceptions to exit code 1 with a hint."""
    for name in _THREAD_VARIABLES:
        os.environ.setdefault(name, "1")
    try:
        code = main()
    except SystemExit:
        raise
    except BaseException:  # noqa: BLE001
        import traceback

        traceback.print_exc()
        print(f"wbmp: internal error: {ISSUES_HINT}", file=sys.stderr)
        code = ExitCode.INTERNAL
    sys.exit(code)


if __name__ == "__main__":
    run()
