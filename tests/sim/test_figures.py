"""The evaluation figures against independent integrations of the recorded torques and motion."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim import SimSettings, simulate
from sim.estop import EStopSettings
from sim.figures import FIGURES, summarize_figures
from sim.handmade import squat_plan


@pytest.fixture(scope="module")
def squat_run(talos):
    return simulate(squat_plan(talos, depth=0.12, duration=1.5), talos, settings=SimSettings(settle_time=0.2),
                    estop=EStopSettings(hold_time=0.5))


def test_energy_against_an_independent_integration(squat_run):
    """The work from positions (sum of tau . dq over the ticks, no velocity used) and the trapezoid rule of
    tau^2 agree with the figures; a squat down and up does work both ways, so |work| > |net work|."""
    ex = squat_run
    fig = ex.figures
    dq = np.diff(ex.q[:, 7:], axis=0)
    work_from_positions = float(np.sum(ex.tau[:-1] * dq))
    assert fig["work"] == pytest.approx(work_from_positions, abs=0.02 * fig["abs_work"] + 0.5)
    tau2 = np.trapezoid(np.sum(ex.tau**2, axis=1), ex.t)
    dt = ex.t[1] - ex.t[0]
    assert fig["torque_squared"] == pytest.approx(tau2, rel=0.01, abs=float(np.sum(ex.tau[-1] ** 2)) * dt)
    assert fig["abs_work"] > abs(fig["work"]) + 10.0  # lowering 90 kg by 12 cm and raising it: ~100 J each way
    assert fig["execution_time"] == pytest.approx(ex.t[-1] + dt)


def test_torque_tracking_and_feet_figures(talos, squat_run):
    """Peak torque ratio = the certificate's peak torque; the CoM error is small for a passing squat; the
    soles stay on the floor (no float, under a millimetre of penetration)."""
    ex = squat_run
    fig = ex.figures
    assert ex.ok, ex.certificate.summary()
    assert set(fig) == set(FIGURES)
    assert fig["peak_torque_ratio"] == pytest.approx(ex.certificate.check("peak torque").value / 100, rel=1e-6)
    assert 0 < fig["rms_torque_ratio"] < fig["peak_torque_ratio"]
    assert fig["com_error_max"] <= 1000 * ex.certificate.check("CoM tracking error").value + 1e-6
    assert 0 <= fig["com_error_rms"] <= fig["com_error_max"] < 20.0
    assert fig["foot_float"] < 2.0 and fig["foot_penetration"] < 3.0 and fig["foot_skate"] < 5.0
    # the jerk from a 10 ms grid of the recorded joint angles, recomputed with a fourth-order stencil
    q = ex.q[::10, 7:]
    h = 10 * (ex.t[1] - ex.t[0])
    jerk = (q[4:] - 2 * q[3:-1] + 2 * q[1:-3] - q[:-4]) / (2 * h**3)
    assert fig["rms_jerk"] == pytest.approx(float(np.sqrt(np.mean(jerk**2))), rel=0.5)
    assert fig["estop_count"] == 0


def test_summary_over_runs():
    """The success rate and the means over runs that have a figure; E-stops are summed."""
    rows = [(True, {"work": 10.0, "estop_count": 0.0}), (False, {"work": 30.0, "estop_count": 1.0}),
            (True, {"estop_count": 1.0})]
    s = summarize_figures(rows)
    assert s["runs"] == 3 and s["success_rate"] == pytest.approx(2 / 3)
    assert s["mean_work"] == 20.0 and s["estop_count"] == 2.0
    assert math.isnan(s["mean_abs_work"]) and math.isnan(summarize_figures([])["success_rate"])
