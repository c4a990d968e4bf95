"""A spec's start state (``TaskSpec.start``): the plan starts there, at rest, and a motion that
starts from the standing posture moved by a rigid motion on the ground (a step and a turn away)
is the standing plan moved by that motion (the reference: the plan from the origin, moved with
Pinocchio's SE3)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from language import parse
from planner import plan
from planner.trajopt.settings import CacheSettings, PlannerSettings
from robots.contact import convex_hull
from tasks.compose import compile_actions, fit_actions
from tasks.specs import StartState

SAME = 1e-6  # [m, rad] the two plans agree to IPOPT's round-off (measured: 1e-12)


def moved(robot, q: np.ndarray, motion: pin.SE3) -> np.ndarray:
    """``q`` with its base carried by ``motion`` (the joints unchanged)."""
    out = np.array(q, dtype=float)
    out[:7] = pin.SE3ToXYZQUAT(motion * pin.XYZQUATToSE3(q[:7]))
    return out


def area(polygon: np.ndarray) -> float:
    x, y = polygon[:, 0], polygon[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


@pytest.mark.parametrize("dx", [-3e-12, 0.0, 3e-12])
@pytest.mark.parametrize("dy", [-3e-12, 3e-12])
def test_hull_keeps_the_outer_corners_when_round_off_reorders_the_inner_ones(dx, dy):
    """Two soles side by side whose inner corners are off the outer edges by round-off: four
    corners, the outer ones, whatever the sorted order of the near-equal x (G1's soles)."""
    left = np.array([[-0.05, 0.0935], [0.12, 0.0935], [0.12, 0.1435], [-0.05, 0.1435]])
    right = left * [1.0, -1.0]
    left[:2] += [dx, dy]
    right[:2] -= [dx, dy]
    hull = convex_hull(np.vstack([left, right]))
    assert len(hull) == 4
    assert area(hull) == pytest.approx(0.17 * 0.287, abs=1e-9)


@pytest.mark.parametrize("yaw", [-0.6, 0.3, 2.5])
def test_hull_of_two_soles_does_not_depend_on_the_heading(talos, yaw):
    """Collinear corners (the front and back edges of two soles side by side) are dropped also when
    round-off leaves them a hair off the line: the hull, and the CoM-centring cost that takes its
    mean, are the same whichever way the robot faces."""
    motion = pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, yaw), np.array([1.0, 0.5, 0.0]))
    q = moved(talos, talos.q_standing, motion)
    here, there = (convex_hull(np.vstack([talos.sole_corners_in_world(c, s) for s in ("left", "right")]))
                   for c in (talos.q_standing, q))
    assert len(here) == len(there) == 4
    carried = (motion.rotation[:2, :2] @ here.mean(axis=0)) + motion.translation[:2]
    np.testing.assert_allclose(there.mean(axis=0), carried, atol=1e-9)


def test_a_plan_from_a_moved_start_is_the_standing_plan_moved(talos, yaw=-0.6):
    motion = pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, yaw), np.array([1.0, 0.5, 0.0]))
    start = moved(talos, talos.q_standing, motion)
    actions = fit_actions(parse("squat").actions, talos)
    here = compile_actions(actions, talos)
    there = compile_actions(actions, talos, start=StartState(q=tuple(float(x) for x in start)))
    assert there.start is not None and here.start is None
    settings = PlannerSettings(cache=CacheSettings(solution_library="off"))
    p0, p1 = plan(here, talos, settings=settings), plan(there, talos, settings=settings)
    assert p0.ok and p1.ok
    np.testing.assert_allclose(p1.q[0], start, atol=1e-12)  # the first knot is the start state
    np.testing.assert_allclose(p1.v[0], 0.0, atol=1e-12)  # at rest
    np.testing.assert_allclose(p1.q[:, 7:], p0.q[:, 7:], atol=SAME)
    reference = np.array([moved(talos, q, motion) for q in p0.q])
    np.testing.assert_allclose(p1.q[:, :3], reference[:, :3], atol=SAME)
    # quaternions: the same rotation (q and -q are one)
    dots = np.abs(np.sum(p1.q[:, 3:7] * reference[:, 3:7], axis=1))
    np.testing.assert_allclose(dots, 1.0, atol=SAME)
