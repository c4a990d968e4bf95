"""``wbmp export --format lafan``: the Unitree/LAFAN1 retargeting CSV (no header; root x y z,
root quaternion x y z w, joint positions) read back with numpy's ``loadtxt`` and compared with
the motion file's q at the frame times through independent interpolators (numpy's ``interp``,
scipy's ``Slerp``)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

from tests.tolerances import EXPORT_ATOL
from wbmp.cli import main
from wbmp.motionfile import load_motion, save_motion

#: the 29 joints in the order of the Unitree G1 SDK, which the retargeted LAFAN1 files and
#: BeyondMimic's csv_to_npz use (written out here from the SDK's documentation, not from our model)
UNITREE_G1_ORDER = [
    *[f"left_{j}_joint" for j in ("hip_pitch", "hip_roll", "hip_yaw", "knee", "ankle_pitch", "ankle_roll")],
    *[f"right_{j}_joint" for j in ("hip_pitch", "hip_roll", "hip_yaw", "knee", "ankle_pitch", "ankle_roll")],
    "waist_yaw_joint", "waist_roll_joint", "waist_pitch_joint",
    *[f"left_{j}_joint" for j in ("shoulder_pitch", "shoulder_roll", "shoulder_yaw", "elbow", "wrist_roll",
                                  "wrist_pitch", "wrist_yaw")],
    *[f"right_{j}_joint" for j in ("shoulder_pitch", "shoulder_roll", "shoulder_yaw", "elbow", "wrist_roll",
                                   "wrist_pitch", "wrist_yaw")],
]


@pytest.fixture(scope="module")
def motion_path(tmp_path_factory, talos, synth_plan, synth_execution):
    """The synthetic squat (knots every 0.05 s) with its 200 Hz execution; the base turns about z
    (yaw up to 0.6 rad) and every other knot's quaternion is stored with the opposite sign."""
    plan = synth_plan
    q = plan.q.copy()
    yaw = 0.6 * np.sin(np.pi * plan.t / plan.t[-1])
    quat = Rotation.from_euler("z", yaw[:, None]).as_quat()  # x, y, z, w
    quat[1::2] *= -1.0
    q[:, 3:7] = quat
    plan = type(plan)(robot=plan.robot, spec=plan.spec, t=plan.t, q=q, v=plan.v, a=plan.a, com=plan.com,
                      stats=plan.stats)
    ex = synth_execution
    execution = ex
    path = tmp_path_factory.mktemp("motion") / "turn.npz"
    return save_motion(path, plan, talos, execution=execution)


def same_rotation(a: np.ndarray, b: np.ndarray) -> float:
    """Largest distance between rows of two quaternion arrays, up to each row's sign."""
    return float(np.max(np.minimum(np.linalg.norm(a - b, axis=1), np.linalg.norm(a + b, axis=1))))


def expected(t: np.ndarray, q: np.ndarray, frames: np.ndarray) -> np.ndarray:
    """q at ``frames`` [s]: numpy's linear interpolation of the positions, scipy's slerp of the
    quaternion (x, y, z, w)."""
    out = np.column_stack([np.interp(frames, t, q[:, i]) for i in range(q.shape[1])])
    out[:, 3:7] = Slerp(t, Rotation.from_quat(q[:, 3:7]))(frames).as_quat()
    return out


