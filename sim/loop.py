"""Closed-loop simulation: the whole-body controller tracks a Plan in MuJoCo, then certifies it.

:func:`simulate` builds the MuJoCo model and the controller, runs the loop (one controller tick
every ``control_every`` physics steps, the push applied to the base, the run stopped after a fall
or a controller that keeps failing), records every tick (:mod:`sim.recording`), and certifies the
record (:mod:`sim.certify`), adding whether the plan itself could balance (:mod:`sim.zmp`).

Every tick also goes through the software E-stop (:mod:`sim.estop`: a stop request, a tilt, failed
QPs, a torque held at its cap, a NaN; then a stand in the plan's nearest double-support posture or
damping), the run may be put through faults (:mod:`sim.faults`), and the certificate carries the
evaluation figures (:mod:`sim.figures`).
"""

from __future__ import annotations

import copy
import math
import time
from collections import deque
from collections.abc import Callable
from dataclasses import replace

import mujoco
import numpy as np

from planner import (
    Check,
    CheckKind,
    JointFriction,
    Plan,
    PlanReference,
    WholeBodyController,
    kernel_ready,
)
from robots import Robot
from sim.certificate import Certificate
from sim.certify import certify, planned_touch
from sim.estop import EStop, EStopSettings, Stop, finite
from sim.execution import Event, Execution
from sim.faults import Faults, apply_to_model, body_id
from sim.figures import figures
from sim.grasp import GraspRig
from sim.model import SimModel, build_model
from sim.push import Push, check_push_time
from sim.recording import BASE_BODY, Recorder, RunRecord, tilt, tilt_of, torque_fraction
from sim.settings import SimSettings
from sim.zmp import plan_zmp_excursion


def simulate(
    plan: Plan,
    robot: Robot,
    *,
    push: Push | None = None,
    settings: SimSettings | None = None,
    progress: Callable[[str], None] | None = None,
    estop: EStopSettings | None = None,
    faults: Faults | None = None,
) -> Execution:
    """Track ``plan`` with the whole-body controller in MuJoCo and certify the motion.

    The robot starts at rest in ``plan.q[0]``; the loop runs the plan's duration plus
    ``settings.settle_time`` (holding the last configuration), and stops early
    ``settings.stop_after_fall`` after a fall.

    Args:
        plan: The motion to execute.
        robot: The robot it was planned for.
        push: An optional force on the base; it must start within the plan (``PushParseError``).
        settings: Simulation and certificate options.
        progress: Called with a short message ("simulated 1.2 of 3.7 s") about ten times a run.
        estop: The E-stop's triggers and response (:mod:`sim.estop`); None: the automatic
            triggers with their defaults and no stop request.
        faults: Pushes, model errors, sensor noise, control delay (:mod:`sim.faults`); None: none.

    Returns:
        The execution, with its certificate.
    """
    if push is not None:
        check_push_time(push, float(plan.t[-1]))  # before any work
    s = settings if settings is not None else SimSettings()
    sm = build_model(robot, timestep=s.timestep, joint_friction=s.joint_friction, scene=plan.spec.scene,
                     floor_timeconst=s.floor_timeconst)
    if faults is not None and faults.changes_model:  # on a copy: the built model may be shared
        sm = replace(sm, model=copy.deepcopy(sm.model))
        apply_to_model(faults, sm.model, base_body=BASE_BODY, floor_geom=sm.floor_geom,
                       left_sole_geom=sm.sole_geoms.get("left_foot"))
    if faults is not None:
        for p in faults.pushes:
            body_id(sm.model, p.body, BASE_BODY)  # an unknown body: FaultsError before any work
    control_dt = s.timestep * s.control_every
    wbc_settings = replace(s.wbc, dt=control_dt)
    ctrl = WholeBodyController(robot, wbc_settings)
    if progress is not None and not kernel_ready():
        progress("compiling the controller's kernel (once per installation, about 15 s)")
    ref = ctrl.reference_for(plan)
    es = EStop(estop if estop is not None else EStopSettings(), robot, ref, sm.torque_limits,
               np.asarray(ctrl.torque_limits, dtype=float), control_dt)
    run, events, wall, rig = _closed_loop(sm, robot, ctrl, ref, s, plan.q[0], push, progress, plan,
                                          es=es, faults=faults)
    stop = _finish_stop(es, run)
    if stop is not None:
        events.append(Event(stop.time, "estop", stop.describe()))
    events += _run_events(run, wbc_settings.torque_scale)
    events += [Event(h.engaged_at, "grasp", f"the {h.side} hand holds the {h.grasp.object} ({h.how})"
                     + (f"; already inside the {h.grasp.object} as the gripper started to close: {', '.join(h.sunk)}"
                        if h.sunk else ""))
               for h in rig.held if h.engaged_at is not None]
    events.sort(key=lambda e: e.time)
    checks = certify(run, rig.poses()) + tuple(rig.checks())
    if stop is not None:
        checks += (_estop_check(stop),)
    certificate = _with_plan_zmp(Certificate.from_checks(checks), events, robot, plan)
    certificate = replace(certificate, figures=figures(run, estops=0 if stop is None else 1,
                                                       stop_time=None if stop is None else stop.time),
                          stops=() if stop is None else (stop.to_dict(),))
    return Execution(
        t=run.t,
        q=run.q,
        v=run.v,
        tau=run.tau,
        com=run.com,
        contact_forces={frame: run.forces[i] for i, frame in enumerate(run.foot_frames)},
        events=tuple(events),
        certificate=certificate,
        wall_time=wall,
        realtime_factor=(run.t[-1] + control_dt) / wall if wall > 0 else math.inf,
        tick_times=run.tick_times,
        timestep=s.timestep,
        joint_names=tuple(robot.joint_names),
        torque_limits=sm.torque_limits.copy(),
        objects={name: rig.pos[: rig.n, i].copy() for i, name in enumerate(rig.names)},
        object_orientations={name: rig.quat[: rig.n, i].copy() for i, name in enumerate(rig.names)},
        stops=() if stop is None else (stop,),
        faults=faults,
    )


