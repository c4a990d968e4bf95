"""Robot profiles: frames exist, standing postures stand, bad inputs are clear errors."""

from __future__ import annotations

import json

import numpy as np
import pinocchio as pin
import pytest

from robots import FrameNotFound, ProfileError, RobotNotFound, available_robots, load_robot
from robots.profile import REQUIRED_ROLES
from tests.tolerances import STANDING_ATOL


def test_builtin_robots_listed_with_talos_default():
    """The four supported humanoids are built in and talos comes first (the default)."""
    names = available_robots()
    assert names[0] == "talos"
    assert set(names) == {"talos", "g1", "romeo", "icub"}


def test_profile_frames_exist(any_robot):
    """Every role the profile names resolves to a frame of the Pinocchio model."""
    for role, frame in any_robot.profile.frames:
        assert any_robot.model.existFrame(frame), f"{any_robot.name}: {role} -> {frame}"
    for role in REQUIRED_ROLES:
        assert any_robot.frame_id(role) < len(any_robot.model.frames)


def test_standing_posture_soles_flat_on_ground(any_robot):
    """Both soles lie flat on z = 0 within 1 mm at every corner of the sole rectangle."""
    q = any_robot.q_standing
    assert q.shape == (any_robot.nq,)
    for side in ("left", "right"):
        corners = any_robot.sole_corners_in_world(q, side)
        np.testing.assert_allclose(corners[:, 2], 0.0, atol=STANDING_ATOL, err_msg=f"{any_robot.name} {side}")


def test_standing_posture_within_joint_limits(any_robot):
    """The standing posture respects the URDF joint limits."""
    q = any_robot.q_standing
    assert np.all(q[7:] >= any_robot.lower_limits[7:] - 1e-9)
    assert np.all(q[7:] <= any_robot.upper_limits[7:] + 1e-9)


def test_standing_com_above_support_polygon(any_robot):
    """The CoM ground projection lies inside the box spanned by both soles."""
    q = any_robot.q_standing
    com = pin.centerOfMass(any_robot.model, any_robot.data(), q)
    pts = np.vstack([any_robot.sole_corners_in_world(q, s) for s in ("left", "right")])
    assert pts[:, 0].min() < com[0] < pts[:, 0].max(), any_robot.name
    assert pts[:, 1].min() < com[1] < pts[:, 1].max(), any_robot.name
    assert com[2] > 0.3, "the CoM of a standing humanoid is well above the ground"


def test_feet_centred_on_origin(any_robot):
    """The standing posture puts the mid-point of the feet at x = y = 0."""
    d = any_robot.data()
    pin.framesForwardKinematics(any_robot.model, d, any_robot.q_standing)
    mid = 0.5 * (d.oMf[any_robot.frame_id("left_foot")].translation + d.oMf[any_robot.frame_id("right_foot")].translation)
    np.testing.assert_allclose(mid, 0.0, atol=1e-6)


def test_limits_shapes(talos):
    """Limits have Pinocchio sizes and the free flyer is unbounded."""
    assert talos.lower_limits.shape == (talos.nq,)
    assert talos.velocity_limits.shape == (talos.nv,)
    assert talos.torque_limits.shape == (talos.nv - 6,)
    assert np.all(np.isinf(talos.lower_limits[:7]))
    assert np.all(talos.torque_limits > 0)


def test_unknown_robot_lists_available():
    """An unknown robot name is a RobotNotFound that lists the available robots."""
    with pytest.raises(RobotNotFound, match="available: talos, g1"):
        load_robot("asimo")


def test_missing_profile_file():
    """A profile path that does not exist is a one-line ProfileError naming the path."""
    with pytest.raises(ProfileError, match="does not exist"):
        load_robot("no/such/robot.toml")


def _user_profile(tmp_path, talos, **changes):
    data = {
        "name": "mytalos",
        "urdf": talos.urdf_path,
        "package_dirs": list(talos.package_dirs),
        "srdf": str(talos.urdf_path).replace("robots/talos_reduced.urdf", "srdf/talos.srdf"),
        "reference_posture": "half_sitting",
        "frames": {"left_foot": "left_sole_link", "right_foot": "right_sole_link",
                   "left_hand": "gripper_left_base_link", "right_hand": "gripper_right_base_link",
                   "base": "base_link"},
        "sole": {"x_min": -0.1, "x_max": 0.1, "y_min": -0.06, "y_max": 0.06},
    }
    data.update(changes)
    path = tmp_path / "mytalos.json"
    path.write_text(json.dumps(data))
    return path


