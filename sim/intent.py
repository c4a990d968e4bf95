"""The certificate's intent lines: did the simulated motion do what its actions mean?

The other checks of :mod:`sim.certify` compare the simulation with the plan within fixed limits
(the CoM within 5 cm, a target within its tolerance + 3 cm), whatever the motion's size: a lean
of 3.4 cm that reached 1.3 cm, or a hop whose sole never left the ground, passes them. The lines
here measure, on the simulated motion (Pinocchio forward kinematics of the recorded
configurations, MuJoCo's floor contacts, coal on the URDF meshes), what the action is for, and
compare it with the plan:

- **contact events**: every planned lift-off and touch-down of a sole happens in the simulation
  within :data:`EVENT_TOLERANCE` of its planned time (off the floor: no MuJoCo contact and
  :data:`LIFT_CLEARANCE` above where it stood), and the sole rises at least
  :data:`AMPLITUDE_FRACTION` of its planned height;
- **flight**: for an action with flight phases (jump, hop, jog), both soles are off the floor
  at least :data:`FLIGHT_FRACTION` of the planned flight time;
- **amplitude**: a HARD CoM target (squat, lean, lunge, a hop's crouch), a frame orientation target
  (bow, head turns, nod) or a frame position target (raise, reach, kick) that moves away from
  where its action began reaches at least :data:`AMPLITUDE_FRACTION` of the planned shift;
- **steps and turns**: each sole's planned steps (length) and turns (yaw), achieved to
  :data:`AMPLITUDE_FRACTION` (a step short by at most :data:`STEP_SLACK` passes);
- **what the words mean**: the hands meet for a clap (coal distance between the hands' meshes
  within :data:`MEET_DISTANCE`), the hand at the head for a salute (within
  :data:`SALUTE_DISTANCE` of the head's meshes), the hand at the named part for a touch (within
  :data:`TOUCH_DISTANCE`: head, chest, the other shoulder, the other hand, the toes, the hip), and the arm points toward the named direction
  (within :data:`POINT_ANGLE` of a horizontal direction, :data:`POINT_VERTICAL_ANGLE` of up or down).

Every line names its action in the spec's words (a target or phase is named ``"<n> <action>:
<what>"``, :meth:`tasks.primitives.base.FragmentBuilder.name`), and a miss says what did not
happen: ``hop (action 1): both feet were off the floor 0.02 s of the planned 0.30 s``.
"""

from __future__ import annotations

import itertools
import math
import re
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from planner import Check, CheckKind
from sim.collisions import MeshDistance, object_shape
from sim.recording import RunRecord
from tasks import Priority

#: [s] a simulated lift-off or touch-down this close to the planned one happens as planned.
EVENT_TOLERANCE = 0.15
#: A simulated contact change must last this long to count [s] (chatter of a loaded sole is none).
EVENT_MIN_DURATION = 0.02
#: [m] a sole is off the floor when MuJoCo sees no contact and it is this far above where it stood.
LIFT_CLEARANCE = 0.003
#: Fraction of a planned shift, swing height, step or turn the simulation must achieve.
AMPLITUDE_FRACTION = 0.8
#: Fraction of the planned flight time the simulation must spend with both soles off the floor.
FLIGHT_FRACTION = 0.25
#: [s] an instant target is looked for this long either side of its time (the robot lags its plan).
LAG = 0.15
#: Planned shifts smaller than these are no amplitude (a "hold still" target) [m], [rad].
MIN_SHIFT = 0.015
MIN_ROTATION = 0.05
MIN_HAND_SHIFT = 0.04
MIN_STEP = 0.03
MIN_TURN = 0.05
#: [m] a step may always fall this much short (a landing's precision: G1's 3 cm forward hops land
#: 7 mm short, 77 %; the placement line allows 2 cm).
STEP_SLACK = 0.01
#: [rad] a turn may always fall this much short (1.7 deg, which nobody watching sees: G1's hand
#: turned 0.04 rad of a planned 0.06 rad as it let go of a box it put down).
TURN_SLACK = 0.03
#: [m] the hands' meshes this close meet (a clap).
MEET_DISTANCE = 0.01
#: [m] the saluting hand's meshes this close to the head's.
SALUTE_DISTANCE = 0.03
#: [rad] the pointing arm (shoulder to hand) this close to a horizontal named direction ...
POINT_ANGLE = math.radians(20.0)
#: [rad] ... and to up or down (the primitive tilts those 0.5 forward, 27 deg: a straight arm up
#: saturates Talos's shoulder, tasks.primitives.arms.point_direction; the arm still reads as up).
POINT_VERTICAL_ANGLE = math.radians(30.0)

_LABEL = re.compile(r"^(?P<n>\d+) (?P<action>[a-z_]+): (?P<what>.*)$")


