"""The feet's relative yaw kept within what the robot's hips can turn.

A human turning in place pivots on one foot and sets the other down turned by up to 90 degrees,
pigeon-toed or splayed (CMU 01_01: the left foot at -168 deg beside the right at -91 deg, toes 77
deg inwards). A foot flat on the floor turns about the vertical only through the leg's vertical
joints (a hip yaw), so while both feet are down their yaws, each taken from its standing yaw, differ
by no more than those joints' ranges allow: talos's hip yaws turn a toe 20 deg inwards and 90 deg
outwards (the two feet: 40 deg toe-in at most), g1's 158 deg either way (never binding). Asked for
more, the planner has no solution and stops at its iteration limit (talos's turn in place, 279 to
629 iterations; its diagnosis, from the plan without collision rows, named a forearm through the
pelvis at 5.4 s, in that stance).

:func:`keep_splay` turns the later-placed foot of two overlapping stances (the one the human set
down second) about its own sole until the pair is :data:`SPLAY_MARGIN` inside the range
(:func:`splay_range`); its position is kept. It says how far it turned (the report's
``splay_turned_deg``).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pinocchio as pin

from robots import Robot

SIDES = ("left", "right")
#: [rad] Kept inside each vertical joint's limit (the two feet: twice this; talos: 34 deg toe-in at
#: most). A stance at a hip yaw's very limit leaves the plan no room for the base's heading between
#: the feet; the certified talos wave and walk with a turn stand up to 31 deg toe-in (unchanged).
SPLAY_MARGIN = 0.05
VERTICAL = 0.9  # a joint turns the sole about the vertical when its yaw rate per joint rate is above this


def _yaw_joints_range(robot: Robot, side: str) -> tuple[float, float]:
    """(lo, hi) [rad]: how far the ``side`` sole's yaw turns from standing by the leg's vertical
    joints within their limits (the sole's yaw rate per joint rate, Pinocchio's frame Jacobian in
    the world's axes at standing, above :data:`VERTICAL`), less :data:`SPLAY_MARGIN` each."""
    model = robot.model
    data = model.createData()
    q = np.asarray(robot.q_standing, dtype=float)
    fid = robot.frame_id(f"{side}_foot")
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    J = pin.getFrameJacobian(model, data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
    lo = hi = 0.0
    j = model.frames[fid].parentJoint
    while j > 1:  # the leg's joints (joint 1: the floating base)
        joint = model.joints[j]
        if joint.nv == 1:
            rate = float(J[5, joint.idx_v])
            if abs(rate) > VERTICAL:
                a = (float(model.lowerPositionLimit[joint.idx_q]) - q[joint.idx_q]) * rate
                b = (float(model.upperPositionLimit[joint.idx_q]) - q[joint.idx_q]) * rate
                lo += min(min(a, b) + SPLAY_MARGIN, 0.0)
                hi += max(max(a, b) - SPLAY_MARGIN, 0.0)
        j = model.parents[j]
    return lo, hi


def splay_range(robot: Robot) -> tuple[float, float]:
    """(lo, hi) [rad]: the left sole's yaw less the right sole's (each from its standing yaw) that
    the legs' vertical joints reach with both feet down, :data:`SPLAY_MARGIN` inside each limit;
    positive: the toes turned apart (splayed), negative: towards each other (pigeon-toed)."""
    l_lo, l_hi = _yaw_joints_range(robot, "left")
    r_lo, r_hi = _yaw_joints_range(robot, "right")
    return l_lo - r_hi, l_hi - r_lo


def _wrap(a: float) -> float:
    return math.atan2(math.sin(a), math.cos(a))


def keep_splay(stance_pose: dict, stand_yaw: dict[str, float], robot: Robot) -> tuple[dict, float]:
    """The stance placements (side -> runs (first knot, end knot, :class:`tasks.specs.Pose`)) with
    each later-placed foot turned about its sole (yaw only, position kept) so that, against the
    other foot's stance it overlaps, the relative yaw lies in :func:`splay_range`; ``stand_yaw``:
    side -> the sole's yaw at standing [rad]. Returns (the runs, the largest turn [rad])."""
    lo, hi = splay_range(robot)
    out = {side: list(runs) for side, runs in stance_pose.items()}
    order = sorted((a, i, j) for i, side in enumerate(SIDES) for j, (a, _b, _p) in enumerate(out[side]))
    turned = 0.0
    for a, i, j in order:
        side, other = SIDES[i], SIDES[1 - i]
        _a, b, pose = out[side][j]
        for oa, ob, opose in out[other]:
            if a == 0 or oa > a or ob <= a:
                continue  # the standing one, or no overlap, or the other foot placed later
            mine = pose.rpy[2] - stand_yaw[side]
            theirs = opose.rpy[2] - stand_yaw[other]
            rel = _wrap(mine - theirs) if side == "left" else _wrap(theirs - mine)  # left less right
            want = min(max(rel, lo), hi)
            if want == rel:
                continue
            turn = (want - rel) if side == "left" else (rel - want)
            pose = dataclasses.replace(pose, rpy=(pose.rpy[0], pose.rpy[1], float(pose.rpy[2] + turn)))
            out[side][j] = (a, b, pose)
            turned = max(turned, abs(turn))
    return out, turned
