"""The scaled source kept out of the robot's own body (tasks.mocap.keepout): feet that would meet are
moved apart, hands inside the pelvis or a thigh are moved out; checked on the robot's meshes (coal)
placed by Pinocchio forward kinematics, not on the capsules the rule uses."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from robots import body_part, collision_model, load_robot
from tasks.mocap import keepout

#: The hip pitch and knee joints ({} the side).
KNEE_JOINTS = {"talos": ("leg_{}_3_joint", "leg_{}_4_joint"), "g1": ("{}_hip_pitch_joint", "{}_knee_joint")}
EXAMPLES = Path(__file__).resolve().parents[3] / "examples" / "motions"


@pytest.fixture(scope="module", params=["talos", "g1"])
def robot(request):
    return load_robot(request.param)


def _standing(robot):
    model, gm = robot.model, robot.collision_model
    data, gd = model.createData(), pin.GeometryData(gm)
    q = np.array(robot.q_standing, dtype=float)
    pin.framesForwardKinematics(model, data, q)
    pin.updateGeometryPlacements(model, data, gm, gd, q)
    return model, data, gm, gd


def _distance(ga, Ma, gb, Mb) -> float:  # noqa: N803
    import coal

    r = coal.DistanceResult()
    coal.distance(ga, coal.Transform3s(Ma), gb, coal.Transform3s(Mb), coal.DistanceRequest(), r)
    return float(r.min_distance)


def _foot_meshes(robot, side):
    """The foot's meshes (its sole frame's joint and the one above) relative to its sole frame."""
    model, data, gm, gd = _standing(robot)
    fid = robot.frame_id(robot.frame(f"{side}_foot"))
    joint = model.frames[fid].parentJoint
    sole = data.oMf[fid]
    return [(g.geometry, sole.inverse() * gd.oMg[i]) for i, g in enumerate(gm.geometryObjects)
            if g.parentJoint in (joint, model.parents[joint])]


def test_the_standing_gap_is_the_soles_distance_by_forward_kinematics(robot):
    model, data, _, _ = _standing(robot)
    y = [data.oMf[robot.frame_id(robot.frame(f"{s}_foot"))].translation[1] for s in ("left", "right")]
    assert keepout.standing_gap(robot) == pytest.approx(abs(y[0] - y[1]), abs=1e-9)
    assert keepout.standing_gap(robot) > 0.1


def test_feet_that_would_meet_are_moved_apart_until_their_meshes_clear(robot):
    """Side by side at gaps from crossed (-5 cm) to 2 standing gaps (both down, then the left
    swinging): where less than FOOT_GAP of the standing gap apart they are moved apart to it (half
    each when both are down, the swinging foot alone otherwise), and then their meshes are clear
    (coal, > 5 mm; the crossed ones overlapped before); feet farther apart are not moved."""
    stand = keepout.standing_gap(robot)
    gaps = np.array([-0.05, 0.0, 0.5 * stand, 0.8 * stand, stand, 2.0 * stand])
    n = len(gaps)
    soles = {"left": np.stack([np.zeros(n), gaps / 2, np.zeros(n)], axis=1),
             "right": np.stack([np.zeros(n), -gaps / 2, np.zeros(n)], axis=1)}
    left, right = _foot_meshes(robot, "left"), _foot_meshes(robot, "right")

    def mesh_gap(pl, pr) -> float:
        L, R = pin.SE3(np.eye(3), pl), pin.SE3(np.eye(3), pr)  # noqa: N806
        return min(_distance(ga, L * Ma, gb, R * Mb) for ga, Ma in left for gb, Mb in right)

    for swinging_left in (False, True):
        contact = {"left": np.full(n, not swinging_left), "right": np.ones(n, dtype=bool)}
        out, moved = keepout.keep_feet_apart(soles, contact, np.zeros(n), robot)
        after = out["left"][:, 1] - out["right"][:, 1]
        least = keepout.FOOT_GAP * stand
        short = gaps < least
        assert np.allclose(after[short], least, atol=1e-9)
        assert np.allclose(after[~short], gaps[~short], atol=1e-12)
        assert np.allclose(moved["left"] + moved["right"], np.maximum(0.0, least - gaps), atol=1e-9)
        if swinging_left:
            assert np.allclose(moved["right"], 0.0)
        else:
            assert np.allclose(moved["left"], moved["right"])
        if not swinging_left:  # the same gaps either way: the meshes checked once
            for k in range(n):
                assert mesh_gap(out["left"][k], out["right"][k]) > 0.005
    assert mesh_gap(soles["left"][0], soles["right"][0]) <= 0.0  # crossed: the meshes overlapped


def test_feet_far_apart_lengthwise_are_not_pushed_apart(robot):
    """A long lunge: one foot 2 x KNEE_REACH soles' lengths (or standing gaps) ahead of the other, on
    the same line: not moved."""
    sole = robot.profile.sole
    ahead = 2.0 * keepout.KNEE_REACH * max(sole.x_max - sole.x_min, keepout.standing_gap(robot))
    soles = {"left": np.array([[ahead, 0.0, 0.0]]), "right": np.array([[0.0, 0.0, 0.0]])}
    contact = {"left": np.array([True]), "right": np.array([True])}
    _, moved = keepout.keep_feet_apart(soles, contact, np.zeros(1), robot)
    assert moved["left"][0] == 0.0 and moved["right"][0] == 0.0


def test_a_lunge_whose_knees_would_meet_is_pushed_apart(robot):
    """The knees lie about halfway between the hips and the soles (Pinocchio FK at standing: the
    premise of KNEE_REACH; 1 would fail), so a lunge with one foot 0.9 x KNEE_REACH soles' lengths ahead of the
    other, the two on one line, has its knees within a sole's length: the feet are moved apart
    sideways to FOOT_GAP x the standing gap, the swinging foot alone; in the hips' frame (yaw 90 deg:
    the lunge along the world's y axis) too."""
    model, data, _, _ = _standing(robot)
    for side in ("left", "right"):
        names = KNEE_JOINTS[robot.name]
        z = {k: data.oMi[model.getJointId(n.format(side))].translation[2] for k, n in zip(("hip", "knee"), names)}
        sole_z = data.oMf[robot.frame_id(robot.frame(f"{side}_foot"))].translation[2]
        f = (z["knee"] - sole_z) / (z["hip"] - sole_z)  # the knee's height up the leg
        # the hips over each other, the knees are (1 - f) as far apart as the feet: KNEE_REACH ~ 1 / (1 - f)
        assert 0.7 < keepout.KNEE_REACH * (1.0 - f) < 1.3, f
    sole = robot.profile.sole
    ahead = 0.9 * keepout.KNEE_REACH * max(sole.x_max - sole.x_min, keepout.standing_gap(robot))
    least = keepout.FOOT_GAP * keepout.standing_gap(robot)
    for yaw in (0.0, np.pi / 2):
        fwd, left_axis = np.array([np.cos(yaw), np.sin(yaw), 0.0]), np.array([-np.sin(yaw), np.cos(yaw), 0.0])
        soles = {"left": (ahead * fwd)[None], "right": np.zeros((1, 3))}
        contact = {"left": np.array([False]), "right": np.array([True])}
        out, moved = keepout.keep_feet_apart(soles, contact, np.array([yaw]), robot)
        assert (out["left"][0] - out["right"][0]) @ left_axis == pytest.approx(least, abs=1e-9)
        assert moved["right"][0] == 0.0 and moved["left"][0] == pytest.approx(least, abs=1e-9)