@dataclass(frozen=True, slots=True)
class Label:
    """The action a spec item belongs to: its number in the sentence, its name, the item's words."""

    number: int
    action: str
    what: str

    @property
    def who(self) -> str:
        """``"hop (action 1)"``."""
        return f"{self.action.replace('_', ' ')} (action {self.number})"


def label_of(name: str) -> Label | None:
    """The action of a target or phase name ``"<n> <action>: <what>"`` (None: not an action's)."""
    m = _LABEL.match(name)
    return Label(int(m["n"]), m["action"], m["what"]) if m else None


#: Object -> (its centre's positions (T', 3) [m], its orientations (T', 4) as (x, y, z, w)) over the
#: run's ticks (MuJoCo; the movable objects), as :class:`sim.grasp.GraspRig` records them.
ObjectPoses = dict[str, tuple[np.ndarray, np.ndarray]]


def intent_checks(run: RunRecord, objects: ObjectPoses | None = None) -> list[Check]:
    """Every intent line of the run (see the module docstring), in the order of their actions.
    ``objects``: where the movable scene objects were (a fixed one, or one not given, stays where
    the scene puts it)."""
    if len(run.t) == 0:
        return []
    frames = _Frames(run)
    out: list[Check] = []
    out += contact_event_checks(run, frames)
    out += flight_checks(run)
    out += amplitude_checks(run, frames)
    out += step_checks(run, frames)
    out += word_checks(run, frames)
    out += object_touch_checks(run, objects or {})
    return out


# --- what the run did, by frame -------------------------------------------------------------
class _Frames:
    """Positions and rotations of frames over the run's ticks (Pinocchio FK on the record), and the
    plan's, computed when first asked for."""

    def __init__(self, run: RunRecord) -> None:
        self.run = run
        self._pos: dict[str, np.ndarray] = {}
        self._rot: dict[str, np.ndarray] = {}
        self.knots = np.array([run.ref.index(t) for t in run.t])
        starts = run.ref.plan.spec.phase_start_times()
        self.action_start: dict[int, float] = {}
        for phase, t0 in zip(run.ref.plan.spec.phases, starts, strict=True):
            lab = label_of(phase.name)
            if lab is not None and lab.number not in self.action_start:
                self.action_start[lab.number] = float(t0)

    def name(self, frame: str) -> str:
        robot = self.run.robot
        return robot.model.frames[robot.frame_id(frame)].name

    def sim(self, frame: str) -> tuple[np.ndarray, np.ndarray]:
        """(positions (T', 3), rotations (T', 3, 3)) of ``frame`` in the simulation."""
        name = self.name(frame)
        if name not in self._pos:
            model = self.run.robot.model
            data = model.createData()
            fid = model.getFrameId(name)
            pos = np.empty((len(self.run.t), 3))
            rot = np.empty((len(self.run.t), 3, 3))
            for n, q in enumerate(self.run.q):
                pin.forwardKinematics(model, data, q)
                placement = pin.updateFramePlacement(model, data, fid)
                pos[n], rot[n] = placement.translation, placement.rotation
            self._pos[name], self._rot[name] = pos, rot
        return self._pos[name], self._rot[name]

    def plan(self, frame: str) -> tuple[np.ndarray, np.ndarray] | None:
        """(positions, rotations) of ``frame`` in the plan at the run's ticks (None: not tracked)."""
        track = self.run.ref.frames.get(self.name(frame))
        if track is None:
            return None
        return track.position[self.knots], track.rotation[self.knots]

    def start_tick(self, lab: Label | None) -> int:
        """The tick where the action of ``lab`` begins (0 without one)."""
        t0 = self.action_start.get(lab.number, 0.0) if lab is not None else 0.0
        return int(np.argmin(np.abs(self.run.t - t0)))


def _mask(ts: np.ndarray, time: float | None, window: tuple[float, float] | None,
          horizon: float) -> tuple[np.ndarray, bool]:
    """Ticks where a target applies, and whether it is held over a window (an instant is looked for
    within :data:`LAG` of its time)."""
    if window is not None:
        return (ts >= window[0] - 1e-9) & (ts <= window[1] + 1e-9), True
    t_at = horizon if time is None else time
    return np.abs(ts - t_at) <= LAG, False


def _achieved(values: np.ndarray, held: bool) -> float:
    """What a target achieved over its ticks: the median of a held window, the best of an instant."""
    return float(np.median(values)) if held else float(np.max(values))


def _line(kind: CheckKind, lab: Label | None, subject: str, what: str, value: float, limit: float, unit: str,
          ok: bool, time: float, message: str, *, upper: bool = False) -> Check:
    who = lab.who if lab is not None else "the motion"
    return Check(name=f"intent: {who}: {what}", kind=kind, subject=subject, value=value, limit=limit, unit=unit,
                 ok=ok, time=time, upper=upper, message="" if ok else f"{who}: {message}")