def _finish_stop(es: EStop, run: RunRecord) -> Stop | None:
    """The E-stop's record with its outcome: no fall from the stop to the end, the joint speeds at the end."""
    if es.stop is None:
        return None
    after = run.t >= es.stop.time - 1e-12
    q_after = run.q[after]
    fell = bool(np.any(q_after[:, 2] < run.fall_height) or np.any(tilt(q_after[:, 3:7]) > run.max_tilt)) \
        if len(q_after) else False
    rest = float(np.abs(run.v[-1, 6:]).max()) if len(run.v) else math.nan
    return es.finish(stayed_up=not fell, rest_speed=rest)


def _estop_check(stop: Stop) -> Check:
    """The certificate's line for an E-stop: the motion did not complete (it fails), with the stop in words."""
    return Check(name="e-stop", kind=CheckKind.ESTOP, value=1.0, limit=0.0, unit="", time=stop.time, ok=False,
                 message=stop.describe(), subject=stop.trigger)


class _Watchdog:
    """Falls and controller failures during the loop: their events, and when to stop.

    Args:
        s: The settings (``stop_after_fall``, ``stop_after_qp_failure``).
        fall_height: A base below this height is a fall [m].
        max_tilt: A base tilted more than this is a fall [rad].
        events: The run's events, appended to.
    """

    def __init__(self, s: SimSettings, fall_height: float, max_tilt: float, events: list[Event]) -> None:
        self.s, self.fall_height, self.max_tilt, self.events = s, fall_height, max_tilt, events
        self.qp_failure_times: list[float] = []
        self._failures = 0
        self._failing_since: float | None = None
        self._fallen_at: float | None = None

    def controller_restarted(self) -> None:
        """The controller was reset (an E-stop's stand): its failure count starts again from 0."""
        self._failures = 0

    def tick(self, t: float, q: np.ndarray, failures: int) -> bool:
        """Note tick ``t`` [s] (configuration ``q``, the controller's failure count); True to stop."""
        if failures != self._failures:
            self._failures = failures
            self.qp_failure_times.append(t)
            self._failing_since = t if self._failing_since is None else self._failing_since
        else:
            self._failing_since = None
        if self._fallen_at is None and (q[2] < self.fall_height or tilt_of(q) > self.max_tilt):
            self._fallen_at = t
            self.events.append(
                Event(t, "fall", f"base height {q[2]:.2f} m, tilt {math.degrees(tilt(q[3:7])):.0f} deg")
            )
        if self._fallen_at is not None and t - self._fallen_at >= self.s.stop_after_fall:
            self.events.append(Event(t, "stopped", "simulation stopped after the fall"))
            return True
        since = self._failing_since
        if since is not None and t - since >= self.s.stop_after_qp_failure:
            self.events.append(
                Event(t, "stopped", f"simulation stopped: the controller QP failed on every tick since t = {since:.3f} s")
            )
            return True
        return False


