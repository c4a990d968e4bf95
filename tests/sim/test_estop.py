"""The software E-stop in MuJoCo: each trigger fires, the robot stands or is damped, never the last torque held."""

from __future__ import annotations

import json
import os
import signal

import numpy as np
import pinocchio as pin
import pytest

from planner.wbc import WbcSettings, WholeBodyController
from sim import SimSettings, simulate
from sim.estop import EStopSettings, damping_gains, damping_torque, finite
from sim.faults import faults_from_dict
from sim.handmade import squat_plan, standing_plan

SETTLE = SimSettings(settle_time=0.2)


@pytest.fixture(scope="module")
def squat(talos):
    return squat_plan(talos, depth=0.1, duration=1.5)


@pytest.fixture(scope="module")
def free_run(talos, squat):
    """The squat without a stop: the reference for the reaction time."""
    return simulate(squat, talos, settings=SETTLE, estop=EStopSettings(hold_time=0.8))


@pytest.fixture(scope="module")
def stopped_run(talos, squat):
    return simulate(squat, talos, settings=SETTLE, estop=EStopSettings(at=0.6, hold_time=1.0))


def _damped_after(ex, t_stop: float) -> float:
    """Largest difference between the applied torques from the stop on and the damping law on the record."""
    kd = damping_gains(ex.torque_limits, EStopSettings().damping)
    after = ex.t >= t_stop - 1e-12
    expected = np.array([damping_torque(v[6:], kd, ex.torque_limits) for v in ex.v[after]])
    return float(np.abs(ex.tau[after] - expected).max())


def test_stop_request_reacts_on_its_tick_and_stands(talos, free_run, stopped_run):
    """A stop at 0.6 s of a squat: the same torques as the free run until the tick before, a different one
    on the stop's own tick (reaction within one tick), then the robot stands still in the posture it had."""
    ex, free = stopped_run, free_run
    stop = ex.stops[0]
    assert (stop.trigger, stop.response, stop.reaction_ticks) == ("request", "stand", 0)
    assert stop.stayed_up and not stop.escalated
    i = int(np.searchsorted(ex.t, 0.6 - 1e-9))
    np.testing.assert_array_equal(ex.tau[:i], free.tau[:i])
    assert np.abs(ex.tau[i] - free.tau[i]).max() > 1e-3
    # it holds the squat's posture of 0.6 s: the CoM height at the end is the plan's there, and at rest
    k = int(round(0.6 / 0.001))
    planned_com = pin.centerOfMass(talos.model, talos.data(), free_run.q[k])[2]
    assert abs(ex.com[-1, 2] - planned_com) < 0.02
    assert abs(ex.com[-1, 2] - free.com[-1, 2]) > 0.03  # the free run came back up
    assert np.abs(ex.v[-1]).max() < 0.05
    assert ex.t[-1] == pytest.approx(0.6 + 1.0, abs=2e-3)  # the run goes on for hold_time after the stop
    cert = ex.certificate
    assert not cert.ok and cert.reason.startswith("E-stop at t = 0.600 s (request")
    assert cert.check("e-stop").value == 1 and cert.figures["estop_count"] == 1
    d = json.loads(json.dumps(cert.to_dict()))
    assert d["stops"][0]["trigger"] == "request" and d["stops"][0]["stayed_up"] is True
    assert any(e.kind == "estop" and "stayed up" in e.message for e in ex.events)


def test_flag_file_and_sigusr1_stop_the_run(talos, tmp_path):
    """A flag file that appears, and SIGUSR1 through ``wbmp solve``'s handler, stop the run at the next check."""
    from wbmp.commands.solve import _stop_on_sigusr1

    plan = standing_plan(talos, duration=1.0)
    flag = tmp_path / "stop"
    seen: list[str] = []

    def touch(message: str) -> None:
        if message.startswith("simulated") and not flag.exists():
            seen.append(message)
            flag.write_text("")

    ex = simulate(plan, talos, settings=SETTLE, progress=touch,
                  estop=EStopSettings(flag_file=str(flag), hold_time=0.3))
    stop = ex.stops[0]
    assert stop.trigger == "request" and "flag file" in stop.detail and stop.stayed_up
    assert 0.05 < stop.time < 0.4  # the first progress message (a tenth of the run) plus one flag period

    class Request:
        stop_request = None

    request = Request()
    old = signal.getsignal(signal.SIGUSR1)
    try:
        _stop_on_sigusr1(request)
        sent: list[bool] = []

        def kill(message: str) -> None:
            if message.startswith("simulated") and not sent:
                sent.append(True)
                os.kill(os.getpid(), signal.SIGUSR1)

        ex = simulate(plan, talos, settings=SETTLE, progress=kill,
                      estop=EStopSettings(request=request.stop_request, hold_time=0.3))
    finally:
        signal.signal(signal.SIGUSR1, old)
    stop = ex.stops[0]
    assert stop.trigger == "request" and stop.detail == "SIGUSR1 received" and stop.response == "stand"
    assert stop.stayed_up and stop.time < 0.5


