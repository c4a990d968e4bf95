"""The certificate's lines for planned contacts on other body parts than the soles (a thigh on a seat).

Per contact frame of the spec that holds a contact with a support region (``Contact.region``) on a
scene object (the object under its region, :func:`tasks.scene.on_top`), over the samples where the
plan holds it (``PlanReference.active``):

* **where** (``SEAT_PLACEMENT``): the executed region corners (Pinocchio forward kinematics of the
  executed configurations) against the planned ones, worst distance [m] (limit: the feet's
  ``placement_limit``);
* **how long** (``SEAT_CONTACT``): the fraction of the planned time the frame's link touched the
  object in MuJoCo (its contacts at every tick); at least ``SEAT_TIME_FRACTION`` once
  ``SEAT_SETTLE`` [s] has passed after the planned touch-down, and no touch more than
  ``SEAT_PADDING`` [s] before it or after the planned lift-off;
* **no slip** (``SEAT_SLIP``): the frame's horizontal drift while held (limit: the feet's
  ``slip_limit``);
* **nothing else touches it**: MuJoCo contacts of the object with any other link of the robot
  (``SEAT_CONTACT``, subject ``others``) but the links between the base and the contact's link
  (a thigh's hip links, 5.7 mm above the seat on talos, touch it when the thigh sinks into MuJoCo's
  soft contact). The rest of the world (the floor, other
  objects) is the unplanned-contact and scene-collision lines' (:mod:`sim.certify`).

The **floor** is a surface too (a knee on it: ``kneel``): a region whose corners lie at the floor's
height (0, within 1 cm) and on no scene object is on the ``floor``; its touches are MuJoCo's floor
contacts of the link (``RunRecord.other_contacts``), and :func:`floor_touch_planned` tells the
unplanned-contact line which of them the plan holds (the link and the links between it and the base,
over its planned time and ``SEAT_PADDING``): any other body part on the floor fails that line.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from planner import Check, CheckKind
from sim.recording import RunRecord

SEAT_TIME_FRACTION = 0.9  # of the planned contact's samples after SEAT_SETTLE
SEAT_SETTLE = 0.3  # [s] after the planned touch-down: the thigh may settle onto the seat
SEAT_PADDING = 0.3  # [s] a touch this much before the planned touch-down (or after the lift-off) counts as planned
FLOOR = "floor"  # the object a region on the floor is on (no scene object)
FLOOR_TOLERANCE = 0.01  # [m] a region corner this close to z = 0 lies on the floor


def _region_contacts(run: RunRecord) -> dict[str, tuple[np.ndarray, str]]:
    """Frame name -> (region corners in the frame (4, 3), the object it sits on)."""
    from tasks import on_top

    spec = run.ref.plan.spec
    model = run.robot.model
    out: dict[str, tuple[np.ndarray, str]] = {}
    for phase in spec.phases:
        for c in phase.contacts:
            if c.region is None:
                continue
            M = pin.SE3(pin.rpy.rpyToMatrix(*c.placement.rpy), np.asarray(c.placement.position, dtype=float))
            corners = np.asarray(c.region, dtype=float)
            world = corners @ M.rotation.T + M.translation
            objects = spec.scene.objects if spec.scene is not None else ()
            obj = next((o.name for o in objects if all(on_top(o, p, tolerance=0.01) for p in world)), None)
            if obj is None and bool(np.all(np.abs(world[:, 2]) <= FLOOR_TOLERANCE)):
                obj = FLOOR
            if obj is not None:
                out[model.frames[run.robot.frame_id(c.frame)].name] = (corners, obj)
    return out


def seat_checks(run: RunRecord) -> list[Check]:
    """The where / how long / no slip / nothing else lines of every region contact on an object."""
    regions = _region_contacts(run)
    if not regions:
        return []
    model, data = run.robot.model, run.robot.model.createData()
    ts, s, ref = run.t, run.settings, run.ref
    knots = np.array([ref.index(t) for t in ts])
    touching: dict[tuple[str, str], set[int]] = {}
    owner = _owners(run, list(regions))
    for tick, link, obj, _ in run.scene_contacts:
        touching.setdefault((owner.get(link, link), obj), set()).add(int(tick))
    floor = any(obj == FLOOR for _, obj in regions.values())
    for t, link in run.other_contacts if floor else ():  # MuJoCo's floor contacts (a knee on the floor)
        touching.setdefault((owner.get(link, link), FLOOR), set()).add(int(np.searchsorted(ts, t - 1e-9)))
    out: list[Check] = []
    for frame, (corners, obj) in regions.items():
        fid = run.robot.frame_id(frame)
        act = ref.active[knots, ref.contact_frames.index(frame)]
        on = np.nonzero(act)[0]
        if not len(on):
            continue
        planned = ref.frames[frame]
        gap = np.zeros(len(ts))
        xy = np.zeros((len(ts), 2))
        for n in on:
            pin.forwardKinematics(model, data, run.q[n])
            M = pin.updateFramePlacement(model, data, fid)
            Mp = pin.SE3(planned.rotation[knots[n]], planned.position[knots[n]])
            gap[n] = float(np.linalg.norm((corners @ M.rotation.T + M.translation)
                                          - (corners @ Mp.rotation.T + Mp.translation), axis=1).max())
            xy[n] = M.translation[:2]
        k = int(np.argmax(gap))
        out.append(Check(name=f"{frame} on the {obj}: placement error", kind=CheckKind.SEAT_PLACEMENT, subject=frame,
                         value=float(gap[k]), limit=s.placement_limit, unit="m", ok=bool(gap[k] <= s.placement_limit),
                         time=float(ts[k]), message="" if gap[k] <= s.placement_limit else f"{frame}'s support region is {gap[k]:.3f} m from its planned place "
                         f"on the {obj} (> {s.placement_limit:.3f} m) at t = {ts[k]:.2f} s"))
        drift = np.linalg.norm(xy[on] - xy[on[0]], axis=1)
        j = int(np.argmax(drift))
        out.append(Check(name=f"{frame} on the {obj}: slip", kind=CheckKind.SEAT_SLIP, subject=frame,
                         value=float(drift[j]), limit=s.slip_limit, unit="m", ok=bool(drift[j] <= s.slip_limit),
                         time=float(ts[on[j]]), message="" if drift[j] <= s.slip_limit else f"{frame} slipped {drift[j]:.3f} m on the {obj} "
                         f"(> {s.slip_limit:.3f} m) by t = {ts[on[j]]:.2f} s"))
        out.append(_time_check(run, frame, obj, on, touching.get((frame, obj), set())))
    if any(obj != FLOOR for _, obj in regions.values()):  # the floor's others: the unplanned-contact line
        out.append(_others_check(run, {f: r for f, r in regions.items() if r[1] != FLOOR}, touching))
    return out


def floor_touch_planned(run: RunRecord) -> list[bool]:
    """Per floor touch of ``run.other_contacts``: True when a region contact on the floor holds its
    link (or the link is between that contact's link and the base: :func:`hip_links`) within
    ``SEAT_PADDING`` of the planned time."""
    floor = [f for f, (_, obj) in _region_contacts(run).items() if obj == FLOOR]
    if not floor:
        return [False] * len(run.other_contacts)
    ref = run.ref
    owner = _owners(run, floor)
    spans: dict[str, list[tuple[float, float]]] = {}
    for frame in floor:
        act = ref.active[:, ref.contact_frames.index(frame)]
        on = np.nonzero(act)[0]
        t0 = float(ref.plan.t[0])
        span = (t0 + on[0] * ref.dt - SEAT_PADDING, t0 + on[-1] * ref.dt + SEAT_PADDING) if len(on) else (1.0, 0.0)
        for link in {frame, *hip_links(run, frame, tuple(floor)), *(k for k, v in owner.items() if v == frame)}:
            spans.setdefault(link, []).append(span)
    return [any(a <= t <= b for a, b in spans.get(link, ())) for t, link in run.other_contacts]


def _owners(run: RunRecord, frames: list[str]) -> dict[str, str]:
    """Link name -> the region contact frame it belongs to: the frame's link and the links below it
    that carry no other contact of the spec (a hand's fingers and gripper links hold the hand's
    contact; a thigh's shin and foot, which carry the sole, are not the thigh's)."""
    model = run.robot.model
    spec = run.ref.plan.spec
    others = {int(model.frames[run.robot.frame_id(c.frame)].parentJoint) for p in spec.phases for c in p.contacts}
    out: dict[str, str] = {}
    for frame in frames:
        joint = int(model.frames[run.robot.frame_id(frame)].parentJoint)
        below = {int(j) for o in others - {joint} for j in model.supports[o]} - {joint}
        mine = set(model.subtrees[joint]) - below
        out.update({f.name: frame for f in model.frames if f.type == pin.FrameType.BODY and f.parentJoint in mine})
    return out


def _time_check(run: RunRecord, frame: str, obj: str, on: np.ndarray, ticks: set[int]) -> Check:
    """The fraction of the planned contact's samples (after SEAT_SETTLE) the link touched the object,
    and no touch outside the planned time (SEAT_PADDING)."""
    ts = run.t
    t0, t1 = float(ts[on[0]]), float(ts[on[-1]])
    settled = [n for n in on if ts[n] >= t0 + SEAT_SETTLE]
    frac = sum(n in ticks for n in settled) / max(len(settled), 1)
    early = sorted(n for n in ticks if ts[n] < t0 - SEAT_PADDING or ts[n] > t1 + SEAT_PADDING)
    ok = frac >= SEAT_TIME_FRACTION and not early
    when = float(ts[early[0]]) if early else t0
    msg = (f"{frame} touched the {obj} at t = {when:.2f} s, outside its planned {t0:.2f} to {t1:.2f} s" if early
           else f"{frame} touched the {obj} {100 * frac:.0f} % of its planned time (< {100 * SEAT_TIME_FRACTION:.0f} %)")
    return Check(name=f"{frame} on the {obj}: contact time", kind=CheckKind.SEAT_CONTACT, subject=frame, value=frac,
                 limit=SEAT_TIME_FRACTION, unit="", ok=ok, time=when, upper=False, message="" if ok else msg)


def hip_links(run: RunRecord, frame: str, regions: tuple[str, ...] = ()) -> set[str]:
    """The links between the base and a contact frame's link (a thigh's hip links: talos's
    ``leg_left_1_link`` and ``leg_left_2_link`` hang 5.7 mm above the sitting thigh's lowest point;
    a hand's arm links), but those that also carry another region contact of ``regions`` (the torso
    above both hands)."""
    model = run.robot.model
    joint = model.frames[run.robot.frame_id(frame)].parentJoint
    others = [model.frames[run.robot.frame_id(f)].parentJoint for f in regions if f != frame]
    chain = {int(j) for j in model.supports[joint] if not any(o in model.subtrees[j] for o in others)} - {0, 1, int(joint)}
    return {f.name for f in model.frames if f.type == pin.FrameType.BODY and f.parentJoint in chain}


def _hands(run: RunRecord, regions: dict[str, tuple[np.ndarray, str]]) -> bool:
    """A region contact on a hand (its frame's link or one below it: talos's fingertip)."""
    model = run.robot.model
    hands = {int(j) for s in ("left", "right") if run.robot.has_role(f"{s}_hand")
             for j in model.subtrees[model.frames[run.robot.frame_id(f"{s}_hand")].parentJoint]}
    return any(int(model.frames[run.robot.frame_id(f)].parentJoint) in hands for f in regions)


def _others_check(run: RunRecord, regions: dict[str, tuple[np.ndarray, str]],
                  touching: dict[tuple[str, str], set[int]]) -> Check:
    """No link but the planned ones (and their hip links, :func:`hip_links`) touches a sat-on object."""
    seats = {obj for _, obj in regions.values()}
    allowed = set(regions).union(*(hip_links(run, f, tuple(regions)) for f in regions))
    others = sorted((min(ticks), link, obj) for (link, obj), ticks in touching.items()
                    if obj in seats and link not in allowed)
    ok = not others
    tick, link, obj = others[0] if others else (0, "", "")
    return Check(name=f"only the planned links (and their {'arms' if _hands(run, regions) else 'hips'}) touch the {'/'.join(sorted(seats))}", kind=CheckKind.SEAT_CONTACT, subject="others",
                 value=float(len(others)), limit=0.0, unit="links", ok=ok, time=float(run.t[tick]),
                 message="" if ok else f"{link} touched the {obj} at t = {run.t[tick]:.2f} s (not planned)")
