r"""Joint torque margin rows: chosen joints' torques kept within a fraction of their limits.

The dynamic formulation plans forces, the CoM and the whole body's momentum, not the joints'
torques: a plan may ask an arm joint for more than the robot's actuator gives (talos's march
swung its left shoulder roll at 0.96-1.02 of its 22.3 N m limit; in MuJoCo the joint lagged and
the hand missed its plan by 50.1 mm). For the joints named in
:attr:`CentroidalSettings.torque_joints` (joints no contact force passes through: the arms), the
torque the planned motion needs is Pinocchio's RNEA on the knots (central differences, as the
full-dynamics checks, :func:`planner.trajopt.centroidal.zmp.central_velocities`).

Rows, per variable knot and joint: :math:`(g_j(q_k) + \max(d_{k,j}, 0)) / \tau_j^{max} \le m`
and :math:`(g_j(q_k) + \min(d_{k,j}, 0)) / \tau_j^{max} \ge -m`
(:attr:`CentroidalSettings.torque_margin` ``m``), where :math:`g_j` is the joint's gravity torque
(exact, symbolic: :math:`g_j = \sum_{i \in subtree(j)} m_i g_0\, a_j \cdot ((c_i - o_j) \times
e_z)`, the axis :math:`a_j` and origin :math:`o_j` of the joint, the bodies' CoMs :math:`c_i`)
and :math:`d_{k,j}` the rest of the RNEA torque (velocities and accelerations), frozen at the
last solution (a parameter). Together they keep :math:`|g_j + d_{k,j}|` and :math:`|g_j|` within
the margin: a frozen rest that relieves the joint is not counted on (with one row
:math:`|g + d| \le m`, talos's bend held its arm up on a frozen deceleration, its gravity torque
0.99 of the limit, and the next solve's RNEA asked 1.14). The rows are added only after a solve whose RNEA torque exceeds
:attr:`CentroidalSettings.torque_trigger` (1.0: more than the actuator gives) somewhere, then their
:math:`d` re-linearized after each solve that still exceeds the margin (``+ TORQUE_TRIGGER``), at most :attr:`CentroidalSettings.torque_rounds` solves
(:meth:`planner.trajopt.centroidal.layout.DynamicLayout.relinearized`): a plan within the
margin is the plan without the rows, bit for bit.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar

import casadi as ca
import numpy as np
import pinocchio as pin

from planner.trajopt.centroidal.zmp import central_velocities
from planner.trajopt.term import NumericKinematics, StageKinematics, Term

if TYPE_CHECKING:
    from planner.trajopt.centroidal.data import DynamicData
    from robots.model import Robot

TORQUE_TRIGGER = 0.02  # [fraction of the limit]: RNEA above margin + this adds (or re-linearizes) the rows


def joint_ids(robot: Robot, names: tuple[str, ...]) -> tuple[int, ...]:
    """Pinocchio joint ids of ``names`` (ValueError naming an unknown or multi-dof joint)."""
    model = robot.model
    out = []
    for name in names:
        if not model.existJointName(name):
            raise ValueError(f"torque_joints: {robot.name} has no joint {name!r}")
        j = model.getJointId(name)
        if model.joints[j].nv != 1:
            raise ValueError(f"torque_joints: {name!r} is not a one-dof joint")
        out.append(int(j))
    return tuple(out)


def gravity_torques(kin: StageKinematics, joints: tuple[int, ...]) -> Any:
    """Gravity torques (len(joints),) [N m] of one-dof revolute ``joints`` (CasADi, of the stage's
    configuration): Pinocchio's ``computeGeneralizedGravity`` at those joints."""
    from planner.trajopt.symbolic import joint_infos

    model = kin.robot.model
    infos = joint_infos(model)
    placements = kin.joints
    g0 = float(np.linalg.norm(model.gravity.linear))
    ez = ca.DM([0.0, 0.0, 1.0])
    out = []
    for j in joints:
        info = infos[j]
        assert info is not None and info.axis is not None
        Rj, pj = placements[j]
        axis = ca.mtimes(Rj, ca.DM(info.axis))
        moment = ca.SX.zeros(3)
        for i in model.subtrees[j]:
            Ri, pi = placements[i]
            inertia = model.inertias[i]
            c = pi + ca.mtimes(Ri, ca.DM(np.asarray(inertia.lever)))
            moment += float(inertia.mass) * g0 * ca.cross(c - pj, ez)
        out.append(ca.dot(axis, moment))
    return ca.vertcat(*out)


