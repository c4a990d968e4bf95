"""The collision model (robots/collision.py) against the URDF collision meshes, with coal."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pinocchio as pin
import pytest

from robots import load_robot
from robots.collision import (
    REST_MARGIN,
    body_part,
    cache_dir,
    capsule_distance,
    collision_model,
    geometry_points,
    mesh_distances,
    sphere_distance,
    srdf_disabled_pairs,
    srdf_path,
)
from robots.exceptions import ProfileError
from robots.profile import RobotProfile, read_profile_file

ENCLOSURE_TOLERANCE = 1e-9  # [m] a vertex may lie this far outside its capsule (rounding)
DISTANCE_TOLERANCE = 1e-6  # [m] coal's distance accuracy on meshes


@pytest.fixture(scope="module")
def talos():
    return load_robot("talos")


@pytest.fixture(scope="module")
def g1():
    return load_robot("g1")


def _point_segment(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    ab = b - a
    denom = float(ab @ ab)
    t = np.zeros(len(points)) if denom == 0 else np.clip((points - a) @ ab / denom, 0.0, 1.0)
    return np.linalg.norm(points - (a + np.outer(t, ab)), axis=1)


@pytest.mark.parametrize("name", ["talos", "g1"])
def test_capsules_enclose_every_vertex_of_the_urdf_collision_geometry(name):
    robot = load_robot(name)
    cm = collision_model(robot)
    worst, n = -np.inf, 0
    for obj in robot.collision_model.geometryObjects:
        pts = geometry_points(obj.geometry)
        assert pts is not None, obj.name
        link = robot.model.frames[obj.parentFrame].name
        in_joint = pts @ obj.placement.rotation.T + obj.placement.translation
        covers = [cm.capsules_of(link)] + [(c,) for c in cm.alternatives if c.link == link]
        for caps in covers:  # the own capsules and every alternative cover some pair is checked with
            assert caps and all(c.joint == obj.parentJoint for c in caps)
            outside = np.min([_point_segment(in_joint, *c.endpoints()) - c.radius for c in caps], axis=0)
            worst = max(worst, float(outside.max()))
        n += len(pts)
    assert n > 1000 and worst <= ENCLOSURE_TOLERANCE
    assert cm.alternatives and cm.covers  # exercised
    # and the fit is not absurdly loose: the total capsule volume is within a few times the links' hull volume
    assert len(cm.links) == len({robot.model.frames[o.parentFrame].name for o in robot.collision_model.geometryObjects})


def _random_postures(robot, n, seed):
    rng = np.random.default_rng(seed)
    lo = np.clip(robot.model.lowerPositionLimit, -4, 4)
    hi = np.clip(robot.model.upperPositionLimit, -4, 4)
    out = []
    for _ in range(n):
        q = robot.q_standing.copy()
        q[7:] = rng.uniform(lo[7:], hi[7:])
        out.append(q)
    return out


def test_capsule_and_sphere_distances_never_exceed_the_mesh_distances(talos):
    """The sound property: capsules enclose the meshes and spheres cover the capsules, so at any
    posture sphere-set distance <= capsule distance <= coal mesh distance, for every pair of links
    on different joints (checked or not: the property holds for any pair)."""
    import itertools

    cm = collision_model(talos)
    pairs = [(a, b) for a, b in itertools.combinations(sorted(cm.links), 2)
             if cm.capsules_of(a)[0].joint != cm.capsules_of(b)[0].joint]
    checked = close = 0
    for q in _random_postures(talos, 3, seed=3):
        mesh = mesh_distances(talos, q, pairs)
        data = talos.model.createData()
        pin.forwardKinematics(talos.model, data, q)
        for a, b in pairs:
            covers = [(cm.capsules_of(a), cm.capsules_of(b))]
            if (a, b) in cm.covers:
                covers.append(cm.pair_capsules(a, b))  # the covers the pair is checked with
            for ca, cb in covers:
                d_caps = min(capsule_distance(c1, c2, data) for c1 in ca for c2 in cb)
                d_sph = min(sphere_distance(c1, c2, data) for c1 in ca for c2 in cb)
                if mesh[(a, b)] > 0:  # coal reports 0 (not a depth) for intersecting meshes
                    assert d_caps <= mesh[(a, b)] + DISTANCE_TOLERANCE, (a, b)
                # spheres cover the capsules: apart, closer; overlapping capsules, overlapping spheres
                assert d_sph <= max(d_caps, 0.0) + 1e-12, (a, b)
                checked += 1
                close += mesh[(a, b)] < 0.05
    assert checked > 3000 and close > 50  # many pairs come close: the property is exercised where it matters


def test_pairs_skip_srdf_adjacent_and_touching_at_rest(talos):
    cm = collision_model(talos)
    srdf = srdf_disabled_pairs(srdf_path(talos))
    assert len(srdf) > 100
    reasons = set(cm.skipped.values())
    assert reasons == {"srdf", "adjacent", "touching at rest"}
    for pair, why in cm.skipped.items():
        if why == "srdf":
            assert pair in srdf
    assert not set(cm.pairs) & srdf
    assert cm.skipped[("arm_left_4_link", "arm_left_5_link")] in ("adjacent", "srdf")
    assert ("arm_left_5_link", "base_link") in cm.pairs  # the forearm/pelvis pair of issue 15
    rest = mesh_distances(talos, talos.q_standing, list(cm.pairs))
    assert min(rest.values()) >= REST_MARGIN
    assert all(p == tuple(sorted(p)) for p in cm.pairs) and list(cm.pairs) == sorted(cm.pairs)


def test_body_parts_name_links_from_the_kinematic_chains(talos, g1):
    assert body_part(talos, "arm_left_5_link") == "left forearm"
    assert body_part(talos, "base_link") == "pelvis"
    assert body_part(talos, "leg_right_3_link") == "right thigh"
    assert body_part(talos, "gripper_right_base_link") == "right hand"
    assert body_part(talos, "torso_2_link") == "torso"
    assert body_part(g1, "left_knee_link") == "left shin"
    assert body_part(g1, "right_elbow_link") == "right forearm"


def _talos_profile(tmp_path, collisions):
    from robots.profile import PROFILE_DIR

    data = read_profile_file(PROFILE_DIR / "talos.toml")
    data["name"] = "mytalos"
    data["collisions"] = collisions
    path = tmp_path / "mytalos.json"
    path.write_text(json.dumps(data))
    return path


def test_profile_adds_removes_and_names_pairs(tmp_path, talos):
    path = _talos_profile(tmp_path, {"add": [["arm_left_4_link", "torso_2_link"]],
                                     "remove": [["base_link", "arm_left_5_link"]],
                                     "body_parts": {"arm_left_5_link": "left lower arm"}})
    robot = load_robot(path)
    cm = collision_model(robot)
    assert ("arm_left_4_link", "torso_2_link") in cm.pairs
    assert cm.skipped[("arm_left_5_link", "base_link")] == "profile"
    assert body_part(robot, "arm_left_5_link") == "left lower arm"


@pytest.mark.parametrize(("collisions", "message"), [
    ({"ad": []}, "collisions: unknown key 'ad' (did you mean 'add'?)"),
    ({"add": [["a"]]}, "collisions.add[0]: expected a pair of link names"),
    ({"remove": "x"}, "collisions.remove: expected a list of link pairs"),
    ({"add": [["base_link", "base_link"]]}, "collisions.add[0]: a link cannot collide with itself"),
    ({"add": [["base_link", "nolink"]]}, "collisions.add[0]: the robot has no link 'nolink'"),
    ({"add": [["a", "b"]], "remove": [["b", "a"]]}, "is both added and removed"),
    ({"body_parts": {"base_link": 3}}, "collisions.body_parts.base_link: expected a human name"),
    ({"meet_joints": -1}, "collisions.meet_joints: expected a whole number of joints in [0, 6]"),
    ({"meet_joints": "two"}, "collisions.meet_joints: expected a whole number of joints in [0, 6]"),
    ({"meet_joints": True}, "collisions.meet_joints: expected a whole number of joints"),
])
def test_bad_collision_tables_are_named(tmp_path, collisions, message):
    path = _talos_profile(tmp_path, collisions)
    with pytest.raises(ProfileError) as e:
        collision_model(load_robot(path))
    assert message in str(e.value)
    assert "mytalos.json" in str(e.value)


@pytest.mark.long  # in make test-long (it fitted twice, ~20 s; now the rebuild copies robots/fits); twin:
# tests/robots/test_robot_cache.py::test_robot_cache_damaged_entry_is_rebuilt_with_one_warning
def test_damaged_cache_file_is_rebuilt(tmp_path, monkeypatch, talos):
    import robots.collision as rc

    monkeypatch.setenv("WBMP_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(rc, "_MEMORY", {})
    first = collision_model(talos)
    files = list(cache_dir().glob("talos-*.json"))
    assert len(files) == 1 and cache_dir() == tmp_path / "collision"
    for garbage in ("{not json", json.dumps({"fit_version": rc.FIT_VERSION, "robot": "talos", "capsules": [1]})):
        files[0].write_text(garbage)
        monkeypatch.setattr(rc, "_MEMORY", {})
        again = collision_model(talos)
        assert again.pairs == first.pairs and len(again.capsules) == len(first.capsules)
        assert json.loads(files[0].read_text())["robot"] == "talos"  # rewritten whole
    monkeypatch.setattr(rc, "_MEMORY", {})
    loaded = collision_model(talos)  # from the file: the same capsules
    assert [dataclasses.astuple(c)[1:2] + (c.length, c.radius) for c in loaded.capsules] == \
        [dataclasses.astuple(c)[1:2] + (c.length, c.radius) for c in first.capsules]


def test_robots_cli_prints_the_collision_model(capsys):
    from wbmp.cli import main

    assert main(["robots", "--collisions", "g1"]) == 0
    out = capsys.readouterr().out
    assert "capsules" in out and "left_knee_link" in out and "skipped (adjacent)" in out
    assert main(["robots", "--collisions", "--json", "talos"]) == 0
    row = json.loads(capsys.readouterr().out)[0]
    assert ["arm_left_5_link", "base_link"] in row["pairs"] and row["skipped"]["srdf"]


def test_meet_links_are_the_hands_links_and_g1s_wrists(talos, g1):
    """A planned self-contact's parts (``Robot.meet_links``): Talos's hand is every link below its
    hand frame's joint (the gripper, the wrist sensor: ``[collisions] meet_joints`` = 0), the head
    the links below its neck; G1's hand is its three wrist links (meet_joints = 2: the wrist roll
    and pitch links sit above the hand frame's joint), its head only the head link (the head is on
    the torso, whose joint carries the arms). Reference: the URDF chains, by name."""
    from robots.profile import CollisionTable

    model = talos.model
    for side in ("left", "right"):
        hand_joint = model.frames[talos.frame_id(f"{side}_hand")].parentJoint
        below = {model.frames[g.parentFrame].name for g in talos.collision_model.geometryObjects
                 if g.parentJoint in model.subtrees[hand_joint]}
        assert talos.meet_links(f"{side}_hand", "head") == below and f"gripper_{side}_base_link" in below
    assert talos.meet_links("head", "left_hand") == {"head_2_link", "rgbd_link"}
    assert g1.profile.collisions.meet_joints == 2 and talos.profile.collisions.meet_joints == 0
    assert g1.meet_links("left_hand", "right_hand") == {f"left_wrist_{j}_link" for j in ("roll", "pitch", "yaw")}
    assert g1.meet_links("head", "right_hand") == {"head_link"}
    # the fitted model does not depend on meet_joints: the cached fits stay valid
    assert CollisionTable(meet_joints=2).fit_key() == CollisionTable().fit_key() == \
        "CollisionTable(add=(), remove=(), body_parts=())"


def test_profile_without_collisions_table_keeps_defaults():
    from robots.profile import builtin_profiles

    assert builtin_profiles()["talos"].collisions == RobotProfile.__dataclass_fields__["collisions"].default_factory()


def test_viewer_draws_one_node_per_capsule(g1):
    """``wbmp show --collisions``: every capsule becomes meshcat objects under its joint's visual node."""
    from viz import scene
    from viz._meshcat import meshcat
    from viz.html import RecordingWindow

    window = RecordingWindow()
    vis = meshcat.Visualizer(window=window)
    scene.add_robot(vis, g1, motion="planned")
    n = scene.add_collision_capsules(vis, g1, motion="planned")
    assert n == len(collision_model(g1).capsules)
    drawn = [c for c in window.commands if b"capsule_" in c]
    assert len(drawn) >= 2 * n  # a sphere at each end (and a cylinder for a capsule of non-zero length)


