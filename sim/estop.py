"""The software E-stop of the closed loop: what triggers it, and the controlled stop that follows.

Triggers (checked every controller tick, on what the controller measured):

* a stop request: a time (``EStopSettings.at``), a flag file that appears, or a
  :class:`StopRequest` set from outside (``wbmp solve`` sets one on SIGUSR1);
* the base's roll or pitch beyond ``max_roll_pitch`` (or beyond the plan's own tilt plus it);
* the controller's QP failing on ``qp_failures`` ticks in a row;
* a joint torque at the controller's cap for longer than ``torque_window`` (off unless set);
* a NaN or infinity in the measured state or in the torques.

Response, decided on the tick of the trigger (the torque sent on that tick is already the stop's):

* **stand** (a stop request, a torque at its limit, a failed QP): the controller keeps balance while
  the reference is frozen at the current double-support posture of the plan, or, in single support
  or a flight, the plan runs on to its next double-support posture (at most ``lookahead``) and is
  frozen there. The frozen posture is a new, static reference (:func:`stand_reference`) with the
  plan's base moved over the soles where they really are; the controller restarts on it, its soles
  anchored where they stand;
* **damp** (a tilt past the limit, a NaN, or a failure during the stand): every joint gets
  :math:`\\tau_j = -k_{d,j} \\dot q_j` (kp = 0, ``k_{d,j} = damping`` times the joint's torque limit),
  never the last torque held.

:class:`EStop` holds the state of one run; :class:`Stop` is the record the certificate reports.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from sim.exceptions import SimError

if TYPE_CHECKING:
    from planner import PlanReference
    from robots import Robot

#: The triggers, as named in the certificate, the events and docs/safety.md.
TRIGGERS = ("request", "tilt", "qp_failure", "torque_limit", "nan")


class StopRequest:
    """A stop asked for from outside the loop (a signal handler, another thread): thread-safe."""

    def __init__(self) -> None:
        self._event = threading.Event()
        self.source = ""

    def request(self, source: str = "a stop request") -> None:
        """Ask the running loop to stop (it reacts on its next tick)."""
        self.source = source
        self._event.set()

    def __bool__(self) -> bool:
        return self._event.is_set()


@dataclass(frozen=True, slots=True, kw_only=True)
class EStopSettings:
    """When the E-stop fires and how it stops.

    Attributes:
        at: Stop request at this time [s] (None: none).
        flag_file: Stop when this file exists (checked every ``flag_period`` of simulated time).
        request: A :class:`StopRequest` set from outside (SIGUSR1 in ``wbmp solve``).
        flag_period: How often the flag file is looked for [s].
        max_roll_pitch: Base roll or pitch beyond this fires the E-stop [rad]; a plan that itself
            tilts the base more gets its own largest tilt plus this.
        qp_failures: Consecutive ticks with a failed controller QP that fire it [-].
        torque_window: A joint torque at the controller's cap this long fires it [s]; None (the
            default) watches no torque: an arm held out at its cap is a motion the certificate
            judges, and a stop there (stand, then damping) made a certified dance fall.
        hold_time: Simulated time after the stop before the run ends [s].
        lookahead: Longest run-on of the plan to its next double-support posture [s].
        damping: Damping mode's gain per unit torque limit: :math:`k_{d,j} = ` damping
            :math:`\\cdot \\tau_{max,j}` [s/rad] (0.1: G1's hip pitch, 88 N m, gets 8.8 N m s/rad).
        automatic: Watch the automatic triggers (tilt, QP, torque); requests and NaNs always count.
    """

    at: float | None = None
    flag_file: str | None = None
    request: StopRequest | None = field(default=None, compare=False)
    flag_period: float = 0.01
    max_roll_pitch: float = 0.5
    qp_failures: int = 3
    torque_window: float | None = None
    hold_time: float = 1.5
    lookahead: float = 1.0
    damping: float = 0.1
    automatic: bool = True

    def __post_init__(self) -> None:
        if self.at is not None and not (math.isfinite(self.at) and self.at >= 0):
            raise SimError(f"E-stop: the stop time must be a finite time >= 0 s, got {self.at!r}")
        if self.flag_file is not None and not str(self.flag_file).strip():
            raise SimError("E-stop: the flag file must be a path, got an empty one")
        if not (self.flag_period > 0 and self.max_roll_pitch > 0 and self.qp_failures >= 1
                and (self.torque_window is None or self.torque_window > 0) and self.hold_time > 0 and self.lookahead >= 0
                and self.damping > 0):
            raise SimError("EStopSettings: flag_period, max_roll_pitch, torque_window, hold_time and damping "
                           "must be > 0, qp_failures >= 1, lookahead >= 0")


@dataclass(frozen=True, slots=True, kw_only=True)
class Stop:
    """One E-stop of a run.

    Attributes:
        time: Tick of the trigger [s].
        trigger: One of :data:`TRIGGERS`.
        detail: The trigger in words ("base pitch 0.52 rad > 0.50 rad").
        response: ``stand`` or ``damp`` (the final mode: a stand that failed ends in ``damp``).
        reaction_ticks: Ticks from the trigger to the first torque of the response (0: that tick).
        hold_from: When the frozen posture's reference began [s] (NaN: damping from the start).
        posture_time: The plan time whose posture was held [s] (NaN: none).
        escalated: Why a stand became damping ("" if it did not).
        stayed_up: No fall from the stop to the end of the run.
        rest_speed: Largest joint speed at the end of the run [rad/s].
    """

    time: float
    trigger: str
    detail: str
    response: str
    reaction_ticks: int = 0
    hold_from: float = math.nan
    posture_time: float = math.nan
    escalated: str = ""
    stayed_up: bool = True
    rest_speed: float = math.nan

    def describe(self) -> str:
        """One line: when, why, what the robot did, whether it stayed up."""
        if self.response == "stand" or self.escalated:
            did = f"stood in the plan's double-support posture of t = {self.posture_time:.2f} s"
            if self.hold_from > self.time + 1e-9:
                did = f"ran on to the plan's double-support posture of t = {self.posture_time:.2f} s and stood"
        else:
            did = "damped every joint"
        if self.escalated:
            did += f", then damped every joint ({self.escalated})"
        up = "stayed up" if self.stayed_up else "fell"
        return (f"E-stop at t = {self.time:.3f} s ({self.trigger}: {self.detail}); {did}; {up}"
                f" (joint speeds at the end <= {self.rest_speed:.2f} rad/s)")

    def to_dict(self) -> dict[str, object]:
        """JSON-friendly dict (NaN as None)."""
        def num(x: float) -> float | None:
            return float(x) if math.isfinite(x) else None

        return {"time": float(self.time), "trigger": self.trigger, "detail": self.detail,
                "response": self.response, "reaction_ticks": int(self.reaction_ticks),
                "hold_from": num(self.hold_from), "posture_time": num(self.posture_time),
                "escalated": self.escalated, "stayed_up": bool(self.stayed_up), "rest_speed": num(self.rest_speed),
                "message": self.describe()}


def damping_gains(torque_limits: np.ndarray, damping: float) -> np.ndarray:
    """Damping mode's joint gains [N m s/rad]: ``damping`` times each usable torque limit (1 N m s/rad
    for a joint without one)."""
    lim = np.asarray(torque_limits, dtype=float)
    usable = (lim > 0) & np.isfinite(lim)
    return np.where(usable, damping * lim, 1.0)


def damping_torque(v_joints: np.ndarray, kd: np.ndarray, limits: np.ndarray) -> np.ndarray:
    """:math:`-k_d \\dot q`, within the torque limits; a joint speed that is not finite gives 0."""
    v = np.where(np.isfinite(v_joints), v_joints, 0.0)
    return np.clip(-kd * v, -limits, limits)


def _double_support(robot: Robot, ref: PlanReference) -> np.ndarray:
    """(n,) both soles in contact at each sample of ``ref``."""
    feet = [robot.frame(r) for r in ("left_foot", "right_foot") if robot.has_role(r)]
    names = [robot.model.frames[robot.frame_id(f)].name for f in feet]
    if len(names) < 2 or not all(n in ref.contact_frames for n in names):
        return np.zeros(ref.n, dtype=bool)
    cols = [ref.contact_frames.index(n) for n in names]
    return np.all(ref.active[:, cols], axis=1)


def stand_sample(robot: Robot, ref: PlanReference, k: int, lookahead: float) -> int | None:
    """The sample whose posture a stop at sample ``k`` freezes: ``k`` in double support, else the next
    double-support sample within ``lookahead`` [s], else ``k`` when some contact is active (a stand on
    the current contacts), else the next sample with a contact; None when there is none (damping)."""
    ds = _double_support(robot, ref)
    end = min(ref.n, k + int(round(lookahead / ref.dt)) + 1)
    ahead = np.nonzero(ds[k:end])[0]
    if len(ahead):
        return k + int(ahead[0])
    touching = np.any(ref.active, axis=1) if ref.active.shape[1] else np.zeros(ref.n, dtype=bool)
    ahead = np.nonzero(touching[k:end])[0]
    return k + int(ahead[0]) if len(ahead) else None


def stand_reference(robot: Robot, ref: PlanReference, k: int, q: np.ndarray, *, hold: float = 1.0) -> PlanReference:
    """A static reference holding the plan's posture of sample ``k`` on its contacts there.

    The posture's base is moved horizontally by the offset between the measured stance soles
    (configuration ``q``) and the planned ones, so that the CoM is held over the feet where they
    really are (a push or a slip moves them away from the plan).
    """
    # imported here, not at the top: `wbmp solve` makes a StopRequest before its motion-cache read,
    # and a repeated request answered from the cache imports neither pinocchio nor the planner's
    # controller reference
    import pinocchio as pin

    from planner import Plan, PlanReference, SolverStats, SolveStatus
    from tasks import Phase, TaskSpec

    plan = ref.plan
    spec = plan.spec
    t_plan = float(ref.times[k])
    phase = spec.phases[spec.phase_at(t_plan)]
    q_star = np.array(ref.q[k], dtype=float)
    model = robot.model
    names = [model.frames[robot.frame_id(c.frame)].name for c in phase.contacts]
    if names:
        data = model.createData()
        pin.framesForwardKinematics(model, data, np.asarray(q, dtype=float))
        measured = np.mean([data.oMf[model.getFrameId(n)].translation for n in names], axis=0)
        planned = np.mean([ref.frames[n].position[k] for n in names if n in ref.frames], axis=0)
        q_star[:2] += (measured - planned)[:2]
    data = model.createData()
    com = pin.centerOfMass(model, data, q_star).copy()
    stand_spec = TaskSpec(robot=spec.robot, phases=(Phase(name="e-stop stand", duration=hold,
                                                          contacts=phase.contacts),),
                          dt=hold / 2.0, name="e-stop stand", description="hold the posture after an E-stop")
    nv = model.nv
    stand = Plan(robot=plan.robot, spec=stand_spec, t=np.array([0.0, hold]), q=np.stack([q_star, q_star]),
                 v=np.zeros((2, nv)), a=np.zeros((2, nv)), com=np.stack([com, com]),
                 stats=SolverStats(status=SolveStatus.SOLVED, backend="e-stop"))
    return PlanReference(stand, robot, dt=ref.dt)


def finite(a: np.ndarray) -> bool:
    """Whether every entry of ``a`` is finite (``np.all(np.isfinite(a))`` without the function
    wrapper: half the time, and the tick asks 3 to 4 times)."""
    return bool(np.isfinite(a).all())


def roll_pitch(q: np.ndarray) -> tuple[float, float]:
    """The base's roll and pitch [rad] of a configuration (quaternion x, y, z, w at 3:7)."""
    x, y, z, w = (float(c) for c in q[3:7])
    roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2.0 * (w * y - z * x))))
    return roll, pitch


