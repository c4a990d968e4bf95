"""The tracking guess of a dynamic plan (planner/trajopt/centroidal/tracking.py): each knot's pose
for its own soft targets, checked with Pinocchio's forward kinematics against a known motion."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from planner.trajopt.centroidal import to_dynamic_layout
from planner.trajopt.centroidal.data import chart_guess
from planner.trajopt.centroidal.heading import heading_guess
from planner.trajopt.centroidal.settings import CentroidalSettings
from planner.trajopt.centroidal.tracking import is_tracking, tracking_guess
from planner.trajopt.layout import make_layout
from planner.trajopt.symbolic import chart_to_configuration
from tasks.footsteps import standing_feet
from tasks.specs import Contact, FrameTarget, Phase, Priority, TaskSpec

DT = 0.1
HORIZON = 1.2
ARM = {"left_shoulder_pitch_joint": -1.0, "left_elbow_joint": -0.4, "right_shoulder_roll_joint": -0.6,
       "right_elbow_joint": 0.5}


def _moved(robot, s: float) -> np.ndarray:
    """Standing with the arms a fraction ``s`` of the way to :data:`ARM` (feet and base untouched)."""
    q = np.array(robot.q_standing)
    for name, value in ARM.items():
        j = robot.model.getJointId(name)
        q[robot.model.joints[j].idx_q] += s * value
    return q


def _spec(robot, every_knot: bool = True) -> TaskSpec:
    """Both feet down; soft hand and base targets on every knot (or one) from the FK of :func:`_moved`."""
    model, data = robot.model, robot.model.createData()
    left, right = standing_feet(robot)
    feet = (Contact(frame="left_foot", placement=left), Contact(frame="right_foot", placement=right))
    targets = []
    times = np.arange(1, int(round(HORIZON / DT)) + 1) * DT if every_knot else np.array([HORIZON])
    for t in times:
        pin.framesForwardKinematics(model, data, _moved(robot, min(t / HORIZON, 1.0)))
        for role, weight in (("left_hand", 200.0), ("right_hand", 200.0), ("base", 400.0)):
            p = data.oMf[robot.frame_id(role)].translation
            targets.append(FrameTarget(name=f"track {role} {t:.2f}", frame=robot.frame(role), position=(float(p[0]), float(p[1]), float(p[2])),
                                       time=round(float(t), 9), priority=Priority.SOFT, weight=weight * DT, tolerance=0.25))
    return TaskSpec(robot=robot.name, phases=(Phase(name="stand", duration=HORIZON, contacts=feet),), targets=tuple(targets),
                    dt=DT, dynamic=True)


@pytest.fixture(scope="module")
def tracked(g1):
    lay = to_dynamic_layout(make_layout(_spec(g1), g1), CentroidalSettings(tracking_guess=True))
    return lay, tracking_guess(lay)


def _hand_errors(robot, lay, dq: np.ndarray) -> list[float]:
    """The hands' distance [m] at every variable knot from the FK of the known motion at that time."""
    model, data, ref = robot.model, robot.model.createData(), robot.model.createData()
    out = []
    for k in range(2, lay.N):
        pin.framesForwardKinematics(model, data, chart_to_configuration(model, lay.q_ref, dq[k]))
        pin.framesForwardKinematics(model, ref, _moved(robot, min(lay.t[k] / HORIZON, 1.0)))
        for role in ("left_hand", "right_hand"):
            fid = robot.frame_id(role)
            out.append(float(np.linalg.norm(data.oMf[fid].translation - ref.oMf[fid].translation)))
    return out


def test_each_knot_reaches_its_targets_with_the_feet_on_their_placements(g1, tracked):
    """The known motion (arms moved, feet and base still) is reached: hands within 2 cm of its FK at
    every knot (the heading guess, joints at standing, is 0.1 m or more off at the end), the soles
    within 1 mm and 0.01 rad of their placements."""
    lay, dq = tracked
    assert dq is not None and dq.shape == (lay.N + 1, g1.nv)
    assert np.all(dq[:2] == 0.0) and np.array_equal(dq[lay.N], dq[lay.N - 1])
    assert max(_hand_errors(g1, lay, dq)) < 0.02  # the weak pull towards standing: 14 mm at most (measured)
    assert max(_hand_errors(g1, lay, heading_guess(lay))) > 0.1
    model, data = g1.model, g1.model.createData()
    for k in range(2, lay.N):
        pin.framesForwardKinematics(model, data, chart_to_configuration(model, lay.q_ref, dq[k]))
        for fid, (_frame, M) in lay.contacts_at[k].items():
            err = pin.log6(M.actInv(data.oMf[fid])).vector
            assert np.linalg.norm(err[:3]) < 1e-3 and np.linalg.norm(err[3:]) < 1e-2


def test_the_guess_and_momentum_point_follow_the_setting(g1, tracked):
    """With the setting, the layout's guess and its momentum rows' point are the tracking guess;
    without it, or for a spec that tracks nothing (one target), the heading guess, bit for bit."""
    lay, dq = tracked
    assert np.array_equal(lay.momentum_point(), dq) and np.array_equal(chart_guess(lay), dq)
    assert np.array_equal(lay.initial_guess()[:lay.n_kinematic], dq[2:lay.N].ravel())
    off = to_dynamic_layout(make_layout(_spec(g1), g1))
    assert np.array_equal(off.momentum_point(), heading_guess(off))
    one = to_dynamic_layout(make_layout(_spec(g1, every_knot=False), g1), CentroidalSettings(tracking_guess=True))
    assert not is_tracking(one) and tracking_guess(one) is None
    assert np.array_equal(chart_guess(one), heading_guess(one))
