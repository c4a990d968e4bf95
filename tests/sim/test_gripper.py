"""talos's closing gripper in MuJoCo (sim/model.py): the fingers that talos_reduced hangs from fixed
joints with ``<mimic>`` tags move in the simulation, coupled to ``gripper_*_joint``; checked against
the shipped URDFs (limits, mimic multipliers) and against Pinocchio on example-robot-data's
talos_full_v2.urdf, where the same finger joints are revolute."""

from __future__ import annotations

import copy
import xml.etree.ElementTree as ET
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from sim.grasp import CLOSED_MARGIN, GRIP_FRACTION
from sim.model import build_model, hand_gripper
from tests.sim.test_model import GRASPABLE

FINGER_TOLERANCE = 1e-3  # [rad] a mimic joint follows the drive within this (MuJoCo's soft joint equality)
TIP_TOLERANCE = 2e-4  # [m] a fingertip where Pinocchio puts it on the full URDF at the simulated angles


def _urdf_joints(path: Path) -> dict[str, ET.Element]:
    return {j.get("name", ""): j for j in ET.parse(path).getroot().findall("joint")}


@pytest.mark.parametrize("side", ["left", "right"])
def test_the_gripper_closes_and_the_fingers_follow(talos, side):
    """Driven at 90 % of its effort limit towards its closed limit (zero gravity, 2.6 s), talos's
    gripper drive gets within CLOSED_MARGIN of the lower limit of ``gripper_<side>_joint`` in the
    URDF (-1.047 rad); each of the six finger joints follows as its ``<mimic>`` tag says (multiplier
    and offset read from the URDF) within 1e-3 rad and stays inside its URDF limits; and the three
    fingertip links sit, in the hand frame, where Pinocchio on talos_full_v2.urdf puts them at the
    same joint angles (0.2 mm), the two-fingertip side and the one-fingertip side moving towards
    each other by more than 4 cm (their pads: 9.2 cm apart open)."""
    urdf = Path(talos.urdf_path)
    joints = _urdf_joints(urdf)
    assert hand_gripper(build_model(talos), side) is None  # no scene, nothing to grasp: fixed fingers
    sm = build_model(talos, scene=GRASPABLE)
    gr = hand_gripper(sm, side)
    assert gr is not None
    drive = f"gripper_{side}_joint"
    assert gr.joint == drive
    limit = joints[drive].find("limit")
    assert limit is not None
    assert gr.closed_angle == pytest.approx(float(limit.get("lower", "nan")))
    assert gr.open_angle == 0.0
    assert gr.effort == pytest.approx(float(limit.get("effort", "nan")))
    tips = [f"gripper_{side}_fingertip_{k}_link" for k in (1, 2, 3)]
    assert {sm.model.body(int(sm.model.geom_bodyid[g])).name for g in gr.pad_geoms} == set(tips)
    assert len(gr.finger_geoms) == 7  # the drive link, two inner links, three fingertips, the single motor link
    mimics = {n: j.find("mimic") for n, j in joints.items() if j.find("mimic") is not None
              and j.find("mimic").get("joint") == drive}  # type: ignore[union-attr]
    assert len(mimics) == 6
    assert {n: (o, k) for n, o, k in gr.mimics} == {
        n: (float(e.get("offset", "0")), float(e.get("multiplier", "1"))) for n, e in mimics.items()}  # type: ignore[union-attr]

    m = copy.deepcopy(sm.model)
    m.opt.gravity[:] = 0.0
    d = mujoco.MjData(m)
    sm.set_state(d, talos.q_standing)
    hand = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, f"gripper_{side}_base_link")

    def tips_in_hand() -> np.ndarray:
        R, p = d.xmat[hand].reshape(3, 3), d.xpos[hand]
        return np.array([R.T @ (d.xpos[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, t)] - p) for t in tips])

    open_tips = tips_in_hand()
    act = sm.actuator_index[gr.actuated]
    checked = 0
    for step in range(2600):
        d.ctrl[:] = 0.0
        d.ctrl[act] = GRIP_FRACTION * gr.effort * np.sign(gr.closed_angle - gr.open_angle)
        mujoco.mj_step(m, d)
        angle = float(d.qpos[gr.qpos])
        if step % 100 or abs(angle - gr.closed_angle) < 0.05:
            continue  # (at the limit the drive's and the fingers' own limits share the load: a few mrad apart)
        checked += 1
        angles = {drive: angle}
        for name, e in mimics.items():
            q = float(d.qpos[m.jnt_qposadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)]])
            want = float(e.get("offset", "0")) + float(e.get("multiplier", "1")) * angle  # type: ignore[union-attr]
            assert q == pytest.approx(want, abs=FINGER_TOLERANCE), (name, angle)
            lim = joints[name].find("limit")
            assert lim is not None
            assert float(lim.get("lower", "nan")) <= q + FINGER_TOLERANCE
            assert q <= float(lim.get("upper", "nan")) + FINGER_TOLERANCE
            angles[name] = q
    assert checked >= 15  # the drive swept most of its range (0.44 rad/s: damping and friction 1 in the URDF)
    assert abs(float(d.qpos[gr.qpos]) - gr.closed_angle) <= CLOSED_MARGIN, float(d.qpos[gr.qpos])
    angles = {drive: float(d.qpos[gr.qpos])}
    for name in mimics:
        angles[name] = float(d.qpos[m.jnt_qposadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)]])

    full = pin.buildModelFromUrdf(str(urdf.with_name("talos_full_v2.urdf")))
    q_full = pin.neutral(full)
    for name, q in angles.items():
        q_full[full.joints[full.getJointId(name)].idx_q] = q
    data = full.createData()
    pin.framesForwardKinematics(full, data, q_full)
    oMh = data.oMf[full.getFrameId(f"gripper_{side}_base_link")]
    want_tips = np.array([oMh.actInv(data.oMf[full.getFrameId(t)].translation) for t in tips])
    closed_tips = tips_in_hand()
    np.testing.assert_allclose(closed_tips, want_tips, atol=TIP_TOLERANCE)
    gap_open = abs(open_tips[:2, 1].mean() - open_tips[2, 1])
    assert gap_open == pytest.approx(0.1022, abs=1e-3)  # the fingertip frames, 2 x 0.0511 m
    assert (open_tips[:2, 1].mean() - open_tips[2, 1]) * (closed_tips[:2, 1].mean() - closed_tips[2, 1]) < 0  # crossed over
    assert abs(closed_tips[:2, 1].mean() - open_tips[:2, 1].mean()) > 0.04