class EStop:
    """The E-stop of one run: watches each tick and, once fired, gives the stop's torques.

    Args:
        settings: Triggers and response.
        robot: The robot.
        ref: The plan's reference.
        torque_limits: The simulated joint torque limits (nv - 6,) [N m].
        cap: The controller's torque cap (its limits) (nv - 6,) [N m].
        dt: The controller period [s].
    """

    def __init__(self, settings: EStopSettings, robot: Robot, ref: PlanReference, torque_limits: np.ndarray,
                 cap: np.ndarray, dt: float) -> None:
        self.s, self.robot, self.ref, self.dt = settings, robot, ref, dt
        self.limits = np.asarray(torque_limits, dtype=float)
        self.cap = np.asarray(cap, dtype=float)
        self.kd = damping_gains(self.limits, settings.damping)
        rp = np.array([roll_pitch(qk) for qk in ref.q[:: max(1, ref.n // 200)]]) if ref.n else np.zeros((1, 2))
        self.tilt_limit = max(settings.max_roll_pitch, float(np.abs(rp).max()) + settings.max_roll_pitch)
        self.mode = "run"  # run -> runon (plan to a double-support sample) -> stand | damp
        self.stop: Stop | None = None
        self._failing = 0
        self._failures_seen = 0
        self._at_cap_since: np.ndarray = np.full(len(self.cap), math.nan)
        self.watched = np.ones(len(self.cap), dtype=bool)  # joints the torque trigger watches
        self._next_flag = 0.0
        self._stand_k: int | None = None
        self.stand_ref: PlanReference | None = None
        self.stand_t0 = 0.0
        self._hold_from = math.nan
        self._escalated = ""

    # ------------------------------------------------------------------ triggers
    def _requested(self, t: float) -> str | None:
        s = self.s
        if s.at is not None and t >= s.at - 1e-9:
            return f"stop requested for t = {s.at:g} s"
        if s.request is not None and s.request:
            return s.request.source or "stop requested"
        if s.flag_file is not None and t >= self._next_flag - 1e-9:
            self._next_flag = t + s.flag_period
            if Path(s.flag_file).exists():
                return f"flag file {s.flag_file} appeared"
        return None

    def tilted(self, q: np.ndarray) -> str | None:
        """The base's roll or pitch beyond the limit, in words (None: within it)."""
        roll, pitch = roll_pitch(q)
        worst = max(abs(roll), abs(pitch))
        if worst > self.tilt_limit:
            which = "roll" if abs(roll) >= abs(pitch) else "pitch"
            return f"base {which} {worst:.2f} rad > {self.tilt_limit:.2f} rad"
        return None

    def check_state(self, t: float, q: np.ndarray, v: np.ndarray) -> tuple[str, str] | None:
        """Triggers seen in the measured state before the controller runs: (trigger, detail) or None."""
        if not (finite(q) and finite(v)):
            return "nan", "the measured state is not finite"
        why = self._requested(t)
        if why is not None:
            return "request", why
        if self.s.automatic:
            why = self.tilted(q)
            if why is not None:
                return "tilt", why
        return None

    def check_output(self, t: float, tau: np.ndarray, failures: int) -> tuple[str, str] | None:
        """Triggers seen in the controller's output: a NaN torque, failed QPs, a torque held at its cap."""
        if not finite(tau):
            return "nan", "the controller's torque is not finite"
        if not self.s.automatic:
            return None
        if failures > self._failures_seen:
            self._failing += 1
        else:
            self._failing = 0
        self._failures_seen = failures
        if self._failing >= self.s.qp_failures:
            return "qp_failure", f"the controller QP failed on {self._failing} ticks in a row"
        if self.s.torque_window is None:
            return None
        at_cap = (np.abs(tau) >= self.cap * (1.0 - 1e-3)) & self.watched
        self._at_cap_since = np.where(at_cap, np.where(np.isnan(self._at_cap_since), t, self._at_cap_since), math.nan)
        held = t - np.where(at_cap, self._at_cap_since, t)
        j = int(np.argmax(held))
        if held[j] >= self.s.torque_window - 1e-9:
            name = self.robot.joint_names[j]
            return "torque_limit", f"{name} at its torque limit for {held[j]:.2f} s"
        return None

    def ignore_joints(self, joints: list[int]) -> None:
        """Joints whose applied torque is not the controller's (a grasping gripper's drive,
        :mod:`sim.grasp`): the torque trigger does not watch them."""
        self.watched[np.asarray(joints, dtype=int)] = False

    def reset_failures(self, failures: int) -> None:
        """The controller restarted (its failure count went back to ``failures``)."""
        self._failures_seen = failures
        self._failing = 0

    # ------------------------------------------------------------------ response
    def fire(self, t: float, trigger: str, detail: str, q: np.ndarray) -> None:
        """Record the stop at tick ``t`` and choose its response."""
        k = self.ref.index(t)
        respond = "damp"
        if trigger in ("request", "torque_limit", "qp_failure"):
            k_star = stand_sample(self.robot, self.ref, k, self.s.lookahead)
            if k_star is not None:
                self._stand_k = k_star
                respond = "stand"
        self.stop = Stop(time=t, trigger=trigger, detail=detail, response=respond,
                         posture_time=float(self.ref.times[self._stand_k]) if respond == "stand" and self._stand_k is not None
                         else math.nan)
        self.mode = "runon" if respond == "stand" else "damp"
        self._at_cap_since[:] = math.nan
        self._failing = 0

    def stand_due(self, t: float) -> int | None:
        """In a run-on: the sample to freeze once the plan reached it (None: keep running the plan)."""
        if self.mode != "runon" or self._stand_k is None:
            return None
        return self._stand_k if self.ref.index(t) >= self._stand_k else None

    def begin_stand(self, t: float, q: np.ndarray) -> PlanReference:
        """Freeze the plan at the chosen sample (measured configuration ``q``): the reference to track."""
        assert self._stand_k is not None
        self.stand_ref = stand_reference(self.robot, self.ref, self._stand_k, q, hold=1.0)
        self.stand_t0 = t
        self._hold_from = t
        self._at_cap_since[:] = math.nan
        self.mode = "stand"
        return self.stand_ref

    def escalate(self, why: str) -> None:
        """The stand failed: damping from now on."""
        self._escalated = why
        self.mode = "damp"

    def damp(self, v: np.ndarray) -> np.ndarray:
        """Damping mode's torques for velocity ``v`` (nv,)."""
        return damping_torque(v[6:], self.kd, self.limits)

    def finish(self, stayed_up: bool, rest_speed: float) -> Stop | None:
        """The stop's record, with how it ended (None when the E-stop never fired)."""
        if self.stop is None:
            return None
        response = "damp" if self.mode == "damp" else "stand"
        return Stop(time=self.stop.time, trigger=self.stop.trigger, detail=self.stop.detail, response=response,
                    reaction_ticks=0, hold_from=self._hold_from, posture_time=self.stop.posture_time,
                    escalated=self._escalated, stayed_up=stayed_up, rest_speed=rest_speed)
