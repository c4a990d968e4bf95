"""Exceptions raised by the simulation layer."""

from __future__ import annotations


class SimError(Exception):
    """Base class of every simulation error."""


class SimModelError(SimError):
    """The robot's URDF cannot be turned into a MuJoCo model."""


class PushParseError(SimError, ValueError):
    """A ``--push`` text is not ``FORCE@TIME`` (e.g. ``80@1.5``)."""
