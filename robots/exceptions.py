"""Exceptions raised by the robots layer."""

from __future__ import annotations


class RobotError(Exception):
    """Base class of every error about a robot model or profile."""


class RobotNotFound(RobotError):
    """The robot name or path does not name a known robot."""

    def __init__(self, name: str, available: list[str]) -> None:
        self.name = name
        self.available = available
        super().__init__(
            f"unknown robot {name!r}; available: {', '.join(available)} "
            "(or give a profile file: path/to/robot.toml)"
        )


class FrameNotFound(RobotError):
    """A profile or spec names a frame that the Pinocchio model does not have."""

    def __init__(self, name: str, robot: str, available: list[str]) -> None:
        self.name = name
        self.available = available
        close = _closest(name, available)
        hint = f"; did you mean {', '.join(repr(c) for c in close)}?" if close else ""
        super().__init__(f"robot {robot!r} has no frame {name!r}{hint}")


class ProfileError(RobotError):
    """A robot profile file is malformed or names files that do not exist."""


def _closest(name: str, candidates: list[str]) -> list[str]:
    import difflib

    return difflib.get_close_matches(name, candidates, n=3, cutoff=0.5)
