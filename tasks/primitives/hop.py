"""Motions with one-leg push-offs: ``hop`` (on one foot) and ``jog`` (in place or forward).

Both need a flight phase pushed off by ONE leg. The flight lasts at least
``MIN_FLIGHT_KNOTS`` knots of the grid (0.15 s on the default 0.075 s grid), so the CoM must
leave the ground at :math:`v_0 = g T / 2` or faster (0.74 m/s). Feasibility in task terms, as
for ``jump`` (:mod:`.jump`), with the push of one leg instead of two: the crouch and push stroke
of :func:`tasks.primitives.jump.push_off` need an upward acceleration that one leg's torque limits
must give, within a margin of it (:func:`one_leg_push`: static :math:`\\tau = J^\\top f` for a vertical
force under one sole, half the two-leg estimate of :func:`tasks.primitives.jump.takeoff_speeds`).
A robot whose leg cannot is refused with the numbers (Talos' knee: about 6.5 m/s^2 available for
3.9 m/s^2 needed, 0.60 of it). The margins are calibrated in MuJoCo, as ``jump``'s two-leg
``TORQUE_MARGIN`` (0.3), not derived:

* ``ONE_LEG_MARGIN`` (0.25, ``hop``): G1's shortest hop needs 0.24 of its knee's static push and
  passes the certificate (1 and 2 hops: the sole off the floor 47 and 38 ms of each 0.15 s
  flight, slip 1 mm, CoM tracking 2.5 cm; it lands ~65 ms early, which the controller absorbs:
  ``WbcSettings.early_touchdown``, docs/control.md); its next flight (3 knots, 1.10 m/s) would
  need 0.45 and was not tried.
* ``JOG_MARGIN`` (0.2, ``jog``): G1's jog at the same 0.24 planned but failed the certificate
  (measured before the early touch-down: the push-off foot touched the floor at the end of the
  first flight, unplanned; landings 2.4-2.7 cm off their placements, slip 1.2-1.8 cm, impacts of
  1,000-1,100 N; with it, the same: the push-off foot back on the floor 66 ms after leaving it,
  a landing 3.3 cm off). No robot jogs yet.

``hop(foot, count, height [m], forward [m])``: shift the weight onto ``foot`` (both feet down,
``SHIFT_TIME``; HARD CoM target over that sole), lift the other foot (``LIFT_TIME``), then per
hop: crouch (``CROUCH_TIME``, HARD CoM height), push (``PUSH_TIME``, HARD CoM heights of a
uniform acceleration, as ``jump``), flight (no contact, whole knots, never stretched), land on
the same foot ``forward`` ahead (``LAND_TIME``); then recover on that foot (CoM back at its
standing height), put the other foot down (both feet, ``SHIFT_TIME``, CoM between the feet).

Forward hops are certified up to ``HOP_FORWARD_MAX`` (0.03 m a hop) and ``HOP_FORWARD_COUNT_MAX``
(2 hops); beyond either they are refused (:class:`tasks.exceptions.BeyondCapability`, exit 4). The
real flight is 45-65 ms of the planned 0.15 s (the push leaves the floor late and slow), so each
landing falls short of its spot and the next hop starts from there. Measured on G1 (certificate,
placement limit 2 cm; the controller's travelling-flight gains, docs/control.md): 3 cm x 1 lands
7.6-8.0 mm off (right, left foot), 3 cm x 2 13.4-13.1 mm, 3.5 cm x 2 16.0 mm (not allowed: the
margin); 3 cm x 3 landed 2.5 cm off (FAIL), 4 cm x 2 and 5 cm x 2 fell, 0.1 m fell at 3.8 s.

``jog(count, forward [m])``: ``count`` flights between alternating single supports: push off
the right foot, fly, land on the left, push off it, ... (each stance ``STRIDE_STANCE_TIME``), the
feet landing ``forward / count`` further on each stride (in place by default); then both feet
down and settle. A soft CoM apex per flight shapes the bounce.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from robots import Robot
from tasks.exceptions import BeyondCapability, TaskDefinitionError
from tasks.primitives.arms import UPPER_ARM_OUT, hold_upper_arms
from tasks.primitives.base import DEFAULT_DT, Fragment, FragmentBuilder, Primitive
from tasks.primitives.gait import (
    OTHER,
    Segment,
    both,
    contact,
    heading_yaw,
    rz,
    sequence_duration,
    shifted,
    stance_from,
    start_placements,
    tau,
    write_segments,
)
from tasks.primitives.geometry import standing_geometry
from tasks.primitives.jump import MIN_FLIGHT_KNOTS, G, push_off, takeoff_speeds
from tasks.specs import Pose, Priority

PARTS = frozenset({"legs", "com"})
SHIFT_TIME = 1.0  # [s]
LIFT_TIME = 0.45  # [s] the other foot leaves the ground before the first hop
CROUCH_TIME = 0.45  # [s]
PUSH_TIME = 0.3  # [s]
LAND_TIME = 0.45  # [s]
STRIDE_STANCE_TIME = 0.45  # [s] jog: one foot on the ground between two flights
COM_TOLERANCE = 0.01  # [m]
CROUCH_TOLERANCE = 0.02  # [m]
PUSH_PROFILE_TOLERANCE = 0.015  # [m]
APEX_WEIGHT = 10.0
FLIGHT_CLEARANCE = 0.01  # [m] sole height at mid-flight
HOP_FORWARD_FRACTION = 0.5  # hop/jog stride: at most this fraction of step_length_max
HOP_FORWARD_MAX = 0.03  # [m] per hop: G1's 3 cm hops certified in MuJoCo (module docstring); 4 cm x 2 fell
HOP_FORWARD_COUNT_MAX = 2  # forward hops in a row: G1's third 3 cm landing was 2.5 cm off its spot
ONE_LEG_MARGIN = 0.25  # hop with at most this fraction of one leg's static push (G1's 0.24 certified in MuJoCo)
JOG_MARGIN = 0.2  # jog: the same, lower (G1's jog at 0.24 failed the MuJoCo certificate: module docstring)


@dataclass(frozen=True, slots=True, kw_only=True)
class OneLegPush:
    """What a one-leg push-off to a take-off speed needs and what the leg gives.

    Attributes:
        speed: Take-off speed [m/s].
        depth: CoM drop at the bottom of the crouch [m].
        stroke: CoM rise over the push [m].
        needed: Uniform upward CoM acceleration over the stroke [m/s^2].
        available: Static upward CoM acceleration one leg's torque limits give at the bottom of
            the crouch [m/s^2] (negative: the leg cannot even hold the body there).
        joint: The joint whose torque limit bounds ``available``.
    """

    speed: float
    depth: float
    stroke: float
    needed: float
    available: float
    joint: str

    @property
    def feasible(self) -> bool:
        """The need is within ``ONE_LEG_MARGIN`` of what the leg gives (a hop)."""
        return self.within(ONE_LEG_MARGIN)

    def within(self, margin: float) -> bool:
        """The need is within ``margin`` of what the leg gives."""
        return self.needed <= margin * self.available


def flight_knots(height: float, dt: float) -> int:
    """Knots of the flight of a CoM rise ``height`` [m] (at least ``MIN_FLIGHT_KNOTS``)."""
    return max(MIN_FLIGHT_KNOTS, math.ceil(2.0 * math.sqrt(2.0 * height / G) / dt - 1e-9))


def one_leg_push(robot: Robot, speed: float) -> OneLegPush:
    """The crouch, stroke and acceleration of a push-off to ``speed`` [m/s], and one leg's capacity."""
    p = push_off(robot, speed)
    bottom = min(takeoff_speeds(robot), key=lambda s: abs(s.com_drop - p.depth))
    one = 0.5 * (bottom.push_acceleration + G) - G  # the two-leg force, halved, minus gravity
    return OneLegPush(speed=speed, depth=p.depth, stroke=p.stroke, needed=p.acceleration, available=one,
                      joint=bottom.torque_joint)