def test_a_hand_inside_the_pelvis_or_a_thigh_is_moved_out_of_the_meshes(robot):
    """Hand targets at the base, inside each thigh, and at the robot's standing
    hand (Pinocchio FK): the inside ones are moved out until a ball of the hand's radius there is
    clear of the convex hulls of the pelvis and thigh meshes at standing (coal; it was inside them
    where put); the standing hand is not moved."""
    import coal

    model, data, gm, gd = _standing(robot)
    base = data.oMf[robot.frame_id(robot.frame("base"))].translation.copy()
    parts = {c.link: body_part(robot, c.link) for c in collision_model(robot).capsules}
    for side in ("left", "right"):
        # the pelvis's and this side's thigh's meshes (the parts the two targets are put into)
        body = [i for i, g in enumerate(gm.geometryObjects)
                if parts.get(model.frames[g.parentFrame].name) in ("pelvis", f"{side} thigh")]
        assert len(body) >= 2
        hand_fk = data.oMf[robot.frame_id(robot.frame(f"{side}_hand"))].translation.copy()
        cap = max((c for c in collision_model(robot).capsules if parts.get(c.link) == f"{side} thigh"),
                  key=lambda c: c.radius)
        thigh = data.oMi[cap.joint].act(cap.placement.translation)  # its axis's middle, by FK
        hands = {s: np.stack([base, thigh, hand_fk]) for s in ("left", "right")}
        R = np.repeat(np.eye(3)[None], 3, axis=0)  # noqa: N806
        out, moved = keepout.keep_hands_out(hands, np.repeat(base[None], 3, axis=0), R, robot)
        assert moved[side][0] > 0.05 and moved[side][1] > 0.05
        assert moved[side][2] == pytest.approx(0.0, abs=1e-12)
        ball = coal.Sphere(keepout.limb_radius(robot, side))

        hulls = []
        for i in body:
            g = gm.geometryObjects[i].geometry
            g.buildConvexRepresentation(False)
            hulls.append((g.convex, gd.oMg[i]))
        for k in (0, 1):
            # to the meshes' convex hulls (an inside point: negative)
            before = min(_distance(ball, pin.SE3(np.eye(3), hands[side][k]), h, M) for h, M in hulls)
            after = min(_distance(ball, pin.SE3(np.eye(3), out[side][k]), h, M) for h, M in hulls)
            assert before < 0.0 < after, (side, k, before, after)
