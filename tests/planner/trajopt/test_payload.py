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


def test_a_held_object_too_heavy_is_refused_naming_it_its_mass_and_the_joint(talos):
    """The payload check on a held 40 kg cup (the fast twin of tests/sim/test_grasp_sim.py's
    CLI refusal, a long test): the spec of "pick up the cup" and a motion that holds the standing
    posture; the check fails at the joint whose |torque| / limit is largest, computed here from
    payload_torques (itself against RNEA above), and its message names the cup, its mass and that
    joint; the real 0.25 kg cup passes."""
    from language import parse
    from planner.trajopt.payload import PAYLOAD_TORQUE_FRACTION, payload_checks
    from tasks.compose import compile_actions
    from tasks.scene import Scene, SceneObject

    def check(mass: float):
        cup = SceneObject(name="cup", shape="cylinder", size=(0.04, 0.1), position=(0.52, -0.2, 0.77), movable=True,
                          mass=mass)
        table = SceneObject(name="table", shape="box", size=(0.6, 1.0, 0.72), position=(0.75, 0.0, 0.36))
        spec = compile_actions(list(parse("pick up the cup").actions), talos, scene=Scene(objects=(table, cup)))
        t = np.arange(0.0, spec.horizon + 1e-9, spec.dt)
        q = np.tile(np.asarray(talos.q_standing, dtype=float), (len(t), 1))
        (c,) = payload_checks(talos, spec, t, q)
        (g,) = spec.grasps
        joints = supporting_joints(talos, g.frame)
        tau = payload_torques(talos, q[0], g.frame, np.asarray(g.offset), mass)[joints]
        frac = np.abs(tau) / np.asarray(talos.torque_limits, dtype=float)[joints]
        return c, talos.joint_names[int(joints[int(np.argmax(frac))])], 100.0 * float(frac.max())

    heavy, joint, percent = check(40.0)
    assert not heavy.ok and heavy.value == pytest.approx(percent, rel=1e-9) and percent > 100 * PAYLOAD_TORQUE_FRACTION
    assert heavy.message.startswith("the cup (40 kg) is too heavy to hold") and f" N m at {joint} " in heavy.message
    light, _, percent = check(0.25)
    assert light.ok and light.value == pytest.approx(percent, rel=1e-9)