@functools.cache
def can_push_off_one_leg(robot: Robot) -> OneLegPush:
    """The shortest flight's push-off on ``robot`` (cached)."""
    T = MIN_FLIGHT_KNOTS * DEFAULT_DT
    return one_leg_push(robot, G * T / 2.0)


def _on_leg(robot: Robot, joint: str, foot: str | None) -> str:
    """``joint`` (the two-leg estimate's limiting joint, of either leg) on the ``foot`` side's leg:
    its mirror name (left <-> right) when that names a joint of the model."""
    if foot is None or foot in joint:
        return joint
    mirror = joint.replace(OTHER[foot], foot)
    return mirror if robot.model.existJointName(mirror) else joint


def _refusal(what: str, robot: Robot, p: OneLegPush, margin: float, height: float | None = None,
             foot: str | None = None) -> str:
    T = 2.0 * p.speed / G
    ask = f"a {height:g} m rise" if height is not None else f"the shortest flight the planner's {DEFAULT_DT:g} s grid holds"
    cap = (f"at most about {margin:g} x {p.available:.1f} m/s^2 there" if p.available > 0
           else f"not even the body's weight there ({p.available:.1f} m/s^2)")
    return (f"{what} needs a push-off from one leg: {ask} is a {T:.2f} s flight with a take-off speed of "
            f"{p.speed:.2f} m/s; from a {p.depth:.2f} m crouch the {p.stroke:.2f} m push stroke needs {p.needed:.1f} "
            f"m/s^2 of upward acceleration, but one of {robot.name}'s legs gives {cap} ({_on_leg(robot, p.joint, foot)} "
            f"torque limit)")


