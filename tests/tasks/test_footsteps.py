"""Footstep generator: contact sequences for steps, walks and turns, checked with numbers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tasks.exceptions import TaskDefinitionError
from tasks.footsteps import (
    TURN_STEP_MAX,
    footsteps,
    lateral_step_max,
    standing_feet,
    step_width,
    turn,
    walk,
)
from tasks.specs import Pose


def _placements(seq, robot):
    """Per phase, side -> placement of the feet in contact."""
    sides = {robot.frame("left_foot"): "left", robot.frame("right_foot"): "right"}
    return [{sides[c.frame]: c.placement for c in p.contacts} for p in seq.phases]


def _check_consistent(seq, robot, start):
    """A foot keeps its placement while in contact and moves only across a phase where it swings."""
    where = dict(zip(("left", "right"), start, strict=True))
    swung = []
    for contacts in _placements(seq, robot):
        for side, pose in contacts.items():
            if pose != where[side]:
                assert swung and swung[-1] == side, f"{side} foot moved without swinging"
                where[side] = pose
        missing = {"left", "right"} - set(contacts)
        assert len(missing) <= 1, "a step phase has both feet in the air"
        swung.extend(missing)
    assert where == {"left": seq.left, "right": seq.right}
    assert [s.side for s in seq.steps] == swung


def _wrap(a: float) -> float:
    return math.atan2(math.sin(a), math.cos(a))


def _yaw_gap(a: Pose, b: Pose) -> float:
    return abs(math.atan2(math.sin(a.rpy[2] - b.rpy[2]), math.cos(a.rpy[2] - b.rpy[2])))


def _sole_polygon(robot, side, pose):
    c, s = math.cos(pose.rpy[2]), math.sin(pose.rpy[2])
    R = np.array([[c, -s], [s, c]])
    return np.array(robot.profile.sole.corners(side)) @ R.T + np.array(pose.position[:2])


def _separation(p, q) -> float:
    """Separating-axis gap of two convex polygons [m]: > 0 is a gap at least that wide, < 0 an
    overlap at least that deep along every edge normal (touching polygons give 0, a knife edge
    that the last bit decides, so the tests ask for a margin on either side)."""
    gap = -math.inf
    for poly in (p, q):
        for i in range(len(poly)):
            edge = poly[(i + 1) % len(poly)] - poly[i]
            n = np.array([-edge[1], edge[0]]) / np.hypot(*edge)
            gap = max(gap, (q @ n).min() - (p @ n).max(), (p @ n).min() - (q @ n).max())
    return gap


CLEARANCE = 0.005  # [m] the two soles stay at least this far apart (talos's closest is ~1 cm)


def _sole_size(robot) -> tuple[float, float]:
    sole = robot.profile.sole
    return sole.x_max - sole.x_min, sole.y_max - sole.y_min


def test_four_steps_forward_talos(talos):
    """4 steps of 0.15 m: right first, alternate, closing step; the body advances 0.6 m."""
    start = standing_feet(talos)
    seq = footsteps(talos, "forward", 0.15, 4)
    assert [s.side for s in seq.steps] == ["right", "left", "right", "left", "right"]
    np.testing.assert_allclose([s.displacement for s in seq.steps], [0.15, 0.3, 0.3, 0.3, 0.15], atol=1e-12)
    for side, p0 in zip(("left", "right"), start, strict=True):
        end = seq.final(side)
        np.testing.assert_allclose(np.subtract(end.position, p0.position), [0.6, 0.0, 0.0], atol=1e-12)
        assert end.rpy == p0.rpy
    prof = talos.profile
    kinds = [len(p.contacts) for p in seq.phases]
    assert kinds == [2] + [1, 2] * 5
    ss = [p.duration for p in seq.phases if len(p.contacts) == 1]
    ds = [p.duration for p in seq.phases[2:-1:2]]
    assert ss == [prof.step_duration] * 5 and ds == [prof.double_support_duration] * 4
    assert seq.duration == pytest.approx(2 * 0.5 * prof.step_duration + 5 * prof.step_duration + 4 * prof.double_support_duration)
    _check_consistent(seq, talos, start)
    # the feet never lead each other by more than the step length
    for contacts in _placements(seq, talos):
        if len(contacts) == 2:
            assert abs(contacts["left"].position[0] - contacts["right"].position[0]) <= 0.15 + 1e-12


def test_g1_timing_and_width_come_from_its_profile(g1):
    """G1's 0.6 s / 0.15 s steps and its standing foot width."""
    seq = footsteps(g1, "backward", 0.1, 2)
    assert {p.duration for p in seq.phases if len(p.contacts) == 1} == {0.6}
    assert seq.phases[2].duration == 0.15
    start = standing_feet(g1)
    np.testing.assert_allclose(seq.left.position[0] - start[0].position[0], -0.2, atol=1e-12)
    assert step_width(g1) == pytest.approx(abs(start[0].position[1] - start[1].position[1]))
    assert step_width(g1) == pytest.approx(2 * 0.118506, abs=1e-5)


