"""Exceptions raised by the tasks layer."""

from __future__ import annotations

from collections.abc import Sequence

from robots import WbmpError

SUGGESTION_BAND = 0.2  # an unknown action name is offered the registry names this close to its best match


class TaskError(WbmpError):
    """Base class of every error about a task specification or an action."""


class TaskDefinitionError(TaskError, ValueError):
    """A spec or action parameter is invalid (out of range, wrong type, unknown frame...)."""


def field_error(field: str, message: str) -> TaskDefinitionError:
    """A TaskDefinitionError about ``field`` of a file (``field`` and ``reason`` set):
    :func:`tasks.jsonio.from_plain` names its path."""
    err = TaskDefinitionError(f"{field}: {message}")
    err.field = field  # type: ignore[attr-defined]
    err.reason = message  # type: ignore[attr-defined]
    return err


class UnknownAction(TaskDefinitionError):
    """An action name is not in the registry."""

    def __init__(self, name: str, available: list[str]) -> None:
        import difflib

        self.name = name
        self.available = available
        close = difflib.get_close_matches(name, available, n=3, cutoff=0.5)
        if close:  # only the names about as close as the best one ("sqat": squat, not salute or step)
            best = difflib.SequenceMatcher(None, name, close[0]).ratio()
            close = [c for c in close if difflib.SequenceMatcher(None, name, c).ratio() >= best - SUGGESTION_BAND]
        hint = f"; did you mean {', '.join(close)}?" if close else f"; known actions: {', '.join(available)}"
        super().__init__(f"unknown action {name!r}{hint}")


class BeyondCapability(TaskDefinitionError):
    """A well-formed motion beyond what the robot can do: its torques cannot (Talos hopping on one
    foot), or it was not certified in simulation (a forward hop longer or with more hops than G1's
    certified ones). Infeasible (exit 4); the message names the limit and what to ask instead."""


class SceneConflict(TaskError):
    """A hand target or a footstep lies inside a scene object, or ``walk_to`` finds no way to an
    object (enclosed, or out of reach from every place around it): infeasible in that scene (exit 4).

    Attributes:
        object_name: The object's name.
    """

    def __init__(self, message: str, object_name: str) -> None:
        self.object_name = object_name
        super().__init__(message)


class GroundingError(TaskDefinitionError):
    """A reference that names no object of the scene, several, or an object with no scene (exit 3).

    Attributes:
        reference: The reference as said.
        candidates: Names of the objects it could mean (ambiguous), else empty.
    """

    def __init__(self, message: str, reference: str, candidates: Sequence[str] = ()) -> None:
        self.reference = reference
        self.candidates = tuple(candidates)
        super().__init__(message)


class ClipError(TaskDefinitionError):
    """A motion-capture clip that cannot be used: a damaged or unsupported BVH file, a skeleton
    wbmp does not know, a time window outside the clip or beyond the work bounds (exit 3)."""
