"""Naming why a keypoint missed: a joint of its chain at its torque limit near that time."""

from __future__ import annotations

import numpy as np

from robots import load_robot
from tasks.mocap.figures import torque_cause


def test_a_saturated_shoulder_is_named_and_a_leg_is_not():
    talos = load_robot("talos")
    t = np.linspace(0.0, 4.0, 4001)
    limits = talos.torque_limits
    tau = 0.3 * np.tile(limits, (len(t), 1))
    col = talos.model.joints[talos.model.getJointId("arm_right_2_joint")].idx_v - 6
    near = np.abs(t - 2.86) < 0.1
    tau[near, col] = -0.97 * limits[col]  # the measured wave: 21.7 of 22.3 N m
    assert torque_cause(talos, "right_hand", 2.86, t, tau).startswith("arm_right_2_joint at its torque limit (21.")
    assert torque_cause(talos, "left_hand", 2.86, t, tau) == ""  # not in the left arm's chain
    assert torque_cause(talos, "right_hand", 1.0, t, tau) == ""  # not near that time
    leg = talos.model.joints[talos.model.getJointId("leg_left_4_joint")].idx_v - 6
    tau[:, leg] = limits[leg]
    assert torque_cause(talos, "right_hand", 1.0, t, tau) == ""  # a leg does not carry the hand
