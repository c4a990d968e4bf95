"""Exceptions raised by the robots layer."""

from __future__ import annotations


class WbmpError(Exception):
    """The root of every error the project raises on purpose.

    One subclass per layer: :class:`RobotError` (robots), ``tasks.TaskError``,
    ``language.LanguageError``, ``planner.PlannerError``, ``sim.SimError``, ``viz.VizError`` and
    ``wbmp.errors.CliError``; ``wbmp.errors.exit_table()`` gives each class its exit code. It lives
    in the lowest layer so that every package can derive from it.
    """


class RobotError(WbmpError):
    """Base class of every error about a robot model or profile."""


class RobotNotFound(RobotError):
    """The robot name or path does not name a known robot."""

    def __init__(self, name: str, available: list[str]) -> None:
        self.name = name
        self.available = available
        super().__init__(
            f"unknown robot {_short(name)}; available: {', '.join(available)} "
            "(or give a profile file: path/to/robot.toml)"
        )


class FrameNotFound(RobotError):
    """A profile or spec names a frame that the Pinocchio model does not have.

    The message suggests close matches, or lists a few of the frames the model has. ``where``
    (e.g. ``myrobot.toml: frames.left_foot``) prefixes the message when the name came from a file.
    """

    def __init__(self, name: str, robot: str, available: list[str], *, where: str = "") -> None:
        self.name = name
        self.available = available
        close = _closest(name, available)
        if close:
            hint = f"; did you mean {', '.join(repr(c) for c in close)}?"
        elif available:
            some = [a for a in available if a not in ("universe", "root_joint")][:6] or available[:6]
            more = f", ... ({len(available)} in all)" if len(available) > len(some) else ""
            hint = f"; its frames include {', '.join(repr(a) for a in some)}{more}"
        else:
            hint = ""
        prefix = f"{where}: " if where else ""
        super().__init__(f"{prefix}robot {robot!r} has no frame {_short(name)}{hint}")


class ProfileError(RobotError):
    """A robot profile file is malformed or names files that do not exist."""


def _short(name: object) -> str:
    """``repr`` of a user's name, cut to a length that keeps the message on one readable line."""
    text = repr(name)
    return text if len(text) <= 80 else text[:70] + "...' (" + f"{len(str(name))} characters)"


def _closest(name: str, candidates: list[str]) -> list[str]:
    import difflib

    if len(str(name)) > 200:  # no frame name is that long, and difflib is quadratic
        return []
    return difflib.get_close_matches(str(name), candidates, n=3, cutoff=0.5)
