"""Rules for the legs of a retarget: how a swinging foot lands, and which of the source's swings
and flights the robot makes as steps (docs/retarget.md, "Session 17").

* :func:`land_softly`: a swinging foot's target comes onto its placement (and leaves the one it
  left) no faster than :data:`LAND_SPEED`. The target is a blend between the placement left and
  the next one plus the source's own departure from that blend (its lift, a kick's excursion); near
  touch-down (and lift-off) that departure is capped to what :data:`LAND_SPEED` covers in the time
  left (since). A march's foot also leaves forwards at 2 m/s (its knee raised): the plan's first
  swinging knot was 0.1 m across, and a foot that leaves a few milliseconds early is that far off
  its placement while the certificate still holds its stance. A marching human stamps
  down from 0.2 m in two knots (2 m/s): the plan, smoothing it, was still 20-53 mm off its placement
  and 5-7 cm up a knot before touch-down, and the simulated foot, lagging it, landed 8-27 mm off.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from robots import Robot
from tasks.mocap.keepout import keep_feet_apart
from tasks.mocap.source import SIDES, HumanMotion, segments

#: [m/s] the fastest a swinging foot's target comes onto its placement (the source's departure from
#: the placement-to-placement blend is capped to this times the time left to touch-down). The
#: certified clips' swings come in slower (0.4 already changed G1's walks' targets; 0.5 changes none
#: of them: their tasks stay byte for byte), a march's at 1.5 to 2.5 m/s.
LAND_SPEED = 0.5
#: [m] a swing whose source foot rises higher than this (at the robot's scale) comes down a knot
#: early: its target is on the placement, on the floor, a knot before the stance begins. The
#: simulated foot lags its plan by 20-40 ms at touch-down; a foot still 1-2 cm up when its stance
#: began was held there and skidded 7-13 mm as it met the floor (talos's march, 10.6 mm of slip; a
#: knot early: none). A walk's swings stay below it (talos 0.073-0.105 m, g1 0.055-0.080: their
#: tasks unchanged), a march's knee raise (0.33-0.64 m) does not.
HIGH_SWING = 0.11
#: [m] ... if it lands less than this from where it left (a march on the spot, its steps 0.01-0.22 m
#: on talos): a long step set down a knot early scuffed the floor still moving across (g1's forward
#: jumps made as 0.31-0.37 m steps: a foot touched 0.1 s early, tripped and fell). A high swing
#: that is a longer step leaves a knot late instead: its first swinging knot is on the placement it
#: leaves (and its second over it). The plan's knots are not the phases' times (talos's forward jumps: 0.0797 s apart), and
#: such a step's plan moved the foot 33 mm across between its last stance knot and its first
#: swinging one, which the certificate, reading the plan between them while the stance still
#: held, counted as the stance's placement error (26-29 mm).
EARLY_STEP = 0.25
#: [m] ... and leaves a knot late only if it is at least this long: talos's forward jumps made as
#: steps (0.45-0.55 m) needed it (their lift-off placement errors 26-29 mm); g1's (0.31-0.37 m) fell
#: with it (the foot kept down a knot into its swing touched the floor again, the hip yaw at its
#: limit) and land within the certificate without it.
LATE_STEP = 0.41


def land_softly(departure: np.ndarray, time_left: float, speed: float = LAND_SPEED) -> np.ndarray:
    """The source's departure (3,) [m] from the blend between a swing's placements, capped in length
    to ``speed`` x ``time_left`` [s] to touch-down (its direction kept): the target then comes
    onto the placement no faster than ``speed``."""
    d = np.asarray(departure, dtype=float)
    most = max(0.0, speed * time_left)
    size = float(np.linalg.norm(d))
    return d if size <= most else d * (most / size)


#: [m] a swing too quick for the robot's step (it would slow the whole clip) that rises less than
#: this (the robot's scale) and lands less than the shuffle step from where it left is a foot
#: adjusted on the spot, not a step: the foot stays down (:func:`quick_shuffles`; the kick's 0.11 to
#: 0.21 s swings of 6 to 8 cm, which slowed it 7.4 x for talos's 0.8 s step).
QUICK_LIFT = 0.10
#: [s] the least a foot stays down between two swings that :func:`steps_for_flights` makes out of a
#: two-footed jump (its landing and take-off are moved into the double supports around it).
STEP_GAP = 0.1


def _sole(motion: HumanMotion, side: str) -> np.ndarray:
    """The source's sole (F, 3): mid-foot xy, the lower of ankle and toe for z (as the retarget's)."""
    p = motion.points
    sole = 0.5 * (p[f"{side}_ankle"] + p[f"{side}_toe"])
    sole[:, 2] = np.minimum(p[f"{side}_ankle"][:, 2], p[f"{side}_toe"][:, 2])
    return sole


def quick_shuffles(motion: HumanMotion, labels: dict[str, np.ndarray], scale: float, least_swing: float,
                   step: float) -> dict[str, np.ndarray]:
    """The contact labels with the quick shuffles filled in: a swing between two stances that lasts
    less than ``least_swing`` [s] (the robot's step: the clip would be slowed for it), rises less than
    :data:`QUICK_LIFT` and lands less than ``step`` [m] from where it left (both at the robot's
    ``scale``) stays a contact; every other label is kept."""
    out = {}
    for side in SIDES:
        lab = np.asarray(labels[side], dtype=bool).copy()
        sole = scale * _sole(motion, side)
        for a, b, down in segments(lab):
            if down or a == 0 or b >= len(lab) or (b - a) * motion.frame_time >= least_swing:
                continue
            if sole[a:b, 2].max() < QUICK_LIFT and np.linalg.norm(sole[b, :2] - sole[a - 1, :2]) < step:
                lab[a:b] = True
        out[side] = lab
    return out


def _swing_at(lab: np.ndarray, i: int) -> tuple[int, int]:
    """The swing run (first frame, end frame) of labels ``lab`` containing frame ``i``."""
    a = i
    while a > 0 and not lab[a - 1]:
        a -= 1
    b = i
    while b < len(lab) and not lab[b]:
        b += 1
    return a, b


def steps_for_flights(labels: dict[str, np.ndarray], frame_time: float) -> tuple[dict[str, np.ndarray], float]:
    """(contact labels, seconds of flight made as steps): every flight (both feet up) made with one
    foot down, the closest walk to it (a flight cannot be slowed for the robot's steps: a 0.2 s
    flight slowed 3 x is a 0.4 m high jump).

    * A running step (a foot still up for more than half the flight's time after it: the kick's
      leap onto its standing foot as the other kicks): the foot that took off last stays down
      until the flight's end.
    * A two-footed jump (both land within half the flight's time, a forward jump): a step of each
      foot, the one that took off first landing before the flight's middle and the other leaving
      after it (:data:`STEP_GAP` of double support between); each swing lasts as long as the
      flight (moved into the double supports around it, keeping :data:`STEP_GAP` of double support
      there too), so that the steps are no quicker than the jump.
    """
    out = {side: np.asarray(labels[side], dtype=bool).copy() for side in SIDES}
    gap = max(1, int(round(STEP_GAP / frame_time)))
    seconds = 0.0
    for _ in range(len(out["left"])):
        up = ~out["left"] & ~out["right"]
        if not up.any():
            break
        a = int(np.argmax(up))
        b = a + int(np.argmin(up[a:])) if not up[a:].all() else len(up)
        seconds += (b - a) * frame_time
        swing = {side: _swing_at(out[side], a) for side in SIDES}
        first, last = sorted(SIDES, key=lambda s: (swing[s][0], -swing[s][1]))
        (s1, e1), (s2, e2) = swing[first], swing[last]
        if b >= len(up) or a == 0:
            out[last][a:b] = True  # a clip that starts or ends in the air: the last foot to leave stays
            continue
        m, length = (a + b) // 2, b - a
        if max(e1, e2) - b > length // 2:  # a running step (one foot still up well after the other
            out[last][s2:b] = True  # lands): the last to leave stays down until the flight's end
            continue
        m1, m2 = m - gap // 2, m + gap - gap // 2  # a double support of STEP_GAP between the steps
        lo = min(s1, max(_previous_landing(out, s1) + gap, m1 - length))
        hi = max(e2, min(_next_takeoff(out, e1, e2) - gap, m2 + length))
        out[first][lo:m1] = False  # the first foot swings [lo, m1) and is down from then
        out[first][m1:e1] = True
        out[last][s2:m2] = True  # the last stays down until m2, then swings [m2, hi)
        out[last][m2:hi] = False
    return out, seconds


def _previous_landing(out: dict[str, np.ndarray], before: int) -> int:
    """The last frame before ``before`` at which a foot landed (0: none)."""
    last = 0
    for lab in out.values():
        for a, _b, down in segments(lab[:before]):
            if down and a > 0:
                last = max(last, a)
    return last


def _next_takeoff(out: dict[str, np.ndarray], *after: int) -> int:
    """The first frame after the flight's landings at which a foot takes off again (the clip's end: none)."""
    start = max(after)
    n = len(out["left"])
    first = n
    for lab in out.values():
        for a, _b, down in segments(lab[start:]):
            if not down and a > 0:
                first = min(first, start + a)
                break
    return first


#: the keypoints :func:`no_higher_than_standing` lowers (the legs' are the contacts' and the scale's)
BODY = ("pelvis", "torso", "head", "left_shoulder", "right_shoulder", "left_hand", "right_hand")


def no_higher_than_standing(motion: HumanMotion, labels: dict[str, np.ndarray]) -> HumanMotion:
    """``motion`` with its body (pelvis, torso, head, shoulders, hands) lowered wherever the pelvis is
    higher than its median over the frames with both feet down (``labels``): a jump made as steps
    (:func:`steps_for_flights`) does not rise into the jump's flight, its feet being on the ground."""
    both = np.asarray(labels["left"], dtype=bool) & np.asarray(labels["right"], dtype=bool)
    z = motion.points["pelvis"][:, 2]
    standing = float(np.median(z[both])) if both.any() else float(np.median(z))
    down = np.maximum(0.0, z - standing)[:, None] * np.array([0.0, 0.0, 1.0])
    points = {k: v - down if k in BODY else v for k, v in motion.points.items()}
    return dataclasses.replace(motion, points=points)


def apart_from_stance(target: np.ndarray, side: str, stance: np.ndarray, yaw: float, robot: Robot) -> np.ndarray:
    """A swinging foot's target (3,) moved sideways away from the other foot's stance placement
    ``stance`` (3,) as :func:`tasks.mocap.keepout.keep_feet_apart` keeps the source's soles apart
    (in the hips' frame, ``yaw``): the target is a blend between placements plus the source's
    departure from its own, and a marching human's raised foot swings in across the other's line
    (talos: 0.03 m beside the standing foot, its shin through the other foot on the meshes)."""
    other = SIDES[1 - SIDES.index(side)]
    soles = {side: np.asarray(target, dtype=float)[None], other: np.asarray(stance, dtype=float)[None]}
    contact = {side: np.array([False]), other: np.array([True])}
    kept, _ = keep_feet_apart(soles, contact, np.array([yaw]), robot)
    return kept[side][0]
