"""``wbmp export --format csv``: the columns are the ones docs/export.md lists, and reading the
CSV back by its header gives the motion file's arrays bit for bit (``repr`` of a float64)."""

from __future__ import annotations

import csv
import json

import numpy as np
import pinocchio as pin
import pytest

from wbmp.cli import main
from wbmp.motionfile import load_motion, save_motion

BASE_Q = ["base_x", "base_y", "base_z", "base_qx", "base_qy", "base_qz", "base_qw"]
BASE_V = ["base_vx", "base_vy", "base_vz", "base_wx", "base_wy", "base_wz"]


@pytest.fixture(scope="module")
def motion_path(tmp_path_factory, talos, synth_plan, synth_execution):
    ex = synth_execution
    execution = ex
    path = tmp_path_factory.mktemp("motion") / "squat.npz"
    return save_motion(path, synth_plan, talos, execution=execution, report={"certificate": {"ok": False}})


def read_csv(path) -> tuple[dict, list[str], np.ndarray]:
    """(comment entries as JSON, header, rows) of an exported CSV, with the csv module."""
    meta, lines = {}, path.read_text().splitlines()
    while lines and lines[0].startswith("# "):
        key, _, value = lines.pop(0)[2:].partition(": ")
        meta[key] = json.loads(value)
    rows = list(csv.reader(lines))
    return meta, rows[0], np.array([[float(x) for x in r] for r in rows[1:]])


def test_csv_round_trips_to_the_motion_files_arrays(motion_path, tmp_path):
    """The plan CSV's columns t, q_*, v_*, com_* and the execution CSV's t, q_*, v_*, tau_* are
    the motion file's t, q, v, com and exec_* arrays exactly, in the documented order."""
    m = load_motion(motion_path)
    out = tmp_path / "m.csv"
    assert main(["export", str(motion_path), "--format", "csv", "--out", str(out)]) == 0
    meta, header, rows = read_csv(out)
    joints = list(m.joint_names)
    assert header == ["t", *[f"q_{n}" for n in BASE_Q + joints], *[f"v_{n}" for n in BASE_V + joints],
                      "com_x", "com_y", "com_z"]
    assert list(meta) == ["robot", "version", "spec", "actions", "report"]
    assert meta["robot"] == "talos" and meta["report"]["certificate"] == {"ok": False}
    col = {name: rows[:, i] for i, name in enumerate(header)}
    np.testing.assert_array_equal(col["t"], m.plan.t)
    np.testing.assert_array_equal(np.column_stack([col[f"q_{n}"] for n in BASE_Q + joints]), m.plan.q)
    np.testing.assert_array_equal(np.column_stack([col[f"v_{n}"] for n in BASE_V + joints]), m.plan.v)
    np.testing.assert_array_equal(np.column_stack([col[f"com_{a}"] for a in "xyz"]), m.plan.com)
    # the quaternion columns are x, y, z, w: Pinocchio's rotation of the base
    for k in (0, len(rows) // 2):
        quat = pin.Quaternion(col["q_base_qw"][k], col["q_base_qx"][k], col["q_base_qy"][k], col["q_base_qz"][k])
        np.testing.assert_allclose(quat.toRotationMatrix(), pin.XYZQUATToSE3(m.plan.q[k, :7]).rotation,
                                   rtol=0, atol=1e-12)

    _, exec_header, exec_rows = read_csv(tmp_path / "m.exec.csv")
    assert exec_header == ["t", *[f"q_{n}" for n in BASE_Q + joints], *[f"v_{n}" for n in BASE_V + joints],
                           *[f"tau_{n}" for n in joints]]
    ex = m.execution
    np.testing.assert_array_equal(exec_rows, np.hstack([ex.t[:, None], ex.q, ex.v,
                                                        ex.tau]))