@dataclass(eq=False)
class TorqueMarginTerm(Term):
    """Joints' torques (gravity, exact, + the rest of RNEA frozen) over their limits at one knot:
    rows ``(g + max(d, 0)) / limit <= margin`` for each joint, then ``(g + min(d, 0)) / limit >=
    -margin``. Structure ``("torque_margin", joint ids)``; parameters the frozen rest :math:`d`
    per joint [N m]."""

    kind: ClassVar[str] = "torque_margin"

    @classmethod
    def at(cls, knot: int, robot: Robot, joints: tuple[int, ...], margin: float, rest: np.ndarray,
           phase: str) -> TorqueMarginTerm:
        """The term at ``knot`` with the frozen rest ``rest`` (len(joints),) [N m]."""
        n = len(joints)
        return cls(knot=knot, structure=(cls.kind, joints), params=np.asarray(rest, dtype=float).copy(),
                   lower=np.concatenate([np.full(n, -np.inf), np.full(n, -margin)]),
                   upper=np.concatenate([np.full(n, margin), np.full(n, np.inf)]), phase=phase,
                   label="torque margin of " + ", ".join(robot.model.names[j] for j in joints))

    @property
    def joints(self) -> tuple[int, ...]:
        """The Pinocchio joint ids."""
        return self.structure[1]

    def _limits(self, model: pin.Model) -> np.ndarray:
        return np.array([model.effortLimit[model.joints[j].idx_v] for j in self.joints])

    def expression(self, p, kin: StageKinematics) -> tuple:
        """(rows, cost) in CasADi (:meth:`Term.expression`)."""
        limits = ca.DM(self._limits(kin.robot.model))
        g = gravity_torques(kin, self.joints)
        return ca.vertcat((g + ca.fmax(p, 0)) / limits, (g + ca.fmin(p, 0)) / limits), 0

    def residual(self, kin: NumericKinematics) -> np.ndarray:
        """The rows in numpy (:meth:`Term.residual`)."""
        model = kin.model
        g = pin.computeGeneralizedGravity(model, kin.data, kin.q)
        idx = [model.joints[j].idx_v for j in self.joints]
        limits = self._limits(model)
        return np.concatenate([(g[idx] + np.maximum(self.params, 0)) / limits,
                               (g[idx] + np.minimum(self.params, 0)) / limits])


def plan_torques(robot: Robot, q: np.ndarray, dt: float, joints: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
    """(RNEA torques, gravity torques), each (T, len(joints)) [N m], of configurations ``q`` (T, nq)
    on a grid of step ``dt`` (central differences; 0 velocity and acceleration at both ends)."""
    model = robot.model
    data = model.createData()
    v, a = central_velocities(model, q, dt)
    idx = [model.joints[j].idx_v for j in joints]
    tau = np.array([pin.rnea(model, data, q[k], v[k], a[k])[idx] for k in range(len(q))])
    grav = np.array([pin.computeGeneralizedGravity(model, data, q[k])[idx] for k in range(len(q))])
    return tau, grav


def torque_margin_terms(lay: DynamicData, dq: np.ndarray) -> tuple[Term, ...] | None:
    """The layout's terms with the torque margin rows added or re-linearized about the solution
    ``dq`` (N+1, nv), or None: the solution's RNEA torques of the settings' ``torque_joints`` are
    within ``torque_trigger`` of their limits at every variable knot (a layout without the rows) or
    within ``torque_margin + TORQUE_TRIGGER`` (a layout with them), or no joint is named."""
    from planner.trajopt.symbolic import chart_to_configuration

    s = lay.centroidal_settings
    if not s.torque_joints:
        return None
    robot = lay.robot
    joints = joint_ids(robot, s.torque_joints)
    q = np.array([chart_to_configuration(robot.model, lay.q_ref, d) for d in dq])
    tau, grav = plan_torques(robot, q, float(lay.dt), joints)
    limits = np.array([robot.model.effortLimit[robot.model.joints[j].idx_v] for j in joints])
    knots = range(2, lay.N)
    kept = tuple(t for t in lay.terms if not isinstance(t, TorqueMarginTerm))
    bound = s.torque_margin + TORQUE_TRIGGER if len(kept) < len(lay.terms) else max(s.torque_trigger, s.torque_margin)
    if max(float(np.max(np.abs(tau[k]) / limits)) for k in knots) <= bound:
        return None
    added = tuple(TorqueMarginTerm.at(k, robot, joints, s.torque_margin, tau[k] - grav[k], lay.phase_name(k))
                  for k in knots)
    return kept + added


__all__ = ["TORQUE_TRIGGER", "TorqueMarginTerm", "gravity_torques", "joint_ids", "plan_torques",
           "torque_margin_terms"]
