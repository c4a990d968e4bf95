"""The one lazy public face (robots/lazy.py) every package's ``__init__`` uses: each public name
resolves to the object its module defines, ``dir()`` lists it, an unknown name is an
AttributeError, and importing a face loads none of the heavy libraries."""

from __future__ import annotations

import importlib
import subprocess
import sys

import pytest

FACES = ("robots", "tasks", "planner", "planner.trajopt", "planner.wbc", "planner.trajopt.centroidal", "sim",
         "viz", "wbmp.bench")


@pytest.mark.parametrize("package", FACES)
def test_every_public_name_is_its_modules_object(package):
    face = importlib.import_module(package)
    exports = getattr(face, "_EXPORTS", None) or face._LAZY
    assert exports, package
    for name, module in exports.items():
        assert getattr(face, name) is getattr(importlib.import_module(module), name), (package, name)
        assert name in dir(face)
    with pytest.raises(AttributeError, match=f"module '{package}' has no attribute 'no_such_name'"):
        face.no_such_name  # noqa: B018


def test_importing_the_faces_loads_no_heavy_library():
    code = ("import sys; import robots, tasks, planner, sim, viz; "
            "print(sorted(m for m in ('casadi', 'mujoco', 'pinocchio', 'proxsuite') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=120)
    assert out.stdout.strip() == "[]", out.stdout + out.stderr


def test_what_a_motion_cache_hit_imports_loads_no_heavy_library():
    """``wbmp solve`` answering a repeated request from the motion cache makes a StopRequest (SIGUSR1)
    and reads the stored actions (``language.ActionPlan``) before anything is planned: neither may load
    pinocchio, the planner's or simulation's libraries, or the rules parser's lexicon (~0.5 s of a
    0.7 s repeat, docs/performance.md). The parser still works afterwards."""
    code = ("import sys; from sim import StopRequest; StopRequest(); "
            "from language import ActionPlan, LanguageError, parse; import wbmp.pipeline, wbmp.motioncache; "
            "print(sorted(m for m in ('casadi', 'mujoco', 'pinocchio', 'language.rules', 'language.lexicon') "
            "if m in sys.modules)); print(parse('squat').actions[0].name)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=120)
    assert out.stdout.split() == ["[]", "squat"], out.stdout + out.stderr