# --- contact events and flights ------------------------------------------------------------
def _runs(flags: np.ndarray) -> list[tuple[int, int]]:
    """(start, end) index ranges (end exclusive) where ``flags`` is True."""
    padded = np.concatenate([[False], flags.astype(bool), [False]])
    edges = np.flatnonzero(np.diff(padded.astype(int)))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist(), strict=True))


def debounce(flags: np.ndarray, dt: float, min_duration: float = EVENT_MIN_DURATION) -> np.ndarray:
    """Contact flags whose state changes only where the new state lasts ``min_duration`` [s]
    (chatter of a loaded sole, a sole grazing the floor in a swing: no change)."""
    n = max(1, int(round(min_duration / dt)))
    flags = flags.astype(bool)
    out = np.empty_like(flags)
    if not len(flags):
        return out
    state, start = bool(flags[0]), 0
    for i in (np.flatnonzero(np.diff(flags.astype(np.int8))) + 1).tolist():
        if bool(flags[i]) != state and np.all(flags[i:i + n] == flags[i]):
            out[start:i] = state
            state, start = bool(flags[i]), i
    out[start:] = state
    return out


def _phase_label(run: RunRecord, t: float) -> Label | None:
    spec = run.ref.plan.spec
    return label_of(spec.phases[spec.phase_at(t)].name)


def _stance_floor(planned: np.ndarray, plan_z: np.ndarray, floor: float) -> float | np.ndarray:
    """The floor a sole's rise is measured from: ``floor`` (the lowest simulated stance height) on
    one level; on steps (planned stances whose median heights differ by more than 1 cm), per tick
    the median planned height of the stance it stands in, and during a swing the lower of the
    stances before and after it (stepping down, the sole is back on a tread below where it stood:
    against the old height it "touched down" 0.17 s early on talos's stairs). Each stance's median, not its every
    tick: the plan's sole, interpolated between knots, is already rising on a stance's last ticks
    before a short flight (a g1 hop's 2-knot flight: 1.8 cm)."""
    runs = _runs(planned)
    heights = [float(np.median(plan_z[a:b])) for a, b in runs]
    if max(heights) - min(heights) <= 0.01:
        return floor
    out = np.full(len(planned), floor, dtype=float)
    starts = [a for a, _ in runs]
    for i, ((a, b), nxt, h) in enumerate(zip(runs, [*starts[1:], len(planned)], heights, strict=True)):
        out[a:b] = h
        # the swing after it: the lower of the two stances (a step down lands below where it stood)
        out[b:nxt] = min(h, heights[i + 1]) if i + 1 < len(heights) else h
    return out


def contact_event_checks(run: RunRecord, frames: _Frames) -> list[Check]:
    """Per sole with planned swings: each lift-off and touch-down within :data:`EVENT_TOLERANCE` of
    the plan's, and the sole's rise at least :data:`AMPLITUDE_FRACTION` of the planned one."""
    ref, ts = run.ref, run.t
    dt = float(np.median(np.diff(ts))) if len(ts) > 1 else ref.dt
    out: list[Check] = []
    for j, frame in enumerate(run.foot_frames):
        if frame not in ref.contact_frames:
            continue
        planned = ref.active[frames.knots, ref.contact_frames.index(frame)]
        swings = [(a, b) for a, b in _runs(~planned) if a > 0]  # the sole's planned time off the floor
        if not swings:
            continue
        side = run.robot.foot_side(frame)
        foot = f"{side} foot" if side else frame
        plan_track = frames.plan(frame)
        sim_z = frames.sim(frame)[0][:, 2]
        lowest = float(np.min(sim_z[planned])) if planned.any() else float(sim_z[0])
        floor: float | np.ndarray = lowest
        if plan_track is not None and planned.any():  # on terrain: the height the sole last stood at (plan)
            floor = _stance_floor(planned, plan_track[0][:, 2], lowest)
        sim_off = debounce(~run.contact_flags[j] & (sim_z > floor + LIFT_CLEARANCE), dt)
        worst: tuple[float, int, str, Label | None] = (0.0, 0, "", None)  # timing error [s], tick, what, label
        low: tuple[float, int, str, Label | None] = (math.inf, 0, "", None)  # rise fraction, tick, what, label
        for a, b in swings:
            lab = _phase_label(run, float(ts[a]))
            ends_on = b < len(ts)
            for tick, change, want_off in ((a, "lift-off", True), (b, "touch-down", False)):
                if tick >= len(ts):
                    continue
                err = _event_error(sim_off, ts, tick, want_off)
                if err > worst[0] or (math.isinf(err) and not math.isinf(worst[0])):
                    worst = (err, tick, change, lab)
                if not ends_on:
                    break
            if plan_track is not None:
                z_plan = plan_track[0][:, 2]
                rise_plan = float(z_plan[a:b].max() - z_plan[a - 1])
                if rise_plan >= MIN_SHIFT:
                    rise_sim = float(sim_z[a:b + 1].max() - sim_z[a - 1]) if b > a else 0.0
                    frac = rise_sim / rise_plan
                    if frac < low[0]:
                        low = (frac, a, f"rose {rise_sim:.3f} m of the planned {rise_plan:.3f} m", lab)
        err, tick, change, lab = worst
        ok = err <= EVENT_TOLERANCE
        msg = (f"the {foot} did not {'leave' if change == 'lift-off' else 'come back to'} the floor at "
               f"t = {ts[tick]:.2f} s as planned" + ("" if math.isinf(err) else f" ({err:.2f} s off)"))
        out.append(_line(CheckKind.INTENT_CONTACTS, lab, foot, f"{foot} lift-offs and touch-downs as planned",
                         err if math.isfinite(err) else 99.0, EVENT_TOLERANCE, "s", ok, float(ts[tick]), msg,
                         upper=True))
        if math.isfinite(low[0]):
            frac, tick, words, lab = low
            ok = frac >= AMPLITUDE_FRACTION
            out.append(_line(CheckKind.INTENT_AMPLITUDE, lab, foot, f"{foot} lifted as high as planned",
                             100 * frac, 100 * AMPLITUDE_FRACTION, "%", ok, float(ts[tick]),
                             f"the {foot} {words} ({100 * frac:.0f} %)"))
    return out


