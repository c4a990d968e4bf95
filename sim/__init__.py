"""Simulation check: MuJoCo model from the robot's URDF, closed-loop WBC, certificate."""

from sim.certificate import Certificate, Check
from sim.exceptions import PushParseError, SimError, SimModelError
from sim.execution import Event, Execution
from sim.model import SimModel, build_model
from sim.run import MAX_PUSH_FORCE, Push, SimSettings, check_push_time, parse_push, simulate

__all__ = [
    "MAX_PUSH_FORCE",
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
    "check_push_time",
    "parse_push",
    "simulate",
]
