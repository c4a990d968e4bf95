"""Bounds on the work one request may ask for, and on the values a spec may hold: in one place.

A request beyond these bounds is refused, with the bound and the reason, before anything is
built: a spec file when it is loaded (:func:`tasks.serialize.load_spec`), a sentence when its
actions are parsed (:class:`language.plan.ActionPlan`) or compiled
(:func:`tasks.compose.compile_actions`), and any :class:`tasks.specs.TaskSpec` on construction.
``docs/spec-format.md`` (section "Limits") lists them with the measurements behind them.

Measured on the 2-core development machine (CasADi 3.7, IPOPT 3.14, no simulation, whole
``wbmp solve`` process): the Talos squat spec stretched to 15 s (200 knots) plans in 4 s with
0.34 GB peak memory, 30 s (400 knots) in 6 s / 0.43 GB, 60 s (800 knots) in 16 s / 0.61 GB
with the solver built in memory; the first-ever compiled plan (gcc) of 30 s takes 12 s and
stores a 37 MB library, of 60 s 32 s and 80 MB. ``walk 10 m`` on Talos (37 s, 491 knots,
contact forces) plans in 35 s / 0.84 GB. Time, memory and the cached library grow with the
knots (time faster than linearly): a 140 s request ran 150 s and left a 254 MB library.
60 s / 800 knots keeps the largest request within about a minute and 1 GB here.
"""

from __future__ import annotations

import math

# Work: how much motion one request may ask for.
MAX_HORIZON = 60.0  # [s] total duration of one spec (every phase together)
MIN_HORIZON = 0.02  # [s] the planner's 4 knot intervals (rest at both ends) of at least MIN_DT
MAX_KNOTS = 800  # knot intervals of the transcription: horizon / dt (60 s on the default 0.075 s grid)
MAX_PHASES = 200  # phases of one spec (walking 10 m on G1 takes 105)
MAX_CONTACTS = 8  # contacts held in one phase (two feet, two hands: 4)
MAX_ITEMS = 3000  # targets + CoM targets + CoM bounds + joint targets of one spec (20 actions on Romeo: 1,351)
MAX_TERMS = 20_000  # (item, knot) pairs the items apply to (a window covers every knot inside it);
#   the largest compiled 20-action request has 2,832 (Romeo)
MAX_ACTIONS = 20  # actions of one instruction, overlays included
MAX_REPEAT = 10  # "squat 10 times": the largest repeat count of an action

# Values: finite numbers in sane ranges (JSON may hold NaN, Infinity or 1e308).
MAX_DISTANCE = 100.0  # [m] any position, bound, tolerance, margin or height in a spec
MAX_ANGLE = 100.0  # [rad] any orientation, orientation tolerance or joint value (~16 turns)
MAX_WEIGHT = 1e6  # [-] any cost weight
MAX_FRICTION = 10.0  # [-] friction coefficient
MAX_MASS = 1000.0  # [kg] a movable scene object
MAX_OBJECTS = 200  # objects of one scene
GROUND_TOLERANCE = 0.01  # [m] a contact placement may be this far below the ground (z = 0), no more
START_TOLERANCE = 1e-3  # [m], [rad] first-phase contacts vs the robot's standing soles
MAX_NAME_LENGTH = 200  # characters of a name, frame or joint in a spec
MAX_TEXT_LENGTH = 10_000  # characters of a spec's description (the sentence it came from)
MIN_DT, MAX_DT = 0.005, 0.5  # [s] knot spacing of a spec

# Spec files.
MAX_SPEC_BYTES = 8 * 1024 * 1024  # a spec is a few kB; a compiled 20-action one is ~0.5 MB
MAX_NESTING = 16  # JSON nesting depth (a spec nests 7 levels: spec.phases[0].contacts[0].placement.position)
MAX_DIGITS = 40  # digits of one JSON number literal


def horizon_message(seconds: float, what: str) -> str:
    """``"the motion would last 180 s; wbmp plans at most 60 s at a time: split the instruction"``."""
    return (f"the motion would last {_seconds(seconds)}; wbmp plans at most {MAX_HORIZON:g} s at a time "
            f"(longer motions take minutes and gigabytes to plan): {what}")


def _seconds(value: float) -> str:
    if not math.isfinite(value):
        return "forever"
    return f"{value:.4g} s" if value < 1e6 else f"{value:.3g} s"


__all__ = [
    "GROUND_TOLERANCE",
    "MAX_ACTIONS",
    "MAX_ANGLE",
    "MAX_CONTACTS",
    "MAX_DIGITS",
    "MAX_DISTANCE",
    "MAX_DT",
    "MAX_FRICTION",
    "MAX_HORIZON",
    "MAX_ITEMS",
    "MAX_KNOTS",
    "MAX_MASS",
    "MAX_NAME_LENGTH",
    "MAX_NESTING",
    "MAX_OBJECTS",
    "MAX_PHASES",
    "MAX_REPEAT",
    "MAX_SPEC_BYTES",
    "MAX_TERMS",
    "MAX_TEXT_LENGTH",
    "MAX_WEIGHT",
    "MIN_DT",
    "MIN_HORIZON",
    "START_TOLERANCE",
    "horizon_message",
]
