"""sim imports MuJoCo without an OpenGL backend (nothing renders), unless the user chose one."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
PROBE = ("import json, os, sim.model, mujoco; "
         "print(json.dumps([os.environ.get('MUJOCO_GL'), hasattr(mujoco, 'GLContext')]))")


@pytest.mark.parametrize(("preset", "expected"), [(None, ["disable", False]), ("glfw", ["glfw", True])])
def test_mujoco_gl_is_disabled_unless_set(preset, expected):
    env = {k: v for k, v in os.environ.items() if k != "MUJOCO_GL"}
    if preset is not None:
        env["MUJOCO_GL"] = preset
    env["PYTHONPATH"] = str(REPO)
    proc = subprocess.run([sys.executable, "-c", PROBE], env=env, capture_output=True, text=True, check=False,
                          cwd=REPO, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert json.loads(proc.stdout.strip().splitlines()[-1]) == expected
