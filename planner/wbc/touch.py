"""The controller's touch-downs: the plan's flights and their landings, and late touches.

A stance that begins while its sole is still up waits for the touch (``WbcSettings.touch_wait``).

The simulated swing foot lags its plan by 20-40 ms on a long or quick step (talos's march, G1's
forward jumps made as steps). Switched to a stance at the planned time, the sole was held where it
was, still 1-2 cm up, by the stance constraint, and met the floor moving: it skidded 7-24 mm.
Instead, a sole whose stance begins while it is more than ``TOUCH_HEIGHT`` above its planned stance
height (the plan's lowest in the wait) stays a swing sole tracking the plan's sole, until it is
within ``TOUCH_HEIGHT`` or ``touch_wait`` has passed; then it is a stance sole, held where it
touched. The flight's early touch-down (:meth:`WholeBodyController._touchdown`) is the mirror case
(a sole down before its planned time).
"""

from __future__ import annotations

import numpy as np

from planner.wbc.reference import flight_spans

TOUCH_HEIGHT = 0.003  # [m] a sole this close to its planned stance height is down (MuJoCo's contact: ~1 mm in)


def late_soles(
    active: tuple[bool, ...],
    was: tuple[bool, ...] | None,
    height: np.ndarray,
    since: np.ndarray,
    k: int,
    max_wait: int,
) -> list[bool]:
    """Which of ``active``'s soles still wait for their touch at sample ``k``.

    Args:
        active: The stance soles the plan (or an early touch-down) asks for at ``k``.
        was: The stance soles of the previous tick (None: the first tick, nothing waits).
        height: Each contact's height above its planned stance height at ``k`` [m].
        since: Per contact, the sample its wait began (-1: not waiting); updated in place
            (set when a wait begins, reset to -1 when a sole is not waiting).
        k: The reference sample.
        max_wait: The longest wait [samples].

    Returns:
        Per contact: True if it is planned in stance at ``k`` but waits (not yet down).
    """
    out = [False] * len(active)
    for i, on in enumerate(active):
        new = on and was is not None and not was[i]
        if new and height[i] > TOUCH_HEIGHT:
            if since[i] < 0:
                since[i] = k
            out[i] = k - since[i] < max_wait
        if not out[i]:
            since[i] = -1
    return out


def flight_landings(active: np.ndarray) -> dict[int, tuple[int, int]]:
    """Sample -> (first sample, touch-down sample) of the flight it lies in (no active contact,
    between two stances)."""
    out: dict[int, tuple[int, int]] = {}
    flags = np.asarray(active, dtype=bool)
    air = [bool(flags.shape[1]) and not row.any() for row in flags]
    for a, k in flight_spans(air):
        for j in range(a, k):
            out[j] = (a, k)
    return out


def flight_window(active: np.ndarray, span: int) -> np.ndarray:
    """Samples (n,) within ``span`` samples of a flight (no active contact, between two stances):
    from ``span`` before its first sample to ``span`` after its touch-down sample."""
    flags = np.asarray(active, dtype=bool)
    air = [bool(flags.shape[1]) and not row.any() for row in flags]
    out = np.zeros(len(flags), dtype=bool)
    for a, touch in flight_spans(air):
        out[max(a - span, 0) : touch + span + 1] = True
    return out
