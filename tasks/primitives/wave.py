"""``wave(arm left|right|both, repeat, duration [s])``: raise a hand above the shoulder and wave.

Geometry, from the standing posture (``L`` = the arm's length, shoulder to hand):

- the raised hand is ``RAISE_HEIGHT * L`` above the shoulder frame and ``RAISE_FORWARD * L``
  in front of it (HARD height target over the whole waving window, tolerance ``HEIGHT_TOLERANCE``);
- it swings sideways about a *midline* ``MIDLINE_OUT * L`` outside the shoulder, with an
  amplitude of ``AMPLITUDE * L``: HARD position targets alternate inner, outer, inner, ...
  (``2 * repeat + 1`` of them, tolerance ``SWING_TOLERANCE``), so each wave (out and back)
  crosses the midline twice and ``repeat`` waves cross it ``2 * repeat`` times;
- the hand goes up in ``RAISE_TIME`` and comes back to rest (soft target) in ``LOWER_TIME``.

With ``arm = both`` the hands wave as mirror images (both outwards at the same time).
"""

from __future__ import annotations

import numpy as np

from robots import Robot
from tasks.primitives.base import Fragment, FragmentBuilder, Primitive, arms_of, rest_targets
from tasks.primitives.geometry import SIDE_SIGN

RAISE_TIME = 1.0  # [s] from rest to the first inner swing target
LOWER_TIME = 1.0  # [s] from the last swing target back to rest
RAISE_HEIGHT = 0.3  # [L] hand height above the shoulder frame
RAISE_FORWARD = 0.2  # [L] hand ahead of the shoulder frame
MIDLINE_OUT = 0.2  # [L] midline outside the shoulder frame
AMPLITUDE = 0.18  # [L] half the swing
HEIGHT_TOLERANCE = 0.04  # [m] hand height band while waving
SWING_TOLERANCE = 0.02  # [m] swing target position tolerance


def nominal_duration(params: dict, robot: Robot) -> float:
    """Raise, ``repeat`` waves of ``duration``, lower [s]."""
    return RAISE_TIME + params["repeat"] * params["duration"] + LOWER_TIME


def parts(params: dict) -> frozenset[str]:
    """The waving arm(s)."""
    return frozenset(f"{s}_arm" for s in arms_of(params["arm"]))


def wave_geometry(b_or_geometry, side: str) -> dict[str, np.ndarray | float]:
    """Midline point, outward unit vector and amplitude of one hand's wave, standing frame."""
    g = getattr(b_or_geometry, "geometry", b_or_geometry)
    L = g.arm_length[side]
    shoulder = g.position(f"{side}_shoulder") if f"{side}_shoulder" in g.placements else g.position(f"{side}_hand")
    fwd, up = g.heading_axis("forward"), g.heading_axis("up")
    out = SIDE_SIGN[side] * g.heading_axis("left")
    mid = shoulder + RAISE_FORWARD * L * fwd + RAISE_HEIGHT * L * up + MIDLINE_OUT * L * out
    return {"midline": mid, "outward": out, "amplitude": AMPLITUDE * L, "shoulder": shoulder}


def build(b: FragmentBuilder) -> Fragment:
    """Raise, swing targets alternating inner/outer, lower."""
    n, period = b.params["repeat"], b.params["duration"]
    sides = arms_of(b.params["arm"])
    t_wave_end = RAISE_TIME + n * period
    for side in sides:
        w = wave_geometry(b, side)
        role = f"{side}_hand"
        b.frame_target(f"{side} hand above shoulder", role, position=b.world(w["midline"]), axes=(False, False, True),
                       window=(RAISE_TIME, t_wave_end), tolerance=HEIGHT_TOLERANCE)
        for k in range(2 * n + 1):
            sign = 1.0 if k % 2 else -1.0  # inner first
            point = w["midline"] + sign * w["amplitude"] * w["outward"]
            what = "out" if sign > 0 else "in"
            b.frame_target(f"{side} hand swing {what} #{k + 1}", role, position=b.world(point),
                           time=RAISE_TIME + 0.5 * k * period, tolerance=SWING_TOLERANCE)
    rest_targets(b, [f"{s}_hand" for s in sides], tau=nominal_duration(b.params, b.robot))
    b.phase("wave", nominal_duration(b.params, b.robot))
    return b.finish(parts(b.params))


PRIMITIVE = Primitive(name="wave", nominal_duration=nominal_duration, build=build, parts=parts)
