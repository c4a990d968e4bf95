"""``reach(hand, target [m] | direction + distance [m], duration [s])``: move a hand to a point.

The point is either ``target``, given in the robot's base frame (origin at the base link's
standing position, x forward, y left, z up: the heading frame's axes), or ``distance`` along
``direction`` (forward, backward, left, right, up, down) from the hand's standing position;
with neither ("reach out with your left hand") the hand reaches ``DEFAULT_DIRECTION`` (forward),
as a person reading the sentence expects.
The hand gets there at ``OUT_FRACTION`` of the duration, holds it until ``HOLD_END_FRACTION``
(HARD position target, tolerance ``REACH_TOLERANCE``) and goes back to rest (soft target).
A point beyond the arm's reach is not refused here: the planner explains by how much it is
missed.
"""

from __future__ import annotations

from typing import cast

import numpy as np

from robots import Robot
from tasks.exceptions import TaskDefinitionError
from tasks.primitives.base import Fragment, FragmentBuilder, Primitive, rest_targets
from tasks.primitives.geometry import StandingGeometry

OUT_FRACTION = 0.4  # the hand arrives at this fraction of the duration
HOLD_END_FRACTION = 0.6  # and leaves at this one
REACH_TOLERANCE = 0.01  # [m]
DEFAULT_DIRECTION = "forward"  # without a target or a direction


def nominal_duration(params: dict, robot: Robot) -> float:
    """``duration`` [s]."""
    return params["duration"]


def parts(params: dict) -> frozenset[str]:
    """The reaching arm."""
    return frozenset({f"{params['hand']}_arm"})


def direction(params: dict) -> str | None:
    """The direction to reach in: ``params["direction"]``, ``DEFAULT_DIRECTION`` without a target, else None."""
    if params.get("direction") is not None:
        return str(params["direction"])
    return DEFAULT_DIRECTION if params.get("target") is None else None


def check(params: dict, robot: Robot) -> None:
    """At most one of ``target`` and ``direction``."""
    if params.get("target") is not None and params.get("direction") is not None:
        raise TaskDefinitionError("reach: give a target point or a direction, not both")


def reach_point(geometry: StandingGeometry, params: dict) -> np.ndarray:
    """The point to reach in the standing world frame (3,) [m]."""
    if params.get("target") is not None:
        base = geometry.position("base")
        return base + geometry.heading.rotation @ np.array(params["target"], dtype=float)
    hand = geometry.position(f"{params['hand']}_hand")
    return hand + params["distance"] * geometry.heading_axis(cast(str, direction(params)))


def build(b: FragmentBuilder) -> Fragment:
    """Out, hold, back."""
    check(b.params, b.robot)
    T = b.params["duration"]
    role = f"{b.params['hand']}_hand"
    point = reach_point(b.geometry, b.params)
    b.frame_target(f"{b.params['hand']} hand at the reach point", role, position=b.world(point),
                   window=(OUT_FRACTION * T, HOLD_END_FRACTION * T), tolerance=REACH_TOLERANCE)
    rest_targets(b, [role], tau=T)
    b.phase("reach", T)
    return b.finish(parts(b.params))


PRIMITIVE = Primitive(name="reach", nominal_duration=nominal_duration, build=build, parts=parts, check=check)
