"""Motion file: exact round trip of the plan, execution, actions and report; JSON/CSV exports."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from planner import CacheSettings, PlannerSettings, plan
from sim import Execution
from tests.planner.planning_cases import squat_spec
from wbmp.errors import MotionFileError
from wbmp.export.files import export_motion
from wbmp.motionfile import load_motion, save_motion


@pytest.fixture(scope="module")
def squat_plan(talos):
    return plan(squat_spec(talos, 0.1, duration=2.0, dt=0.1), talos,
                settings=PlannerSettings(cache=CacheSettings(compile=False)))


def _execution(talos, rng):
    T = 7
    return Execution(t=np.linspace(0, 0.006, T), q=np.tile(talos.q_standing, (T, 1)),
                     v=rng.normal(size=(T, talos.nv)), tau=rng.normal(size=(T, talos.nv - 6)), certificate=None)


def test_round_trip_is_exact(tmp_path, talos, squat_plan, rng):
    """save_motion then load_motion gives back the arrays, spec, stats, checks, execution, actions
    and report; no temporary file is left behind."""
    exe = _execution(talos, rng)
    actions = [{"action": "squat", "params": {"depth": 0.1}}]
    path = save_motion(tmp_path / "m.npz", squat_plan, talos, execution=exe, actions=actions,
                       report={"certificate": {"ok": True}})
    m = load_motion(path)
    for key in ("t", "q", "v", "a", "com"):
        assert np.array_equal(getattr(m.plan, key), getattr(squat_plan, key))
    assert m.plan.spec == squat_plan.spec
    assert m.plan.stats == squat_plan.stats
    assert m.plan.checks == squat_plan.checks
    assert m.plan.ok == squat_plan.ok
    assert m.robot_name == "talos" and m.joint_names == talos.joint_names
    assert m.frame_names == ["left_sole_link", "right_sole_link"]
    assert np.array_equal(m.execution.tau, exe.tau)
    assert np.array_equal(m.execution.q, exe.q)
    assert m.actions == actions
    assert m.report["certificate"] == {"ok": True} and m.report["solver"]["iterations"] == squat_plan.stats.iterations
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.npz"]
    with np.load(path) as raw:  # the keys other tools read (docs/formats.md)
        assert {"t", "q", "v", "com", "robot", "joint_names", "frame_names", "exec_t", "exec_q", "exec_v",
                "exec_tau", "spec_json", "actions_json", "report_json", "version"} <= set(raw.files)


def test_without_execution_or_actions(tmp_path, talos, squat_plan):
    """A plan-only file loads with no execution arrays and actions None."""
    m = load_motion(save_motion(tmp_path / "p.npz", squat_plan, talos))
    assert m.execution is None and m.actions is None


def test_json_and_csv_exports_carry_the_content(tmp_path, talos, squat_plan, rng):
    """The JSON export holds every array and the spec; the CSV has one row per knot after its metadata."""
    m = load_motion(save_motion(tmp_path / "m.npz", squat_plan, talos, execution=_execution(talos, rng)))
    (jpath,) = export_motion(m, tmp_path / "m.json")
    doc = json.loads(jpath.read_text())
    assert np.allclose(doc["q"], squat_plan.q) and doc["spec"]["name"] == "squat"
    assert len(doc["exec_tau"]) == 7
    paths = export_motion(m, tmp_path / "m.csv")
    lines = paths[0].read_text().splitlines()
    meta = [ln for ln in lines if ln.startswith("#")]
    rows = list(csv.reader([ln for ln in lines if not ln.startswith("#")]))
    assert rows[0][:2] == ["t", "q_base_x"] and len(rows) == 1 + len(squat_plan.t)
    assert np.allclose([float(r[0]) for r in rows[1:]], squat_plan.t)
    assert any(ln.startswith("# spec:") for ln in meta)
    assert paths[1].name == "m.exec.csv"


def test_bad_files_and_formats_are_refused(tmp_path, talos, squat_plan):
    """Missing file, a non-npz file and an unknown export format raise MotionFileError."""
    with pytest.raises(MotionFileError, match="does not exist"):
        load_motion(tmp_path / "nope.npz")
    (tmp_path / "bad.npz").write_text("hello")
    with pytest.raises(MotionFileError, match="not a motion file"):
        load_motion(tmp_path / "bad.npz")
    m = load_motion(save_motion(tmp_path / "m.npz", squat_plan, talos))
    with pytest.raises(MotionFileError, match="unknown export format"):
        export_motion(m, tmp_path / "m.xlsx")


@pytest.fixture(scope="module")
def pick(talos):
    """A synthetic plan holding a cup (tests/viz/conftest.py) and an execution with the objects' poses."""
    from tests.viz.conftest import synthetic_pick_up, synthetic_pick_up_execution, synthetic_plan

    plan_ = synthetic_pick_up(talos, synthetic_plan(talos))
    ex = synthetic_pick_up_execution(talos, plan_)
    return plan_, ex