def test_wide_boxy_link_gets_two_thinner_capsules_close_to_its_mesh(talos):
    """Talos's torso (a 0.31 x 0.45 x 0.46 m box) gets two capsules: in front of the chest, where
    crossed arms and claps go, its sphere set stands at most 6 cm out of the mesh (coal distance of
    probe points minus their sphere-set distance; one 0.27 m capsule stood 15-16 cm out), and never
    inside it (the set still encloses the mesh)."""
    import coal

    cm = collision_model(talos)
    caps = cm.capsules_of("torso_2_link")
    assert len(caps) == 2 and max(c.radius for c in caps) < 0.2
    data = talos.model.createData()
    pin.forwardKinematics(talos.model, data, talos.q_standing)
    J = data.oMi[caps[0].joint]
    objs = [o for o in talos.collision_model.geometryObjects if talos.model.frames[o.parentFrame].name == "torso_2_link"]
    probe = coal.Sphere(1e-4)

    def mesh(p):
        out = np.inf
        for o in objs:
            M = J * o.placement
            out = min(out, coal.distance(o.geometry, coal.Transform3s(M.rotation, M.translation), probe,
                                         coal.Transform3s(np.eye(3), p), coal.DistanceRequest(), coal.DistanceResult()))
        return out

    def spheres(p):
        out = np.inf
        for c in caps:
            centres, r = c.spheres()
            out = min(out, float(np.min(np.linalg.norm(centres @ J.rotation.T + J.translation - p, axis=1)) - r))
        return out

    for dz in (0.0, 0.1, 0.2, 0.3):  # chest height and above, 0.45 m in front of the torso joint
        p = J.translation + J.rotation @ np.array([0.45, 0.0, dz])
        inflation = mesh(p) - spheres(p)
        assert 0.0 <= inflation <= 0.06, (dz, inflation)


