"""Only the command line reads the planner's ``WBMP_*`` switches (wbmp/environment.py); the
planner's own defaults are constants, whatever the shell says."""

from __future__ import annotations

import ast
import os
import subprocess
import sys
from pathlib import Path

import pytest

from planner import PlannerSettings, SolverSettings
from planner.trajopt.builds import BUILD_MEMORY
from wbmp.environment import planner_settings, settings_from_environment
from wbmp.errors import CliError, ExitCode

ROOT = Path(__file__).resolve().parents[2]
SWITCHES = ("WBMP_COMPILE", "WBMP_COMPILE_BACKGROUND", "WBMP_SOLUTION_LIBRARY", "WBMP_BUILD_MEMORY", "WBMP_COMPILER")


def _environment_reads(path: Path) -> list[str]:
    """``WBMP_*`` names read through ``os.environ.get``/``[...]``, ``os.getenv`` in one file."""
    names = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        key = None
        if isinstance(node, ast.Call) and node.args and isinstance(node.func, ast.Attribute) and \
                node.func.attr in ("get", "getenv", "setdefault", "pop"):
            key = node.args[0]
        elif isinstance(node, ast.Subscript) and ast.unparse(node.value).endswith("environ"):
            key = node.slice
        if isinstance(key, ast.Constant) and isinstance(key.value, str) and key.value.startswith("WBMP_") \
                and "environ" in ast.unparse(node) + ("getenv" if isinstance(node, ast.Call) else ""):
            names.append(f"{path.relative_to(ROOT)}:{node.lineno} {key.value}")
    return names


def test_the_planner_reads_no_wbmp_switch():
    """No module of planner/ reads a WBMP_* variable (the check finds the reads wbmp/ does)."""
    reads = [r for path in sorted((ROOT / "planner").rglob("*.py")) for r in _environment_reads(path)]
    assert reads == []
    assert any("WBMP_COMPILE" in r for r in _environment_reads(ROOT / "wbmp" / "environment.py"))


def test_library_defaults_ignore_the_shell(monkeypatch):
    """PlannerSettings() is the same with every switch set the other way: in memory, no library, and a
    compile (when asked for) in the foreground: a library call leaves no detached process."""
    for name, value in zip(SWITCHES, ("1", "0", "on", "1M", "clang"), strict=True):
        monkeypatch.setenv(name, value)
    s = PlannerSettings()
    c = s.cache
    assert (c.compile, c.background_compile, c.solution_library, c.build_memory, c.compiler) == \
        (False, False, "off", BUILD_MEMORY, "gcc")


@pytest.mark.parametrize("environ, expected", [
    ({}, (True, True, "on", BUILD_MEMORY, "gcc")),
    ({"WBMP_COMPILE": "0", "WBMP_COMPILE_BACKGROUND": "no", "WBMP_SOLUTION_LIBRARY": "read",
      "WBMP_BUILD_MEMORY": "2500M", "WBMP_COMPILER": " clang "}, (False, False, "read", 2500 << 20, "clang")),
    ({"WBMP_COMPILE": "false", "WBMP_SOLUTION_LIBRARY": "0", "WBMP_BUILD_MEMORY": "0"},
     (False, True, "off", 0, "gcc")),
    ({"WBMP_SOLUTION_LIBRARY": "sometimes", "WBMP_BUILD_MEMORY": "3.5GiB"}, (True, True, "on", int(3.5 * (1 << 30)), "gcc")),
], ids=["unset", "all-set", "off-words", "unknown-mode"])
def test_the_command_line_reads_the_switches(environ, expected):
    """The same words the planner used to read, with the same defaults when unset."""
    got = settings_from_environment(environ)
    assert tuple(got[k] for k in ("compile", "background_compile", "solution_library", "build_memory",
                                  "compiler")) == expected
    s = planner_settings(environ, solver=SolverSettings(max_iterations=7))
    assert s.solver.max_iterations == 7 and s.cache.compile == expected[0] and s.cache.solution_library == expected[2]


def test_given_fields_win_over_the_environment():
    s = planner_settings({"WBMP_COMPILE": "1", "WBMP_SOLUTION_LIBRARY": "on"},
                         cache={"compile": False, "solution_library": "off"})
    assert not s.cache.compile and s.cache.solution_library == "off"


def test_a_build_memory_that_is_not_a_size_is_one_line_exit_2():
    with pytest.raises(CliError) as info:
        settings_from_environment({"WBMP_BUILD_MEMORY": "lots"})
    assert info.value.code == ExitCode.USAGE and "WBMP_BUILD_MEMORY='lots' is not a size" in str(info.value)
    env = {**os.environ, "WBMP_BUILD_MEMORY": "lots", "PYTHONPATH": str(ROOT)}
    out = subprocess.run([sys.executable, "-m", "wbmp", "cache", "planner"], cwd=ROOT, env=env,
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == ExitCode.USAGE and "Traceback" not in out.stderr
    assert len(out.stderr.strip().splitlines()) == 1 and "WBMP_BUILD_MEMORY" in out.stderr
