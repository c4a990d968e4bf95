"""The certificate of a simulated motion: every physical check with its number and verdict.

Each check is a :class:`planner.results.Check` (the record the planner's report uses too).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from planner.results import Check, CheckKind

__all__ = ["Certificate", "Check", "CheckKind"]


@dataclass(frozen=True, slots=True, kw_only=True)
class Certificate:
    """Pass/fail verdict of a simulated motion with the evidence.

    Attributes:
        ok: Every check passed.
        checks: The checks in a fixed order (fall, contacts, slip, torque, tracking, targets).
        reason: The earliest failure in words ("fell at t = 1.23 s (base height 0.42 m <
            0.60 m)"); empty when ok.
        figures: The evaluation figures (:data:`sim.figures.FIGURES`: energy, torque use, jerk,
            feet, tracking, E-stops), key -> value; empty when not computed.
        stops: The run's E-stops, each :meth:`sim.estop.Stop.to_dict` (when, why, what the robot
            did, whether it stayed up).
    """

    ok: bool
    checks: tuple[Check, ...]
    reason: str = ""
    figures: dict[str, float] = field(default_factory=dict)
    stops: tuple[dict[str, Any], ...] = ()

    @classmethod
    def from_checks(cls, checks: tuple[Check, ...]) -> Certificate:
        """Build the verdict: ok when all pass; the reason is the failure that happened first."""
        failed = [c for c in checks if not c.ok]
        if not failed:
            return cls(ok=True, checks=checks, reason="")
        first = min(failed, key=lambda c: c.time if math.isfinite(c.time) else math.inf)
        return cls(ok=False, checks=checks, reason=first.message or f"{first.name} failed")

    def check(self, name: str) -> Check:
        """The check called ``name`` (KeyError listing the names otherwise)."""
        for c in self.checks:
            if c.name == name:
                return c
        raise KeyError(f"no check {name!r}; checks are {[c.name for c in self.checks]}")

    def summary(self) -> str:
        """Multi-line human-readable table."""
        head = "certificate: PASS" if self.ok else f"certificate: FAIL - {self.reason}"
        lines = [head]
        for c in self.checks:
            mark = "ok  " if c.ok else "FAIL"
            rel = "<=" if c.upper else ">="
            lines.append(
                f"  {mark} {c.name:<34} {c.value:10.4g} {c.unit:<5} ({rel} {c.limit:.4g}, t = {c.time:.3f} s)"
            )
        for stop in self.stops:
            lines.append(f"  {stop.get('message', '')}")
        if self.figures:
            lines.append(describe_figures(self.figures))
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly dict."""
        out: dict[str, Any] = {
            "ok": bool(self.ok),
            "reason": self.reason,
            "checks": [c.to_dict() for c in self.checks],
        }
        if self.figures:
            out["figures"] = {k: float(v) for k, v in self.figures.items()}
        if self.stops:
            out["stops"] = [dict(s) for s in self.stops]
        return out


def describe_figures(fig: Mapping[str, float]) -> str:
    """Two lines of the evaluation figures (:mod:`sim.figures`) for a report: energy and torque, then smoothness, feet and tracking."""
    if not fig:
        return ""
    g = dict(fig)
    return (f"  figures: {g.get('execution_time', math.nan):.2f} s, work {g.get('work', math.nan):.1f} J "
            f"(|work| {g.get('abs_work', math.nan):.1f} J, int tau^2 {g.get('torque_squared', math.nan):.3g} N2m2s), "
            f"torque peak {100 * g.get('peak_torque_ratio', math.nan):.0f}% rms "
            f"{100 * g.get('rms_torque_ratio', math.nan):.1f}%\n"
            f"           jerk rms {g.get('rms_jerk', math.nan):.3g} rad/s3, feet skate "
            f"{g.get('foot_skate', math.nan):.1f} float {g.get('foot_float', math.nan):.1f} penetration "
            f"{g.get('foot_penetration', math.nan):.1f} mm, CoM error rms {g.get('com_error_rms', math.nan):.1f} "
            f"max {g.get('com_error_max', math.nan):.1f} mm, hands rms {g.get('hand_error_rms', math.nan):.1f} "
            f"max {g.get('hand_error_max', math.nan):.1f} mm, E-stops {int(g.get('estop_count', 0))}")
