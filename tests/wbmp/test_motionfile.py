"""Motion file: exact round trip of the plan, execution, actions and report; JSON/CSV exports."""

from __future__ import annotations

import csv
import json
from types import SimpleNamespace

import numpy as np
import pytest

from planner import PlannerSettings, plan
from tests.planner.planning_cases import squat_spec
from wbmp.motionfile import MotionFileError, export_motion, load_motion, save_motion


@pytest.fixture(scope="module")
def squat_plan(talos):
    return plan(squat_spec(talos, 0.1, duration=2.0, dt=0.1), talos, settings=PlannerSettings(compile=False))


def _execution(talos, rng):
    T = 7
    return SimpleNamespace(t=np.linspace(0, 0.006, T), q=np.tile(talos.q_standing, (T, 1)),
                           v=rng.normal(size=(T, talos.nv)), tau=rng.normal(size=(T, talos.nv - 6)))


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
    assert np.array_equal(m.execution_arrays["exec_tau"], exe.tau)
    assert np.array_equal(m.execution_arrays["exec_q"], exe.q)
    assert m.actions == actions
    assert m.report["certificate"] == {"ok": True} and m.report["solver"]["iterations"] == squat_plan.stats.iterations
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.npz"]
    with np.load(path) as raw:  # the keys other tools read (DESIGN.md section 6)
        assert {"t", "q", "v", "com", "robot", "joint_names", "frame_names", "exec_t", "exec_q", "exec_v",
                "exec_tau", "spec_json", "actions_json", "report_json", "version"} <= set(raw.files)


def test_without_execution_or_actions(tmp_path, talos, squat_plan):
    """A plan-only file loads with no execution arrays and actions None."""
    m = load_motion(save_motion(tmp_path / "p.npz", squat_plan, talos))
    assert m.execution_arrays == {} and m.actions is None


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