def _event_error(sim_off: np.ndarray, ts: np.ndarray, tick: int, want_off: bool) -> float:
    """How far [s] from tick ``tick`` the simulated sole changes to off (``want_off``) or on: the
    nearest tick where it is in the wanted state after being in the other one (inf: never within
    twice the tolerance)."""
    state = sim_off if want_off else ~sim_off
    lo = int(np.searchsorted(ts, ts[tick] - 2 * EVENT_TOLERANCE))
    hi = int(np.searchsorted(ts, ts[tick] + 2 * EVENT_TOLERANCE))
    seg = state[max(lo, 1):hi]
    prev = state[max(lo, 1) - 1:hi - 1]
    changes = np.flatnonzero(seg & ~prev) + max(lo, 1)
    if len(changes) == 0:
        return math.inf
    return float(np.min(np.abs(ts[changes] - ts[tick])))


def flight_checks(run: RunRecord) -> list[Check]:
    """Per action with flight phases: the time both soles are off the floor in the simulation, at
    least :data:`FLIGHT_FRACTION` of the planned flight time."""
    spec, ts = run.ref.plan.spec, run.t
    if not run.foot_frames:
        return []
    dt = float(np.median(np.diff(ts))) if len(ts) > 1 else run.ref.dt
    airborne = ~np.any([debounce(f, dt, 0.0) for f in run.contact_flags], axis=0)
    flights: dict[int, list[tuple[float, float]]] = {}
    labels: dict[int, Label] = {}
    for phase, t0 in zip(spec.phases, spec.phase_start_times(), strict=True):
        if phase.contacts:
            continue
        lab = label_of(phase.name) or Label(0, "flight", phase.name)
        flights.setdefault(lab.number, []).append((float(t0), float(t0 + phase.duration)))
        labels[lab.number] = lab
    out = []
    for number, spans in flights.items():
        planned = sum(b - a for a, b in spans)
        inside = np.zeros(len(ts), dtype=bool)
        for a, b in spans:
            inside |= (ts >= a - EVENT_TOLERANCE) & (ts <= b + EVENT_TOLERANCE)
        achieved = float(np.count_nonzero(airborne & inside)) * dt
        frac = achieved / planned
        lab = labels[number]
        out.append(_line(CheckKind.INTENT_FLIGHT, lab, lab.action, "flight time as planned", 100 * frac,
                         100 * FLIGHT_FRACTION, "%", frac >= FLIGHT_FRACTION, spans[0][0],
                         f"both feet were off the floor {achieved:.2f} s of the planned {planned:.2f} s "
                         f"({100 * frac:.0f} %): the robot did not leave the ground"))
    return out


