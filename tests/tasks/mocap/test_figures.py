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


def test_the_tracks_soles_and_corners_are_each_configurations_forward_kinematics():
    """The tracks read the soles' corners off their own forward kinematics (session 17: a fresh
    Pinocchio Data per sample and foot was 5 s of a retarget's CPU); against the Robot's own
    ``sole_corners_in_world`` (its own Data and FK) and the sole frame's placement."""
    import pinocchio as pin

    from tasks.mocap.figures import tracks
    from tasks.mocap.retarget import TRACKED, Reference

    talos = load_robot("talos")
    rng = np.random.default_rng(7)
    q = np.array([pin.randomConfiguration(talos.model, talos.model.lowerPositionLimit.clip(-3, 3),
                                          talos.model.upperPositionLimit.clip(-3, 3)) for _ in range(5)])
    t = np.arange(5) * 0.1
    ref = Reference(t=t, points={r: rng.normal(size=(5, 3)) for r in TRACKED},
                    contact={s: np.zeros(5, dtype=bool) for s in ("left", "right")},
                    placements={}, heading=np.zeros(5), scale=1.0, arm_scale=1.0, lead_in=0.0)
    tr = tracks(talos, t, q, ref)
    data = talos.model.createData()
    for i, qi in enumerate(q):
        pin.framesForwardKinematics(talos.model, data, qi)
        for side in ("left", "right"):
            np.testing.assert_array_equal(tr.corners[side][i], talos.sole_corners_in_world(qi, side))
            sole = data.oMf[talos.frame_id(f"{side}_foot")].translation
            np.testing.assert_allclose(tr.soles[side][i], sole, atol=1e-12)
            # the corners lie around the sole frame, within the sole's half-diagonal
            assert np.linalg.norm(tr.corners[side][i] - sole, axis=1).max() < 0.2
        np.testing.assert_allclose(tr.error["base"][i], np.linalg.norm(tr.robot["base"][i] - ref.points["base"][i]))