def _takeoff_speed(height: float, dt: float = DEFAULT_DT) -> float:
    return G * flight_knots(height, dt) * dt / 2.0


def stride_max(robot: Robot) -> float:
    """Longest hop or jog stride [m]: ``HOP_FORWARD_FRACTION * step_length_max``."""
    return HOP_FORWARD_FRACTION * robot.profile.step_length_max


# ---------------------------------------------------------------------------------------------
# hop
# ---------------------------------------------------------------------------------------------


def _check_hop(params: dict, robot: Robot) -> None:
    p = one_leg_push(robot, _takeoff_speed(params["height"]))
    if not p.feasible:
        raise BeyondCapability(
            _refusal(f"hopping on the {params['foot']} foot", robot, p, ONE_LEG_MARGIN, params["height"], params["foot"])
            + (f"; {robot.name} cannot hop on one foot" if not can_push_off_one_leg(robot).feasible
               else "; ask for a lower hop")
        )
    top = stride_max(robot)
    if params["forward"] > top + 1e-12 and top < HOP_FORWARD_MAX:
        raise BeyondCapability(
            f"hop forward {params['forward']:g} m is beyond {robot.name}'s {top:.2f} m per hop; ask for at most {top:.2f} m"
        )
    if params["forward"] > HOP_FORWARD_MAX + 1e-12:
        raise BeyondCapability(
            f"hopping forward {params['forward']:g} m a hop on one foot is beyond the {HOP_FORWARD_MAX:g} m a hop "
            f"certified in simulation (longer hops land short of their spot and fall); ask for "
            f"\"hop forward {HOP_FORWARD_MAX * 100:g} cm\" or hop in place"
        )
    if params["forward"] > 0.0 and params["count"] > HOP_FORWARD_COUNT_MAX:
        raise BeyondCapability(
            f"hopping forward {params['count']} times on one foot is beyond the {HOP_FORWARD_COUNT_MAX} forward hops "
            f"certified in simulation (each landing falls up to 1.5 cm short and the next hop starts from there); "
            f"ask for {HOP_FORWARD_COUNT_MAX} hops forward, or hop in place {params['count']} times"
        )


