"""Simulation check: MuJoCo model from the robot's URDF, closed-loop WBC, certificate."""

from sim.certificate import Certificate, Check
from sim.exceptions import PushParseError, SimError, SimModelError
from sim.execution import Event, Execution
from sim.model import SimModel, build_model
from sim.run import Push, SimSettings, parse_push, simulate

__all__ = [
    "Certificate",
    "Check",
    "Event",
    "Execution",
    "Push",
    "PushParseError",
    "SimError",
    "SimModel",
    "SimModelError",
    "SimSettings",
    "build_model",
    "parse_push",
    "simulate",
]