# --- amplitudes -----------------------------------------------------------------------------
def amplitude_checks(run: RunRecord, frames: _Frames) -> list[Check]:
    """CoM, orientation and position targets reached to :data:`AMPLITUDE_FRACTION` of their planned
    shift from where their action began."""
    spec, ts = run.ref.plan.spec, run.t
    horizon = run.ref.duration
    plan_com = run.ref.plan_com[frames.knots]
    out: list[Check] = []
    for com_target in spec.com_targets:
        lab = label_of(com_target.name)
        mask, held = _mask(ts, com_target.time, com_target.window, horizon)
        if not mask.any() or com_target.priority is Priority.SOFT:  # soft: a waypoint shaping the path
            continue
        axes = np.array([v is not None for v in com_target.position], dtype=float)
        k0 = frames.start_tick(lab)
        shift_plan = (plan_com[mask] - plan_com[k0]) * axes
        mean_plan = shift_plan.mean(axis=0)
        size = float(np.linalg.norm(mean_plan))
        if size < MIN_SHIFT:
            continue
        u = mean_plan / size
        shift_sim = ((run.com[mask] - run.com[k0]) * axes) @ u
        achieved = _achieved(shift_sim, held)
        out.append(_ratio_line(lab, com_target.name, "CoM shift", achieved, size, "m", ts, mask))
    for target in spec.targets:
        lab = label_of(target.name)
        mask, held = _mask(ts, target.time, target.window, horizon)
        track = frames.plan(target.frame)
        if not mask.any() or track is None or target.touch is not None or target.priority is Priority.SOFT:
            continue
        k0 = frames.start_tick(lab)
        sim_pos, sim_rot = frames.sim(target.frame)
        if target.rpy is not None:
            rel = [pin.log3(track[1][k0].T @ r) for r in track[1][mask]]
            mean_plan = np.mean(rel, axis=0)
            size = float(np.linalg.norm(mean_plan))
            if size >= MIN_ROTATION:
                u = mean_plan / size
                turned = np.array([pin.log3(sim_rot[k0].T @ r) @ u for r in sim_rot[mask]])
                out.append(_ratio_line(lab, target.name, "turn", _achieved(turned, held), size, "rad", ts, mask,
                                       slack=TURN_SLACK))
        if target.position is not None:
            axes = np.array(target.axes, dtype=float)
            shift_plan = (track[0][mask] - track[0][k0]) * axes
            mean_plan = shift_plan.mean(axis=0)
            size = float(np.linalg.norm(mean_plan))
            if size >= MIN_HAND_SHIFT:
                u = mean_plan / size
                moved = ((sim_pos[mask] - sim_pos[k0]) * axes) @ u
                out.append(_ratio_line(lab, target.name, "reach", _achieved(moved, held), size, "m", ts, mask))
    return _worst_per_action(out)


def _worst_per_action(lines: list[Check]) -> list[Check]:
    """The worst line of each action and measure (one "CoM shift" line of a squat of three
    repetitions, the one that reached least)."""
    best: dict[tuple[str, str], Check] = {}
    for c in lines:
        key = (c.name.split(": ")[1], c.name.rsplit(": ", 1)[-1])
        if key not in best or c.value < best[key].value:
            best[key] = c
    return list(best.values())


def _ratio_line(lab: Label | None, name: str, what: str, achieved: float, planned: float, unit: str,
                ts: np.ndarray, mask: np.ndarray, *, slack: float = 0.0) -> Check:
    """``achieved`` at least :data:`AMPLITUDE_FRACTION` of ``planned``, or short of it by at most ``slack``."""
    frac = achieved / planned
    words = lab.what if lab is not None else name
    t_at = float(ts[np.flatnonzero(mask)[0]])
    fmt = ".3f" if unit == "m" else ".2f"
    return _line(CheckKind.INTENT_AMPLITUDE, lab, name, f"{words}: {what}", 100 * frac, 100 * AMPLITUDE_FRACTION,
                 "%", frac >= AMPLITUDE_FRACTION or planned - achieved <= slack, t_at,
                 f"{words}: the {what} reached {achieved:{fmt}} {unit} of the planned {planned:{fmt}} {unit} "
                 f"({100 * frac:.0f} %) at t = {t_at:.2f} s")


# --- steps and turns ------------------------------------------------------------------------
def _yaw(rot: np.ndarray) -> float:
    return float(math.atan2(rot[1, 0], rot[0, 0]))


def _wrap(a: float) -> float:
    return (a + math.pi) % (2 * math.pi) - math.pi