@pytest.mark.parametrize("robot_name, limit", [("talos", 0.30), ("g1", 0.20)])
def test_step_beyond_the_robot_is_refused_in_task_terms(robot_name, limit, request):
    """A 2 m step names the robot's limit and suggests shorter steps."""
    robot = request.getfixturevalue(robot_name)
    with pytest.raises(TaskDefinitionError, match=rf"step length 2 m is beyond {robot_name}'s {limit:.2f} m; take more, shorter steps \(e.g. {math.ceil(2 / limit)} steps"):
        footsteps(robot, "forward", 2.0, 1)
    with pytest.raises(TaskDefinitionError, match="side step 0.4 m is beyond"):
        footsteps(robot, "left", 0.4, 1)
    footsteps(robot, "forward", limit, 1)  # the limit itself is fine


def test_bad_arguments(talos):
    """Unknown direction, zero length or count, one start foot only, zero turn."""
    for call, msg in (
        (lambda: footsteps(talos, "up", 0.1, 1), "direction must be one of"),
        (lambda: footsteps(talos, "forward", 0.0, 1), "step length must be a positive number"),
        (lambda: footsteps(talos, "forward", 0.1, 0), "count must be a whole number >= 1"),
        (lambda: footsteps(talos, "forward", 0.1, 1, left=standing_feet(talos)[0]), "both start placements"),
        (lambda: turn(talos, 0.0), "nonzero"),
        (lambda: turn(talos, 4.0), "within"),
        (lambda: walk(talos, -1.0), "positive"),
    ):
        with pytest.raises(TaskDefinitionError, match=msg):
            call()


def test_two_steps_sideways_alternate_the_leading_foot(talos, g1):
    """Left: left foot out, right foot follows, twice; the width never shrinks; 2 x length moved."""
    for robot in (talos, g1):
        start = standing_feet(robot)
        w0 = step_width(robot)
        length = lateral_step_max(robot)
        seq = footsteps(robot, "left", length, 2)
        assert [s.side for s in seq.steps] == ["left", "right", "left", "right"]
        for contacts in _placements(seq, robot):
            if len(contacts) == 2:
                w = contacts["left"].position[1] - contacts["right"].position[1]
                assert w0 - 1e-12 <= w <= w0 + length + 1e-12
        for side, p0 in zip(("left", "right"), start, strict=True):
            np.testing.assert_allclose(np.subtract(seq.final(side).position, p0.position), [0.0, 2 * length, 0.0], atol=1e-12)
        _check_consistent(seq, robot, start)
        right = footsteps(robot, "right", 0.05, 1)
        assert [s.side for s in right.steps] == ["right", "left"]


TOE_IN_GAP = 0.9  # toe-in double supports keep this share of the standing soles' gap (unwidened: talos 20 %)


