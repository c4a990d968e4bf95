"""Closed-loop simulation: the whole-body controller tracks a Plan in MuJoCo, then certifies it."""

from __future__ import annotations

import math
import re
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import mujoco
import numpy as np
import pinocchio as pin

from planner import Plan
from planner.wbc import WbcSettings, WholeBodyController
from planner.wbc.kernel import kernel_ready
from planner.wbc.reference import PlanReference
from robots.model import Robot
from sim.certificate import Certificate, Check
from sim.exceptions import PushParseError, SimError
from sim.execution import Event, Execution
from sim.model import SimModel, build_model

_NUMBER = r"[-+]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][-+]?\d+)?|[-+]?(?:nan|inf|infinity)"
#: ``FORCE@TIME`` with optional units (``80N@1.5s``); ASCII digits only (``re.ASCII``: no Arabic
#: or full-width digits), and case-insensitive so that ``nan``/``inf`` reach the range check.
_PUSH_RE = re.compile(
    rf"^\s*({_NUMBER})\s*(?:N)?\s*@\s*({_NUMBER})\s*(?:s)?\s*$", re.ASCII | re.IGNORECASE
)
#: Largest push force [N]. Talos weighs 93 kg (910 N): a 0.1 s push of 5000 N gives it about
#: 5 m/s, far past any recovery; larger forces say nothing more about the controller.
MAX_PUSH_FORCE = 5000.0
#: Longest push [s] (a push is a short disturbance, not a steady wind).
MAX_PUSH_DURATION = 10.0
_PUSH_FORM = "FORCE@TIME, e.g. 80@1.5 = 80 N on the base at t = 1.5 s"


def _quote(text: str, limit: int = 40) -> str:
    """``text`` for a message: control characters escaped (repr), cut to ``limit`` characters."""
    if len(text) <= limit:
        return repr(text)
    return f"{text[:limit]!r}... ({len(text)} characters)"


