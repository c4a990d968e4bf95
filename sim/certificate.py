"""The certificate of a simulated motion: every physical check with its number and verdict.

Each check is a :class:`planner.results.Check` (the record the planner's report uses too).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from planner import Check, CheckKind

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

    @classmethod
    def from_dict(cls, record: Any) -> Certificate | None:
        """The certificate of :meth:`to_dict`'s dict (a motion file's report keeps it), or None
        when ``record`` is not one; its checks have :attr:`CheckKind.RECORDED` (the dict keeps no
        kind; kind takes no part in a check's equality)."""
        if not isinstance(record, dict):
            return None

        def number(x: Any) -> float:
            return float("nan") if x is None else float(x)

        try:
            checks = tuple(Check(name=str(c["name"]), kind=CheckKind.RECORDED, value=number(c["value"]),
                                 limit=number(c["limit"]), unit=str(c["unit"]), time=number(c["time"]),
                                 ok=bool(c["ok"]), message=str(c.get("message", "")),
                                 upper=bool(c.get("upper", True)))
                           for c in record["checks"])
            figures = record.get("figures") or {}
            stops = record.get("stops") or []
            return cls(ok=bool(record["ok"]), checks=checks, reason=str(record.get("reason", "")),
                       figures={str(k): number(v) for k, v in figures.items()} if isinstance(figures, dict) else {},
                       stops=tuple(dict(x) for x in stops if isinstance(x, dict)) if isinstance(stops, list) else ())
        except (KeyError, TypeError, ValueError, AttributeError):
            return None

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly dict (:meth:`from_dict` reads it back)."""
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
