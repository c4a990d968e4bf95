"""A push on the base during the simulation: the record, its ``FORCE@TIME`` text form and its range."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

from sim.exceptions import PushParseError

_NUMBER = r"[-+]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][-+]?\d+)?|[-+]?(?:nan|inf|infinity)"
#: ``FORCE@TIME`` with optional units (``80N@1.5s``); ASCII digits only (``re.ASCII``: no Arabic
#: or full-width digits), and case-insensitive so that ``nan``/``inf`` reach the range check.
_PUSH_RE = re.compile(
    rf"^\s*({_NUMBER})\s*(?:N)?\s*@\s*({_NUMBER})\s*(?:s)?\s*$", re.ASCII | re.IGNORECASE
)
#: Largest push force [N]. Talos weighs 93 kg (910 N): a 0.1 s push of 5000 N gives it about
#: 5 m/s, far past any recovery; larger forces say nothing more about the controller.
MAX_PUSH_FORCE = 5000.0
#: Longest push [s] (a push is a short disturbance, not a steady wind).
MAX_PUSH_DURATION = 10.0
_PUSH_FORM = "FORCE@TIME, e.g. 80@1.5 = 80 N on the base at t = 1.5 s"


def _quote(text: str, limit: int = 40) -> str:
    """``text`` for a message: control characters escaped (repr), cut to ``limit`` characters."""
    if len(text) <= limit:
        return repr(text)
    return f"{text[:limit]!r}... ({len(text)} characters)"


@dataclass(frozen=True, slots=True)
class Push:
    """A force applied to the base during the simulation.

    Attributes:
        force: Magnitude [N], in (0, :data:`MAX_PUSH_FORCE`].
        time: Start [s], >= 0; it must fall within the motion (:func:`check_push_time`).
        duration: Length [s], in (0, :data:`MAX_PUSH_DURATION`].
        direction: Direction in the world (normalized on use).

    Raises:
        PushParseError: A value out of range (a one-line message naming it and the range).
    """

    force: float
    time: float
    duration: float = 0.1
    direction: tuple[float, float, float] = (1.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        if not (_real(self.force) and 0.0 < self.force <= MAX_PUSH_FORCE):
            raise PushParseError(
                f"push: the force must be above 0 N and at most {MAX_PUSH_FORCE:g} N, got {_value(self.force)} N"
            )
        if not (_real(self.time) and math.isfinite(self.time) and self.time >= 0.0):
            raise PushParseError(f"push: the time must be at least 0 s (within the motion), got {_value(self.time)} s")
        if not (_real(self.duration) and 0.0 < self.duration <= MAX_PUSH_DURATION):
            raise PushParseError(
                f"push: the duration must be above 0 s and at most {MAX_PUSH_DURATION:g} s, got {_value(self.duration)} s"
            )
        try:
            d = np.asarray(self.direction, dtype=float)
        except (TypeError, ValueError):
            d = np.zeros(0)
        if d.shape != (3,) or not np.all(np.isfinite(d)) or not np.linalg.norm(d) > 0:
            raise PushParseError(
                f"push: the direction must be a non-zero, finite 3-vector, got {self.direction!r}"
            )

    def force_in_world(self) -> np.ndarray:
        """The force vector [N]."""
        d = np.asarray(self.direction, dtype=float)
        return self.force * d / np.linalg.norm(d)


def _real(x: object) -> bool:
    """A real number (int or float, not bool), NaN included (the range checks refuse it)."""
    return isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(x, (bool, np.bool_))


def _value(x: object) -> str:
    return f"{x:g}" if _real(x) else repr(x)


def parse_push(text: str) -> Push:
    """Parse ``FORCE@TIME`` (``"80@1.5"``: 80 N at t = 1.5 s for 0.1 s along +x).

    Units may be written (``80N@1.5s``). The force must be above 0 N and at most
    :data:`MAX_PUSH_FORCE`; the time at least 0 s (and, once the motion is known, before its
    end: :func:`check_push_time`).

    Raises:
        PushParseError: The text is not of that form, or a value is out of range (the message
            quotes the text, escaped and cut to 40 characters, and names the range).
    """
    if not isinstance(text, str):
        raise PushParseError(f"push {text!r} is not {_PUSH_FORM}")
    match = _PUSH_RE.match(text)
    if not match:
        raise PushParseError(f"push {_quote(text)} is not {_PUSH_FORM} (ASCII digits; the units N and s may be written)")
    force, time_ = float(match.group(1)), float(match.group(2))
    try:
        return Push(force=force, time=time_)
    except PushParseError as e:
        raise PushParseError(f"push {_quote(text)} ({_PUSH_FORM}): {str(e).removeprefix('push: ')}") from None


def check_push_time(push: Push, horizon: float) -> None:
    """Refuse a push that starts outside the motion ``[0, horizon)`` [s] (it would never act).

    Raises:
        PushParseError: One line with the push, the motion's length and the valid range.
    """
    if not (0.0 <= push.time < horizon):
        raise PushParseError(
            f"push {push.force:g}@{push.time:g}: t = {push.time:g} s is outside the motion, which lasts "
            f"{horizon:.3g} s: give a time from 0 to below {horizon:.3g} s"
        )