@pytest.mark.parametrize("angle", [math.pi / 2, -math.pi / 2, 0.3, math.pi])
def test_turn_in_place(talos, g1, angle):
    """Alternating swings, feet within TURN_STEP_MAX in yaw, no overlap, same mid point, same width;
    the far-side foot swings last, and where it overtakes the other (toe-in) the soles stay about
    as far apart as standing (talos's shins met there when they did not)."""
    for robot in (talos, g1):
        start = standing_feet(robot)
        left_sole = _sole_polygon(robot, "left", start[0])
        length, width = _sole_size(robot)
        # the check itself: a sole shifted by half its size overlaps, by 1.5 times its width it does not
        assert _separation(left_sole, left_sole + [0.5 * length, 0.5 * width]) == pytest.approx(-0.5 * width)
        assert _separation(left_sole, left_sole + [0.0, 1.5 * width]) == pytest.approx(0.5 * width)
        assert _separation(left_sole, _sole_polygon(robot, "right", start[1])) > CLEARANCE
        seq = turn(robot, angle)
        n = math.ceil(abs(angle) / TURN_STEP_MAX - 1e-9)
        assert len(seq.steps) == n + 1
        far = "right" if angle > 0 else "left"
        assert seq.steps[-1].side == far
        assert all(a.side != b.side for a, b in zip(seq.steps, seq.steps[1:]))
        standing_gap = _separation(_sole_polygon(robot, "left", start[0]), _sole_polygon(robot, "right", start[1]))
        swung = None
        toe_ins = 0
        for i, contacts in enumerate(_placements(seq, robot)):
            if len(contacts) == 1:
                swung = ({"left", "right"} - set(contacts)).pop()
            elif len(contacts) == 2:
                assert _yaw_gap(contacts["left"], contacts["right"]) <= TURN_STEP_MAX + 1e-9
                gap = _separation(_sole_polygon(robot, "left", contacts["left"]),
                                  _sole_polygon(robot, "right", contacts["right"]))
                assert gap > CLEARANCE
                # the far-side foot, turned past the near-side one: toe-in
                ahead = _wrap(contacts[far].rpy[2] - contacts["left" if far == "right" else "right"].rpy[2]) * math.copysign(1.0, angle)
                if swung == far and ahead > 1e-6:
                    toe_ins += 1
                    assert gap >= TOE_IN_GAP * standing_gap, f"toe-in double support {i}: soles {gap:.4f} m apart"
        assert toe_ins == n // 2
        for side, p0 in zip(("left", "right"), start, strict=True):
            assert seq.final(side).rpy[2] == pytest.approx(math.atan2(math.sin(p0.rpy[2] + angle), math.cos(p0.rpy[2] + angle)), abs=1e-12)
        mid0 = 0.5 * np.add(start[0].position, start[1].position)
        mid1 = 0.5 * np.add(seq.left.position, seq.right.position)
        np.testing.assert_allclose(mid1, mid0, atol=1e-12)
        assert step_width(robot, seq.left, seq.right) == pytest.approx(step_width(robot), abs=1e-12)
        _check_consistent(seq, robot, start)


def test_walk_picks_the_fewest_equal_steps(talos, g1):
    """1 m on talos (0.30 m max) is 4 steps of 0.25 m; sideways uses the side-step limit."""
    seq = walk(talos, 1.0)
    assert len(seq.steps) == 5  # 4 steps + the closing one
    start = standing_feet(talos)
    np.testing.assert_allclose(seq.left.position[0] - start[0].position[0], 1.0, atol=1e-12)
    side = walk(g1, 0.25, "right")
    assert len(side.steps) == 2 * math.ceil(0.25 / lateral_step_max(g1))
    np.testing.assert_allclose(side.right.position[1] - standing_feet(g1)[1].position[1], -0.25, atol=1e-12)


def test_steps_follow_the_start_heading(talos):
    """After a 90 deg turn, 'forward' is the world +y axis."""
    turned = turn(talos, math.pi / 2)
    seq = footsteps(talos, "forward", 0.2, 2, left=turned.left, right=turned.right)
    for side in ("left", "right"):
        np.testing.assert_allclose(np.subtract(seq.final(side).position, turned.final(side).position), [0.0, 0.4, 0.0], atol=1e-12)
