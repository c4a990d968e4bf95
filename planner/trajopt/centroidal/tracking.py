"""Initial guess of a tracking plan (a retargeted clip): every knot's pose by inverse kinematics of
its own soft targets.

The heading guess (:func:`planner.trajopt.centroidal.heading.heading_guess`) keeps the joints at
the standing posture. A spec that tracks a motion (a soft frame target at almost every knot: a
retarget, :mod:`tasks.mocap`) is itself a guess of the whole trajectory: solving each knot's
pose for its targets gives IPOPT a start near the motion, and the collision rows screened on it
are the ones the motion needs (on the heading guess, g1's squat screened none of the 16 link
pairs its solution then brought within the margin: a second build and solve).

Per variable knot, from the knot before's pose (a damped, weighted Gauss-Newton, Pinocchio):

* the contacts active at the knot, in 6D, weighted :data:`CONTACT_WEIGHT` (far above the targets:
  a stance sole ends within a fraction of a millimetre of its placement);
* each soft frame position target of the knot, weighted by the square root of its own weight
  over the knot's largest (the spec's relative weights), and each soft orientation target
  likewise (a base heading, in metres per radian as the spec's weights say);
* the joints pulled weakly towards the standing reference (:data:`REGULARIZATION`);
* joint limits by clipping.

A knot without targets (the lead-out) keeps the pose before it with its contacts met.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from planner.trajopt.kinds import FrameOrientationTerm, FramePositionTerm
from planner.trajopt.layout_data import LayoutData

CONTACT_WEIGHT = 30.0  # a contact's 6D error against a target's weight of 1 [1/m, 1/rad]
REGULARIZATION = 1e-3  # pull of the joints towards the standing reference, per iteration
DAMPING = 1e-4
ITERATIONS = 12  # Gauss-Newton steps per knot, from the knot before's pose
#: A spec is tracked (this guess is used) when at least this share of its variable knots holds a
#: soft frame position target.
TRACKED_SHARE = 0.5


def _soft_targets(lay: LayoutData) -> dict[int, list[tuple]]:
    """Knot -> [("pos", fid, goal, axes, weight) | ("rot", fid, rotation, None, weight)] of the soft targets."""
    out: dict[int, list[tuple]] = {}
    for term in lay.terms:
        if isinstance(term, FramePositionTerm) and not term.hard:
            out.setdefault(term.knot, []).append(("pos", term.frame_id, np.array(term.params[:3]),
                                                  np.array(term.axes, dtype=bool), float(term.params[3])))
        elif isinstance(term, FrameOrientationTerm) and not term.hard and term.item is not None:
            R = np.array(term.params[:9]).reshape(3, 3).T
            out.setdefault(term.knot, []).append(("rot", term.frame_id, R, None, float(term.params[9])))
    return out


def is_tracking(lay: LayoutData) -> bool:
    """The spec tracks a motion: a soft frame position target at :data:`TRACKED_SHARE` of its variable knots."""
    targets = _soft_targets(lay)
    variable = range(2, lay.N)
    return len(variable) > 0 and sum(1 for k in variable if any(t[0] == "pos" for t in targets.get(k, ()))) \
        >= TRACKED_SHARE * len(variable)


def _knot_pose(lay: LayoutData, knot: int, tasks: list[tuple], q0: np.ndarray, data: pin.Data) -> np.ndarray:
    """The pose of ``knot`` (nq,) from ``q0``: contacts, then the weighted targets ``tasks``."""
    model = lay.robot.model
    q = np.array(q0)
    w_max = max((t[4] for t in tasks), default=1.0)
    lo, hi = model.lowerPositionLimit[7:], model.upperPositionLimit[7:]
    lo, hi = np.where(np.abs(lo) < 1e10, lo, -np.inf), np.where(np.abs(hi) < 1e10, hi, np.inf)
    for _ in range(ITERATIONS):
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        rows, errs = [], []
        for fid, (_frame, M) in lay.contacts_at[knot].items():
            err_M = M.actInv(data.oMf[fid])
            J = pin.getFrameJacobian(model, data, fid, pin.ReferenceFrame.LOCAL)
            rows.append(CONTACT_WEIGHT * pin.Jlog6(err_M) @ J)
            errs.append(CONTACT_WEIGHT * pin.log6(err_M).vector)
        for kind, fid, goal, axes, weight in tasks:
            s = float(np.sqrt(weight / w_max)) if w_max > 0 else 1.0
            if kind == "pos":
                J = pin.getFrameJacobian(model, data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)[:3]
                rows.append(s * J[axes])
                errs.append(s * (data.oMf[fid].translation - goal)[axes])
            else:
                J = pin.getFrameJacobian(model, data, fid, pin.ReferenceFrame.LOCAL)[3:]
                rows.append(s * J)
                errs.append(s * pin.log3(goal.T @ data.oMf[fid].rotation))
        A, e = np.vstack(rows), np.concatenate(errs)
        reg = pin.difference(model, lay.q_ref, q)
        reg[:6] = 0.0
        H = A.T @ A + (DAMPING + REGULARIZATION) * np.eye(model.nv)
        step = -np.linalg.solve(H, A.T @ e + REGULARIZATION * reg)
        q = pin.integrate(model, q, step)
        q[7:] = np.clip(q[7:], lo, hi)
        if np.linalg.norm(step) < 1e-6:
            break
    return q


def tracking_guess(lay: LayoutData) -> np.ndarray | None:
    """Chart displacements (N+1, nv) of every knot's pose for its soft targets (module docstring),
    or None when the spec tracks no motion (:func:`is_tracking`) or a pose is not finite."""
    from planner.trajopt.symbolic import configuration_to_chart

    if not is_tracking(lay):
        return None
    model = lay.robot.model
    data = model.createData()
    targets = _soft_targets(lay)
    dq = np.zeros((lay.N + 1, lay.robot.nv))
    q = np.array(lay.q_ref)
    for k in range(2, lay.N):
        q = _knot_pose(lay, k, targets.get(k, []), q, data)
        if not np.all(np.isfinite(q)):
            return None
        dq[k] = configuration_to_chart(model, lay.q_ref, q)
    dq[lay.N] = dq[lay.N - 1]
    return dq


__all__ = ["is_tracking", "tracking_guess"]
