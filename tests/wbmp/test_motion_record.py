"""One typed motion record: a simulated execution converts exactly to the motion file and back,
and a result answered from the motion cache is the same typed record as a fresh one (no
stand-ins): its execution, certificate, events and object poses equal the fresh result's."""

from __future__ import annotations

import dataclasses
import io
from pathlib import Path

import numpy as np
import pytest

from planner import Check, CheckKind
from sim import Certificate, Event, Execution
from tests.viz.conftest import synthetic_pick_up, synthetic_pick_up_execution
from viz import motion as vm
from wbmp.export.files import export_motion
from wbmp.motioncache import Hit
from wbmp.motionfile import load_motion, motion_from_arrays, save_motion
from wbmp.pipeline import SolveRequest, SolveResult, _from_cache, result_arrays


def _certificate() -> Certificate:
    checks = (
        Check(name="no fall", kind=CheckKind.BASE_HEIGHT, value=0.81, limit=0.6, unit="m", time=1.25, ok=True,
              upper=False),
        Check(name="torque", kind=CheckKind.PEAK_TORQUE, value=1.07, limit=1.0, unit="-", time=2.5, ok=False,
              message="the left knee's torque reached 107 % of its limit at t = 2.50 s"),
    )
    cert = Certificate.from_checks(checks)
    return dataclasses.replace(cert, figures={"work": 12.5, "rms_jerk": 0.125},
                               stops=({"time": 2.0, "reason": "--estop-at", "message": "e-stop at 2.00 s: stood"},))


@pytest.fixture(scope="module")
def pick(talos, synth_plan):
    """The synthetic pick-up plan and its execution, with a certificate and events."""
    plan = synthetic_pick_up(talos, synth_plan)
    ex = synthetic_pick_up_execution(talos, plan)
    events = (Event(0.5, "push", "pushed the base with 40 N for 0.1 s"), Event(2.0, "estop", "e-stop: stood"))
    return plan, dataclasses.replace(ex, certificate=_certificate(), events=events, contact_forces={})


def _same_execution(a: Execution, b: Execution) -> None:
    for name in ("t", "q", "v", "tau"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert a.certificate == b.certificate and a.events == b.events
    pa, pb = a.object_poses(), b.object_poses()
    assert list(pa) == list(pb) and all(np.array_equal(pa[k], pb[k]) for k in pa)


def test_an_execution_converts_exactly_to_the_file_and_back(tmp_path, talos, pick):
    """Saved then loaded: the same arrays, certificate (checks, figures, stops), events and object
    poses; written again from the loaded record (``wbmp export --format npz``): the same keys with the
    same values, so the record is the file's content and nothing else."""
    plan, ex = pick
    path = save_motion(tmp_path / "m.npz", plan, talos, execution=ex)
    m = load_motion(path)
    assert m.execution is not None
    _same_execution(m.execution, ex)
    assert m.execution.certificate is not None and not m.execution.ok  # the torque check failed
    assert m.execution.certificate.check("torque").message.startswith("the left knee's torque")
    (copy,) = export_motion(m, tmp_path / "copy.npz")
    with np.load(path) as first, np.load(copy) as second:
        assert sorted(first.files) == sorted(second.files)
        for key in first.files:
            assert np.array_equal(first[key], second[key]), key
    _same_execution(load_motion(copy).execution, ex)


def test_the_viewers_see_the_same_numbers_from_either_source(tmp_path, talos, pick):
    """viz reads one type: the simulated motion of the fresh execution and of the one read back
    from the file are equal (times, configurations, torques, object poses)."""
    plan, ex = pick
    loaded = load_motion(save_motion(tmp_path / "m.npz", plan, talos, execution=ex)).execution
    fresh, back = vm.execution_motion(talos, ex), vm.execution_motion(talos, loaded)
    assert fresh is not None and back is not None
    for name in ("t", "q", "v", "tau"):
        assert np.array_equal(getattr(fresh, name), getattr(back, name)), name
    assert list(fresh.objects) == ["cup", "box"] == list(back.objects)
    assert all(np.array_equal(fresh.objects[k], back.objects[k]) for k in fresh.objects)
    assert np.ptp(back.objects["cup"][:, 2]) > 0.05  # the held cup moves: not a constant stand-in


def test_a_cached_result_is_the_fresh_result(talos, pick):
    """A result rebuilt from a motion cache entry carries the same execution, certificate and events,
    its report equals the fresh one's but for ``cached``, the timings and the solver's cache field,
    and it loads no robot model until a view asks for one."""
    plan, ex = pick
    fresh = SolveResult(robot=talos, spec=plan.spec, plan=plan, execution=ex)
    arrays = result_arrays(fresh)
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    motion = motion_from_arrays(arrays, source="entry.npz")
    hit = Hit(key="0" * 64, arrays=arrays, motion=motion, path=Path("entry.npz"), data=buf.getvalue())
    cached = _from_cache(SolveRequest(spec_path="spec.json"), hit, None, 0.01)
    assert cached.robot is None and cached.robot_name == "talos"
    assert cached.execution is not None
    _same_execution(cached.execution, ex)
    assert cached.exit_code == fresh.exit_code != 0  # the failed torque check: exit 5 both ways
    mine, theirs = cached.report(), fresh.report()
    assert mine.pop("cached") is True and theirs.pop("cached") is False
    for report in (mine, theirs):
        report.pop("timings")
        report["solver"].pop("cache")
    assert mine == theirs
    assert "events" in mine and mine["events"][1]["kind"] == "estop"
    assert cached.model().nq == talos.nq and cached.robot is not None



def test_a_report_entry_that_is_not_a_certificate_or_an_event_is_left_out(tmp_path, talos, pick):
    """The certificate and events are read from the report with Certificate.from_dict and
    Event.from_dict: a dict that is not one gives no certificate and skips the event (the file
    still loads, as a file written by another tool does)."""
    plan, ex = pick
    bare = dataclasses.replace(ex, certificate=None, events=())
    good = {"time": 1.5, "kind": "push", "message": "pushed"}
    report = {"certificate": {"ok": True}, "events": [{"time": "soon", "kind": "push", "message": "x"}, good, 3]}
    m = load_motion(save_motion(tmp_path / "m.npz", plan, talos, execution=bare, report=report))
    assert m.execution is not None and m.execution.certificate is None and not m.execution.ok
    assert m.execution.events == (Event(1.5, "push", "pushed"),)
    assert Certificate.from_dict(_certificate().to_dict()) == _certificate()
