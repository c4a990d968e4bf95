"""Exceptions raised by the tasks layer."""

from __future__ import annotations


class TaskError(Exception):
    """Base class of every error about a task specification or an action."""


class TaskDefinitionError(TaskError, ValueError):
    """A spec or action parameter is invalid (out of range, wrong type, unknown frame...)."""


class UnknownAction(TaskDefinitionError):
    """An action name is not in the registry."""

    def __init__(self, name: str, available: list[str]) -> None:
        import difflib

        self.name = name
        self.available = available
        close = difflib.get_close_matches(name, available, n=3, cutoff=0.5)
        hint = f"; did you mean {', '.join(close)}?" if close else f"; known actions: {', '.join(available)}"
        super().__init__(f"unknown action {name!r}{hint}")


class SceneConflict(TaskError):
    """A hand target or a footstep lies inside a scene object: infeasible in that scene (exit 4).

    Attributes:
        object_name: The object's name.
    """

    def __init__(self, message: str, object_name: str) -> None:
        self.object_name = object_name
        super().__init__(message)