def test_rows_are_q_at_the_frame_times(motion_path, tmp_path, capsys):
    """Default 30 frames/s (not a multiple of the 20 Hz knots): every row is the plan's q at
    j / 30 s, in the order root x y z, quaternion x y z w, joints in joint_names order."""
    m = load_motion(motion_path)
    out = tmp_path / "m.csv"
    assert main(["export", str(motion_path), "--format", "lafan", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert f"lafan: {out}" in printed and "30 frames/s" in printed
    assert " ".join(m.joint_names) in printed  # the joint order is stated
    text = out.read_text()
    assert not text.startswith("#") and text.count("\n") == len(text.splitlines())
    rows = np.loadtxt(out, delimiter=",", ndmin=2)  # as BeyondMimic's csv_to_npz reads it
    t = m.plan.t
    frames = np.arange(int(np.floor((t[-1] - t[0]) * 30.0 + 1e-9)) + 1) / 30.0
    assert rows.shape == (len(frames), m.plan.q.shape[1]) and rows.shape[1] == 7 + len(m.joint_names)
    ref = expected(t, m.plan.q, frames)
    np.testing.assert_allclose(rows[:, :3], ref[:, :3], rtol=0, atol=EXPORT_ATOL)
    np.testing.assert_allclose(rows[:, 7:], ref[:, 7:], rtol=0, atol=EXPORT_ATOL)
    assert same_rotation(rows[:, 3:7], ref[:, 3:7]) <= 1e-12
    np.testing.assert_allclose(np.linalg.norm(rows[:, 3:7], axis=1), 1.0, rtol=0, atol=EXPORT_ATOL)
    # no sign jump between frames though the file flips every other knot's quaternion
    assert np.all(np.sum(rows[1:, 3:7] * rows[:-1, 3:7], axis=1) > 0.0)
    # the motion moves: the comparison is not between constants
    assert np.ptp(rows[:, 7:], axis=0).max() > 0.05 and np.ptp(rows[:, 3:7], axis=0).max() > 0.1


def test_fps_and_execution_source(motion_path, tmp_path):
    """--fps 50 --source execution: every 4th sample of the 200 Hz simulation, exactly."""
    m = load_motion(motion_path)
    ex = m.execution
    out = tmp_path / "exec.csv"
    assert main(["export", str(motion_path), "--format", "lafan", "--fps", "50", "--source", "execution",
                 "--out", str(out)]) == 0
    rows = np.loadtxt(out, delimiter=",", ndmin=2)
    sampled = ex.q[::4]
    assert rows.shape == sampled.shape
    np.testing.assert_allclose(rows[:, :3], sampled[:, :3], rtol=0, atol=EXPORT_ATOL)
    np.testing.assert_allclose(rows[:, 7:], sampled[:, 7:], rtol=0, atol=EXPORT_ATOL)
    assert same_rotation(rows[:, 3:7], sampled[:, 3:7]) <= EXPORT_ATOL


def test_default_name_and_csv_suffix(motion_path, tmp_path, capsys):
    """Without --out: <motion>.lafan.csv; --out x.csv alone stays the wbmp CSV (with a header)."""
    import shutil

    src = shutil.copy(motion_path, tmp_path / "walk.npz")
    assert main(["export", str(src), "--format", "lafan"]) == 0
    assert f"lafan: {tmp_path / 'walk.lafan.csv'}" in capsys.readouterr().out
    assert (tmp_path / "walk.lafan.csv").read_text()[0] in "-0123456789"
    assert main(["export", str(src), "--out", str(tmp_path / "plain.csv")]) == 0
    assert (tmp_path / "plain.csv").read_text().startswith("# robot:")


def test_g1_joint_order_is_the_unitree_order(g1):
    """For the G1 our joint order (Pinocchio's, the motion file's joint_names) is the one the
    retargeted LAFAN1 files and BeyondMimic use, so the CSV needs no reordering."""
    assert list(g1.joint_names) == UNITREE_G1_ORDER


def test_bad_input_is_one_line_and_writes_nothing(motion_path, tmp_path, synth_plan, capsys):
    """No joint names, an unwritable path, an option of another format, a rate too low: one line,
    exit 2, no file."""
    nameless = save_motion(tmp_path / "nameless.npz", synth_plan, None)
    out = tmp_path / "x.csv"
    assert main(["export", str(nameless), "--format", "lafan", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "joint_names" in err and not out.exists()

    blocker = tmp_path / "file"
    blocker.write_text("a file, not a folder")
    code = main(["export", str(motion_path), "--format", "lafan", "--out", str(blocker / "m.csv")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "is a file, not a folder" in err
    assert blocker.read_text() == "a file, not a folder"

    assert main(["export", str(motion_path), "--format", "lafan", "--stamp", "1", "--out", str(out)]) == 2
    assert "--stamp applies to --format mcap" in capsys.readouterr().err
    assert main(["export", str(motion_path), "--format", "lafan", "--fps", "0.1", "--out", str(out)]) == 2
    assert "--fps" in capsys.readouterr().err and not out.exists()
    assert main(["export", str(motion_path), "--format", "lafan", "--out", str(tmp_path / "x.json")]) == 2
    assert "ends in .json but --format is lafan" in capsys.readouterr().err