def test_tilt_beyond_the_limit_damps_every_joint(talos):
    """A push that tips the base past 0.5 rad: damping mode at once, the damping law on every tick after.
    (The QP trigger is set apart: while talos topples, its controller's QP fails 3 ticks in a row at a
    pitch of 0.16 rad, 0.52 s, and that trigger would fire first; this test is the tilt's.)"""
    plan = standing_plan(talos, duration=1.0)
    faults = faults_from_dict({"pushes": [{"t": 0.3, "impulse": 80, "direction": [1, 0, 0]}]})
    ex = simulate(plan, talos, settings=SETTLE, estop=EStopSettings(hold_time=0.5, qp_failures=10_000), faults=faults)
    stop = ex.stops[0]
    # a forward push, but the toppling body may pass the limit in roll first (it did with the CoM weight 50)
    assert stop.trigger == "tilt" and stop.response == "damp" and ("pitch" in stop.detail or "roll" in stop.detail)
    i = int(np.searchsorted(ex.t, stop.time - 1e-9))

    def tilt(q):
        return float(np.abs(pin.rpy.matrixToRpy(pin.Quaternion(q[6], *q[3:6]).toRotationMatrix())[:2]).max())

    # the limit is 0.5 rad beyond the plan's own largest tilt (a standing plan's: well under a mrad)
    limit = 0.5 + max(tilt(q) for q in plan.q)
    assert limit < 0.51 and tilt(ex.q[i]) > limit - 1e-6 and tilt(ex.q[i - 1]) < limit + 1e-6  # the first tick past it
    assert _damped_after(ex, stop.time) < 1e-9


def test_failed_qp_stands_then_damps(talos):
    """A controller whose QP gives up (one proxsuite iteration): after three failed ticks the E-stop fires;
    the stand's QP fails too, so every joint is damped from that very tick (not the last torque)."""
    plan = standing_plan(talos, duration=0.5)
    s = SimSettings(settle_time=0.1, wbc=WbcSettings(fast_path=False, max_iter=1, max_iter_in=1))
    ex = simulate(plan, talos, settings=s, estop=EStopSettings(hold_time=0.2))
    stop = ex.stops[0]
    assert stop.trigger == "qp_failure" and stop.response == "damp" and stop.escalated
    assert stop.time == pytest.approx(0.002)  # failed on ticks 0, 1, 2
    assert _damped_after(ex, stop.time) < 1e-9


def test_torque_at_its_limit_fires(talos):
    """With the controller allowed 20 % of each torque limit, an arm joint sits at that cap: after the
    window the E-stop fires on it."""
    plan = standing_plan(talos, duration=1.0)
    s = SimSettings(settle_time=0.2, wbc=WbcSettings(torque_scale=0.2))
    ex = simulate(plan, talos, settings=s, estop=EStopSettings(hold_time=0.3, torque_window=0.1))
    stop = ex.stops[0]
    assert stop.trigger == "torque_limit" and "torque limit for 0.10 s" in stop.detail
    assert stop.time == pytest.approx(0.1, abs=0.01)


def test_nan_torque_damps_at_once(talos, monkeypatch):
    """A controller that returns NaN at 0.3 s (fault injection into the real controller): damping on that tick."""
    real = WholeBodyController.compute

    def broken(self, t, q, v, reference):
        tau = real(self, t, q, v, reference)
        return tau * np.nan if abs(t - 0.3) < 5e-4 else tau

    monkeypatch.setattr(WholeBodyController, "compute", broken)
    plan = standing_plan(talos, duration=1.0)
    ex = simulate(plan, talos, settings=SETTLE, estop=EStopSettings(hold_time=0.3))
    stop = ex.stops[0]
    assert stop.trigger == "nan" and stop.response == "damp" and stop.time == pytest.approx(0.3)
    assert np.all(np.isfinite(ex.tau))
    assert _damped_after(ex, stop.time) < 1e-9


