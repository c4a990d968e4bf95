"""A stance that begins while its sole is still up waits for the touch (planner.wbc.touch).

Fast twin of the g1 forward jumps' certificate in tests/wbmp/test_retarget_certified.py (long)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin
import pytest

from planner.wbc import WbcSettings, WholeBodyController
from planner.wbc.touch import TOUCH_HEIGHT, late_soles
from sim.handmade import foot_lift_plan

SWITCH = 3.0  # [s] foot_lift_plan's right foot is planned back down (both feet in stance) from here


@pytest.fixture(scope="module")
def lift(talos):
    return foot_lift_plan(talos, side="right", height=0.05)


def _sole_height(robot, q, frame):
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, q)
    return float(data.oMf[robot.frame_id(frame)].translation[2])


def _ticks(robot, plan, q_up, touch_wait):
    """Ticks at 2.95 s (single support) and 3.02 s (both feet planned down) from ``q_up``; the
    controller after the second."""
    ctrl = WholeBodyController(robot, WbcSettings(touch_wait=touch_wait))
    v = np.zeros(robot.nv)
    ctrl.reset(q_up, v)
    ctrl.compute(SWITCH - 0.05, q_up, v, plan)
    ctrl.compute(SWITCH + 0.02, q_up, v, plan)
    return ctrl


def test_late_soles_wait_while_up_and_at_most_the_longest_wait():
    since = np.full(2, -1)
    up = np.array([0.0, 0.02])
    # a new stance, the sole 2 cm up: waits (from sample 10), the other was already down
    assert late_soles((True, True), (True, False), up, since, 10, 5) == [False, True]
    assert list(since) == [-1, 10]
    assert late_soles((True, True), (True, False), up, since, 14, 5) == [False, True]
    assert late_soles((True, True), (True, False), up, since, 15, 5) == [False, False]  # 5 samples: no longer
    assert list(since) == [-1, -1]
    down = np.array([0.0, TOUCH_HEIGHT - 1e-4])
    assert late_soles((True, True), (True, False), down, since, 16, 5) == [False, False]
    assert late_soles((True, True), None, up, since, 0, 5) == [False, False]  # the first tick: nothing waits


def test_a_sole_still_up_when_its_stance_begins_is_tracked_straight_down_until_it_touches(talos, lift):
    """The plan's right foot at 2.8 s (8 mm up) when its stance begins at 3.0 s: with the wait its
    contact carries nothing and the QP accelerates it down, not across; without it (touch_wait 0)
    the stance constraint holds it up in the air carrying weight."""
    right = talos.frame("right_foot")
    q_up = lift.q[int(np.argmin(np.abs(lift.t - 2.8)))].copy()
    q_down = lift.q[int(np.argmin(np.abs(lift.t - SWITCH)))].copy()
    z_up, z_down = _sole_height(talos, q_up, right), _sole_height(talos, q_down, right)
    assert z_up - z_down > 2 * TOUCH_HEIGHT  # the premise: up by more than the touch height

    waiting = _ticks(talos, lift, q_up, touch_wait=0.08)
    assert waiting.touch_waits == 1 and waiting.last.ok
    forces = waiting.contact_forces()
    assert np.linalg.norm(forces[right]) < 1.0  # [N] not a stance sole yet
    assert forces[talos.frame("left_foot")][2] > 0.9 * talos.mass * 9.81
    # the sole's acceleration (Pinocchio, from the QP's a): down, hardly across
    model, data = talos.model, talos.model.createData()
    v = np.zeros(talos.nv)
    pin.forwardKinematics(model, data, q_up, v, waiting.acceleration())
    pin.updateFramePlacements(model, data)
    acc = pin.getFrameClassicalAcceleration(model, data, talos.frame_id(right), pin.LOCAL_WORLD_ALIGNED).linear
    assert acc[2] < -0.5 and np.linalg.norm(acc[:2]) < 0.5 * abs(acc[2])

    held = _ticks(talos, lift, q_up, touch_wait=0.0)
    assert held.touch_waits == 0
    assert held.contact_forces()[right][2] > 50.0  # [N] held up there as a stance

    # the touch: once down (the plan's pose at the switch), the stance begins and carries weight
    waiting.compute(SWITCH + 0.03, q_down, v, lift)
    assert waiting.contact_forces()[right][2] > 50.0


def test_a_bad_touch_wait_is_refused():
    from planner.wbc import ControllerError

    with pytest.raises(ControllerError, match="touch_wait"):
        dataclasses.replace(WbcSettings(), touch_wait=-0.1)