def test_alternative_covers_keep_the_hanging_forearm_clear_of_the_pelvis(talos):
    """Talos's pelvis capsule (0.16 m, along the pelvis's width) bulges 7 cm beyond its flanks, where
    the forearms hang: at rest their sphere sets were 13 mm apart (the meshes 93 mm), and a 2 degree
    arm roll brought them within the 1 cm margin in every task. The pair is now checked with the
    pelvis's capsule along its depth, which hugs the flanks: more than the 3 cm screening distance
    apart at rest, and still never farther apart than the meshes (coal), also with the arm
    swung in front of and behind the pelvis and across it."""
    cm = collision_model(talos)
    pair = ("arm_left_5_link", "base_link")
    assert pair in cm.covers and cm.covers[pair][0] == 0  # the forearm keeps its own capsule
    caps_a, caps_b = cm.pair_capsules(*pair)
    assert len(caps_b) == 1 and caps_b[0].cover >= 1
    model = talos.model
    iq = {name: model.joints[model.getJointId(name)].idx_q for name in ("arm_left_1_joint", "arm_left_2_joint",
                                                                        "arm_left_4_joint")}
    postures = [talos.q_standing]
    for pitch, roll, elbow in ((-0.8, 0.0, -1.2), (0.6, 0.0, -0.3), (-0.3, -0.4, -1.8), (0.0, 0.3, 0.0)):
        q = talos.q_standing.copy()
        q[iq["arm_left_1_joint"]] += pitch
        q[iq["arm_left_2_joint"]] += roll
        q[iq["arm_left_4_joint"]] = elbow
        postures.append(q)
    for k, q in enumerate(postures):
        data = model.createData()
        pin.forwardKinematics(model, data, q)
        d = min(sphere_distance(c1, c2, data) for c1 in caps_a for c2 in caps_b)
        mesh = mesh_distances(talos, q, [pair])[pair]
        assert d <= max(mesh, 0.0) + DISTANCE_TOLERANCE, (k, d, mesh)
        if k == 0:
            assert 0.03 < d and 0.08 < mesh, (d, mesh)
