"""The mink peer of benchmarks/bench_retarget.py sees the robot wbmp measures: the sites it tracks
in its MJCF are the tracked Pinocchio frames (MuJoCo forward kinematics of the converted
configuration against Pinocchio's, to 1e-5: the MJCF text rounds), and configurations convert both ways."""

from __future__ import annotations

import sys
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from robots import load_robot

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks" / "peers"))

import peer_mink  # noqa: E402


@pytest.mark.parametrize("name", ["talos", "g1"])
def test_the_peer_sites_are_the_tracked_frames(name):
    robot = load_robot(name)
    model = robot.model
    rng = np.random.default_rng(3)
    q = np.asarray(robot.q_standing, dtype=float).copy()
    lo, hi = model.lowerPositionLimit[7:], model.upperPositionLimit[7:]
    q[7:] = np.clip(q[7:] + rng.uniform(-0.4, 0.4, model.nq - 7), lo, hi)
    q[:3] += [0.3, -0.2, 0.05]
    q[3:7] = pin.Quaternion(pin.rpy.rpyToMatrix(0.1, -0.2, 0.7)).coeffs()
    back = peer_mink.to_pinocchio(robot, peer_mink.to_mujoco(robot, q)[None])[0]
    np.testing.assert_allclose(back, q, atol=1e-12)
    xml, _ = peer_mink._mjcf(robot.name, robot)
    mj = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(mj)
    data.qpos[:] = peer_mink.to_mujoco(robot, q)
    mujoco.mj_kinematics(mj, data)
    pdata = model.createData()
    pin.framesForwardKinematics(model, pdata, q)
    for role in peer_mink.TRACKED:
        sid = mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_SITE, f"wbmp_{role}")
        M = pdata.oMf[robot.frame_id(role)]
        np.testing.assert_allclose(data.site_xpos[sid], M.translation, atol=1e-5, err_msg=role)
        np.testing.assert_allclose(data.site_xmat[sid].reshape(3, 3), M.rotation, atol=1e-5, err_msg=role)
