"""Hand targets within what the robot's arm joints hold (tasks.mocap.strength): the torques are
checked against Pinocchio's recursive Newton-Euler algorithm (RNEA), and a moved target against a
witness pose that reaches it (forward kinematics) within the joints' margin (RNEA again)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from robots import load_robot
from tasks.mocap import strength
from tasks.primitives.geometry import standing_geometry


@pytest.fixture(scope="module")
def talos():
    return load_robot("talos")


def _arm_out(robot, side: str = "right") -> np.ndarray:
    """Talos standing, its ``side`` arm stretched and rolled out sideways to horizontal."""
    model = robot.model
    q = np.array(robot.q_standing, dtype=float)
    for i in range(1, 8):
        q[model.joints[model.getJointId(f"arm_{side}_{i}_joint")].idx_q] = 0.0
    q[model.joints[model.getJointId(f"arm_{side}_2_joint")].idx_q] = -np.pi / 2 if side == "right" else np.pi / 2
    return q


def test_arm_torques_are_rnea_at_rest_and_under_a_uniform_acceleration(talos):
    """At rest, the torques are RNEA's with zero velocity and acceleration; an acceleration ``a`` of
    the whole robot (its free flyer's, no rotation) loads the arm as gravity minus ``a`` would."""
    model, data = talos.model, talos.model.createData()
    joints = strength.strained_joints(talos, "right")
    cols = [model.joints[j].idx_v for j in joints]
    q = _arm_out(talos)
    zero = np.zeros(model.nv)
    np.testing.assert_allclose(strength.arm_torques(talos, q[None], joints)[0],
                               pin.rnea(model, data, q, zero, zero)[cols], atol=1e-9)
    a = np.array([1.5, -2.0, 3.0])  # [m/s^2] in the world
    acc = zero.copy()
    R = pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix()  # the base's orientation (x, y, z, w)
    acc[:3] = R.T @ a  # the free flyer's linear acceleration, in its own frame
    np.testing.assert_allclose(strength.arm_torques(talos, q[None], joints, a[None])[0],
                               pin.rnea(model, data, q, zero, acc)[cols], atol=1e-9)
    assert abs(strength.arm_torques(talos, q[None], joints)[0][joints.index(model.getJointId("arm_right_2_joint"))]) \
        > model.effortLimit[model.joints[model.getJointId("arm_right_2_joint")].idx_v]  # out: beyond the roll


def test_the_strained_joints_are_those_a_stretched_arm_could_overload(talos):
    """Talos's shoulder roll cannot hold its stretched arm out (RNEA above its limit): it is checked.
    G1's arm joints hold its stretched arm out sideways within the margin (RNEA): none is checked,
    and the rule leaves G1's targets as they are."""
    model = talos.model
    for side in ("left", "right"):
        assert model.getJointId(f"arm_{side}_2_joint") in strength.strained_joints(talos, side)
    g1 = load_robot("g1")
    assert strength.strained_joints(g1, "left") == [] and strength.strained_joints(g1, "right") == []
    model, data = g1.model, g1.model.createData()
    for side, out in (("left", np.pi / 2), ("right", -np.pi / 2)):
        q = np.array(g1.q_standing, dtype=float)
        for name in ("shoulder_pitch", "shoulder_yaw", "elbow", "wrist_roll", "wrist_pitch", "wrist_yaw"):
            q[model.joints[model.getJointId(f"{side}_{name}_joint")].idx_q] = 0.0
        q[model.joints[model.getJointId(f"{side}_shoulder_roll_joint")].idx_q] = out
        tau = pin.rnea(model, data, q, np.zeros(model.nv), np.zeros(model.nv))
        for name in ("shoulder_pitch", "shoulder_roll", "shoulder_yaw", "elbow"):
            i = model.joints[model.getJointId(f"{side}_{name}_joint")].idx_v
            assert abs(tau[i]) < strength.ARM_STRENGTH_MARGIN * model.effortLimit[i]


def _standing_points(robot, seconds: float, fps: float = 30.0) -> tuple[dict[str, np.ndarray], np.ndarray]:
    g = standing_geometry(robot)
    n = int(seconds * fps) + 1
    pts = {role: np.tile(g.placements[role].translation, (n, 1))
           for role in ("base", "torso", "head", "left_hand", "right_hand", "left_shoulder", "right_shoulder")}
    return pts, np.arange(n) / fps + 0.8


def test_a_hand_held_out_is_brought_in_to_a_pose_the_shoulder_holds(talos):
    """The right hand held out sideways at the stretched arm's reach, level with the shoulder (talos's
    shoulder roll cannot hold it: RNEA above its limit) is brought in horizontally, its height kept;
    a witness pose (the module's inverse kinematics) reaches the moved target (forward kinematics,
    within 3 cm) with every arm joint's torque (RNEA, at rest) within the margin (+3 %). The hanging
    left hand is not moved; the gap is named with the joint."""
    model, data = talos.model, talos.model.createData()
    pts, t = _standing_points(talos, 1.0)
    shoulder = pts["right_shoulder"][0]
    pin.framesForwardKinematics(model, data, _arm_out(talos))
    reach = float(np.linalg.norm(data.oMf[talos.frame_id("right_hand")].translation
                                 - data.oMf[talos.frame_id("right_shoulder")].translation))
    pts["right_hand"] = np.tile(shoulder + [0.0, -reach, 0.0], (len(t), 1))
    left = pts["left_hand"]
    hands, moved, gaps = strength.hold_within_strength(talos, pts, np.zeros(len(t)), t)
    assert hands["left"] is left and moved["left"].max() == 0.0
    held = hands["right"]
    np.testing.assert_allclose(held[:, 2], pts["right_hand"][:, 2])  # the height kept
    inward = -(held[:, 1] - shoulder[1])
    assert np.all(inward < 0.8 * reach) and np.all(inward > 0.2 * reach)  # brought in, not to the body
    np.testing.assert_allclose(moved["right"], reach - inward, atol=1e-9)
    witness = strength.whole_body_poses(talos, {**pts, "right_hand": held}, np.zeros(len(t)), np.array([15]),
                                        strength.strained_joints(talos, "right"))[0]
    pin.framesForwardKinematics(model, data, witness)
    assert np.linalg.norm(data.oMf[talos.frame_id("right_hand")].translation - held[15]) < 0.03
    tau = pin.rnea(model, data, witness, np.zeros(model.nv), np.zeros(model.nv))
    for i in range(1, 8):
        j = model.getJointId(f"arm_right_{i}_joint")
        assert abs(tau[model.joints[j].idx_v]) <= 1.03 * strength.ARM_STRENGTH_MARGIN * model.effortLimit[
            model.joints[j].idx_v]
    (gap,) = gaps
    assert gap.role == "right_hand" and "arm_right_2_joint's torque limit" in gap.cause
    assert gap.metres == pytest.approx(moved["right"].max())
    assert gap.text().startswith(f"right hand {gap.metres:.2f} m from the source at ")
    assert "left of it" in gap.direction  # the robot's hand is inwards (left) of the source's right hand


def test_a_gap_is_named_in_the_heading_frame():
    """A target moved 0.3 m down at 2.4 s is "0.30 m below it"; one moved 0.2 m along the world's +y
    with the body turned 90 degrees left (heading +y) is "0.20 m ahead of it"."""
    t = np.linspace(0.0, 4.0, 41)
    before = np.zeros((41, 3))
    after = before.copy()
    after[24, 2] = -0.3
    gap = strength.gaps_of("right_hand", before, after, t, np.zeros(41), "a cause")
    assert gap is not None and gap.time == pytest.approx(2.4) and gap.metres == pytest.approx(0.3)
    assert gap.text() == "right hand 0.30 m from the source at 2.40 s, mostly 0.30 m below it: a cause"
    after = before.copy()
    after[10, 1] = 0.2  # world +y; facing +y (heading 90 deg) that is ahead
    assert "0.20 m ahead of it" in strength.gaps_of("base", before, after, t, np.full(41, np.pi / 2), "c").direction
    assert strength.gaps_of("base", before, before + 0.001, t, np.zeros(41), "c") is None  # under 5 mm: none


def test_a_run_of_knots_that_never_asks_more_than_the_trigger_is_not_moved(talos, monkeypatch):
    """The same hand held out (its pose asks more than the roll's limit) with the trigger set above
    what it asks: nothing is moved (a swing that only brushes past the margin is left to the
    controller: talos's march)."""
    pts, t = _standing_points(talos, 0.5)
    shoulder = pts["right_shoulder"][0]
    pts["right_hand"] = np.tile(shoulder + [0.0, -0.6, 0.0], (len(t), 1))
    _, moved, gaps = strength.hold_within_strength(talos, pts, np.zeros(len(t)), t)
    assert moved["right"].max() > 0.1 and gaps
    monkeypatch.setattr(strength, "ARM_STRENGTH_TRIGGER", 10.0)
    hands, moved, gaps = strength.hold_within_strength(talos, pts, np.zeros(len(t)), t)
    assert hands["right"] is pts["right_hand"] and moved["right"].max() == 0.0 and gaps == []
