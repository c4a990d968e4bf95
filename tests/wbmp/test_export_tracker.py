"""``wbmp export --format tracker``: a uniform-rate ``.npz`` whose samples are the motion file's
knots where they fall on one, and its linear/slerp interpolation between them (checked against
numpy's ``interp`` and scipy's ``Slerp``, independent implementations)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from scipy.spatial.transform import Rotation, Slerp

from tests.tolerances import EXPORT_ATOL
from wbmp.cli import main
from wbmp.motionfile import load_motion, save_motion


@pytest.fixture(scope="module")
def motion_path(tmp_path_factory, talos, synth_plan, synth_execution):
    """The synthetic squat (knots every 0.05 s, 20 Hz) with its 200 Hz execution; the base turns
    about z (yaw up to 0.6 rad) so that slerp has work to do, and every other knot's quaternion
    is stored with the opposite sign (the same rotation)."""
    plan = synth_plan
    q = plan.q.copy()
    yaw = 0.6 * np.sin(np.pi * plan.t / plan.t[-1])
    quat = Rotation.from_euler("z", yaw[:, None]).as_quat()  # x, y, z, w
    quat[1::2] *= -1.0
    q[:, 3:7] = quat
    v = plan.v.copy()
    v[:, 0:3] = [0.1, -0.2, 0.05]  # [m/s] in the base frame
    v[:, 5] = np.gradient(yaw, plan.t)  # [rad/s] about the base's z (the world's: a pure yaw)
    plan = type(plan)(robot=plan.robot, spec=plan.spec, t=plan.t, q=q, v=v, a=plan.a, com=plan.com,
                      stats=plan.stats)
    ex = synth_execution
    execution = ex
    path = tmp_path_factory.mktemp("motion") / "turn.npz"
    return save_motion(path, plan, talos, execution=execution)


def export(motion_path, tmp_path, *args: str) -> dict:
    out = tmp_path / "m.npz"
    assert main(["export", str(motion_path), "--format", "tracker", "--out", str(out), *args]) == 0
    with np.load(out) as f:
        return {k: f[k] for k in f.files}


def same_rotation(a: np.ndarray, b: np.ndarray) -> float:
    """Largest distance between rows of two quaternion arrays, up to each row's sign."""
    return float(np.max(np.minimum(np.linalg.norm(a - b, axis=1), np.linalg.norm(a + b, axis=1))))


def test_fps_that_divides_the_knots_samples_every_knot(motion_path, tmp_path):
    """At 60 fps (3 samples per 20 Hz knot) every knot is a sample with the file's values, and the
    samples between are numpy's linear interpolation and scipy's slerp."""
    m = load_motion(motion_path)
    d = export(motion_path, tmp_path, "--fps", "60")
    assert str(d["format"]) == "wbmp-tracker" and str(d["root_rot_order"]) == "xyzw" and float(d["fps"]) == 60.0
    assert list(d["joint_names"]) == list(m.joint_names) and str(d["root_frame"]) == "base_link"
    t, knots = m.plan.t, d["t"]
    n = len(t)
    assert len(knots) == 3 * (n - 1) + 1
    np.testing.assert_allclose(knots, np.arange(len(knots)) / 60.0, rtol=0, atol=EXPORT_ATOL)
    at_knots = slice(0, None, 3)
    np.testing.assert_allclose(d["root_pos"][at_knots], m.plan.q[:, :3], rtol=0, atol=EXPORT_ATOL)
    np.testing.assert_allclose(d["joint_pos"][at_knots], m.plan.q[:, 7:], rtol=0, atol=EXPORT_ATOL)
    np.testing.assert_allclose(d["joint_vel"][at_knots], m.plan.v[:, 6:], rtol=0, atol=EXPORT_ATOL)
    assert same_rotation(d["root_rot"][at_knots], m.plan.q[:, 3:7]) <= EXPORT_ATOL
    # between the knots: independent interpolators
    for j in range(m.plan.q.shape[1] - 7):
        np.testing.assert_allclose(d["joint_pos"][:, j], np.interp(knots, t, m.plan.q[:, 7 + j]), rtol=0,
                                   atol=EXPORT_ATOL)
    reference = Slerp(t, Rotation.from_quat(m.plan.q[:, 3:7]))(np.clip(knots, t[0], t[-1])).as_quat()
    assert same_rotation(d["root_rot"], reference) <= 1e-12
    # no sign jump between consecutive samples though the file flips every other knot
    assert np.all(np.sum(d["root_rot"][1:] * d["root_rot"][:-1], axis=1) > 0.0)
    np.testing.assert_allclose(np.linalg.norm(d["root_rot"], axis=1), 1.0, rtol=0, atol=EXPORT_ATOL)