def test_no_stop_without_a_trigger(free_run):
    """The free squat: no E-stop, a passing certificate with its figures."""
    assert free_run.stops == () and free_run.certificate.ok, free_run.certificate.summary()
    assert free_run.certificate.figures["estop_count"] == 0


def test_the_stop_travels_in_the_motion_file_the_bag_and_the_replay(talos, squat, stopped_run, tmp_path):
    """The motion file's report holds the stop and the events, the ROS 2 bag has one message on
    /wbmp/execution/estop at the stop's time, and the HTML replay's subtitle names it."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    from viz.html import _subtitle
    from wbmp.export.rosbag import BagOptions, write_bag
    from wbmp.motionfile import load_motion
    from wbmp.pipeline import SolveResult, result_arrays

    result = SolveResult(robot=talos, spec=squat.spec, plan=squat, execution=stopped_run)
    path = tmp_path / "stopped.npz"
    np.savez(path, **result_arrays(result))
    motion = load_motion(path)
    (stop,) = motion.report["certificate"]["stops"]
    assert stop["trigger"] == "request" and stop["time"] == pytest.approx(0.6) and stop["stayed_up"]
    assert any(e["kind"] == "estop" for e in motion.report["events"])
    assert motion.report["certificate"]["figures"]["estop_count"] == 1
    bag = tmp_path / "stopped.mcap"
    with bag.open("wb") as fh:
        write_bag(fh, motion, BagOptions(stamp=100.0))
    with bag.open("rb") as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        found = [(m.log_time, json.loads(d.data)) for _, ch, m, d in reader.iter_decoded_messages()
                 if ch.topic == "/wbmp/execution/estop"]
    assert len(found) == 1 and found[0][0] == 100_600_000_000 and found[0][1]["trigger"] == "request"
    assert "E-stop at t = 0.600 s" in _subtitle("talos", squat, stopped_run)


def test_a_stop_in_single_support_runs_on_to_double_support(talos):
    """A stop at 0.5 s while the plan stands on its right foot (0.4-1.0 s): the plan runs on to its next
    double-support sample (1.0 s), whose posture is then held; the robot stays up."""
    from sim.handmade import ik_plan

    plan = ik_plan(talos, duration=1.5, name="phases", phases=(
        ("stand", 0.4, ("left_foot", "right_foot")), ("right only", 0.6, ("right_foot",)),
        ("stand again", 0.5, ("left_foot", "right_foot"))))
    ex = simulate(plan, talos, settings=SETTLE, estop=EStopSettings(at=0.5, hold_time=0.8))
    stop = ex.stops[0]
    assert (stop.trigger, stop.response, stop.stayed_up) == ("request", "stand", True)
    assert stop.posture_time == pytest.approx(1.0, abs=2e-3) and stop.hold_from == pytest.approx(1.0, abs=2e-3)
    assert "ran on to the plan's double-support posture of t = 1.00 s" in stop.describe()


def test_g1_stops_and_stands(g1):
    """The same stop on G1 (33 kg, four contact spheres a sole): it stands still in the squat's posture of
    0.5 s, its CoM as low as the plan's there."""
    plan = squat_plan(g1, depth=0.08, duration=1.5)
    ex = simulate(plan, g1, settings=SETTLE, estop=EStopSettings(at=0.5, hold_time=0.8))
    stop = ex.stops[0]
    assert (stop.trigger, stop.response, stop.stayed_up) == ("request", "stand", True)
    assert np.abs(ex.v[-1]).max() < 0.1
    ref = WholeBodyController(g1).reference_for(plan)
    planned = ref.com[ref.index(0.5), 2]
    assert abs(ex.com[-1, 2] - planned) < 0.015


def test_the_tick_finiteness_test_agrees_with_numpy_entry_by_entry():
    rng = np.random.default_rng(3)
    cases = [np.zeros(0), rng.normal(size=40), np.array([1e308, 1e308, -5.0]),
             np.array([-1e308, -1e308]), np.array([np.inf, -np.inf, 1.0]), np.array([1e308, 1e308, np.nan])]
    for bad in (np.nan, np.inf, -np.inf):
        x = rng.normal(size=40)
        x[17] = bad
        cases.append(x)
    for a in cases:
        assert finite(a) == bool(np.all(np.isfinite(a))), a
