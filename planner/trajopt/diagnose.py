"""Failure diagnosis of a kinematic plan, in task terms: hard targets are relaxed into costs and the
problem is solved again; a target still missed by more than its tolerance is the culprit, and the
relaxed solution tells by how much."""

from __future__ import annotations

import dataclasses

from planner.results import Check, CheckKind, Plan
from planner.trajopt.kinds import FrameOrientationTerm
from planner.trajopt.layout import Layout
from planner.trajopt.settings import PlannerSettings
from planner.trajopt.term import kind_of_check
from tasks import Priority

RELAXED_WEIGHT = 1e4  # [1/m^2] weight of a hard target turned into a cost while diagnosing


def diagnose_failure(lay: Layout, failed: Plan, settings: PlannerSettings, targets_only: bool = False, relax: bool = True) -> str:
    """Explain a failed solve in task terms (which item, when, by how much): a hard target the
    relaxed problem (targets as heavy costs, no collision or scene rows) cannot reach, else the
    worst violated group of ``failed`` (with ``targets_only``: else an empty string; without
    ``relax``, the relaxed solve is skipped: it was asked before)."""
    from planner.trajopt.layout import make_layout
    from planner.trajopt.report import make_plan
    from planner.trajopt.solve import solve_layout

    spec = lay.spec
    hard = [tg for tg in spec.targets if tg.priority is Priority.HARD]
    hard_com = [tg for tg in spec.com_targets if tg.priority is Priority.HARD]
    if relax and settings.diagnose and (hard or hard_com):
        relaxed_spec = dataclasses.replace(
            spec,
            targets=tuple(dataclasses.replace(tg, priority=Priority.SOFT, weight=RELAXED_WEIGHT) if tg in hard else tg
                          for tg in spec.targets),
            com_targets=tuple(dataclasses.replace(tg, priority=Priority.SOFT, weight=RELAXED_WEIGHT)
                              if tg in hard_com else tg for tg in spec.com_targets),
        )
        relaxed_lay = make_layout(relaxed_spec, lay.robot)
        in_memory = dataclasses.replace(settings, cache=dataclasses.replace(settings.cache, compile=False))
        dq, stats, _ = solve_layout(relaxed_lay, in_memory)
        if stats.status.ok:
            relaxed = make_plan(relaxed_lay, dq, stats, settings)
            misses = []
            for chk in relaxed.checks:
                item = _target_of(chk, hard, hard_com)
                if item is None:
                    continue
                tol = item.orientation_tolerance if chk.kind in FrameOrientationTerm.check_kinds else item.tolerance
                if chk.violation > tol:
                    misses.append((chk.violation - tol, chk, tol))
            if misses:
                misses.sort(key=lambda m: -m[0])
                gap, chk, tol = misses[0]
                text = kind_of_check(chk.kind).missed(chk, gap, tol)
                if len(misses) > 1:
                    text += "; also " + ", ".join(f"{m[1].name} ({m[0]:.2f} {m[1].unit})" for m in misses[1:])
                return text
    if targets_only:
        return ""
    # no target to blame: the worst violated group at the returned point
    bad = sorted((c for c in failed.checks if not c.ok), key=lambda c: -(c.violation / max(c.tolerance, 1e-12)))
    status = failed.stats.status.value
    if not bad:
        return f"the solver stopped: {status} ({failed.stats.raw_status}) after {failed.stats.iterations} iterations"
    c = bad[0]
    return kind_of_check(c.kind).diagnosis(c, spec.phases[spec.phase_at(c.time)].name, status)


def _target_of(check: Check, hard, hard_com):
    """The hard frame or CoM target that ``check`` is about, or None."""
    if check.kind in (CheckKind.TARGET_POSITION, CheckKind.TARGET_ORIENTATION):
        candidates = hard
    elif check.kind is CheckKind.COM_TARGET:
        candidates = hard_com
    else:
        return None
    return next((tg for tg in candidates if tg.name == check.subject), None)