def _step(m: mujoco.MjModel, d: mujoco.MjData, steps: int, pushes: list[tuple[int, float, float, np.ndarray]]) -> None:
    """``steps`` physics steps, each push ``(body, start [s], end [s], force [N])`` on its body while it lasts."""
    for _ in range(steps):
        if pushes:
            tt = d.time
            for body, *_ in pushes:
                d.xfrc_applied[body, :3] = 0.0
            for body, t0, t1, force in pushes:
                if t0 <= tt < t1:
                    d.xfrc_applied[body, :3] += force
        mujoco.mj_step(m, d)


def _pushes(m: mujoco.MjModel, push: Push | None, faults: Faults | None) -> list[tuple[int, float, float, np.ndarray]]:
    """The ``--push`` and the faults' pushes as ``(body, start, end, force)``."""
    out = []
    if push is not None:
        out.append((BASE_BODY, push.time, push.time + push.duration, push.force_in_world()))
    for p in faults.pushes if faults is not None else ():
        out.append((body_id(m, p.body, BASE_BODY), p.t, p.t + p.duration, p.force()))
    return out


class _Drive:
    """The controller's torque of a tick, or the E-stop's once it fired (:mod:`sim.estop`)."""

    def __init__(self, ctrl: WholeBodyController, ref: PlanReference, es: EStop, friction: JointFriction,
                 limits: np.ndarray, watch: _Watchdog, events: list[Event]) -> None:
        self.ctrl, self.ref, self.es, self.friction, self.limits = ctrl, ref, es, friction, limits
        self.watch, self.events = watch, events

    def _controller(self, t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        es = self.es
        if es.mode == "stand":
            assert es.stand_ref is not None
            ref, tr = es.stand_ref, t - es.stand_t0
        else:
            ref, tr = self.ref, t
        tau = self.ctrl.compute(tr, q, v, ref)
        if self.friction.active and finite(tau):  # the URDF's joint friction, which the QP lacks
            k = ref.index(tr)
            tau = self.friction.add(tau, q, v, ref.q[k], ref.v[k], self.limits)
        return tau

    def _stand(self, t: float, q: np.ndarray, v: np.ndarray) -> None:
        """Switch the controller to the frozen posture (its soles anchored where they stand)."""
        self.es.begin_stand(t, q)
        self.ctrl.reset(q, v)
        self.watch.controller_restarted()
        self.es.reset_failures(self.ctrl.failures)

    def tick(self, t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """The torque for tick ``t`` (measured state ``q``, ``v``)."""
        es = self.es
        if es.mode == "run":
            trig = es.check_state(t, q, v)
            if trig is not None:
                es.fire(t, *trig, q)
        elif es.mode in ("runon", "stand"):  # the stand fails on a state that is not finite or a tilt
            if not (finite(q) and finite(v)):
                es.escalate("the measured state is not finite")
            else:
                tilted = es.tilted(q)
                if tilted is not None:
                    es.escalate(tilted)
        if es.mode == "runon" and es.stand_due(t) is not None:
            self._stand(t, q, v)
        if es.mode == "damp":
            return es.damp(v)
        failures = self.ctrl.failures
        tau = self._controller(t, q, v)
        if es.mode != "run" and self.ctrl.failures > failures:  # a stop holds with a working controller only
            es.escalate("the controller QP failed during the stop")
            return es.damp(v)
        trig = es.check_output(t, tau, self.ctrl.failures)
        if trig is None:
            return tau
        if es.mode == "run":
            es.fire(t, *trig, q)
            if es.mode == "runon" and es.stand_due(t) is not None:
                self._stand(t, q, v)
                tau = self._controller(t, q, v)
                if self.ctrl.failures == 0 and finite(tau):
                    return tau
                es.escalate("the controller could not hold the posture")
            elif es.mode == "runon":
                # running on to a double-support posture: this tick's controller torque stands unless it failed
                if trig[0] != "qp_failure" and finite(tau):
                    return tau
                es.escalate("the controller failed while running on to a double-support posture")
        else:
            es.escalate(f"{trig[1]} during the stop")
        return es.damp(v)


def _closed_loop(
    sm: SimModel,
    robot: Robot,
    ctrl: WholeBodyController,
    ref: PlanReference,
    s: SimSettings,
    q0: np.ndarray,
    push: Push | None,
    progress: Callable[[str], None] | None,
    plan: Plan,
    *,
    es: EStop,
    faults: Faults | None = None,
) -> tuple[RunRecord, list[Event], float, GraspRig]:
    """Run the loop from rest in ``q0``: the run's record, its events so far, the wall time [s] and
    the grasps (:mod:`sim.grasp`: the welds engaged and the objects' record).

    The E-stop ``es`` watches every tick; once it fires the run goes on for its ``hold_time`` (past
    the plan's end if need be). The faults: their pushes, the noise on the joint angles the
    controller measures (the record keeps the true ones), the delay between a torque and its
    application (the record keeps the applied one)."""
    control_dt = s.timestep * s.control_every
    duration = ref.duration + s.settle_time
    n_plan = int(round(duration / control_dt)) + 1
    hold_ticks = int(round(es.s.hold_time / control_dt))
    n_ticks = n_plan + hold_ticks  # room for a stop at the very end
    rig = GraspRig(sm, robot, plan.spec, n_ticks)
    m, d = rig.model, rig.data()
    es.ignore_joints([int(gr.actuated) for gr in rig.grippers.values()])  # the rig drives them, not the controller
    if faults is not None and faults.changes_model:
        mujoco.mj_setConst(m, d)
    q = np.array(q0, dtype=float)
    v = np.zeros(robot.nv)
    sm.set_state(d, q, v)
    ctrl.reset(q, v)
    rec = Recorder(sm, robot, n_ticks, s, exempt=rig.exempt)
    events: list[Event] = []
    pushes = _pushes(m, push, faults)
    if push is not None:
        events.append(Event(push.time, "push", f"{push.force:g} N on the base for {push.duration:g} s"))
    for p in faults.pushes if faults is not None else ():
        events.append(Event(p.t, "push", f"{p.impulse:g} N s on {p.body} over {p.duration:g} s"))
    fall_height = float(np.min(ref.q[:, 2])) - s.fall_height_margin
    max_tilt = float(np.max(tilt(ref.q[:, 3:7]))) + s.max_tilt
    watch = _Watchdog(s, fall_height, max_tilt, events)
    friction = JointFriction(robot, ctrl.settings.friction_compensation)
    limits = np.asarray(ctrl.torque_limits, dtype=float)
    drive = _Drive(ctrl, ref, es, friction, limits, watch, events)
    noise = faults.joint_noise if faults is not None else 0.0
    rng = np.random.default_rng(faults.seed if faults is not None else 0)
    delay = faults.delay_ticks if faults is not None else 0
    queue: deque[np.ndarray] = deque()
    q_meas = np.empty_like(q)
    report_every = max(1, n_plan // 10)
    end = n_plan
    wall0 = time.perf_counter()
    i = 0
    t = 0.0
    while i < end:
        t = i * control_dt
        sm.state(d, q, v)
        tic = time.perf_counter()
        if noise:
            q_meas[:] = q
            q_meas[7:] += rng.normal(0.0, noise, len(q) - 7)
        fired = es.stop is not None
        tau = drive.tick(t, q_meas if noise else q, v)
        if not fired and es.stop is not None:
            end = min(n_ticks, i + hold_ticks + 1)
        if delay:
            queue.append(tau)
            tau = queue.popleft() if len(queue) > delay else np.zeros_like(tau)
        tau = rig.drive(t, d, tau)  # a grasping hand's gripper closes on its object (sim/grasp.py)
        tick_time = time.perf_counter() - tic
        d.ctrl[sm.actuator_select] = tau
        rec.record(i, t, q, v, tau, d, tick_time)
        rig.tick(t, d)
        if watch.tick(t, q, ctrl.failures):
            break
        _step(m, d, s.control_every, pushes)
        if progress is not None and i % report_every == 0 and i > 0:
            progress(f"simulated {t:.1f} of {(end - 1) * control_dt:.1f} s")
        i += 1
    wall = time.perf_counter() - wall0
    if progress is not None:
        progress(f"simulated {rec.t[rec.n - 1] if rec.n else 0.0:.1f} s in {wall:.1f} s; certifying")
    run = rec.finish(robot=robot, ref=ref, settings=s, qp_failure_times=watch.qp_failure_times,
                     torque_limits=sm.torque_limits, fall_height=fall_height, max_tilt=max_tilt)
    return run, events, wall, rig


def _run_events(run: RunRecord, torque_scale: float) -> list[Event]:
    """Events found in the record: QP failures, the first saturated torque, each body's first unplanned contact."""
    events: list[Event] = []
    failures = run.qp_failure_times
    if failures:
        events.append(
            Event(failures[0], "qp_failure", f"the QP failed on {len(failures)} ticks (first at t = {failures[0]:.3f} s)")
        )
    frac = torque_fraction(run.tau, run.torque_limits)
    # saturated: over the certificate's limit, or at the controller's own cap (WbcSettings.torque_scale)
    cap = min(run.settings.torque_fraction_limit, torque_scale - 1e-3)
    saturated = np.nonzero(frac.max(axis=1) > cap)[0] if len(run.tau) else np.zeros(0, dtype=int)
    if len(saturated):
        n0 = int(saturated[0])
        j0 = int(np.argmax(frac[n0]))
        events.append(
            Event(
                float(run.t[n0]), "torque_limit", f"{run.robot.joint_names[j0]} at {100 * frac[n0, j0]:.0f}% of its torque limit"
            )
        )
    seen_bodies: set[str] = set()
    for t_c, body in run.other_contacts:
        if body not in seen_bodies:
            seen_bodies.add(body)
            events.append(Event(t_c, "unplanned_contact", f"{body} touched the floor"))
    seen_objects: set[tuple[str, str]] = set()
    for tick, link, obj, _ in run.scene_contacts:
        if (link, obj) not in seen_objects and not planned_touch(run, tick, link, obj):
            seen_objects.add((link, obj))
            events.append(Event(float(run.t[tick]), "unplanned_contact", f"{link} touched {obj!r}"))
    return events


def _with_plan_zmp(certificate: Certificate, events: list[Event], robot: Robot, plan: Plan) -> Certificate:
    """When the plan's own ZMP leaves its support polygon: a ``plan_zmp`` event (into ``events``, kept
    in time order) and, on a failed certificate, the reason says that the plan itself could not balance."""
    zmp = plan_zmp_excursion(robot, plan)
    if zmp is None:
        return certificate
    events.append(Event(zmp[1], "plan_zmp", f"the plan's ZMP leaves the support polygon by {zmp[0]:.3f} m"))
    events.sort(key=lambda e: e.time)
    if certificate.ok:
        return certificate
    return replace(
        certificate,
        reason=(
            f"{certificate.reason}; the plan itself is dynamically infeasible: its ZMP leaves the support "
            f"polygon by {zmp[0]:.3f} m at t = {zmp[1]:.2f} s"
        ),
    )