def _hop_segments(params: dict, robot: Robot, where: dict[str, Pose], dt: float) -> tuple[list[Segment], dict[str, Pose]]:
    foot, free = params["foot"], OTHER[params["foot"]]
    _, yaw = heading_yaw(where)
    ahead = rz(yaw) @ np.array([params["forward"], 0.0, 0.0])
    n_flight = flight_knots(params["height"], dt)
    cur = dict(where)
    one = (contact(robot, foot, cur[foot]),)
    segs = [Segment(name=f"shift onto the {foot} foot", duration=SHIFT_TIME, contacts=both(robot, cur)),
            Segment(name=f"lift the {free} foot", duration=LIFT_TIME, contacts=one)]
    for i in range(params["count"]):
        segs.append(Segment(name=f"hop {i + 1}: crouch", duration=CROUCH_TIME, contacts=one))
        segs.append(Segment(name=f"hop {i + 1}: push off", duration=PUSH_TIME, contacts=one))
        segs.append(Segment(name=f"hop {i + 1}: flight", duration=n_flight * dt, contacts=(),
                            swing_height=FLIGHT_CLEARANCE, rounding="ceil"))
        cur[foot] = shifted(cur[foot], ahead)
        one = (contact(robot, foot, cur[foot]),)
        segs.append(Segment(name=f"hop {i + 1}: landing", duration=LAND_TIME, contacts=one))
    segs.append(Segment(name=f"recover on the {foot} foot", duration=CROUCH_TIME, contacts=one))
    cur[free] = shifted(cur[free], ahead * params["count"])
    segs.append(Segment(name=f"put the {free} foot down", duration=SHIFT_TIME, contacts=both(robot, cur)))
    return segs, cur


def _hop_duration(params: dict, robot: Robot) -> float:
    return sequence_duration(_hop_segments(params, robot, start_placements(robot, None), DEFAULT_DT)[0])


def _push_targets(b: FragmentBuilder, what: str, z_stand: float, k_crouch: int, k_takeoff: int, speed: float,
                  apex_knot: int | None, t_apex: float) -> None:
    """HARD crouch height, HARD push profile of a uniform acceleration, soft apex (as ``jump``)."""
    p = push_off(b.robot, speed)
    b.com_target(f"{what}: crouch", (None, None, z_stand - p.depth), time=tau(b, k_crouch), tolerance=CROUCH_TOLERANCE)
    z_off = z_stand - p.takeoff.com_drop
    acc = speed * speed / (2.0 * max(p.stroke, 1e-3))
    t_acc = speed / acc
    n_push = k_takeoff - k_crouch
    for j in range(1, n_push + 1):
        left = (n_push - j) * b.dt
        if left >= t_acc:
            continue
        zj = z_off - speed * left + 0.5 * acc * left * left
        b.com_target(f"{what}: take-off" if j == n_push else f"{what}: push {j}", (None, None, zj),
                     time=tau(b, k_crouch + j), tolerance=PUSH_PROFILE_TOLERANCE)
    if apex_knot is not None:
        apex = z_off + speed * t_apex - 0.5 * G * t_apex**2
        b.com_target(f"{what}: flight apex", (None, None, apex), time=tau(b, apex_knot), tolerance=0.02,
                     priority=Priority.SOFT, weight=APEX_WEIGHT)


