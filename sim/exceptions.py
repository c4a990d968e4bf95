"""Exceptions raised by the simulation layer."""

from __future__ import annotations

from robots import WbmpError


class SimError(WbmpError):
    """Base class of every simulation error."""


class SimModelError(SimError):
    """The robot's URDF cannot be turned into a MuJoCo model."""


class PushParseError(SimError, ValueError):
    """A push is not ``FORCE@TIME`` (e.g. ``80@1.5``), or a value is out of range: the force
    (above 0 N, at most ``sim.push.MAX_PUSH_FORCE``), the time (within the motion) or the duration.
    The CLI maps it to exit code 2 (bad usage)."""


class FaultsError(SimError, ValueError):
    """A faults file (``wbmp solve --faults FILE``) that cannot be read, is not JSON, has an unknown
    key or a value out of range (docs/safety.md). The CLI maps it to exit code 3 (invalid input)."""
