"""The ``wbmp`` command line.

Each subcommand lives in ``wbmp/commands/<name>.py`` with ``add_parser(subparsers)`` and
``run(args) -> int``; this module only assembles them and turns known errors into a
one-line message and the exit code of :class:`wbmp.errors.ExitCode`.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
import warnings

from wbmp import __version__
from wbmp.errors import ExitCode, classify

COMMANDS = ("solve", "parse", "show", "export", "bench", "robots", "actions", "demo")

ISSUES_HINT = "this is a bug in wbmp; please report it with the command line and the traceback above"


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every available subcommand."""
    parser = argparse.ArgumentParser(
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
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the console script; returns the exit code."""
    warnings.filterwarnings("ignore", category=DeprecationWarning, module="zmq")
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "command", None):
        parser.print_help()
        return ExitCode.USAGE
    debug = getattr(args, "debug", False)
    try:
        return int(args.run(args))
    except KeyboardInterrupt:
        print("wbmp: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # The reader went away (`wbmp robots | head`): stop quietly, as Unix tools do.
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return ExitCode.OK
    except Exception as exc:  # noqa: BLE001 - the CLI boundary
        code = classify(exc)
        if code is None or debug:
            raise
        print(f"wbmp {args.command}: error: {exc}", file=sys.stderr)
        return code


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