def _build_hop(b: FragmentBuilder) -> Fragment:
    robot, params = b.robot, b.params
    foot = params["foot"]
    where = start_placements(robot, b.stance)
    segs, end = _hop_segments(params, robot, where, b.dt)
    bounds = write_segments(b, segs)
    g = standing_geometry(robot)
    z0 = b.world_z(float(g.com[2]))
    n_flight = flight_knots(params["height"], b.dt)
    speed = G * n_flight * b.dt / 2.0
    sole = b.world(g.sole_centers[foot])
    b.com_target(f"CoM over the {foot} sole", (sole[0], sole[1], None), time=tau(b, bounds[1]), tolerance=COM_TOLERANCE)
    for i in range(params["count"]):
        first = 2 + 4 * i  # index of this hop's crouch segment
        k_crouch, k_takeoff = bounds[first + 1], bounds[first + 2]
        _push_targets(b, f"hop {i + 1}", z0, k_crouch, k_takeoff, speed, k_takeoff + n_flight // 2,
                      (n_flight // 2) * b.dt)
    b.com_target(f"standing on the {foot} foot", (None, None, z0), time=tau(b, bounds[-2]), tolerance=CROUCH_TOLERANCE)
    b.end_stance = stance_from(end)
    home = b.end_stance.transform_from_standing(robot).act(g.com)
    b.com_target("CoM back between the feet", (float(home[0]), float(home[1]), None), time=tau(b, bounds[-1]),
                 tolerance=COM_TOLERANCE)
    hold_upper_arms(b, b.nominal, ("left", "right"), out=UPPER_ARM_OUT)  # G1's right upper arm went into the torso's meshes
    return b.finish(PARTS, dynamic=True)


def _margin(what: str) -> float:
    return ONE_LEG_MARGIN if what == "hop" else JOG_MARGIN


def _limits(what: str):
    def limits(robot: Robot) -> dict[str, str]:
        p = can_push_off_one_leg(robot)
        margin = _margin(what)
        if not p.within(margin):
            gives = (f"gives at most {margin:g} x {p.available:.1f} = {margin * p.available:.1f} m/s^2 "
                     f"of push for the {p.needed:.1f} m/s^2" if p.available > 0
                     else f"cannot even carry the body in the {p.depth:.2f} m crouch, let alone give the {p.needed:.1f} m/s^2")
            return {"count": f"{robot.name} cannot {what}: one leg {gives} the shortest flight needs ({p.joint} torque limit)"}
        if what == "hop":
            top = min(stride_max(robot), HOP_FORWARD_MAX)
            return {"forward": f"at most {top:.2f} m per hop and {HOP_FORWARD_COUNT_MAX} hops forward on {robot.name} "
                               f"(certified in simulation)"}
        return {"forward": f"at most {stride_max(robot):.2f} m per stride on {robot.name}"}
    return limits


HOP = Primitive(name="hop", nominal_duration=_hop_duration, build=_build_hop, parts=lambda p: PARTS,
                check=_check_hop, limits=_limits("hop"), dynamic=True)


# ---------------------------------------------------------------------------------------------
# jog
# ---------------------------------------------------------------------------------------------


def _check_jog(params: dict, robot: Robot) -> None:
    p = can_push_off_one_leg(robot)
    if not p.within(JOG_MARGIN):
        raise BeyondCapability(
            _refusal("jogging (a flight between the steps)", robot, p, JOG_MARGIN) + f"; {robot.name} cannot jog or run; walk instead"
        )
    stride, top = params["forward"] / params["count"], stride_max(robot)
    if stride > top + 1e-12:
        raise TaskDefinitionError(
            f"jog forward {params['forward']:g} m in {params['count']} strides is {stride:.2f} m a stride, beyond "
            f"{robot.name}'s {top:.2f} m; take at least {math.ceil(params['forward'] / top)} strides"
        )


def _jog_segments(params: dict, robot: Robot, where: dict[str, Pose], dt: float) -> tuple[list[Segment], dict[str, Pose]]:
    _, yaw = heading_yaw(where)
    axis = rz(yaw) @ np.array([1.0, 0.0, 0.0])
    stride = params["forward"] / params["count"]
    progress = {"left": 0.0, "right": 0.0}
    cur = dict(where)
    side = "right"
    segs = [Segment(name="shift weight", duration=SHIFT_TIME, contacts=both(robot, cur)),
            Segment(name=f"crouch on the {side} foot", duration=CROUCH_TIME, contacts=(contact(robot, side, cur[side]),))]
    for i in range(params["count"]):
        segs.append(Segment(name=f"stride {i + 1}: {side} foot pushes off", duration=PUSH_TIME,
                            contacts=(contact(robot, side, cur[side]),)))
        segs.append(Segment(name=f"stride {i + 1}: flight", duration=MIN_FLIGHT_KNOTS * dt, contacts=(),
                            swing_height=FLIGHT_CLEARANCE, rounding="ceil"))
        side = OTHER[side]
        progress[side] = progress[OTHER[side]] + stride  # each landing foot one stride ahead of the other
        cur[side] = shifted(where[side], axis * progress[side])
        if i < params["count"] - 1:
            segs.append(Segment(name=f"stride {i + 1}: land on the {side} foot", duration=STRIDE_STANCE_TIME - PUSH_TIME,
                                contacts=(contact(robot, side, cur[side]),)))
    segs.append(Segment(name=f"land on the {side} foot", duration=CROUCH_TIME, contacts=(contact(robot, side, cur[side]),)))
    other = OTHER[side]
    cur[other] = shifted(where[other], axis * progress[side])
    segs.append(Segment(name="both feet down", duration=SHIFT_TIME, contacts=both(robot, cur)))
    return segs, cur


def _jog_duration(params: dict, robot: Robot) -> float:
    return sequence_duration(_jog_segments(params, robot, start_placements(robot, None), DEFAULT_DT)[0])


def _build_jog(b: FragmentBuilder) -> Fragment:
    robot, params = b.robot, b.params
    where = start_placements(robot, b.stance)
    segs, end = _jog_segments(params, robot, where, b.dt)
    bounds = write_segments(b, segs)
    g = standing_geometry(robot)
    z0 = b.world_z(float(g.com[2]))
    speed = G * MIN_FLIGHT_KNOTS * b.dt / 2.0
    sole = b.world(g.sole_centers["right"])
    b.com_target("CoM over the right sole", (sole[0], sole[1], None), time=tau(b, bounds[1]), tolerance=COM_TOLERANCE)
    # first push: from a crouch, as a hop; later strides: a soft apex per flight
    _push_targets(b, "stride 1", z0, bounds[2], bounds[3], speed, None, 0.0)
    for i in range(params["count"]):
        k_flight = next(k for k, s in zip(bounds, segs, strict=False) if s.name == f"stride {i + 1}: flight")
        z_off = z0 - push_off(robot, speed).takeoff.com_drop
        t_apex = (MIN_FLIGHT_KNOTS // 2) * b.dt
        b.com_target(f"stride {i + 1}: flight apex", (None, None, z_off + speed * t_apex - 0.5 * G * t_apex**2),
                     time=tau(b, k_flight + MIN_FLIGHT_KNOTS // 2), tolerance=0.02, priority=Priority.SOFT,
                     weight=APEX_WEIGHT)
    b.end_stance = stance_from(end)
    home = b.end_stance.transform_from_standing(robot).act(g.com)
    b.com_target("CoM back between the feet", (float(home[0]), float(home[1]), None), time=tau(b, bounds[-1]),
                 tolerance=COM_TOLERANCE)
    return b.finish(PARTS, dynamic=True)


JOG = Primitive(name="jog", nominal_duration=_jog_duration, build=_build_jog, parts=lambda p: PARTS,
                check=_check_jog, limits=_limits("jog"), dynamic=True)

__all__ = ["HOP", "JOG", "JOG_MARGIN", "ONE_LEG_MARGIN", "OneLegPush", "can_push_off_one_leg", "flight_knots", "one_leg_push", "stride_max"]
