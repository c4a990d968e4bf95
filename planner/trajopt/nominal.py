"""A nominal motion to warm-start the NLP: inverse kinematics at the target times, interpolated.

At every knot that holds a HARD position target (frame or CoM), a damped Gauss-Newton solves
the static inverse kinematics with Pinocchio: the contacts active at that knot fixed in 6D, the
targets' positions reached, the CoM ground projection pulled towards where it stands, and the
smallest change from the standing posture. Between these keyframes (and the rest at both ends)
the tangent displacements are blended with a smoothstep. The result is only an initial guess:
the NLP enforces everything; when the inverse kinematics does not converge the standing posture
is used instead for that keyframe.
"""

from __future__ import annotations

from itertools import pairwise
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from planner.trajopt.symbolic import configuration_to_chart

if TYPE_CHECKING:
    from planner.trajopt.layout import Layout

IK_ITERATIONS = 30
IK_DAMPING = 1e-3
CONTACT_WEIGHT = 10.0
COM_XY_WEIGHT = 1.0
REGULARIZATION = 1e-2  # pull towards the standing posture, per iteration


def _keyframe_tasks(lay: Layout) -> dict[int, list]:
    """Knot -> list of ('frame', fid, goal, axes) / ('com', goal, axes) hard position targets."""
    out: dict[int, list] = {}
    for term in lay.terms:
        if term.kind == "frame_pos" and term.structure[3] != "soft":
            out.setdefault(term.knot, []).append(("frame", term.structure[1], term.params[:3], term.structure[2]))
        elif term.kind == "com_pos" and term.structure[2] != "soft":
            out.setdefault(term.knot, []).append(("com", None, term.params[:3], term.structure[1]))
    return out


def solve_ik(lay: Layout, knot: int, tasks: list) -> np.ndarray | None:
    """Configuration meeting the contacts at ``knot`` and ``tasks`` (None if it does not converge)."""
    robot = lay.robot
    model, data = robot.model, robot.data()
    q = np.array(lay.q_ref)
    pin.framesForwardKinematics(model, data, q)
    com_xy0 = pin.centerOfMass(model, data, q)[:2].copy()
    contacts = lay.contacts_at[knot]
    for _ in range(IK_ITERATIONS):
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        rows, errs = [], []
        for fid, (_frame, M) in contacts.items():
            J = pin.getFrameJacobian(model, data, fid, pin.ReferenceFrame.LOCAL)
            err = pin.log6(M.actInv(data.oMf[fid])).vector
            rows.append(CONTACT_WEIGHT * pin.Jlog6(M.actInv(data.oMf[fid])) @ J)
            errs.append(CONTACT_WEIGHT * err)
        com = pin.centerOfMass(model, data, q)
        J_com = pin.jacobianCenterOfMass(model, data, q)
        has_com_xy = False
        for task in tasks:
            kind, fid, goal, axes = task
            sel = np.array(axes, dtype=bool)
            if kind == "frame":
                J = pin.getFrameJacobian(model, data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)[:3]
                rows.append(J[sel])
                errs.append((data.oMf[fid].translation - goal)[sel])
            else:
                rows.append(J_com[sel])
                errs.append((com - goal)[sel])
                has_com_xy |= bool(sel[0] or sel[1])
        if not has_com_xy:
            rows.append(COM_XY_WEIGHT * J_com[:2])
            errs.append(COM_XY_WEIGHT * (com[:2] - com_xy0))
        A = np.vstack(rows)
        e = np.concatenate(errs)
        reg = REGULARIZATION * pin.difference(model, lay.q_ref, q)
        reg[:6] = 0.0
        H = A.T @ A + (IK_DAMPING + REGULARIZATION) * np.eye(model.nv)
        step = -np.linalg.solve(H, A.T @ e + REGULARIZATION * reg)
        q = pin.integrate(model, q, step)
        lo, hi = model.lowerPositionLimit[7:], model.upperPositionLimit[7:]
        q[7:] = np.clip(q[7:], np.where(np.abs(lo) < 1e10, lo, -np.inf), np.where(np.abs(hi) < 1e10, hi, np.inf))
        if np.linalg.norm(step) < 1e-6:
            break
    pin.framesForwardKinematics(model, data, q)
    for fid, (_frame, M) in contacts.items():
        if np.linalg.norm(pin.log6(M.actInv(data.oMf[fid])).vector) > 1e-3:
            return None
    return q


def _smoothstep(s: float) -> float:
    s = min(max(s, 0.0), 1.0)
    return s * s * (3.0 - 2.0 * s)


def nominal_motion(lay: Layout) -> np.ndarray:
    """Chart displacements (N+1, nv) of the nominal motion (zeros where no target asks)."""
    nv, N = lay.robot.nv, lay.N
    dq = np.zeros((N + 1, nv))
    tasks = _keyframe_tasks(lay)
    if not tasks:
        return dq
    keys: list[tuple[int, np.ndarray]] = [(1, np.zeros(nv))]
    for k in sorted(tasks):
        q = solve_ik(lay, k, tasks[k])
        keys.append((k, np.zeros(nv) if q is None else configuration_to_chart(lay.robot.model, lay.q_ref, q)))
    if keys[-1][0] < N - 1:
        keys.append((N - 1, np.zeros(nv)))
    for (k0, d0), (k1, d1) in pairwise(keys):
        for k in range(k0, k1 + 1):
            s = _smoothstep((k - k0) / max(k1 - k0, 1))
            dq[k] = (1 - s) * d0 + s * d1
    dq[:2] = 0.0
    dq[N] = dq[N - 1]
    return dq
