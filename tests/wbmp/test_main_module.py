"""``python -m wbmp`` is the console script: same output and exit codes."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _run(*argv: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run([sys.executable, "-m", "wbmp", *argv], capture_output=True, text=True, env=env,
                          cwd=ROOT, timeout=300)


def test_module_parses_a_sentence():
    out = _run("parse", "march in place")
    assert out.returncode == 0, out.stderr
    assert out.stdout.splitlines()[0].startswith("1. march")


def test_module_refuses_like_the_console_script():
    out = _run("robots", "--collisions", "nosuchbot")
    assert out.returncode == 3
    assert out.stderr.count("wbmp robots: error: unknown robot 'nosuchbot'") == 1
    assert "Traceback" not in out.stderr
