"""Simulation check: MuJoCo model from the robot's URDF, closed-loop WBC, certificate.

``from sim import simulate``; public names load on first access (MuJoCo only when needed).
"""

from __future__ import annotations

import os
import sys
from typing import TYPE_CHECKING

from robots import lazy_face

# The simulation never renders: unless the user chose an OpenGL backend, MuJoCo is imported
# without one (its GLFW context costs ~0.1 s of every simulated solve). This runs before any
# sim module imports mujoco; a process that wants mujoco.Renderer after importing sim sets
# MUJOCO_GL (glfw, egl, osmesa) itself, which is kept.
if "mujoco" not in sys.modules:
    os.environ.setdefault("MUJOCO_GL", "disable")

if TYPE_CHECKING:
    from planner.results import Check, CheckKind
    from sim.certificate import Certificate
    from sim.estop import EStopSettings, Stop, StopRequest
    from sim.exceptions import FaultsError, PushParseError, SimError, SimModelError
    from sim.execution import Event, Execution
    from sim.faults import Faults, load_faults
    from sim.figures import FIGURES, summarize_figures
    from sim.loop import simulate
    from sim.model import SimModel, build_model
    from sim.push import MAX_PUSH_FORCE, Push, check_push_time, parse_push
    from sim.settings import SimSettings

_EXPORTS = {  # public name -> module that defines it
    "Certificate": "sim.certificate",
    "Check": "planner.results",
    "CheckKind": "planner.results",
    "EStopSettings": "sim.estop",
    "Event": "sim.execution",
    "Execution": "sim.execution",
    "FIGURES": "sim.figures",
    "Faults": "sim.faults",
    "FaultsError": "sim.exceptions",
    "MAX_PUSH_FORCE": "sim.push",
    "Push": "sim.push",
    "PushParseError": "sim.exceptions",
    "SimError": "sim.exceptions",
    "SimModel": "sim.model",
    "SimModelError": "sim.exceptions",
    "SimSettings": "sim.settings",
    "Stop": "sim.estop",
    "StopRequest": "sim.estop",
    "build_model": "sim.model",
    "check_push_time": "sim.push",
    "load_faults": "sim.faults",
    "parse_push": "sim.push",
    "simulate": "sim.loop",
    "summarize_figures": "sim.figures",
}

__all__ = [
    "FIGURES",
    "MAX_PUSH_FORCE",
    "Certificate",
    "Check",
    "CheckKind",
    "EStopSettings",
    "Event",
    "Execution",
    "Faults",
    "FaultsError",
    "Push",
    "PushParseError",
    "SimError",
    "SimModel",
    "SimModelError",
    "SimSettings",
    "Stop",
    "StopRequest",
    "build_model",
    "check_push_time",
    "load_faults",
    "parse_push",
    "simulate",
    "summarize_figures",
]


__getattr__, __dir__ = lazy_face(__name__, _EXPORTS)
