"""The certificate's target orientation check measures only the ticks where the target applies
(sim/certify.py ``target_checks``; session 17 computed the error there alone): the angle against
an independent one (arccos of the relative rotation's trace), and the ticks outside ignored."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pinocchio as pin

from sim.certify import target_checks
from tasks.specs import FrameTarget


def _rz(a: float) -> np.ndarray:
    return pin.rpy.rpyToMatrix(0.0, 0.0, a)


def _checks(off_at: float, off_elsewhere: float):
    ts = np.arange(0, 1001) * 1e-3
    target = FrameTarget(name="heading", frame="base", position=(0.0, 0.0, 1.0), rpy=(0.0, 0.0, 0.3),
                         time=0.5, tolerance=0.1, orientation_tolerance=0.05)
    rots = np.array([_rz(0.3 + off_elsewhere)] * len(ts))
    rots[500] = _rz(0.3 + off_at)
    run = SimpleNamespace(t=ts, settings=SimpleNamespace(target_margin=0.05),
                          ref=SimpleNamespace(plan=SimpleNamespace(spec=SimpleNamespace(targets=(target,))), duration=1.0))
    meas = SimpleNamespace(target_frames={"heading": 3}, target_pos={3: np.tile([0.0, 0.0, 1.0], (len(ts), 1))},
                           target_rot={3: rots})
    (check,) = target_checks(run, meas)
    return check


def _angle(a: float) -> float:  # the independent reference: arccos((trace - 1) / 2)
    R = _rz(0.3).T @ _rz(0.3 + a)
    return math.acos(min(1.0, (np.trace(R) - 1.0) / 2.0))


def test_the_orientation_off_where_the_target_holds_fails_and_elsewhere_does_not_count():
    limit = 0.05 + 0.1  # orientation_tolerance + the certificate's 0.1 rad
    assert _angle(0.12) < limit < _angle(0.2)
    assert _checks(0.12, 2.0).ok  # 2 rad off away from t = 0.5 s: ignored
    failed = _checks(0.2, 0.0)
    assert not failed.ok
    assert "orientation off by 0.20 rad" in failed.message
    assert failed.time == 0.5
