"""The certificate's checks of a simulated motion, each a small function of the run's record.

:func:`certify` runs them in a fixed order: fall (base height, tilt), unplanned contacts, per
stance foot (placement, slip), peak torque, controller QP failures, CoM and hand tracking, then
the spec's frame and CoM targets as measured in the simulation, self-collision and scene collision
(docs/simulation-collisions.md) and on the meshes for the pairs the collision model leaves out
(:mod:`sim.meshcheck`), and last the intent lines of :mod:`sim.intent` (did the motion do
what its actions mean, relative to the plan).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
import pinocchio as pin

from planner import Check, CheckKind
from robots import body_part
from sim.collisions import MeshDistance
from sim.intent import ObjectPoses, intent_checks
from sim.meshcheck import mesh_self_collision_check
from sim.recording import RunRecord, tilt, torque_fraction
from sim.seat import floor_touch_planned, seat_checks

#: Ticks of a pair whose MuJoCo contact is deeper than the limit that coal checks on the meshes.
CONFIRM_TICKS = 5


@dataclass(frozen=True, eq=False, kw_only=True)
class Measured:
    """Frame positions of a run, from Pinocchio at every recorded tick.

    Attributes:
        knots: The plan sample each tick tracks (T',).
        foot_xy: Horizontal position of each ``RunRecord.foot_frames`` sole (n_feet, T', 2) [m].
        hand_roles: The hand roles the robot has (``left_hand``, ``right_hand``).
        hand_names: Their frames.
        hand_pos: Their positions (n_hands, T', 3) [m].
        target_frames: Spec target name -> frame id.
        target_pos: Frame id -> position (T', 3) [m], for every target frame.
        target_rot: Frame id -> rotation (T', 3, 3), for every target frame.
    """

    knots: np.ndarray
    foot_xy: np.ndarray
    hand_roles: list[str]
    hand_names: list[str]
    hand_pos: np.ndarray
    target_frames: dict[str, int]
    target_pos: dict[int, np.ndarray]
    target_rot: dict[int, np.ndarray]


def certify(run: RunRecord, objects: ObjectPoses | None = None) -> tuple[Check, ...]:
    """Every check of the certificate, in its fixed order (``objects``: the movable objects' poses
    over the run, for the intent lines of actions on them)."""
    meas = measure(run)
    return (
        *fall_checks(run),
        unplanned_contacts_check(run, meas),
        *foot_checks(run, meas),
        *seat_checks(run),
        peak_torque_check(run),
        qp_failures_check(run),
        com_tracking_check(run, meas),
        *hand_checks(run, meas),
        *target_checks(run, meas),
        *com_target_checks(run),
        self_collision_check(run),
        mesh_self_collision_check(run),
        scene_collision_check(run),
        *intent_checks(run, objects),
    )


def measure(run: RunRecord) -> Measured:
    """Sole, hand and target frame positions at every tick (Pinocchio forward kinematics)."""
    robot, ts = run.robot, run.t
    model = robot.model
    data = model.createData()
    foot_ids = [robot.frame_id(f) for f in run.foot_frames]
    foot_xy = np.empty((len(foot_ids), len(ts), 2))
    hand_roles = [r for r in ("left_hand", "right_hand") if robot.has_role(r)]
    hand_names = [robot.frame(r) for r in hand_roles]
    hand_ids = [robot.frame_id(h) for h in hand_names]
    hand_pos = np.empty((len(hand_ids), len(ts), 3))
    target_frames = {t.name: robot.frame_id(t.frame) for t in run.ref.plan.spec.targets}
    target_ids = sorted(set(target_frames.values()))
    target_pos = {fid: np.empty((len(ts), 3)) for fid in target_ids}
    target_rot = {fid: np.empty((len(ts), 3, 3)) for fid in target_ids}
    for n in range(len(ts)):
        pin.forwardKinematics(model, data, run.q[n])
        for j, fid in enumerate(foot_ids):
            foot_xy[j, n] = pin.updateFramePlacement(model, data, fid).translation[:2]
        for j, fid in enumerate(hand_ids):
            hand_pos[j, n] = pin.updateFramePlacement(model, data, fid).translation
        for fid in target_ids:
            placement = pin.updateFramePlacement(model, data, fid)
            target_pos[fid][n] = placement.translation
            target_rot[fid][n] = placement.rotation
    return Measured(
        knots=np.array([run.ref.index(t) for t in ts]), foot_xy=foot_xy, hand_roles=hand_roles,
        hand_names=hand_names, hand_pos=hand_pos, target_frames=target_frames, target_pos=target_pos,
        target_rot=target_rot,
    )


def fall_checks(run: RunRecord) -> tuple[Check, Check]:
    """Base height above the fall height, base tilt below the largest tilt."""
    ts, fall_height, max_tilt = run.t, run.fall_height, run.max_tilt
    z = run.q[:, 2]
    k = int(np.argmin(z))
    below = np.nonzero(z < fall_height)[0]
    tk = int(below[0]) if len(below) else k
    height = Check(
        name="base height",
        kind=CheckKind.BASE_HEIGHT,
        value=float(z[tk]),
        limit=fall_height,
        unit="m",
        ok=not len(below),
        time=float(ts[tk]),
        upper=False,
        message=f"fell at t = {ts[tk]:.2f} s (base height {z[tk]:.2f} m < {fall_height:.2f} m)",
    )
    angle = tilt(run.q[:, 3:7])
    over = np.nonzero(angle > max_tilt)[0]
    tk = int(over[0]) if len(over) else int(np.argmax(angle))
    tilted = Check(
        name="base tilt",
        kind=CheckKind.BASE_TILT,
        value=float(angle[tk]),
        limit=max_tilt,
        unit="rad",
        ok=not len(over),
        time=float(ts[tk]),
        message=f"fell at t = {ts[tk]:.2f} s (base tilted {math.degrees(angle[tk]):.0f} deg > "
        f"{math.degrees(max_tilt):.0f} deg)",
    )
    return height, tilted


def unplanned_contacts_check(run: RunRecord, meas: Measured) -> Check:
    """No body touches the floor but the soles of planned stances (a landing within 0.1 s counts) and
    the links of planned region contacts on the floor (a knee: :func:`sim.seat.floor_touch_planned`)."""
    ref, ts = run.ref, run.t
    planned = np.zeros_like(run.contact_flags)
    for i, frame in enumerate(run.foot_frames):
        if frame in ref.contact_frames:
            act = ref.active[:, ref.contact_frames.index(frame)]
            # a sole touching within 0.1 s of a planned stance is a landing, not a fault
            w = max(1, int(round(0.1 / ref.dt)))
            grown = np.convolve(act.astype(float), np.ones(2 * w + 1), mode="same") > 0
            planned[i] = grown[meas.knots]
    stray = run.contact_flags & ~planned
    held = floor_touch_planned(run)  # a knee on the floor where and when the plan holds it
    bad_times = [t for (t, _), h in zip(run.other_contacts, held, strict=True) if not h]
    names = [b for (_, b), h in zip(run.other_contacts, held, strict=True) if not h]
    for i, frame in enumerate(run.foot_frames):
        for j in np.nonzero(stray[i])[0][:1]:
            bad_times.append(float(ts[j]))
            names.append(frame)
    if not bad_times:
        return Check(name="unplanned contacts", kind=CheckKind.UNPLANNED_CONTACTS, value=0.0, limit=0.0, unit="count", ok=True, time=0.0)
    j = int(np.argmin(bad_times))
    return Check(
        name="unplanned contacts",
        kind=CheckKind.UNPLANNED_CONTACTS,
        value=float(len(set(names))),
        limit=0.0,
        unit="count",
        ok=False,
        time=float(bad_times[j]),
        message=f"{names[j]} touched the floor at t = {bad_times[j]:.2f} s (not planned)",
    )


def _worst_slip(foot_xy: np.ndarray, active: np.ndarray, ts: np.ndarray) -> tuple[float, float]:
    """Largest horizontal displacement of a sole from where each of its stances began [m], and when [s]."""
    worst, worst_t = 0.0, 0.0
    start = None
    for n in range(len(ts) + 1):
        on = n < len(ts) and active[n]
        if on and start is None:
            start = n
        if not on and start is not None:
            disp = np.linalg.norm(foot_xy[start:n] - foot_xy[start], axis=1)
            a = int(np.argmax(disp))
            if disp[a] > worst:
                worst, worst_t = float(disp[a]), float(ts[start + a])
            start = None
    return worst, worst_t


def foot_checks(run: RunRecord, meas: Measured) -> list[Check]:
    """Per planned stance foot: its distance from the planned placement, and its slip."""
    ref, ts, s = run.ref, run.t, run.settings
    out: list[Check] = []
    for j, frame in enumerate(run.foot_frames):
        if frame not in ref.contact_frames:
            continue
        act = ref.active[meas.knots, ref.contact_frames.index(frame)]
        worst, worst_t = _worst_slip(meas.foot_xy[j], act, ts)
        role = run.robot.foot_side(frame)
        label = f"{role}_foot" if role else frame
        planned_xy = ref.frames[frame].position[meas.knots, :2]
        gap = np.where(act, np.linalg.norm(meas.foot_xy[j] - planned_xy, axis=1), 0.0)
        kg = int(np.argmax(gap))
        over_gap = np.nonzero(gap > s.placement_limit)[0]
        kg_first = int(over_gap[0]) if len(over_gap) else kg
        out.append(
            Check(
                name=f"{label} placement error",
                kind=CheckKind.FOOT_PLACEMENT,
                subject=label,
                value=float(gap[kg]),
                limit=s.placement_limit,
                unit="m",
                ok=bool(gap[kg] <= s.placement_limit),
                time=float(ts[kg_first]),
                message=f"{label} is {gap[kg]:.3f} m from its planned stance placement (> {s.placement_limit:.3f} m) "
                f"from t = {ts[kg_first]:.2f} s",
            )
        )
        out.append(
            Check(
                name=f"{label} slip",
                kind=CheckKind.FOOT_SLIP,
                subject=label,
                value=worst,
                limit=s.slip_limit,
                unit="m",
                ok=worst <= s.slip_limit,
                time=worst_t,
                message=f"{label} slipped {worst:.3f} m > {s.slip_limit:.3f} m at t = {worst_t:.2f} s",
            )
        )
    return out


def peak_torque_check(run: RunRecord) -> Check:
    """Peak |tau| as a fraction of the joint's limit."""
    ts, s, limits, names = run.t, run.settings, run.torque_limits, run.robot.joint_names
    frac = torque_fraction(run.tau, limits)
    n_t, j_t = np.unravel_index(int(np.argmax(frac)), frac.shape)
    peak = float(frac[n_t, j_t])
    over = np.nonzero(frac.max(axis=1) > s.torque_fraction_limit)[0]
    first = int(over[0]) if len(over) else n_t
    j_first = int(np.argmax(frac[first]))
    return Check(
        name="peak torque",
        kind=CheckKind.PEAK_TORQUE,
        value=100 * peak,
        limit=100 * s.torque_fraction_limit,
        unit="%",
        ok=peak <= s.torque_fraction_limit,
        time=float(ts[first]),
        message=f"{names[j_first]} torque at {100 * frac[first, j_first]:.0f}% of its limit "
        f"({limits[j_first]:g} N m) at t = {ts[first]:.2f} s"
        if len(over)
        else f"{names[j_t]} over its limit",
    )


def qp_failures_check(run: RunRecord) -> Check:
    """The fraction of controller ticks whose QP failed."""
    s = run.settings
    qp_failures, n_ticks = len(run.qp_failure_times), run.n_ticks
    ratio = qp_failures / max(n_ticks, 1)
    return Check(
        name="QP failures",
        kind=CheckKind.QP_FAILURES,
        value=100 * ratio,
        limit=100 * s.qp_failure_limit,
        unit="%",
        ok=ratio <= s.qp_failure_limit,
        time=run.qp_failure_times[0] if run.qp_failure_times else 0.0,
        message=f"the controller QP failed on {qp_failures} of {n_ticks} ticks",
    )


def com_tracking_check(run: RunRecord, meas: Measured) -> Check:
    """Largest distance of the CoM from the plan's."""
    ts, s = run.t, run.settings
    com_err = np.linalg.norm(run.com - run.ref.plan_com[meas.knots], axis=1)
    k = int(np.argmax(com_err))
    return Check(
        name="CoM tracking error",
        kind=CheckKind.COM_TRACKING,
        value=float(com_err[k]),
        limit=s.com_error_limit,
        unit="m",
        ok=bool(com_err[k] <= s.com_error_limit),
        time=float(ts[k]),
        message=f"CoM off its plan by {com_err[k]:.3f} m > {s.com_error_limit:.3f} m at t = {ts[k]:.2f} s",
    )


def hand_checks(run: RunRecord, meas: Measured) -> list[Check]:
    """Per hand: largest distance from the plan's hand position."""
    ts, s = run.t, run.settings
    out: list[Check] = []
    for j, name in enumerate(meas.hand_names):
        err = np.linalg.norm(meas.hand_pos[j] - run.ref.frames[name].position[meas.knots], axis=1)
        k = int(np.argmax(err))
        role = meas.hand_roles[j]
        out.append(
            Check(
                name=f"{role} tracking error",
                kind=CheckKind.HAND_TRACKING,
                subject=role,
                value=float(err[k]),
                limit=s.hand_error_limit,
                unit="m",
                ok=bool(err[k] <= s.hand_error_limit),
                time=float(ts[k]),
                message=f"{role} off its plan by {err[k]:.3f} m > {s.hand_error_limit:.3f} m at t = {ts[k]:.2f} s",
            )
        )
    return out


def _target_mask(ts: np.ndarray, time: float | None, window: tuple[float, float] | None,
                 horizon: float) -> np.ndarray:
    """The ticks where a target applies: its window, or the tick within 10 ms of its time (the end by default)."""
    if window is not None:
        return (ts >= window[0] - 1e-9) & (ts <= window[1] + 1e-9)
    t_at = horizon if time is None else time
    n_at = int(np.argmin(np.abs(ts - t_at)))
    mask = np.zeros(len(ts), dtype=bool)
    mask[n_at] = abs(ts[n_at] - t_at) < 0.01
    return mask


def target_checks(run: RunRecord, meas: Measured) -> list[Check]:
    """Per spec frame target: its position (and orientation) error where it applies, measured in the simulation."""
    ts, s = run.t, run.settings
    out: list[Check] = []
    for target in run.ref.plan.spec.targets:
        fid = meas.target_frames[target.name]
        mask = _target_mask(ts, target.time, target.window, run.ref.duration)
        limit = target.tolerance + s.target_margin
        if not mask.any():
            out.append(_never_reached(f"target {target.name!r}", CheckKind.TARGET_POSITION, target.name, limit, ts))
            continue
        err = np.zeros(len(ts))
        if target.position is not None:
            axes = np.array(target.axes, dtype=float)
            err = np.linalg.norm((meas.target_pos[fid] - np.array(target.position)) * axes, axis=1)
        rot_err = np.zeros(len(ts))
        if target.rpy is not None:
            r_t = pin.rpy.rpyToMatrix(*target.rpy)
            # only where the target applies (the rest is masked out below): a retarget's heading
            # targets each hold at one tick, and log3 at every tick of each took 2.2 s of g1 squat's 29 s of CPU
            rots = meas.target_rot[fid]
            for i in np.flatnonzero(mask):
                rot_err[i] = np.linalg.norm(pin.log3(r_t.T @ rots[i]))
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
        out.append(
            Check(
                name=f"target {target.name!r}",
                kind=CheckKind.TARGET_POSITION,
                subject=target.name,
                value=float(err_m[k]),
                limit=limit,
                unit="m",
                ok=ok and rot_ok,
                time=float(ts[k] if not ok else ts[kr]),
                message=msg,
            )
        )
    return out


def com_target_checks(run: RunRecord) -> list[Check]:
    """Per spec CoM target: its error where it applies, measured in the simulation."""
    ts, s = run.t, run.settings
    out: list[Check] = []
    for target in run.ref.plan.spec.com_targets:
        mask = _target_mask(ts, target.time, target.window, run.ref.duration)
        limit = target.tolerance + s.target_margin
        name = f"CoM target {target.name!r}"
        if not mask.any():
            out.append(_never_reached(name, CheckKind.COM_TARGET, target.name, limit, ts))
            continue
        axes = np.array([v is not None for v in target.position], dtype=float)
        goal = np.array([0.0 if v is None else v for v in target.position])
        err = np.where(mask, np.linalg.norm((run.com - goal) * axes, axis=1), -1.0)
        k = int(np.argmax(err))
        out.append(
            Check(
                name=name,
                kind=CheckKind.COM_TARGET,
                subject=target.name,
                value=float(err[k]),
                limit=limit,
                unit="m",
                ok=bool(err[k] <= limit),
                time=float(ts[k]),
                message=f"{name} missed by {err[k]:.3f} m > {limit:.3f} m at t = {ts[k]:.2f} s",
            )
        )
    return out


def _never_reached(name: str, kind: CheckKind, subject: str, limit: float, ts: np.ndarray) -> Check:
    """The failed check of a target whose time the simulation never reached (it stopped early)."""
    return Check(
        name=name, kind=kind, subject=subject, value=math.inf, limit=limit, unit="m", ok=False, time=float(ts[-1]),
        message=f"{name} was never reached: the simulation stopped at t = {ts[-1]:.2f} s",
    )


def _mm(x: float) -> float:
    return 1000.0 * x


def self_collision_check(run: RunRecord) -> Check:
    """The closest approach of two links of the collision model, or the collision of two.

    MuJoCo's contacts between the links' convex hulls are seen at every tick. A pair collides
    when, at a tick where its contact is deeper than ``self_penetration_limit`` or pushes harder
    than ``self_contact_force_limit``, coal confirms that the URDF meshes themselves intersect
    (the deepest / hardest :data:`CONFIRM_TICKS` such ticks are checked); otherwise the pair
    counts at its depth, or at its coal mesh distance when the hulls went deeper than the limit
    but the meshes did not touch. Distances come from the samples (``collision_sample_period``).
    """
    s, ts, pairs = run.settings, run.t, run.collision_pairs
    limit, force_limit = s.self_penetration_limit, s.self_contact_force_limit
    mesh: MeshDistance | None = None
    # (distance [m], tick, pair index) of every pair's closest approach
    found: list[tuple[float, int, int]] = []
    # (first offending tick, deepest distance [m], largest force [N], pair index) of colliding pairs
    collided: list[tuple[int, float, float, int]] = []
    contacts = run.self_contacts
    for k in np.unique(contacts[:, 1]).astype(int).tolist() if len(contacts) else []:
        rows = contacts[contacts[:, 1] == k]
        bad = rows[(rows[:, 2] < -limit) | (rows[:, 3] > force_limit)]
        if not len(bad):
            deepest = rows[np.argmin(rows[:, 2])]
            found.append((float(deepest[2]), int(deepest[0]), k))
            continue
        mesh = mesh or MeshDistance(run.robot)
        # the worst ticks first: deepest over the limit, else the largest force
        worst = bad[np.lexsort((-bad[:, 3], bad[:, 2]))]
        apart = []
        for n in list(dict.fromkeys(worst[:, 0].astype(int).tolist()))[:CONFIRM_TICKS]:
            gap = mesh.between(run.q[n], *pairs[k])
            if gap == 0.0:
                collided.append((int(bad[:, 0].min()), float(rows[:, 2].min()), float(rows[:, 3].max()), k))
                break
            apart.append((gap, n))
        else:  # the hulls pressed together, the meshes did not touch: the pair counts at its mesh distance
            gap, n = min(apart)
            found.append((gap, n, k))
    for tick, k, dist in run.self_samples.tolist() if len(run.self_samples) else []:
        if k >= 0 and dist >= 0:
            found.append((dist, int(tick), int(k)))
    if run.rest_overlap:  # pairs MuJoCo does not collide: coal at the sample ticks
        mesh = mesh or MeshDistance(run.robot)
        index = {p: k for k, p in enumerate(pairs)}
        for tick in run.self_samples[:, 0].astype(int).tolist() if len(run.self_samples) else []:
            for pair in run.rest_overlap:
                found.append((mesh.between(run.q[tick], *pair), tick, index[pair]))
    horizon = s.self_distance_horizon
    if not found and not collided:
        return Check(
            name=f"self-collision: no pair within {_mm(horizon):.0f} mm", kind=CheckKind.SELF_COLLISION,
            value=_mm(horizon), limit=-_mm(limit), unit="mm", ok=True, time=0.0, upper=False,
        )
    message = ""
    if collided:  # the pair that collided first
        tick, dist, force, k = min(collided)
        a, b = (body_part(run.robot, link) for link in pairs[k])
        message = (f"{a} hit the {b} at t = {ts[tick]:.2f} s ({_mm(max(-dist, 0.0)):.1f} mm deep, "
                   f"{force:.0f} N; {pairs[k][0]} / {pairs[k][1]}): the robot collides with itself")
    else:
        dist, tick, k = min(found)
        a, b = (body_part(run.robot, link) for link in pairs[k])
    subject = f"{a} / {b}"
    return Check(
        name=f"self-collision: {subject}" + (f", {force:.0f} N" if collided else ""),
        kind=CheckKind.SELF_COLLISION, subject=subject,
        value=_mm(dist), limit=-_mm(limit), unit="mm", ok=not collided, time=float(ts[tick]), upper=False,
        message=message,
    )


TOUCH_PADDING = 0.3  # [s] around a planned touch's time or window, its hand may touch its object


def planned_touch(run: RunRecord, tick: int, link: str, obj: str) -> bool:
    """Whether a robot-object contact is planned: a frame target of the spec touches ``obj``
    (``FrameTarget.touch``) around that time (:data:`TOUCH_PADDING`; a window to the motion's end:
    after it too, the robot still sits), and ``link`` is the target frame's link or one below it."""
    model = run.robot.model
    t = float(run.t[tick])
    if _stands_on(run, t, link, obj):
        return True
    for target in run.ref.plan.spec.targets:
        if target.touch != obj:
            continue
        start, end = target.window if target.window is not None else (target.time, target.time)
        if end is not None and end >= float(run.ref.plan.t[-1]) - 1e-9:
            end = math.inf  # held to the motion's end (seated): it stays touching after it
        if start is None or end is None or not start - TOUCH_PADDING <= t <= end + TOUCH_PADDING:
            continue
        joint = model.frames[run.robot.frame_id(target.frame)].parentJoint
        if model.existFrame(link) and model.frames[model.getFrameId(link)].parentJoint in model.subtrees[joint]:
            return True
    return False


def _stands_on(run: RunRecord, t: float, link: str, obj: str) -> bool:
    """A foot planned to stand on ``obj`` (a phase's contact placed on its walkable top,
    :func:`tasks.surface_at`) around time ``t`` (:data:`TOUCH_PADDING`), and ``link`` is that foot's
    link or one below it: a step onto a tread is a planned contact with it (the last phase's feet
    stay there after the motion's end)."""
    memo = _STANCES[0] if _STANCES else None
    if memo is None or memo[0] is not run.ref.plan.spec or memo[3] is not run.robot.model:
        _stances(run)
        memo = _STANCES[0]
    spans = memo[2].get((link, obj))
    if spans is None:
        spans = _link_spans(run, link, obj)
    for start, end in spans:
        if start - TOUCH_PADDING <= t <= end + TOUCH_PADDING:
            return True
    return False


def _link_spans(run: RunRecord, link: str, obj: str) -> list[tuple[float, float]]:
    """The stance spans (start, end [s]) of :func:`_stances` on ``obj`` whose foot holds ``link``
    (that foot's link or one below it), remembered with the spec's stances."""
    model = run.robot.model
    spans: list[tuple[float, float]] = []
    if model.existFrame(link):
        parent = model.frames[model.getFrameId(link)].parentJoint
        spans = [(start, end) for start, end, joint, name in _stances(run)
                 if name == obj and parent in model.subtrees[joint]]
    _STANCES[0][2][(link, obj)] = spans
    return spans


# the last spec's feet on objects, per (link, object) their spans (asked ~10^5 times on the stairs), the model
_STANCES: list[tuple[object, list[tuple[float, float, int, str]], dict[tuple[str, str], list[tuple[float, float]]], object]] = []


def _stances(run: RunRecord) -> list[tuple[float, float, int, str]]:
    """Each foot contact of the plan placed on a walkable object: (its phase's start, end [s] (the
    last: to infinity), the foot's joint, the object), worked out once per spec (:func:`_stands_on`
    asks for every MuJoCo contact and distance sample: ~10^5 times on the stairs)."""
    from tasks import surface_at

    spec = run.ref.plan.spec
    if _STANCES and _STANCES[0][0] is spec and _STANCES[0][3] is run.robot.model:
        return _STANCES[0][1]
    out: list[tuple[float, float, int, str]] = []
    start = 0.0
    for i, phase in enumerate(spec.phases):
        end = math.inf if i == len(spec.phases) - 1 else start + phase.duration  # the robot stays on it
        for c in phase.contacts:
            x, y, z = c.placement.position
            under = surface_at(spec.scene, x, y)
            if run.robot.foot_side(c.frame) is None or under.name is None or abs(under.height - z) > 0.01:
                continue
            out.append((start, end, run.robot.model.frames[run.robot.frame_id(c.frame)].parentJoint, under.name))
        start += phase.duration
    _STANCES[:] = [(spec, out, {}, run.robot.model)]
    return out


def scene_collision_check(run: RunRecord) -> Check:
    """The robot's closest approach to a scene object, or its first contact with one that is not
    planned (a hand touching the object of a ``touch`` target in its window, :func:`planned_touch`,
    is planned; any other fails). MuJoCo contacts at every tick, distances from the samples."""
    ts = run.t
    memo: dict[tuple, bool] = {}  # MuJoCo gives several contacts a tick per link and object (a height field: many)

    def is_planned(tick: int, link: str, obj: str) -> bool:
        if (tick, link, obj) not in memo:
            memo[(tick, link, obj)] = planned_touch(run, tick, link, obj)
        return memo[(tick, link, obj)]

    planned = [is_planned(c[0], c[1], c[2]) for c in run.scene_contacts]
    touches = [c for c, p in zip(run.scene_contacts, planned, strict=True) if p]
    touched = ""
    if touches:
        tick, link, obj, _ = touches[0]
        touched = f"; planned touch: {body_part(run.robot, link)} / {obj!r} at t = {ts[tick]:.2f} s"
        # every contact equal to a planned one is planned too (planned_touch reads only its tick,
        # link and object): dropped by its flag, not by a search of the list (quadratic: 6 min on the stairs)
        run = replace(run, scene_contacts=tuple(c for c, p in zip(run.scene_contacts, planned, strict=True) if not p),
                      scene_samples=tuple(x for x in run.scene_samples if not is_planned(*x[:3])))
    horizon = run.settings.scene_distance_horizon
    if not run.object_names:  # reported at the horizon: a finite number survives the JSON report
        return Check(
            name="scene collision: no objects", kind=CheckKind.SCENE_COLLISION, value=_mm(horizon), limit=0.0,
            unit="mm", ok=True, time=0.0, upper=False,
        )
    if run.scene_contacts:
        tick, link, obj, _ = run.scene_contacts[0]
        deepest = min(c[3] for c in run.scene_contacts if c[2] == obj and c[1] == link)
        part = body_part(run.robot, link)
        subject = f"{part} / {obj!r}"
        return Check(
            name=f"scene collision: {subject}{touched}", kind=CheckKind.SCENE_COLLISION, subject=subject,
            value=_mm(min(deepest, 0.0)), limit=0.0, unit="mm", ok=False, time=float(ts[tick]), upper=False,
            message=f"{part} ({link}) touched {obj!r} at t = {ts[tick]:.2f} s "
            f"({_mm(-min(deepest, 0.0)):.0f} mm deep; no contact with an object is planned)",
        )
    if not run.scene_samples:
        return Check(
            name=f"scene collision: no object within {horizon:g} m{touched}", kind=CheckKind.SCENE_COLLISION,
            value=_mm(horizon), limit=0.0, unit="mm", ok=True, time=0.0, upper=False,
        )
    tick, link, obj, dist = min(run.scene_samples, key=lambda x: x[3])
    subject = f"{body_part(run.robot, link)} / {obj!r}"
    return Check(
        name=f"scene collision: {subject}{touched}", kind=CheckKind.SCENE_COLLISION, subject=subject,
        value=_mm(dist), limit=0.0, unit="mm", ok=True, time=float(ts[tick]), upper=False,
    )
