"""Diagnosis of a failed dynamic plan in task terms."""

from __future__ import annotations

from planner.results import CheckKind, Plan
from planner.trajopt.centroidal.data import DynamicData

#: What to try when a dynamic plan fails on a group of this kind.
HINTS = {
    CheckKind.FRICTION_CONE: "the feet would slip: ask for shorter or slower steps",
    CheckKind.COM_DYNAMICS: "the contact forces cannot move the body as planned: ask for a slower motion",
    CheckKind.JOINT_VELOCITY_LIMITS: "the joints would move faster than their limits: ask for a slower or smaller motion",
    CheckKind.COM_TARGET: "the centre of mass cannot reach the target in time",
}


def diagnose_dynamic(lay: DynamicData, failed: Plan) -> str:
    """Explain a failed dynamic plan in task terms: the worst violated group, when, in which phase."""
    spec = lay.spec
    status = failed.stats.status.value
    bad = sorted((c for c in failed.checks if not c.ok), key=lambda c: -(c.violation / max(c.tolerance, 1e-12)))
    if not bad:
        return (f"the solver stopped: {status} ({failed.stats.raw_status}) after {failed.stats.iterations} "
                "iterations, with every checked constraint met")
    c = bad[0]
    phase = spec.phases[spec.phase_at(c.time)].name
    text = (f"{c.name} violated by {c.violation:.3g} {c.unit} at t = {c.time:.2f} s in phase {phase!r} ({status})")
    hint = HINTS.get(c.kind)
    if hint:
        text += f"; {hint}"
    if len(bad) > 1:
        text += "; also " + ", ".join(f"{b.name} ({b.violation:.2g} {b.unit})" for b in bad[1:4])
    return text
