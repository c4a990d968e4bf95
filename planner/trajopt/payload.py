"""The payload of a grasp: the object's weight on the arm that holds it, checked on the plan.

While a :class:`tasks.specs.Grasp` holds an object of mass ``m``, the arm carries its weight at the
object's centre ``p`` (the grasp's ``offset`` in the hand frame); two hands holding it together (two
grasps with the same start and end) carry half each. At every such knot the static
torque of each joint that supports the hand (torso and arm joints, from the base to the hand) is

    tau = g(q) + J_p(q)^T (0, 0, m g)

with ``g(q)`` Pinocchio's generalized gravity (the joints above the base hold their subtree; the
base is where the legs take over) and ``J_p`` the translational Jacobian of the point ``p``. It
must stay within :data:`PAYLOAD_TORQUE_FRACTION` of the joint's torque limit (the rest is the
controller's: accelerations and tracking). A plan that exceeds it is refused at planning, with
the object, the joint and the numbers (:func:`payload_checks`, raised by :func:`planner.plan`).

The payload does not enter the NLP's rows: a light object shifts the CoM by millimetres (a 0.25 kg
cup 0.5 m ahead moves talos's CoM 1.3 mm), and a heavy one is refused here.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from planner.results import Check, CheckKind
from robots import Robot
from tasks import TaskSpec

PAYLOAD_TORQUE_FRACTION = 0.9  # of a joint's torque limit, holding the object still
GRAVITY = 9.81  # [m/s^2]


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def payload_torques(robot: Robot, q: np.ndarray, frame: str, offset: np.ndarray, mass: float) -> np.ndarray:
    """Static actuated torques (nv - 6,) [N m] holding configuration ``q`` with ``mass`` [kg] at
    ``offset`` [m] in ``frame``."""
    model, data = robot.model, robot.data()
    fid = robot.frame_id(frame)
    tau = pin.computeGeneralizedGravity(model, data, q).copy()
    pin.framesForwardKinematics(model, data, q)
    M = data.oMf[fid]
    J = pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL_WORLD_ALIGNED)
    lever = M.rotation @ np.asarray(offset, dtype=float)
    Jp = J[:3] - _skew(lever) @ J[3:]  # v_p = v_o + w x lever
    tau += Jp.T @ np.array([0.0, 0.0, mass * GRAVITY])
    return tau[6:]


def supporting_joints(robot: Robot, frame: str) -> np.ndarray:
    """Actuated velocity indices (into ``tau[6:]``) of the one-dof joints from the base to ``frame``."""
    model = robot.model
    joint = model.frames[robot.frame_id(frame)].parentJoint
    out = [model.joints[j].idx_v - 6 for j in model.supports[joint] if j > 1 and model.joints[j].nv == 1]
    return np.array(out, dtype=int)


def payload_checks(robot: Robot, spec: TaskSpec, t: np.ndarray, q: np.ndarray) -> list[Check]:
    """One check per grasp of ``spec`` on the plan (``t`` (T,) [s], ``q`` (T, nq)): the largest
    static torque of a joint that carries the object, as a fraction of its limit [%]."""
    if not spec.grasps or spec.scene is None:
        return []
    masses = {o.name: float(o.mass) for o in spec.scene.objects}
    limits = np.asarray(robot.torque_limits, dtype=float)
    out = []
    for g in spec.grasps:
        joints = supporting_joints(robot, g.frame)
        hands = sum(1 for h in spec.grasps if h.object == g.object and abs(h.start - g.start) < 1e-9 and h.end == g.end)
        share = masses[g.object] / hands  # a box held by both hands: each arm carries half its weight
        held = (t >= g.start - 1e-9) & (t <= (t[-1] if g.end is None else g.end) + 1e-9)
        worst = (-1.0, 0.0, 0, 0.0, 0.0)  # fraction, time, joint, torque, without the object
        for k in np.flatnonzero(held):
            tau = payload_torques(robot, q[k], g.frame, np.asarray(g.offset), share)[joints]
            frac = np.abs(tau) / limits[joints]
            j = int(np.argmax(frac))
            if frac[j] > worst[0]:
                bare = payload_torques(robot, q[k], g.frame, np.asarray(g.offset), 0.0)[joints][j]
                worst = (float(frac[j]), float(t[k]), int(joints[j]), float(tau[j]), float(bare))
        if worst[0] < 0:
            continue
        frac, time, j, tau_j, bare = worst
        name = robot.joint_names[j]
        ok = frac <= PAYLOAD_TORQUE_FRACTION
        message = "" if ok else (
            f"the {g.object} ({masses[g.object]:g} kg) is too heavy to hold: at t = {time:.1f} s it needs "
            f"{abs(tau_j):.0f} N m at {name} ({abs(bare):.0f} N m without it), beyond "
            f"{PAYLOAD_TORQUE_FRACTION * 100:.0f} % of its {limits[j]:.0f} N m limit; lighten it in the scene "
            "or hold it closer to the body")
        out.append(Check(
            name=f"payload torque: {g.object} ({masses[g.object]:g} kg) at {name}", kind=CheckKind.PAYLOAD_TORQUE,
            subject=g.name, value=100.0 * frac, limit=100.0 * PAYLOAD_TORQUE_FRACTION, unit="%", time=time, ok=ok,
            message=message))
    return out


__all__ = ["PAYLOAD_TORQUE_FRACTION", "payload_checks", "payload_torques", "supporting_joints"]