def step_checks(run: RunRecord, frames: _Frames) -> list[Check]:
    """Per action that moves a sole to a new placement: each step's length and each turn's yaw in
    the simulation (the sole's position and heading in the middle of each stance) to
    :data:`AMPLITUDE_FRACTION` of the plan's; one line per action for steps, one for turns (the
    worst)."""
    spec, ts = run.ref.plan.spec, run.t
    starts = spec.phase_start_times()
    # (action, "step" | "turn") -> (passes, fraction, achieved, planned, time, label, foot) of its worst step
    worst: dict[tuple[int, str], tuple[bool, float, float, float, float, Label, str]] = {}
    for frame in spec.contact_frames():
        stances: list[tuple[float, float, np.ndarray, float, Label | None]] = []  # t0, t1, xy, yaw, label
        for phase, t0 in zip(spec.phases, starts, strict=True):
            contact = next((c for c in phase.contacts if c.frame == frame), None)
            if contact is None:
                continue
            xy = np.array(contact.placement.position[:2])
            yaw = float(contact.placement.rpy[2])
            t1 = t0 + phase.duration
            if stances and np.allclose(stances[-1][2], xy, atol=1e-6) and abs(stances[-1][3] - yaw) < 1e-6 \
                    and stances[-1][1] >= t0 - 1e-9:
                stances[-1] = (stances[-1][0], t1, xy, yaw, stances[-1][4])
            else:
                stances.append((t0, t1, xy, yaw, label_of(phase.name)))
        if len(stances) < 2:
            continue
        pos, rot = frames.sim(frame)
        side = run.robot.foot_side(frame)
        foot = f"{side} foot" if side else frame

        def at(s, pos=pos, rot=rot):
            n = int(np.argmin(np.abs(ts - 0.5 * (s[0] + s[1]))))
            return pos[n, :2], _yaw(rot[n]), n

        for prev, cur in itertools.pairwise(stances):
            lab = cur[4] or _phase_label(run, cur[0])
            if lab is None or cur[0] > ts[-1]:
                continue
            (p0, y0, _), (p1, y1, n1) = at(prev), at(cur)
            step_plan = cur[2] - prev[2]
            length = float(np.linalg.norm(step_plan))
            if length >= MIN_STEP:
                achieved = float((p1 - p0) @ step_plan / length)
                frac = achieved / length
                ok = frac >= AMPLITUDE_FRACTION or length - achieved <= STEP_SLACK
                key = (lab.number, "step")
                if key not in worst or (ok, frac) < worst[key][:2]:
                    worst[key] = (ok, frac, achieved, length, float(ts[n1]), lab, foot)
            turn = _wrap(cur[3] - prev[3])
            if abs(turn) >= MIN_TURN:
                achieved = _wrap(y1 - y0) * math.copysign(1.0, turn)
                frac = achieved / abs(turn)
                key = (lab.number, "turn")
                if key not in worst or (frac >= AMPLITUDE_FRACTION, frac) < worst[key][:2]:
                    worst[key] = (frac >= AMPLITUDE_FRACTION, frac, achieved, abs(turn), float(ts[n1]), lab, foot)
    out = []
    for (_, kind), (ok, frac, achieved, planned, t, lab, foot) in sorted(worst.items()):
        if kind == "step":
            what, msg = "step lengths as planned", (f"a step of the {foot} went {achieved:.3f} m of the planned "
                                                    f"{planned:.3f} m ({100 * frac:.0f} %)")
        else:
            what, msg = "turn angles as planned", (f"the {foot} turned {math.degrees(achieved):.0f} deg of the planned "
                                                   f"{math.degrees(planned):.0f} deg ({100 * frac:.0f} %)")
        out.append(_line(CheckKind.INTENT_STEPS, lab, foot, what, 100 * frac, 100 * AMPLITUDE_FRACTION, "%",
                         ok, t, msg))
    return out


# --- what the words mean: clap, salute, point ------------------------------------------------
def _subtree_links(run: RunRecord, frame: str, mesh: MeshDistance, *, subtree: bool = True,
                   toucher: str | None = None) -> list[str]:
    """The links with collision meshes at or below ``frame``'s parent joint (only on it: not
    ``subtree``, for a body part whose subtree is most of the robot: the torso, the pelvis). A part
    whose joint carries the ``toucher`` frame's (G1's head, fixed on the torso that carries the
    arms) is its own link only: the torso and the touching arm are not the head."""
    model = run.robot.model
    fid = run.robot.frame_id(frame)
    joint = model.frames[fid].parentJoint
    if toucher is not None and joint in set(model.supports[model.frames[run.robot.frame_id(toucher)].parentJoint]):
        return [link for link in mesh.links() if link == model.frames[fid].name]
    below = set(model.subtrees[joint]) if subtree else {joint}
    return [link for link in mesh.links() if model.frames[model.getFrameId(link)].parentJoint in below]


#: [m] a touching hand's meshes this close to the named part's.
TOUCH_DISTANCE = 0.03


def _touched_part(run: RunRecord, side: str, part: str) -> tuple[str, bool] | None:
    """(frame, whole subtree) of the body part a ``side`` hand touches (None: no frame for it)."""
    other = "right" if side == "left" else "left"
    role, subtree = {"head": ("head", True), "chest": ("torso", False), "shoulder": (f"{other}_shoulder", False),
                     "hand": (f"{other}_hand", True), "toes": (f"{side}_foot", True),
                     "hip": ("base", False)}.get(part, ("", False))
    return (role, subtree) if role and run.robot.has_role(role) else None


