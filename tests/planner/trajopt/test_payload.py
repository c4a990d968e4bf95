"""The payload check's static torques (planner/trajopt/payload.py) against Pinocchio's RNEA with the
object's weight as an external force on the hand's joint, and the joints it reports."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from planner.trajopt.payload import GRAVITY, payload_torques, supporting_joints
from robots import load_robot


@pytest.fixture(scope="module")
def talos():
    return load_robot("talos")


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_payload_torques_match_rnea_with_an_external_force(talos, seed):
    """tau = g(q) + J_p^T (0, 0, m g) equals RNEA (v = a = 0) with the weight -m g z applied at the
    point, expressed in the hand joint's frame, at standing configurations with random arm angles."""
    model, data = talos.model, talos.data()
    rng = np.random.default_rng(seed)
    q = talos.q_standing.copy()
    arm = supporting_joints(talos, talos.frame("right_hand"))
    q[7 + arm] += rng.uniform(-0.4, 0.4, size=len(arm))
    offset = np.array([0.02, -0.05, -0.1])
    mass = 3.0
    frame = talos.frame("right_hand")
    pin.framesForwardKinematics(model, data, q)
    fid = talos.frame_id(frame)
    joint = model.frames[fid].parentJoint
    point = data.oMf[fid].act(offset)
    oMj = data.oMi[joint]
    fext = [pin.Force.Zero() for _ in range(model.njoints)]
    f_local = oMj.rotation.T @ np.array([0.0, 0.0, -mass * GRAVITY])
    fext[joint] = pin.Force(f_local, np.cross(oMj.actInv(point), f_local))
    expected = pin.rnea(model, data, q, np.zeros(model.nv), np.zeros(model.nv), fext)[6:]
    np.testing.assert_allclose(payload_torques(talos, q, frame, offset, mass), expected, atol=1e-9)


def test_supporting_joints_are_the_torso_and_the_arm(talos):
    """The joints that carry a right-hand payload: torso and right arm, no leg, no left arm."""
    names = [talos.joint_names[j] for j in supporting_joints(talos, talos.frame("right_hand"))]
    assert names[0].startswith("torso") and names[-1] == "arm_right_7_joint"
    assert not any(n.startswith(("leg", "arm_left")) for n in names)