def test_object_poses_in_the_motion_file(tmp_path, talos, pick):
    """The movable objects' planned poses (object_pose, one row per knot) and simulated poses
    (exec_object_pose, one row per sample) are written under object_names, read back by load_motion,
    and carried by the JSON and CSV exports; a file written before them (no such keys) still loads."""
    from viz import motion as vm

    plan_, exe = pick
    path = save_motion(tmp_path / "m.npz", plan_, talos, execution=exe)
    with np.load(path) as z:
        arrays = dict(z)
    assert list(arrays["object_names"]) == ["cup", "box"]
    planned = vm.planned_object_poses(talos, plan_.spec, plan_.t, plan_.q)
    assert arrays["object_pose"].shape == (len(plan_.t), 2, 7)
    assert np.array_equal(arrays["object_pose"][:, 0], planned["cup"])
    assert np.array_equal(arrays["exec_object_pose"][:, 0, :3], exe.objects["cup"])
    assert np.array_equal(arrays["exec_object_pose"][:, 1, 3:], exe.object_orientations["box"])
    m = load_motion(path)
    assert np.array_equal(m.objects["cup"], planned["cup"])
    assert np.array_equal(np.stack(list(m.execution.object_poses().values()), axis=1), arrays["exec_object_pose"])
    doc = json.loads((export_motion(m, tmp_path / "m.json")[0]).read_text())
    assert doc["object_names"] == ["cup", "box"] and np.allclose(doc["exec_object_pose"], arrays["exec_object_pose"])
    csv_path, exec_path = export_motion(m, tmp_path / "m.csv")
    rows = list(csv.reader(line for line in csv_path.read_text().splitlines() if not line.startswith("#")))
    col = rows[0].index("object_cup_z")
    assert np.allclose([float(r[col]) for r in rows[1:]], planned["cup"][:, 2], rtol=0, atol=0)
    rows = list(csv.reader(exec_path.read_text().splitlines()))
    col = rows[0].index("object_box_qw")
    assert np.array_equal([float(r[col]) for r in rows[1:]], exe.object_orientations["box"][:, 3])
    old = {k: v for k, v in arrays.items() if "object" not in k}
    np.savez(tmp_path / "old.npz", **old)
    m_old = load_motion(tmp_path / "old.npz")
    assert m_old.objects == {} and m_old.execution.objects == {}


@pytest.mark.parametrize(("change", "message"), [
    (lambda a: a.pop("object_names"), "key 'object_pose' needs the key 'object_names'"),
    (lambda a: a.update(object_pose=a["object_pose"][:, :1]), "key 'object_pose' must have shape"),
    (lambda a: a.update(exec_object_pose=a["exec_object_pose"][:-1]), "key 'exec_object_pose' must have shape"),
    (lambda a: a.update(object_names=np.array(["cup", "cup"])), "key 'object_names' must hold distinct"),
    (lambda a: [a.pop(k) for k in ("exec_t", "exec_q", "exec_v", "exec_tau")], "needs a simulated execution"),
])
def test_bad_object_keys_are_refused(tmp_path, talos, pick, change, message):
    """A damaged object key is one MotionFileError naming it."""
    plan_, exe = pick
    path = save_motion(tmp_path / "m.npz", plan_, talos, execution=exe)
    with np.load(path) as z:
        arrays = dict(z)
    change(arrays)
    np.savez(tmp_path / "bad.npz", **arrays)
    with pytest.raises(MotionFileError, match=message):
        load_motion(tmp_path / "bad.npz")