def test_user_urdf_profile_loads(tmp_path, talos):
    """A user profile (URDF + SRDF + frames) loads like the built-in one and stands the same."""
    robot = load_robot(_user_profile(tmp_path, talos))
    assert robot.name == "mytalos" and robot.nq == talos.nq
    np.testing.assert_allclose(robot.q_standing, talos.q_standing, atol=1e-9)


def test_user_profile_missing_frame(tmp_path, talos):
    """A profile naming a frame the URDF lacks fails with FrameNotFound and close matches."""
    frames = {"left_foot": "left_sole_lnk", "right_foot": "right_sole_link", "left_hand": "gripper_left_base_link",
              "right_hand": "gripper_right_base_link", "base": "base_link"}
    with pytest.raises(FrameNotFound, match="left_sole_link"):
        load_robot(_user_profile(tmp_path, talos, frames=frames))


def test_user_profile_missing_urdf(tmp_path, talos):
    """A profile whose URDF is missing names the file."""
    with pytest.raises(ProfileError, match="nothere.urdf"):
        load_robot(_user_profile(tmp_path, talos, urdf="nothere.urdf"))


def test_user_profile_missing_roles(tmp_path, talos):
    """A profile without the required roles says which are missing."""
    with pytest.raises(ProfileError, match="missing"):
        load_robot(_user_profile(tmp_path, talos, frames={"base": "base_link"}))


def test_convex_hull_contains_every_point_counter_clockwise(rng):
    """The support-polygon hull is counter-clockwise and every input point lies inside it."""
    from robots.contact import convex_hull

    for _ in range(50):
        pts = rng.uniform(-0.3, 0.3, size=(int(rng.integers(3, 20)), 2))
        hull = convex_hull(pts)
        edges = np.roll(hull, -1, axis=0) - hull
        assert np.all(edges[:, 0] * np.roll(edges[:, 1], -1) - edges[:, 1] * np.roll(edges[:, 0], -1) > 0)
        for a, e in zip(hull, edges, strict=True):  # inside = left of every edge
            assert np.all(e[0] * (pts[:, 1] - a[1]) - e[1] * (pts[:, 0] - a[0]) >= -1e-12)
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.5], [0.5, 0.0]])
    np.testing.assert_allclose(convex_hull(square), [[0, 0], [1, 0], [1, 1], [0, 1]])


def _mesh_centroid(robot, name: str, data, gdata) -> np.ndarray:
    gid = robot.visual_model.getGeometryId(name)
    vertices = np.asarray(robot.visual_model.geometryObjects[gid].geometry.vertices())
    return gdata.oMg[gid].act(vertices.mean(axis=0))


def test_collada_meshes_are_z_up(any_robot):
    """Every limb mesh hangs between its joints: Y_UP Collada files (iCub) are turned upright.

    Pinocchio keeps a Collada file's raw coordinates; without the up-axis correction iCub's
    thigh pointed forward from the hip and its head hung below the neck.
    """
    robot = any_robot
    data, gdata = robot.data(), pin.GeometryData(robot.visual_model)
    pin.forwardKinematics(robot.model, data, robot.q_standing)
    pin.updateGeometryPlacements(robot.model, data, robot.visual_model, gdata)
    for obj in robot.visual_model.geometryObjects:
        shape = obj.geometry
        if not (hasattr(shape, "num_tris") and shape.num_tris > 0):
            continue
        # every mesh is above the floor (the sole meshes may dip a few millimetres)
        placement = gdata.oMg[robot.visual_model.getGeometryId(obj.name)]
        heights = np.asarray(shape.vertices()) @ placement.rotation[2] + placement.translation[2]
        lowest = float(heights.min())
        assert lowest > -0.02, f"{robot.name}: mesh {obj.name} reaches {lowest:.3f} m below the floor"
    if robot.name != "icub":
        return
    hip = data.oMi[robot.model.getJointId("l_hip_pitch")].translation
    knee = data.oMi[robot.model.getJointId("l_knee")].translation
    thigh = _mesh_centroid(robot, "l_upper_leg_0", data, gdata)
    assert knee[2] < thigh[2] < hip[2]
    neck = data.oMi[robot.model.getJointId("neck_pitch")].translation
    assert _mesh_centroid(robot, "head_0", data, gdata)[2] > neck[2] + 0.05
