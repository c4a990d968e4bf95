"""Feed-forward compensation of the URDF's joint friction (:class:`JointFriction`).

The inverse-dynamics QP plans accelerations with Pinocchio's rigid-body model, which has no joint
friction, while the URDF states a viscous ``damping`` [N m s/rad] and a Coulomb ``friction``
[N m] per joint (Talos: 0.5-1 N m s/rad and 1 N m on the arms, torso and neck; none on the legs;
G1 none). On a light link the QP's torques never break that friction: Talos's head yaw link
(0.0045 kg m² about its axis) asked for 0.36 N m at most while turning 0.25 rad, so against its
1 N m of friction the head lagged 0.2 rad behind the plan (``look to the left`` failed its
orientation target by 0.22 rad).

The compensation adds, per actuated joint,

    tau_f = s * (damping * w + friction * tanh(w / VELOCITY_SCALE)),
    w = v_ref + RETURN_RATE * (q_ref - q),

a fraction ``s`` (:attr:`WbcSettings.friction_compensation`) of the URDF's own friction model
evaluated at the velocity the joint should have: the plan's, plus a return towards the plan's
angle (without it a joint that stopped short of its plan stays there, held by static friction).
``s < 1`` leaves part of the friction unknown to the controller, which the certificate still
tests. The sum is clipped to the torque limits.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from robots import Robot

VELOCITY_SCALE = 0.02  # [rad/s] the Coulomb term's tanh reaches 76 % of the friction at this speed
RETURN_RATE = 20.0  # [1/s] desired joint speed per radian of error


class JointFriction:
    """The feed-forward friction torques of ``robot``'s actuated joints.

    Args:
        robot: The robot (its Pinocchio model's ``damping`` and ``friction``).
        scale: Fraction of the URDF friction to compensate [-], 0 disables.
    """

    def __init__(self, robot: Robot, scale: float) -> None:
        model = robot.model
        self.model = model
        self.damping = scale * np.asarray(model.damping[6:], dtype=float)
        self.friction = scale * np.asarray(model.friction[6:], dtype=float)
        self.active = bool(np.any(self.damping > 0) or np.any(self.friction > 0))

    def torques(self, q: np.ndarray, v: np.ndarray, q_ref: np.ndarray, v_ref: np.ndarray) -> np.ndarray:
        """Compensation torques (nv - 6,) [N m] at measured ``q`` and reference ``q_ref, v_ref``
        (``v`` is unused: the compensation is evaluated at the desired speed, not the measured one)."""
        w = v_ref[6:] + RETURN_RATE * pin.difference(self.model, q, q_ref)[6:]
        return self.damping * w + self.friction * np.tanh(w / VELOCITY_SCALE)

    def add(self, tau: np.ndarray, q: np.ndarray, v: np.ndarray, q_ref: np.ndarray, v_ref: np.ndarray,
            limits: np.ndarray) -> np.ndarray:
        """``tau`` plus the compensation, clipped to ``±limits``."""
        if not self.active:
            return tau
        out = tau + self.torques(q, v, q_ref, v_ref)
        np.maximum(out, -limits, out=out)  # np.clip's values, without its Python wrapper (a 1 kHz call)
        return np.minimum(out, limits, out=out)


__all__ = ["RETURN_RATE", "VELOCITY_SCALE", "JointFriction"]