def _mesh_gap(mesh: MeshDistance, q: np.ndarray, a: Iterable[str], b: Iterable[str]) -> float:
    return min(mesh.between(q, x, y) for x in a for y in b)


def word_checks(run: RunRecord, frames: _Frames) -> list[Check]:
    """The clap's hands meet, the salute's hand is at the head, the point's arm points the way."""
    spec, ts = run.ref.plan.spec, run.t
    horizon = run.ref.duration
    out: list[Check] = []
    mesh: MeshDistance | None = None
    claps: dict[int, list] = {}
    for target in spec.targets:
        lab = label_of(target.name)
        if lab is None:
            continue
        if lab.action == "clap" and re.search(r"hand clap #\d+$", lab.what):
            claps.setdefault(lab.number, []).append(target)
        elif lab.action == "salute" and lab.what.endswith("at the forehead"):
            mesh = mesh or MeshDistance(run.robot)
            mask, _ = _mask(ts, target.time, target.window, horizon)
            if not mask.any() or not run.robot.has_role("head"):
                continue
            hand = _subtree_links(run, target.frame, mesh)
            head = _subtree_links(run, "head", mesh, toucher=target.frame)
            ticks = np.flatnonzero(mask)[:: max(1, int(np.count_nonzero(mask) // 8))]
            gaps = [_mesh_gap(mesh, run.q[n], hand, head) for n in ticks]
            gap = float(np.median(gaps))
            n = int(ticks[int(np.argmin(gaps))])
            out.append(_line(CheckKind.INTENT_WORDS, lab, "salute", "the hand at the head", gap, SALUTE_DISTANCE, "m",
                             gap <= SALUTE_DISTANCE, float(ts[n]),
                             f"the hand stayed {gap:.3f} m from the head (at most {SALUTE_DISTANCE:.2f} m: a "
                             "salute touches the forehead)", upper=True))
        elif lab.action == "touch" and " at the " in lab.what:
            side = "left" if lab.what.startswith("left") else "right"
            part = lab.what.rsplit(" at the ", 1)[-1].strip()
            found = _touched_part(run, side, "hand" if part == "other hand" else part)
            mask, _ = _mask(ts, target.time, target.window, horizon)
            if found is None or not mask.any():
                continue
            mesh = mesh or MeshDistance(run.robot)
            hand = _subtree_links(run, target.frame, mesh)
            body = _subtree_links(run, found[0], mesh, subtree=found[1],
                                  toucher=target.frame if found[0] == "head" else None)
            ticks = np.flatnonzero(mask)[:: max(1, int(np.count_nonzero(mask) // 8))]
            gaps = [_mesh_gap(mesh, run.q[n], hand, body) for n in ticks]
            gap = float(np.median(gaps))
            out.append(_line(CheckKind.INTENT_WORDS, lab, f"touch {part}", f"the {side} hand at the {part}", gap,
                             TOUCH_DISTANCE, "m", gap <= TOUCH_DISTANCE, float(ts[ticks[0]]),
                             f"the {side} hand stayed {gap:.3f} m from the {part} (a touch comes within "
                             f"{TOUCH_DISTANCE:.2f} m)", upper=True))
        elif lab.action == "point" and " pointing " in f" {lab.what}" and target.window is not None:
            out.append(_point_line(run, frames, target, lab))
    for targets in claps.values():
        mesh = mesh or MeshDistance(run.robot)
        lab = label_of(targets[0].name)
        if lab is None:  # pragma: no cover - claps are collected by their label
            continue
        sides = {t.frame: t for t in targets}
        if len(sides) < 2:
            continue
        hands = [_subtree_links(run, f, mesh) for f in sides]
        times = sorted({t.time for t in targets if t.time is not None})
        worst, t_worst = 0.0, 0.0
        for t_at in times:
            ticks = np.flatnonzero(np.abs(ts - t_at) <= LAG)[::10]
            if not len(ticks):
                worst, t_worst = math.inf, t_at
                break
            gap = min(_mesh_gap(mesh, run.q[n], hands[0], hands[1]) for n in ticks)
            if gap >= worst:
                worst, t_worst = gap, t_at
        out.append(_line(CheckKind.INTENT_WORDS, lab, "clap", "the hands meet", worst if math.isfinite(worst) else 99.0,
                         MEET_DISTANCE, "m", worst <= MEET_DISTANCE, t_worst,
                         f"the hands never met at t = {t_worst:.2f} s: their meshes stayed {worst:.3f} m apart "
                         f"(a clap closes to {MEET_DISTANCE:.2f} m)", upper=True))
    return out


#: [m] the hand's meshes this close to the object it touches (touch_object: coal, median over the hold).
OBJECT_TOUCH_DISTANCE = 0.01


def _object_placement(obj, poses: ObjectPoses, tick: int) -> pin.SE3:
    """Where ``obj`` is at ``tick``: its recorded pose, else where the scene puts it."""
    if obj.name in poses and len(poses[obj.name][0]):
        pos, quat = poses[obj.name]
        k = min(tick, len(pos) - 1)
        x, y, z, w = (float(v) for v in quat[k])
        return pin.SE3(pin.Quaternion(w, x, y, z).toRotationMatrix(), np.asarray(pos[k], dtype=float))
    return pin.SE3(pin.rpy.rpyToMatrix(*(float(v) for v in obj.rpy)), np.asarray(obj.position, dtype=float))


def object_touch_checks(run: RunRecord, poses: ObjectPoses) -> list[Check]:
    """touch_object: the touching hand's collision meshes (every link below its frame's joint) at
    the object's box, cylinder or sphere (coal, where MuJoCo has the object), the median over the
    held window within :data:`OBJECT_TOUCH_DISTANCE`."""
    spec, ts = run.ref.plan.spec, run.t
    scene = {o.name: o for o in spec.scene.objects} if spec.scene is not None else {}
    mesh: MeshDistance | None = None
    out: list[Check] = []
    for target in spec.targets:
        lab = label_of(target.name)
        obj = scene.get(target.touch or "")
        if lab is None or lab.action != "touch_object" or obj is None:
            continue
        shape = object_shape(obj.shape, obj.size)
        mask, _ = _mask(ts, target.time, target.window, run.ref.duration)
        if shape is None or not mask.any():
            continue
        mesh = mesh or MeshDistance(run.robot)
        hand = _subtree_links(run, target.frame, mesh)
        ticks = np.flatnonzero(mask)[:: max(1, int(np.count_nonzero(mask) // 8))]
        gaps = [mesh.to_shape(run.q[n], hand, shape, _object_placement(obj, poses, int(n))) for n in ticks]
        gap = float(np.median(gaps))
        side = "left" if lab.what.startswith("left") else "right"
        out.append(_line(CheckKind.INTENT_WORDS, lab, f"touch the {obj.name}", f"the {side} hand at the {obj.name}",
                         gap, OBJECT_TOUCH_DISTANCE, "m", gap <= OBJECT_TOUCH_DISTANCE, float(ts[ticks[0]]),
                         f"the {side} hand stayed {gap:.3f} m from the {obj.name} (a touch comes within "
                         f"{OBJECT_TOUCH_DISTANCE:.2f} m)", upper=True))
    return out


_DIRECTIONS = {"forward": (1.0, 0.0, 0.0), "left": (0.0, 1.0, 0.0), "right": (0.0, -1.0, 0.0),
               "up": (0.0, 0.0, 1.0), "down": (0.0, 0.0, -1.0), "backward": (-1.0, 0.0, 0.0)}


def _point_line(run: RunRecord, frames: _Frames, target, lab: Label) -> Check:
    """The arm (shoulder frame to hand frame) within :data:`POINT_ANGLE` of the named direction, in
    the heading of the stance the point starts from (the soles' mean yaw)."""
    ts = run.t
    direction = lab.what.rsplit("pointing ", 1)[-1].strip()
    side = "left" if target.frame in ("left_hand", run.robot.frame("left_hand")) else "right"
    mask, _ = _mask(ts, target.time, target.window, run.ref.duration)
    want = np.array(_DIRECTIONS.get(direction, (1.0, 0.0, 0.0)))
    k0 = frames.start_tick(lab)
    yaws = [_yaw(frames.sim(f)[1][k0]) for f in run.foot_frames]
    heading = float(np.arctan2(np.mean(np.sin(yaws)), np.mean(np.cos(yaws)))) if yaws else 0.0
    want = pin.rpy.rpyToMatrix(0.0, 0.0, heading) @ want
    shoulder_role = f"{side}_shoulder"
    if not run.robot.has_role(shoulder_role):
        shoulder_role = "torso"
    hand = frames.sim(target.frame)[0][mask]
    root = frames.sim(shoulder_role)[0][mask]
    arm = hand - root
    cosines = (arm @ want) / np.maximum(np.linalg.norm(arm, axis=1), 1e-9)
    angle = float(np.median(np.arccos(np.clip(cosines, -1.0, 1.0))))
    t_at = float(ts[np.flatnonzero(mask)[0]])
    limit = POINT_VERTICAL_ANGLE if direction in ("up", "down") else POINT_ANGLE
    return _line(CheckKind.INTENT_WORDS, lab, "point", f"the arm points {direction}", angle, limit, "rad",
                 angle <= limit, t_at,
                 f"the {side} arm points {math.degrees(angle):.0f} deg away from {direction} (at most "
                 f"{math.degrees(limit):.0f} deg)", upper=True)
