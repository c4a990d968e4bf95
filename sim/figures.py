"""The evaluation figures of a simulated motion: time, energy, torque use, smoothness, feet, tracking.

Each figure is defined in docs/safety.md; :func:`figures` computes them from a run's record (one row
per controller tick, the torque of a tick held until the next), :func:`summarize_figures` turns the figures
of many runs into a table's numbers (``wbmp batch``).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping

import numpy as np
import pinocchio as pin

from sim.recording import RunRecord, torque_fraction

#: The figures, in the order reports print them: key -> (unit, what it is).
FIGURES: dict[str, tuple[str, str]] = {
    "execution_time": ("s", "simulated time from the start to the end of the run"),
    "work": ("J", "net mechanical work of the joint torques, integral of tau . qdot"),
    "abs_work": ("J", "work without regeneration, integral of sum |tau_j qdot_j|"),
    "torque_squared": ("N2m2s", "integral of sum tau_j^2 (the Joule losses' proxy)"),
    "peak_torque_ratio": ("-", "largest |tau_j| / limit_j"),
    "rms_torque_ratio": ("-", "RMS of tau_j / limit_j over joints and ticks"),
    "rms_jerk": ("rad/s3", "RMS joint jerk (third derivative of the joint angles, 10 ms grid)"),
    "foot_skate": ("mm", "horizontal travel of the soles while they touch the floor, summed"),
    "foot_float": ("mm", "highest sole frame above the floor where the plan has it in contact"),
    "foot_penetration": ("mm", "deepest sole frame below the floor"),
    "com_error_rms": ("mm", "RMS distance of the CoM from its reference (until an E-stop)"),
    "com_error_max": ("mm", "largest distance of the CoM from its reference (until an E-stop)"),
    "hand_error_rms": ("mm", "RMS distance of the hands from their references (until an E-stop)"),
    "hand_error_max": ("mm", "largest distance of a hand from its reference (until an E-stop)"),
    "estop_count": ("-", "E-stops during the run"),
}
#: Grid of the jerk figure [s] (the 1 kHz record's contact impacts would dominate a finer one).
JERK_PERIOD = 0.01


def _integrals(t: np.ndarray, v: np.ndarray, tau: np.ndarray, dt: float) -> tuple[float, float, float]:
    """Work, work without regeneration and integral of tau^2: each tick's torque held for ``dt``
    (its last tick too), the joint speed of the tick's start (rectangle rule, as the loop applies)."""
    if not len(t):
        return 0.0, 0.0, 0.0
    qd = v[:, 6:]
    power = tau * qd
    return float(power.sum() * dt), float(np.abs(power).sum() * dt), float((tau * tau).sum() * dt)


def _jerk(q: np.ndarray, dt: float) -> float:
    step = max(1, int(round(JERK_PERIOD / dt)))
    joints = q[::step, 7:]
    if len(joints) < 4:
        return 0.0
    h = step * dt
    jerk = np.diff(joints, n=3, axis=0) / h**3
    return float(np.sqrt(np.mean(jerk * jerk)))


def figures(run: RunRecord, *, estops: int = 0, stop_time: float | None = None) -> dict[str, float]:
    """Every figure of :data:`FIGURES` for the run (tracking only before ``stop_time`` [s])."""
    robot, ref = run.robot, run.ref
    n = run.n_ticks
    dt = float(run.t[1] - run.t[0]) if n >= 2 else ref.dt
    out: dict[str, float] = {"execution_time": float(run.t[-1] - run.t[0] + dt) if n else 0.0}
    out["work"], out["abs_work"], out["torque_squared"] = _integrals(run.t, run.v, run.tau, dt)
    frac = torque_fraction(run.tau, run.torque_limits) if n else np.zeros((0, 0))
    out["peak_torque_ratio"] = float(frac.max()) if frac.size else 0.0
    out["rms_torque_ratio"] = float(np.sqrt(np.mean(frac * frac))) if frac.size else 0.0
    out["rms_jerk"] = _jerk(run.q, dt)
    model = robot.model
    data = model.createData()
    feet = [robot.frame_id(f) for f in run.foot_frames]
    hands = [robot.frame(r) for r in ("left_hand", "right_hand") if robot.has_role(r)]
    hands = [h for h in hands if h in ref.frames]
    hand_ids = [robot.frame_id(h) for h in hands]
    sole = np.empty((len(feet), n, 3))
    hand = np.empty((len(hands), n, 3))
    for i in range(n):
        pin.framesForwardKinematics(model, data, run.q[i])
        for j, fid in enumerate(feet):
            sole[j, i] = data.oMf[fid].translation
        for j, fid in enumerate(hand_ids):
            hand[j, i] = data.oMf[fid].translation
    knots = np.array([ref.index(float(t)) for t in run.t], dtype=int)
    skate = 0.0
    floating = 0.0
    for j, name in enumerate(run.foot_frames):
        touching = run.contact_flags[j]
        both = touching[1:] & touching[:-1]
        step = np.linalg.norm(np.diff(sole[j, :, :2], axis=0), axis=1)
        skate += float(step[both].sum()) if len(step) else 0.0
        col = ref.contact_frames.index(name) if name in ref.contact_frames else None
        if col is not None:
            planned = ref.active[knots, col]
            if stop_time is not None:
                planned = planned & (run.t < stop_time)
            if planned.any():
                floating = max(floating, float(sole[j, planned, 2].max()))
    out["foot_skate"] = 1000.0 * skate
    out["foot_float"] = 1000.0 * max(0.0, floating)
    out["foot_penetration"] = 1000.0 * max(0.0, -float(sole[:, :, 2].min())) if sole.size else 0.0
    until = run.t < stop_time if stop_time is not None else np.ones(n, dtype=bool)
    com_err = np.linalg.norm(run.com[until] - ref.com[knots[until]], axis=1)
    out["com_error_rms"] = 1000.0 * float(np.sqrt(np.mean(com_err**2))) if len(com_err) else 0.0
    out["com_error_max"] = 1000.0 * float(com_err.max()) if len(com_err) else 0.0
    if hands and until.any():
        errs = np.stack([np.linalg.norm(hand[j, until] - ref.frames[h].position[knots[until]], axis=1)
                         for j, h in enumerate(hands)])
        out["hand_error_rms"] = 1000.0 * float(np.sqrt(np.mean(errs**2)))
        out["hand_error_max"] = 1000.0 * float(errs.max())
    else:
        out["hand_error_rms"] = out["hand_error_max"] = 0.0
    out["estop_count"] = float(estops)
    return out


def summarize_figures(runs: Iterable[tuple[bool, Mapping[str, float]]]) -> dict[str, float]:
    """Over many runs (passed?, figures): ``success_rate`` [-], ``runs``, and the mean of every figure
    (``mean_<key>``) over the runs that have it; E-stops are summed (``estop_count``)."""
    rows = list(runs)
    out: dict[str, float] = {"runs": float(len(rows))}
    out["success_rate"] = sum(1 for ok, _ in rows if ok) / len(rows) if rows else math.nan
    for key in FIGURES:
        vals = [float(f[key]) for _, f in rows if key in f and f[key] is not None and math.isfinite(float(f[key]))]
        if key == "estop_count":
            out[key] = float(sum(vals))
        else:
            out[f"mean_{key}"] = float(np.mean(vals)) if vals else math.nan
    return out
