"""The feet's relative yaw kept within the robot's hip yaw range (tasks.mocap.splay): the range
against Pinocchio forward kinematics of the soles with the hip yaw joints at their limits, and a
pivot turn's pigeon-toed stance (CMU 01_01 on talos: 77 deg toe-in) turned into it."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

from robots import load_robot
from tasks.mocap import splay
from tasks.specs import Pose

#: The hip yaw joint of each leg ({} the side), named here, not found as the rule finds it.
HIP_YAW = {"talos": "leg_{}_1_joint", "g1": "{}_hip_yaw_joint"}


@pytest.fixture(scope="module", params=["talos", "g1"])
def robot(request):
    return load_robot(request.param)


def _sole_yaws(robot, hips: dict[str, float]) -> dict[str, float]:
    """Each sole's yaw [rad] by forward kinematics at standing with the hip yaws set to ``hips``."""
    model, data = robot.model, robot.model.createData()
    q = np.array(robot.q_standing, dtype=float)
    for side, value in hips.items():
        q[model.joints[model.getJointId(HIP_YAW[robot.name].format(side))].idx_q] = value
    pin.framesForwardKinematics(model, data, q)
    out = {}
    for side in ("left", "right"):
        R = data.oMf[robot.frame_id(robot.frame(f"{side}_foot"))].rotation
        out[side] = math.atan2(R[1, 0], R[0, 0])
    return out


def _limits(robot, side: str) -> tuple[float, float]:
    model = robot.model
    i = model.joints[model.getJointId(HIP_YAW[robot.name].format(side))].idx_q
    return float(model.lowerPositionLimit[i]), float(model.upperPositionLimit[i])


def test_the_splay_range_is_the_hip_yaws_limits_by_forward_kinematics(robot):
    """Toes apart at most: the left hip yawed outwards to its limit, the right likewise; toes
    together: both inwards. Each end of the range is the soles' relative yaw there, less the margin
    per hip: by the sole's yaw rate per hip yaw (forward kinematics, finite differences: g1's hip
    yaw follows its hip pitch and roll and is tilted at standing) and, on talos (its hip yaw is the
    leg's first joint, vertical), by forward kinematics at the limits themselves."""
    stand = _sole_yaws(robot, {})
    q = np.array(robot.q_standing, dtype=float)
    ends = {}
    for side in ("left", "right"):
        i = robot.model.joints[robot.model.getJointId(HIP_YAW[robot.name].format(side))].idx_q
        eps = 1e-6
        rate = (_sole_yaws(robot, {side: q[i] + eps})[side] - stand[side]) / eps
        lo, hi = sorted((v - q[i]) * rate for v in _limits(robot, side))
        ends[side] = (lo + splay.SPLAY_MARGIN, hi - splay.SPLAY_MARGIN)
    lo, hi = splay.splay_range(robot)
    assert hi == pytest.approx(ends["left"][1] - ends["right"][0], abs=1e-4)
    assert lo == pytest.approx(ends["left"][0] - ends["right"][1], abs=1e-4)
    if robot.name == "talos":
        (l_lo, l_hi), (r_lo, r_hi) = _limits(robot, "left"), _limits(robot, "right")
        apart = _sole_yaws(robot, {"left": l_hi, "right": r_lo})
        together = _sole_yaws(robot, {"left": l_lo, "right": r_hi})

        def rel(y):
            return (y["left"] - stand["left"]) - (y["right"] - stand["right"])

        assert hi == pytest.approx(rel(apart) - 2 * splay.SPLAY_MARGIN, abs=1e-4)  # the axis is vertical to 1e-6
        assert lo == pytest.approx(rel(together) + 2 * splay.SPLAY_MARGIN, abs=1e-4)
        # 20 deg inwards per hip: 40 deg toe-in at most, less the margins
        assert math.degrees(lo) == pytest.approx(-40.0 + 2 * math.degrees(splay.SPLAY_MARGIN), abs=0.1)
    else:  # g1's hips turn its toes more than 90 deg inwards each: never binding
        assert lo < -math.pi and hi > math.pi


def _stances(left_yaw: float, right_yaw: float) -> dict:
    """A pivot turn: the right foot down from knot 0 (standing), the left set down at knot 10
    beside it turned by ``left_yaw`` (the right by ``right_yaw``)."""
    return {"right": [(0, 40, Pose(position=(0.0, -0.1, 0.0), rpy=(0.0, 0.0, right_yaw)))],
            "left": [(0, 5, Pose(position=(0.0, 0.1, 0.0), rpy=(0.0, 0.0, 0.0))),
                     (10, 40, Pose(position=(0.1, 0.05, 0.0), rpy=(0.0, 0.0, left_yaw)))]}


@pytest.mark.parametrize("toe_in_deg", [77.0, 10.0])
def test_a_pigeon_toed_stance_beyond_the_hips_is_turned_into_their_range(robot, toe_in_deg):
    stand = {"left": 0.0, "right": 0.0}
    right = math.radians(-91.0)  # the right foot turned; the left set down toes towards it
    left = right - math.radians(toe_in_deg)
    out, turned = splay.keep_splay(_stances(left, right), stand, robot)
    lo, hi = splay.splay_range(robot)
    new_left = out["left"][1][2]
    rel = math.atan2(math.sin(new_left.rpy[2] - right), math.cos(new_left.rpy[2] - right))
    assert lo - 1e-9 <= rel <= hi + 1e-9
    assert out["right"] == _stances(left, right)["right"]  # placed first: not moved
    assert new_left.position == (0.1, 0.05, 0.0)  # turned about its sole, not moved
    if robot.name == "talos" and toe_in_deg > 40.0:
        assert rel == pytest.approx(lo, abs=1e-9)  # turned to the range's edge, no further
        assert math.degrees(turned) == pytest.approx(toe_in_deg + math.degrees(lo), abs=1e-6)
    else:  # within the hips' range (g1's hips turn 158 deg): unchanged
        assert turned == 0.0
        assert new_left.rpy[2] == left
