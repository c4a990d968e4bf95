"""The environment's say in the planner's settings: the one place that reads ``WBMP_*`` for them.

Library code reads no environment variable: :class:`planner.PlannerSettings`' defaults are
constants, and a plan depends on its arguments only (no disk cache written, no stored solution
read, unless the caller asks). The command line and the programs of :mod:`wbmp` build their
settings here, so a user's shell switches what it always did:

========================== ====================================== =========================
variable                    field of ``settings.cache``             unset
========================== ====================================== =========================
``WBMP_COMPILE``            ``compile`` (``0``/``false``/``no``:   on: gcc, solvers on disk
                            off)
``WBMP_COMPILE_BACKGROUND`` ``background_compile`` (same words)     on
``WBMP_SOLUTION_LIBRARY``   ``solution_library``: ``on``, ``read``, on
                            ``off`` (``0``/``false``/``no``)
``WBMP_BUILD_MEMORY``       ``build_memory``: a size (``3.7G``,      3.7 GB
                            ``2500M``; ``0``: no estimate)
``WBMP_COMPILER``           ``compiler``                            ``gcc``
========================== ====================================== =========================

(``WBMP_CACHE_DIR`` is read by :func:`robots.store.cache_base`, the default ``cache_dir``.) Every
variable sets a field of :class:`planner.CacheSettings`.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from wbmp.errors import CliError, ExitCode

if TYPE_CHECKING:
    from planner import PlannerSettings

OFF_WORDS = ("0", "false", "no")
LIBRARY_MODES = ("on", "read", "off")


def _flag(environ: Mapping[str, str], name: str) -> bool:
    return environ.get(name, "1").strip().lower() not in OFF_WORDS


def _library(environ: Mapping[str, str]) -> str:
    value = environ.get("WBMP_SOLUTION_LIBRARY", "on").strip().lower()
    if value in OFF_WORDS:
        return "off"
    return value if value in LIBRARY_MODES else "on"


def build_memory(environ: Mapping[str, str] | None = None) -> int:
    """``$WBMP_BUILD_MEMORY`` [bytes], else :data:`planner.trajopt.builds.BUILD_MEMORY`.

    Raises:
        CliError: Not a size (exit 2, one line saying what is accepted).
    """
    from planner import BUILD_MEMORY
    from robots import parse_size

    environ = os.environ if environ is None else environ
    text = environ.get("WBMP_BUILD_MEMORY", "").strip()
    if not text:
        return BUILD_MEMORY
    try:
        size = parse_size(text)
    except ValueError:
        raise CliError(f"WBMP_BUILD_MEMORY={text!r} is not a size: give the memory one solver build needs, "
                       "e.g. 3.7G, 2500M or a number of bytes (0: no estimate)", ExitCode.USAGE) from None
    return 0 if size is None else size


def settings_from_environment(environ: Mapping[str, str] | None = None) -> dict[str, Any]:
    """The :class:`planner.CacheSettings` fields that the environment sets (the table above),
    each with the command line's default when its variable is unset."""
    environ = os.environ if environ is None else environ
    return {
        "compile": _flag(environ, "WBMP_COMPILE"),
        "background_compile": _flag(environ, "WBMP_COMPILE_BACKGROUND"),
        "solution_library": _library(environ),
        "build_memory": build_memory(environ),
        "compiler": environ.get("WBMP_COMPILER", "").strip() or "gcc",
    }


def planner_settings(environ: Mapping[str, str] | None = None, *, cache: Mapping[str, Any] | None = None,
                     **given: Any) -> PlannerSettings:
    """:class:`planner.PlannerSettings` whose cache settings come from the environment
    (:func:`settings_from_environment`), the fields in ``cache`` winning; ``given``: the other
    fields (``solver=SolverSettings(...)``, ``collision=...``)."""
    from planner import CacheSettings, PlannerSettings

    return PlannerSettings(cache=CacheSettings(**{**settings_from_environment(environ), **(cache or {})}),
                           **given)