@dataclass(frozen=True, slots=True)
class Push:
    """A force applied to the base during the simulation.

    Attributes:
        force: Magnitude [N], in (0, :data:`MAX_PUSH_FORCE`].
        time: Start [s], >= 0; it must fall within the motion (:func:`check_push_time`).
        duration: Length [s], in (0, :data:`MAX_PUSH_DURATION`].
        direction: Direction in the world (normalized on use).

    Raises:
        PushParseError: A value out of range (a one-line message naming it and the range).
    """

    force: float
    time: float
    duration: float = 0.1
    direction: tuple[float, float, float] = (1.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        if not (_real(self.force) and 0.0 < self.force <= MAX_PUSH_FORCE):
            raise PushParseError(
                f"push: the force must be above 0 N and at most {MAX_PUSH_FORCE:g} N, got {_value(self.force)} N"
            )
        if not (_real(self.time) and math.isfinite(self.time) and self.time >= 0.0):
            raise PushParseError(f"push: the time must be at least 0 s (within the motion), got {_value(self.time)} s")
        if not (_real(self.duration) and 0.0 < self.duration <= MAX_PUSH_DURATION):
            raise PushParseError(
                f"push: the duration must be above 0 s and at most {MAX_PUSH_DURATION:g} s, got {_value(self.duration)} s"
            )
        try:
            d = np.asarray(self.direction, dtype=float)
        except (TypeError, ValueError):
            d = np.zeros(0)
        if d.shape != (3,) or not np.all(np.isfinite(d)) or not np.linalg.norm(d) > 0:
            raise PushParseError(
                f"push: the direction must be a non-zero, finite 3-vector, got {self.direction!r}"
            )

    def force_in_world(self) -> np.ndarray:
        """The force vector [N]."""
        d = np.asarray(self.direction, dtype=float)
        return self.force * d / np.linalg.norm(d)


def _real(x: object) -> bool:
    """A real number (int or float, not bool), NaN included (the range checks refuse it)."""
    return isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(x, (bool, np.bool_))


def _value(x: object) -> str:
    return f"{x:g}" if _real(x) else repr(x)


def parse_push(text: str) -> Push:
    """Parse ``FORCE@TIME`` (``"80@1.5"``: 80 N at t = 1.5 s for 0.1 s along +x).

    Units may be written (``80N@1.5s``). The force must be above 0 N and at most
    :data:`MAX_PUSH_FORCE`; the time at least 0 s (and, once the motion is known, before its
    end: :func:`check_push_time`).

    Raises:
        PushParseError: The text is not of that form, or a value is out of range (the message
            quotes the text, escaped and cut to 40 characters, and names the range).
    """
    if not isinstance(text, str):
        raise PushParseError(f"push {text!r} is not {_PUSH_FORM}")
    match = _PUSH_RE.match(text)
    if not match:
        raise PushParseError(f"push {_quote(text)} is not {_PUSH_FORM} (ASCII digits; the units N and s may be written)")
    force, time_ = float(match.group(1)), float(match.group(2))
    try:
        return Push(force=force, time=time_)
    except PushParseError as e:
        raise PushParseError(f"push {_quote(text)} ({_PUSH_FORM}): {str(e).removeprefix('push: ')}") from None


def check_push_time(push: Push, horizon: float) -> None:
    """Refuse a push that starts outside the motion ``[0, horizon)`` [s] (it would never act).

    Raises:
        PushParseError: One line with the push, the motion's length and the valid range.
    """
    if not (0.0 <= push.time < horizon):
        raise PushParseError(
            f"push {push.force:g}@{push.time:g}: t = {push.time:g} s is outside the motion, which lasts "
            f"{horizon:.3g} s: give a time from 0 to below {horizon:.3g} s"
        )


@dataclass(frozen=True, slots=True, kw_only=True)
class SimSettings:
    """Simulation and certificate options.

    Attributes:
        timestep: MuJoCo step [s]; the controller runs every ``control_every`` steps.
        control_every: Steps per controller tick (1 = controller at the physics rate).
        settle_time: Simulated time after the plan's end [s].
        joint_friction: Keep the URDF joint damping and friction in MuJoCo.
        wbc: Controller settings (its ``dt`` is set to ``timestep * control_every``).
        fall_height_margin: A fall is the base this far below its lowest planned height [m].
        max_tilt: A fall is the base tilted this much more than planned [rad].
        slip_limit: Largest horizontal sole displacement during a stance [m].
        placement_limit: Largest horizontal distance of a stance sole from the plan's [m].
        torque_fraction_limit: Largest |tau| / limit [-].
        com_error_limit: Largest CoM tracking error [m].
        hand_error_limit: Largest hand tracking error [m].
        target_margin: Execution tolerance added to each spec target's tolerance [m].
        qp_failure_limit: Largest fraction of controller ticks whose QP failed [-].
        stop_after_fall: Simulated time kept after a fall before stopping [s].
        stop_after_qp_failure: Stop when the controller QP has failed on every tick for this long [s].
    """

    timestep: float = 0.001
    control_every: int = 1
    settle_time: float = 0.5
    joint_friction: bool = True
    wbc: WbcSettings = field(default_factory=WbcSettings)
    fall_height_margin: float = 0.25
    max_tilt: float = 0.6
    slip_limit: float = 0.01
    placement_limit: float = 0.02
    torque_fraction_limit: float = 0.98
    com_error_limit: float = 0.05
    hand_error_limit: float = 0.05
    target_margin: float = 0.03
    qp_failure_limit: float = 0.01
    stop_after_fall: float = 0.3
    stop_after_qp_failure: float = 0.5

    def __post_init__(self) -> None:
        if not (self.timestep > 0 and self.control_every >= 1 and self.settle_time >= 0):
            raise SimError(
                "SimSettings: timestep must be > 0, control_every >= 1, settle_time >= 0"
            )


def _tilt(quat_xyzw: np.ndarray) -> np.ndarray:
    """Angle between the base z axis and the vertical [rad], for (N, 4) quaternions."""
    x, y = quat_xyzw[..., 0], quat_xyzw[..., 1]
    zz = 1.0 - 2.0 * (x * x + y * y)
    return np.arccos(np.clip(zz, -1.0, 1.0))


def _tilt_of(q: np.ndarray) -> float:
    """Angle between the base z axis and the vertical [rad] of one configuration (scalar math)."""
    x, y = q[3:5].tolist()
    return math.acos(min(1.0, max(-1.0, 1.0 - 2.0 * (x * x + y * y))))


def simulate(
    plan: Plan,
    robot: Robot,
    *,
    push: Push | None = None,
    settings: SimSettings | None = None,
    progress: Callable[[str], None] | None = None,
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

    Returns:
        The execution, with its certificate.
    """
    if push is not None:
        check_push_time(push, float(plan.t[-1]))  # before any work
    s = settings if settings is not None else SimSettings()
    sm = build_model(robot, timestep=s.timestep, joint_friction=s.joint_friction)
    m = sm.model
    d = sm.data()
    control_dt = s.timestep * s.control_every
    wbc_settings = replace(s.wbc, dt=control_dt)
    ctrl = WholeBodyController(robot, wbc_settings)
    if progress is not None and not kernel_ready():
        progress("compiling the controller's kernel (once per installation, about 15 s)")
    ref = ctrl.reference_for(plan)

    nq, nv = robot.nq, robot.nv
    q = np.array(plan.q[0], dtype=float)
    v = np.zeros(nv)
    sm.set_state(d, q, v)
    ctrl.reset(q, v)

    duration = ref.duration + s.settle_time
    n_ticks = int(round(duration / control_dt)) + 1
    ts = np.empty(n_ticks)
    qs = np.empty((n_ticks, nq))
    vs = np.empty((n_ticks, nv))
    taus = np.empty((n_ticks, nv - 6))
    coms = np.empty((n_ticks, 3))
    tick_times = np.empty(n_ticks)
    foot_roles = [role for role in ("left_foot", "right_foot") if role in sm.sole_geoms]
    foot_frames = [robot.frame(role) for role in foot_roles]
    forces = np.zeros((len(foot_roles), n_ticks, 3))
    sole_ids = np.array([sm.sole_geoms[role] for role in foot_roles], dtype=int)
    foot_bodies = np.array([m.geom_bodyid[g] for g in sole_ids], dtype=int)
    contact_flags = np.zeros((len(foot_roles), n_ticks), dtype=bool)
    other_contacts: list[tuple[float, str]] = []
    events: list[Event] = []
    base_body = 1
    push_force = push.force_in_world() if push is not None else None
    if push is not None:
        events.append(
            Event(push.time, "push", f"{push.force:g} N on the base for {push.duration:g} s")
        )
    fall_height = float(np.min(ref.q[:, 2])) - s.fall_height_margin
    max_tilt = float(np.max(_tilt(ref.q[:, 3:7]))) + s.max_tilt
    fallen_at: float | None = None
    floor = sm.floor_geom
    n_soles = len(sole_ids)
    geom_label = np.full(m.ngeom + 1, -1, dtype=int)  # index -1 (no floor in the pair) -> -2
    geom_label[-1] = -2
    geom_label[sole_ids] = np.arange(n_soles)
    report_every = max(1, n_ticks // 10)
    was_failures = 0
    qp_failure_times: list[float] = []

    failing_since: float | None = None
    wall0 = time.perf_counter()
    n_done = 0
    for i in range(n_ticks):
        t = i * control_dt
        sm.state(d, q, v)
        tic = time.perf_counter()
        tau = ctrl.compute(t, q, v, ref)
        tick_times[i] = time.perf_counter() - tic
        if ctrl.failures != was_failures:
            was_failures = ctrl.failures
            qp_failure_times.append(t)
            failing_since = t if failing_since is None else failing_since
        else:
            failing_since = None
        d.ctrl[sm.actuator_select] = tau
        ts[i] = t
        qs[i] = q
        vs[i] = v
        taus[i] = tau
        coms[i] = d.subtree_com[base_body]
        # contacts of the current state (vectorized: a Python loop over contacts costs ~0.2 ms)
        if d.ncon:
            geom = d.contact.geom
            g1, g2 = geom[:, 0], geom[:, 1]
            other = np.where(g1 == floor, g2, np.where(g2 == floor, g1, -1))
            # what touches the floor: sole j -> j, another robot geom -> -1, no floor -> -2
            labels = geom_label[other]
            touching = set(labels.tolist())
            for j in range(n_soles):
                contact_flags[j, i] = j in touching
            if -1 in touching:
                for g in other[labels == -1].tolist():
                    other_contacts.append((t, sm.geom_body_names[g]))
            mujoco.mj_rnePostConstraint(m, d)  # net contact force per body in cfrc_ext
            forces[:, i] = d.cfrc_ext[foot_bodies, 3:]
        n_done = i + 1
        if fallen_at is None and (q[2] < fall_height or _tilt_of(q) > max_tilt):
            fallen_at = t
            events.append(
                Event(
                    t,
                    "fall",
                    f"base height {q[2]:.2f} m, tilt {math.degrees(_tilt(q[3:7])):.0f} deg",
                )
            )
        if fallen_at is not None and t - fallen_at >= s.stop_after_fall:
            events.append(Event(t, "stopped", "simulation stopped after the fall"))
            break
        if failing_since is not None and t - failing_since >= s.stop_after_qp_failure:
            events.append(
                Event(
                    t,
                    "stopped",
                    f"simulation stopped: the controller QP failed on every tick since "
                    f"t = {failing_since:.3f} s",
                )
            )
            break
        for _ in range(s.control_every):
            if push is not None:
                tt = d.time
                d.xfrc_applied[base_body, :3] = (
                    push_force if push.time <= tt < push.time + push.duration else 0.0
                )
            mujoco.mj_step(m, d)
        if progress is not None and i % report_every == 0 and i > 0:
            progress(f"simulated {t:.1f} of {duration:.1f} s")
    wall = time.perf_counter() - wall0
    if progress is not None:
        progress(f"simulated {ts[n_done - 1] if n_done else 0.0:.1f} s in {wall:.1f} s; certifying")

    sl = slice(0, n_done)
    ts, qs, vs, taus, coms, tick_times = ts[sl], qs[sl], vs[sl], taus[sl], coms[sl], tick_times[sl]
    forces = forces[:, sl]
    contact_flags = contact_flags[:, sl]
    if qp_failure_times:
        events.append(
            Event(
                qp_failure_times[0],
                "qp_failure",
                f"the QP failed on {len(qp_failure_times)} ticks (first at t = {qp_failure_times[0]:.3f} s)",
            )
        )
    frac = _torque_fraction(taus, sm.torque_limits)
    # saturated: over the certificate's limit, or at the controller's own cap (WbcSettings.torque_scale)
    cap = min(s.torque_fraction_limit, wbc_settings.torque_scale - 1e-3)
    saturated: np.ndarray | list[int] = np.nonzero(frac.max(axis=1) > cap)[0] if len(taus) else []
    if len(saturated):
        n0 = int(saturated[0])
        j0 = int(np.argmax(frac[n0]))
        events.append(
            Event(
                float(ts[n0]),
                "torque_limit",
                f"{robot.joint_names[j0]} at {100 * frac[n0, j0]:.0f}% of its torque limit",
            )
        )
    seen_bodies: set[str] = set()
    for t_c, body in other_contacts:
        if body not in seen_bodies:
            seen_bodies.add(body)
            events.append(Event(t_c, "unplanned_contact", f"{body} touched the floor"))
    events.sort(key=lambda e: e.time)
    checks = _certify(
        robot,
        sm,
        ref,
        s,
        ts,
        qs,
        taus,
        coms,
        contact_flags,
        foot_frames,
        other_contacts,
        fall_height,
        max_tilt,
        len(qp_failure_times),
        qp_failure_times[0] if qp_failure_times else 0.0,
        n_done,
    )
    certificate = Certificate.from_checks(checks)
    zmp = plan_zmp_excursion(robot, plan)
    if zmp is not None:
        events.append(
            Event(
                zmp[1], "plan_zmp", f"the plan's ZMP leaves the support polygon by {zmp[0]:.3f} m"
            )
        )
        events.sort(key=lambda e: e.time)
        if not certificate.ok:
            certificate = replace(
                certificate,
                reason=(
                    f"{certificate.reason}; the plan itself is dynamically infeasible: its ZMP leaves the support "
                    f"polygon by {zmp[0]:.3f} m at t = {zmp[1]:.2f} s"
                ),
            )
    return Execution(
        t=ts,
        q=qs,
        v=vs,
        tau=taus,
        com=coms,
        contact_forces={frame: forces[i] for i, frame in enumerate(foot_frames)},
        events=tuple(events),
        certificate=certificate,
        wall_time=wall,
        realtime_factor=(ts[-1] + control_dt) / wall if wall > 0 else math.inf,
        tick_times=tick_times,
        timestep=s.timestep,
        joint_names=tuple(robot.joint_names),
        torque_limits=sm.torque_limits.copy(),
    )


def _torque_fraction(taus: np.ndarray, limits: np.ndarray) -> np.ndarray:
    """|tau| / limit per sample and joint; joints without a usable limit (0 or inf) count as 0."""
    usable = (limits > 0) & np.isfinite(limits)
    safe = np.where(usable, limits, 1.0)
    return np.where(usable, np.abs(taus) / safe, 0.0)


def plan_zmp(robot: Robot, plan: Plan) -> np.ndarray:
    r"""ZMP of the plan at its knots from the full rigid-body dynamics (flat ground at z = 0).

    At each knot, inverse dynamics (``pin.rnea`` on the plan's own ``q``, ``v``, ``a``) gives the
    wrench the contacts must exert on the floating base; its moment about the ground point
    :math:`p` has no horizontal part when :math:`p_x = -N_y / F_z`, :math:`p_y = N_x / F_z` (world
    frame, moments about the origin). This includes the rate of angular momentum, unlike the
    CoM-only formula, and uses no interpolation.

    Returns:
        (T, 2) ZMP per knot [m] (NaN where the contacts would have to pull, :math:`F_z \le 0`).
    """
    model = robot.model
    data = model.createData()
    out = np.full((len(plan.t), 2), np.nan)
    for k in range(len(plan.t)):
        tau = pin.rnea(model, data, plan.q[k], plan.v[k], plan.a[k])
        pin.forwardKinematics(model, data, plan.q[k])  # rnea leaves data.oMi untouched
        wrench = data.oMi[1].act(pin.Force(tau[:6]))
        fz = wrench.linear[2]
        if fz > 1e-6:
            out[k] = (-wrench.angular[1] / fz, wrench.angular[0] / fz)
    return out


def plan_zmp_excursion(
    robot: Robot, plan: Plan, *, tolerance: float = 0.005
) -> tuple[float, float] | None:
    """Largest distance of the plan's ZMP outside its support polygon, with its time.

    The ZMP is :func:`plan_zmp` at the plan's knots (full dynamics); the support polygon is the
    convex hull of the sole corners of the contacts active at the knot, placed by the knot's
    configuration. A knot whose contacts would have to pull counts as outside by the
    distance from the polygon's centre to its farthest corner.

    Returns:
        ``(distance [m], time [s])`` when the ZMP leaves the polygon by more than ``tolerance``,
        else None.
    """
    from scipy.spatial import ConvexHull, QhullError

    model = robot.model
    data = model.createData()
    zmp = plan_zmp(robot, plan)
    worst, worst_t = 0.0, 0.0
    spec = plan.spec
    for k in range(len(plan.t)):
        phase = spec.phases[spec.phase_at(float(plan.t[k]))]
        pin.framesForwardKinematics(model, data, plan.q[k])
        pts = []
        for contact in phase.contacts:
            fid = robot.frame_id(contact.frame)
            side = robot.foot_side(model.frames[fid].name) or "left"
            corners = np.array([[x, y, 0.0] for x, y in robot.profile.sole.corners(side)])
            pts.append(corners @ data.oMf[fid].rotation.T + data.oMf[fid].translation)
        if not pts:
            continue
        pts2 = np.vstack(pts)[:, :2]
        try:
            hull = ConvexHull(pts2)
        except QhullError:  # degenerate polygon (a line): skip the knot
            continue
        if np.isnan(zmp[k]).any():
            dist = float(np.max(np.linalg.norm(pts2 - pts2.mean(axis=0), axis=1)))
        else:
            dist = float(np.max(hull.equations[:, :2] @ zmp[k] + hull.equations[:, 2]))
        if dist > worst:
            worst, worst_t = dist, float(plan.t[k] - plan.t[0])
    return (worst, worst_t) if worst > tolerance else None


def _certify(
    robot: Robot,
    sm: SimModel,
    ref: PlanReference,
    s: SimSettings,
    ts: np.ndarray,
    qs: np.ndarray,
    taus: np.ndarray,
    coms: np.ndarray,
    contact_flags: np.ndarray,
    foot_frames: list[str],
    other_contacts: list[tuple[float, str]],
    fall_height: float,
    max_tilt: float,
    qp_failures: int,
    qp_first: float,
    n_ticks: int,
) -> tuple[Check, ...]:
    model = robot.model
    checks: list[Check] = []
    idx = np.array([ref.index(t) for t in ts])

    # ---- fall: base height and tilt
    z = qs[:, 2]
    k = int(np.argmin(z))
    below = np.nonzero(z < fall_height)[0]
    tk = int(below[0]) if len(below) else k
    checks.append(
        Check(
            name="base height",
            value=float(z[tk]),
            limit=fall_height,
            unit="m",
            ok=not len(below),
            time=float(ts[tk]),
            upper=False,
            message=f"fell at t = {ts[tk]:.2f} s (base height {z[tk]:.2f} m < {fall_height:.2f} m)",
        )
    )
    tilt = _tilt(qs[:, 3:7])
    over = np.nonzero(tilt > max_tilt)[0]
    tk = int(over[0]) if len(over) else int(np.argmax(tilt))
    checks.append(
        Check(
            name="base tilt",
            value=float(tilt[tk]),
            limit=max_tilt,
            unit="rad",
            ok=not len(over),
            time=float(ts[tk]),
            message=f"fell at t = {ts[tk]:.2f} s (base tilted {math.degrees(tilt[tk]):.0f} deg > "
            f"{math.degrees(max_tilt):.0f} deg)",
        )
    )
    # ---- contacts other than the planned ones
    planned = np.zeros_like(contact_flags)
    for i, frame in enumerate(foot_frames):
        if frame in ref.contact_frames:
            col = ref.contact_frames.index(frame)
            act = ref.active[:, col]
            # a sole touching within 0.1 s of a planned stance is a landing, not a fault
            w = max(1, int(round(0.1 / ref.dt)))
            grown = np.convolve(act.astype(float), np.ones(2 * w + 1), mode="same") > 0
            planned[i] = grown[idx]
    stray = contact_flags & ~planned
    bad_times = [t for t, _ in other_contacts]
    names = [b for _, b in other_contacts]
    for i, frame in enumerate(foot_frames):
        for j in np.nonzero(stray[i])[0][:1]:
            bad_times.append(float(ts[j]))
            names.append(frame)
    if bad_times:
        j = int(np.argmin(bad_times))
        checks.append(
            Check(
                name="unplanned contacts",
                value=float(len(set(names))),
                limit=0.0,
                unit="count",
                ok=False,
                time=float(bad_times[j]),
                message=f"{names[j]} touched the floor at t = {bad_times[j]:.2f} s (not planned)",
            )
        )
    else:
        checks.append(
            Check(name="unplanned contacts", value=0.0, limit=0.0, unit="count", ok=True, time=0.0)
        )

    # ---- foot slip per planned stance interval
    data = model.createData()
    foot_ids = [robot.frame_id(f) for f in foot_frames]
    foot_xy = np.empty((len(foot_ids), len(ts), 2))
    hand_roles = [r for r in ("left_hand", "right_hand") if robot.has_role(r)]
    hand_names = [robot.frame(r) for r in hand_roles]
    hand_ids = [robot.frame_id(h) for h in hand_names]
    hand_pos = np.empty((len(hand_ids), len(ts), 3))
    target_frames = {t.name: robot.frame_id(t.frame) for t in ref.plan.spec.targets}
    target_ids = sorted(set(target_frames.values()))
    target_pose = {fid: np.empty((len(ts), 3)) for fid in target_ids}
    target_rot = {fid: np.empty((len(ts), 3, 3)) for fid in target_ids}
    for n in range(len(ts)):
        pin.forwardKinematics(model, data, qs[n])
        for j, fid in enumerate(foot_ids):
            foot_xy[j, n] = pin.updateFramePlacement(model, data, fid).translation[:2]
        for j, fid in enumerate(hand_ids):
            hand_pos[j, n] = pin.updateFramePlacement(model, data, fid).translation
        for fid in target_ids:
            placement = pin.updateFramePlacement(model, data, fid)
            target_pose[fid][n] = placement.translation
            target_rot[fid][n] = placement.rotation
    for j, frame in enumerate(foot_frames):
        if frame not in ref.contact_frames:
            continue
        act = ref.active[idx, ref.contact_frames.index(frame)]
        worst, worst_t = 0.0, 0.0
        start = None
        for n in range(len(ts) + 1):
            on = n < len(ts) and act[n]
            if on and start is None:
                start = n
            if not on and start is not None:
                disp = np.linalg.norm(foot_xy[j, start:n] - foot_xy[j, start], axis=1)
                a = int(np.argmax(disp))
                if disp[a] > worst:
                    worst, worst_t = float(disp[a]), float(ts[start + a])
                start = None
        role = robot.foot_side(frame)
        label = f"{role}_foot" if role else frame
        planned_xy = ref.frames[frame].position[idx, :2]
        gap = np.where(act, np.linalg.norm(foot_xy[j] - planned_xy, axis=1), 0.0)
        kg = int(np.argmax(gap))
        over_gap = np.nonzero(gap > s.placement_limit)[0]
        kg_first = int(over_gap[0]) if len(over_gap) else kg
        checks.append(
            Check(
                name=f"{label} placement error",
                value=float(gap[kg]),
                limit=s.placement_limit,
                unit="m",
                ok=bool(gap[kg] <= s.placement_limit),
                time=float(ts[kg_first]),
                message=f"{label} is {gap[kg]:.3f} m from its planned stance placement (> {s.placement_limit:.3f} m) "
                f"from t = {ts[kg_first]:.2f} s",
            )
        )
        checks.append(
            Check(
                name=f"{label} slip",
                value=worst,
                limit=s.slip_limit,
                unit="m",
                ok=worst <= s.slip_limit,
                time=worst_t,
                message=f"{label} slipped {worst:.3f} m > {s.slip_limit:.3f} m at t = {worst_t:.2f} s",
            )
        )

    # ---- peak torque as a fraction of the limit
    limits = sm.torque_limits
    frac = _torque_fraction(taus, limits)
    n_t, j_t = np.unravel_index(int(np.argmax(frac)), frac.shape)
    peak = float(frac[n_t, j_t])
    joint = robot.joint_names[j_t]
    over = np.nonzero(frac.max(axis=1) > s.torque_fraction_limit)[0]
    first = int(over[0]) if len(over) else n_t
    j_first = int(np.argmax(frac[first]))
    checks.append(
        Check(
            name="peak torque",
            value=100 * peak,
            limit=100 * s.torque_fraction_limit,
            unit="%",
            ok=peak <= s.torque_fraction_limit,
            time=float(ts[first]),
            message=f"{robot.joint_names[j_first]} torque at {100 * frac[first, j_first]:.0f}% of its limit "
            f"({limits[j_first]:g} N m) at t = {ts[first]:.2f} s"
            if len(over)
            else f"{joint} over its limit",
        )
    )
    # ---- controller health
    ratio = qp_failures / max(n_ticks, 1)
    checks.append(
        Check(
            name="QP failures",
            value=100 * ratio,
            limit=100 * s.qp_failure_limit,
            unit="%",
            ok=ratio <= s.qp_failure_limit,
            time=qp_first,
            message=f"the controller QP failed on {qp_failures} of {n_ticks} ticks",
        )
    )
    # ---- CoM tracking
    com_err = np.linalg.norm(coms - ref.plan_com[idx], axis=1)
    k = int(np.argmax(com_err))
    checks.append(
        Check(
            name="CoM tracking error",
            value=float(com_err[k]),
            limit=s.com_error_limit,
            unit="m",
            ok=bool(com_err[k] <= s.com_error_limit),
            time=float(ts[k]),
            message=f"CoM off its plan by {com_err[k]:.3f} m > {s.com_error_limit:.3f} m at t = {ts[k]:.2f} s",
        )
    )
    # ---- hand tracking
    for j, name in enumerate(hand_names):
        err = np.linalg.norm(hand_pos[j] - ref.frames[name].position[idx], axis=1)
        k = int(np.argmax(err))
        role = hand_roles[j]
        checks.append(
            Check(
                name=f"{role} tracking error",
                value=float(err[k]),
                limit=s.hand_error_limit,
                unit="m",
                ok=bool(err[k] <= s.hand_error_limit),
                time=float(ts[k]),
                message=f"{role} off its plan by {err[k]:.3f} m > {s.hand_error_limit:.3f} m at t = {ts[k]:.2f} s",
            )
        )
    # ---- task targets measured in the simulation
    horizon = ref.duration
    for target in ref.plan.spec.targets:
        fid = target_frames[target.name]
        if target.window is not None:
            mask = (ts >= target.window[0] - 1e-9) & (ts <= target.window[1] + 1e-9)
        else:
            t_at = horizon if target.time is None else target.time
            mask = np.zeros(len(ts), dtype=bool)
            mask[int(np.argmin(np.abs(ts - t_at)))] = (
                abs(ts[int(np.argmin(np.abs(ts - t_at)))] - t_at) < 0.01
            )
        limit = target.tolerance + s.target_margin
        if not mask.any():
            checks.append(_never_reached(f"target {target.name!r}", limit, ts))
            continue
        err = np.zeros(len(ts))
        if target.position is not None:
            axes = np.array(target.axes, dtype=float)
            err = np.linalg.norm((target_pose[fid] - np.array(target.position)) * axes, axis=1)
        rot_err = np.zeros(len(ts))
        if target.rpy is not None:
            r_t = pin.rpy.rpyToMatrix(*target.rpy)
            rot_err = np.array([np.linalg.norm(pin.log3(r_t.T @ r)) for r in target_rot[fid]])
        err_m = np.where(mask, err, -1.0)
        k = int(np.argmax(err_m))
        ok = bool(err_m[k] <= limit)
        rot_lim = target.orientation_tolerance + 0.1
        rot_m = np.where(mask, rot_err, -1.0)
        kr = int(np.argmax(rot_m))
        rot_ok = bool(rot_m[kr] <= rot_lim)
        msg = (
            f"target {target.name!r} missed by {err_m[k]:.3f} m > {limit:.3f} m at t = {ts[k]:.2f} s"
            if not ok
            else f"target {target.name!r} orientation off by {rot_m[kr]:.2f} rad > {rot_lim:.2f} rad"
        )
        checks.append(
            Check(
                name=f"target {target.name!r}",
                value=float(err_m[k]),
                limit=limit,
                unit="m",
                ok=ok and rot_ok,
                time=float(ts[k] if not ok else ts[kr]),
                message=msg,
            )
        )
    # ---- CoM targets measured in the simulation
    for com_target in ref.plan.spec.com_targets:
        if com_target.window is not None:
            mask = (ts >= com_target.window[0] - 1e-9) & (ts <= com_target.window[1] + 1e-9)
        else:
            t_at = horizon if com_target.time is None else com_target.time
            n_at = int(np.argmin(np.abs(ts - t_at)))
            mask = np.zeros(len(ts), dtype=bool)
            mask[n_at] = abs(ts[n_at] - t_at) < 0.01
        limit = com_target.tolerance + s.target_margin
        name = f"CoM target {com_target.name!r}"
        if not mask.any():
            checks.append(_never_reached(name, limit, ts))
            continue
        axes = np.array([v is not None for v in com_target.position], dtype=float)
        goal = np.array([0.0 if v is None else v for v in com_target.position])
        err = np.where(mask, np.linalg.norm((coms - goal) * axes, axis=1), -1.0)
        k = int(np.argmax(err))
        checks.append(
            Check(
                name=name,
                value=float(err[k]),
                limit=limit,
                unit="m",
                ok=bool(err[k] <= limit),
                time=float(ts[k]),
                message=f"{name} missed by {err[k]:.3f} m > {limit:.3f} m at t = {ts[k]:.2f} s",
            )
        )
    return tuple(checks)


def _never_reached(name: str, limit: float, ts: np.ndarray) -> Check:
    """The failed check of a target whose time the simulation never reached (it stopped early)."""
    return Check(
        name=name, value=math.inf, limit=limit, unit="m", ok=False, time=float(ts[-1]),
        message=f"{name} was never reached: the simulation stopped at t = {ts[-1]:.2f} s",
    )