def test_root_velocities_are_in_the_world_frame(motion_path, tmp_path):
    """root_lin_vel and root_ang_vel at a knot are the file's base-frame velocities rotated to the world."""
    m = load_motion(motion_path)
    d = export(motion_path, tmp_path, "--fps", "20")
    for k in range(len(m.plan.t)):
        rotation = pin.XYZQUATToSE3(m.plan.q[k, :7]).rotation
        np.testing.assert_allclose(d["root_lin_vel"][k], rotation @ m.plan.v[k, :3], rtol=0, atol=EXPORT_ATOL)
        np.testing.assert_allclose(d["root_ang_vel"][k], rotation @ m.plan.v[k, 3:6], rtol=0, atol=EXPORT_ATOL)


def test_default_fps_round_trips_within_the_interpolation_bound(motion_path, tmp_path):
    """At the default 50 fps (not a multiple of 20 Hz), resampling back to the knots linearly errs
    by at most h/4 times the change of slope at the knot (h = 1/fps): the corner of a piecewise-
    linear curve is cut by that much; knots on the 50 fps grid (every 0.1 s) are exact."""
    m = load_motion(motion_path)
    d = export(motion_path, tmp_path)
    assert float(d["fps"]) == 50.0
    h = 1.0 / 50.0
    t = m.plan.t
    np.testing.assert_allclose(d["t"], np.arange(int(round(t[-1] / h)) + 1) * h, rtol=0, atol=EXPORT_ATOL)
    back = np.column_stack([np.interp(t, d["t"], d["joint_pos"][:, j]) for j in range(d["joint_pos"].shape[1])])
    slopes = np.diff(m.plan.q[:, 7:], axis=0) / np.diff(t)[:, None]
    bound = np.zeros_like(back)
    bound[1:-1] = h / 4.0 * np.abs(np.diff(slopes, axis=0))
    err = np.abs(back - m.plan.q[:, 7:])
    assert np.all(err <= bound + EXPORT_ATOL)
    on_grid = np.isclose(t / 0.1, np.round(t / 0.1), rtol=0, atol=1e-9)
    assert on_grid.sum() == 31 and np.max(err[on_grid]) <= EXPORT_ATOL
    assert np.max(err) > 1e-6  # the bound is not vacuous: the corners are cut


def test_execution_source_samples_the_simulation(motion_path, tmp_path):
    """--source execution resamples the 200 Hz simulation: at 50 fps every 4th simulated sample."""
    m = load_motion(motion_path)
    d = export(motion_path, tmp_path, "--source", "execution")
    ex = m.execution
    assert str(d["source"]) == "execution" and len(d["t"]) == (len(ex.t) - 1) // 4 + 1
    np.testing.assert_allclose(d["t"], ex.t[::4], rtol=0, atol=EXPORT_ATOL)
    np.testing.assert_allclose(d["joint_pos"], ex.q[::4, 7:], rtol=0, atol=EXPORT_ATOL)
    np.testing.assert_allclose(d["root_pos"], ex.q[::4, :3], rtol=0, atol=EXPORT_ATOL)
    assert same_rotation(d["root_rot"], ex.q[::4, 3:7]) <= EXPORT_ATOL


def test_default_output_name(motion_path, tmp_path, capsys):
    """Without --out the tracker file is <motion>.tracker.npz beside the motion file."""
    import shutil

    src = shutil.copy(motion_path, tmp_path / "walk.npz")
    assert main(["export", str(src), "--format", "tracker"]) == 0
    assert f"tracker: {tmp_path / 'walk.tracker.npz'}" in capsys.readouterr().out
    with np.load(tmp_path / "walk.tracker.npz") as f:
        assert not any(f[k].dtype.hasobject for k in f.files)  # plain arrays: np.load without pickles
        # a motion without scene objects: the keys of the tracker format before objects, no object_*
        assert sorted(f.files) == sorted(["format", "version", "fps", "robot", "source", "joint_names",
                                          "root_rot_order", "world_frame", "up_axis", "root_frame",
                                          "interpolation", "knot_t", "t", "root_pos", "root_rot", "root_lin_vel",
                                          "root_ang_vel", "joint_pos", "joint_vel"])
        assert str(f["interpolation"]) == "linear: root_pos, joint_pos, velocities; slerp (shorter arc): root_rot"
        assert int(f["version"]) == 1
