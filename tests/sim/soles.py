"""The soles of a planned and executed terrain walk against the ground, by hand: at the middle of each
phase, every standing sole's corners (Pinocchio forward kinematics of the planned and of the executed
configuration) on the ground the caller computes by hand, and the sole frame at its placement."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pinocchio as pin


def check_soles_on_the_ground(robot, spec, result, execution, ground: Callable[[np.ndarray], float], *,
                              executed: float, tilted: float) -> list[tuple[object, np.ndarray]]:
    """Assert, at each phase's middle, every contact's sole corners within 1 mm of ``ground`` in the
    plan and within ``executed`` [m] in the execution, and the sole frame within 1 mm (plan) and
    ``executed`` (``tilted`` on an incline) [m] of its placement. Returns (contact, executed corners)."""
    model, data = robot.model, robot.data()
    t_exec = np.asarray(execution.t) - float(execution.t[0])
    t0, out = 0.0, []
    for phase in spec.phases:
        middle = t0 + 0.5 * phase.duration
        t0 += phase.duration
        k_plan = int(np.argmin(np.abs(result.t - middle)))
        k_exec = int(np.argmin(np.abs(t_exec - middle)))
        for contact in phase.contacts:
            side = "left" if contact.frame.startswith("left") else "right"
            on_incline = abs(contact.placement.rpy[1]) > 1e-3
            for q, tolerance, along in ((result.q[k_plan], 1e-3, 1e-3),
                                        (execution.q[k_exec], executed, tilted if on_incline else executed)):
                pin.framesForwardKinematics(model, data, q)
                corners = robot.sole_corners_in_world(q, side)
                gaps = [float(c[2] - ground(np.asarray(c))) for c in corners]
                assert max(abs(g) for g in gaps) < tolerance, f"{contact.frame} at t = {middle:.2f} s: {gaps}"
                M = data.oMf[robot.frame_id(contact.frame)]
                off = float(np.linalg.norm(M.translation - np.array(contact.placement.position)))
                assert off < along, f"{contact.frame} at t = {middle:.2f} s: {off * 1e3:.1f} mm from its placement"
            out.append((contact, np.asarray(corners)))
    return out
