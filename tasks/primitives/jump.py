"""``jump(height [m], forward [m])``: crouch, push off, fly, land, recover.

``height`` is the rise of the centre of mass during the flight, from take-off to apex (the
jump height that a flight time measures: :math:`h = g T^2 / 8`). The flight phase has no
contact and lasts :math:`T = 2\\sqrt{2h/g}`, rounded *up* to whole knots (at least
``MIN_FLIGHT_KNOTS``) and never stretched, so the planned rise is at least ``height``. Under the
planner's CoM dynamics the flight is ballistic, which fixes the rise; the take-off height is the
planner's choice.

Phases (both feet down except in flight):

1. ``crouch`` (``CROUCH_TIME``): the CoM goes down to ``z_standing - crouch depth`` (HARD);
   the depth is the take-off drop (below) plus a push stroke long enough to reach the take-off
   speed at a mean upward acceleration of ``PUSH_ACCELERATION`` g, within ``squat_depth_max``.
2. ``push off`` (``PUSH_TIME``): the legs extend and accelerate the body.
3. ``flight``: no contact; each foot ``swing_height`` above the ground at mid-flight.
4. ``landing`` (``LAND_TIME``): the feet land ``forward`` ahead (heading frame), the legs absorb.
5. ``recover`` (the rest): back to the standing CoM height over the landing feet (HARD).

Feasibility in task terms: a rise ``h`` needs a take-off speed :math:`v_0 = \\sqrt{2 g h}`
(+ the knot rounding of the flight). :func:`takeoff_speeds` estimates, for crouches of
increasing depth, the fastest the CoM can move straight up with both soles flat on the ground
and every leg joint within its velocity limit (base translating vertically, upper body still).
A jump whose take-off speed exceeds ``TAKEOFF_MARGIN`` times the best of these is refused with
the numbers (e.g. a 1 m jump needs 4.4 m/s; Talos's legs give about 1.9 m/s). A forward jump
covers ``forward`` during the flight, so it needs a forward take-off speed of ``forward / T``,
which the landing must absorb: beyond the profile's ``jump_forward_speed_max`` (talos 0.5 m/s;
g1 0: its forward jumps fell in MuJoCo, even 5 cm) it is refused with the longest forward jump for
that rise. On Talos, with the 5 cm rise (0.20 s flight), 0.10 m forward passes the
certificate (the soles land 15 mm from their planned placements, limit 20 mm); 0.15 m lands 23 mm
off, 0.20 m 30 mm; 0.25 m and 0.30 m do not plan (the landing's contact moment misses the full
dynamics by 1.0-1.25 cm).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import cast

import numpy as np
import pinocchio as pin

from robots import Robot
from tasks.exceptions import BeyondCapability, TaskDefinitionError
from tasks.primitives.base import Fragment, FragmentBuilder, Primitive
from tasks.primitives.geometry import Stance, standing_geometry
from tasks.specs import Contact, JointTarget, Pose, Priority, Vec3

G = 9.81  # [m/s^2]
CROUCH_TIME = 0.6  # [s]
PUSH_TIME = 0.3  # [s]
LAND_TIME = 0.4  # [s]
RECOVER_TIME = 0.6  # [s]
MIN_FLIGHT_KNOTS = 2
MIN_HEIGHT = 0.01  # [m] the smallest jump the registry accepts
TAKEOFF_MARGIN = 0.9  # plan with at most this fraction of the estimated take-off speed
PUSH_ACCELERATION = 0.4  # [g] mean upward acceleration over the push stroke
PUSH_PROFILE_TOLERANCE = 0.015  # [m] CoM heights along a uniform-acceleration push (HARD)
MIN_STROKE = 0.04  # [m]
TORQUE_MARGIN = 0.3  # plan with at most this fraction of the static torque-limited push acceleration (calibrated in MuJoCo: docs/control.md)
HEIGHT_STEP = 0.005  # [m] grid of max_jump_height
CROUCH_STEP = 0.025  # [m] base-height grid of the take-off speed estimate
CROUCH_TOLERANCE = 0.02  # [m] CoM height at the bottom of the crouch
END_TOLERANCE = 0.01  # [m] CoM at the end
APEX_WEIGHT = 10.0  # soft apex target (shapes the take-off height)
FLIGHT_CLEARANCE_MAX = 0.02  # [m] sole height at mid-flight
TORSO_HOLD_WEIGHT = 10.0  # joint-target weight holding each torso joint at its standing angle
PARTS = frozenset({"legs", "com"})


@dataclass(frozen=True, slots=True, kw_only=True)
class TakeoffSpeed:
    """Fastest straight-up CoM speed with the base lowered by ``base_drop``.

    Attributes:
        base_drop: How far the base is lowered from standing [m].
        com_drop: How far the CoM is below its standing height [m].
        speed: Largest upward CoM speed with both soles flat and leg joints within their
            velocity limits [m/s].
        limiting_joint: The joint that reaches its velocity limit first.
        push_acceleration: Largest upward CoM acceleration both legs can give in this posture
            from their torque limits (static: :math:`\tau = J^\top f` for a vertical force under
            each sole, minus gravity) [m/s^2].
        torque_joint: The joint whose torque limit bounds ``push_acceleration``.
    """

    base_drop: float
    com_drop: float
    speed: float
    limiting_joint: str
    push_acceleration: float = math.inf
    torque_joint: str = ""


def flight_time(height: float) -> float:
    """Ballistic flight time of a CoM rise ``height`` [m]: :math:`2\\sqrt{2h/g}` [s]."""
    return 2.0 * math.sqrt(2.0 * height / G)


def _leg_joints(robot: Robot) -> list[int]:
    out = []
    for side in ("left", "right"):
        joint = robot.model.frames[robot.frame_id(f"{side}_foot")].parentJoint
        out += [j for j in robot.model.supports[joint] if j > 1]
    return out


def torso_joints(robot: Robot) -> list[str]:
    """Names of the 1-dof joints between the base and both hands (g1's waist, talos's torso)."""
    model = robot.model
    if not (robot.has_role("left_hand") and robot.has_role("right_hand")):
        return []
    chains = [set(model.supports[model.frames[robot.frame_id(r)].parentJoint]) for r in ("left_hand", "right_hand")]
    legs = set(_leg_joints(robot))
    common = sorted(j for j in chains[0] & chains[1] if j > 1 and j not in legs and model.joints[j].nv == 1)
    return [model.names[j] for j in common]


def _crouch(robot: Robot, base_drop: float, legs: list[int], q_guess: np.ndarray) -> np.ndarray | None:
    """Standing posture with the base lowered by ``base_drop``, soles kept (Newton on the legs)."""
    model, data = robot.model, robot.data()
    pin.framesForwardKinematics(model, data, robot.q_standing)
    fids = [robot.frame_id(f"{s}_foot") for s in ("left", "right")]
    targets = [pin.SE3(data.oMf[f]) for f in fids]
    q = q_guess.copy()
    q[2] = robot.q_standing[2] - base_drop
    idx = [model.joints[j].idx_v for j in legs]
    for _ in range(30):
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        errs, jacs = [], []
        for fid, target in zip(fids, targets, strict=True):
            M = target.actInv(data.oMf[fid])
            errs.append(pin.log6(M).vector)
            jacs.append(pin.Jlog6(M) @ pin.getFrameJacobian(model, data, fid, pin.ReferenceFrame.LOCAL))
        e = np.concatenate(errs)
        if np.linalg.norm(e) < 1e-9:
            lo, hi = robot.lower_limits, robot.upper_limits
            return q if np.all(q[7:] >= lo[7:] - 1e-9) and np.all(q[7:] <= hi[7:] + 1e-9) else None
        dq = np.zeros(model.nv)
        dq[idx] = -np.linalg.lstsq(np.vstack(jacs)[:, idx], e, rcond=None)[0]
        q = pin.integrate(model, q, dq)
    return None


def _push_acceleration(robot: Robot, q: np.ndarray) -> tuple[float, str]:
    """Largest upward CoM acceleration at ``q`` from the leg torque limits (static, both feet)."""
    model, data = robot.model, robot.data()
    pin.computeJointJacobians(model, data, q)
    pin.framesForwardKinematics(model, data, q)
    total, joint = 0.0, ""
    per_foot = []
    for s in ("left", "right"):
        J = pin.getFrameJacobian(model, data, robot.frame_id(f"{s}_foot"), pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        ratio = np.abs(J[2, 6:]) / np.maximum(robot.torque_limits, 1e-9)  # torque per newton / limit
        i = int(np.argmax(ratio))
        per_foot.append((1.0 / ratio[i], robot.joint_names[i]))
    total = sum(f for f, _ in per_foot)
    joint = min(per_foot)[1]
    return float(total / robot.mass - G), joint


def _straight_up_speed(robot: Robot, q: np.ndarray) -> tuple[float, str]:
    """Largest upward CoM speed at ``q`` for a vertical base motion with the soles fixed."""
    model, data = robot.model, robot.data()
    pin.computeJointJacobians(model, data, q)
    pin.framesForwardKinematics(model, data, q)
    J = np.vstack([pin.getFrameJacobian(model, data, robot.frame_id(f"{s}_foot"), pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
                   for s in ("left", "right")])
    base = np.zeros(6)
    base[:3] = pin.Quaternion(q[3:7]).matrix().T @ np.array([0.0, 0.0, 1.0])  # world up, in the base frame
    joints = np.linalg.lstsq(J[:, 6:], -J[:, :6] @ base, rcond=None)[0]
    v = np.concatenate([base, joints])
    ratio = np.abs(joints) / np.maximum(robot.velocity_limits[6:], 1e-9)
    i = int(np.argmax(ratio))
    scale = 1.0 / ratio[i]
    com_vz = float((pin.jacobianCenterOfMass(model, data, q) @ v)[2])
    return float(com_vz * scale), robot.joint_names[i]


@functools.cache
def takeoff_speeds(robot: Robot) -> tuple[TakeoffSpeed, ...]:
    """Take-off speed estimates for crouches from standing to ``squat_depth_max`` (cached).

    Returns:
        One entry per reachable crouch (joint limits respected), shallowest first.
    """
    legs = _leg_joints(robot)
    data = robot.data()
    z0 = float(pin.centerOfMass(robot.model, data, robot.q_standing)[2])
    out = []
    q = robot.q_standing.copy()
    n = int(math.floor(robot.profile.squat_depth_max / CROUCH_STEP + 1e-9))
    for i in range(n + 1):
        drop = i * CROUCH_STEP
        qc = _crouch(robot, drop, legs, q)
        if qc is None:
            break
        q = qc
        speed, joint = _straight_up_speed(robot, q)
        com_drop = z0 - float(pin.centerOfMass(robot.model, data, q)[2])
        acc, tjoint = _push_acceleration(robot, q)
        out.append(TakeoffSpeed(base_drop=drop, com_drop=com_drop, speed=float(speed), limiting_joint=joint,
                                push_acceleration=acc, torque_joint=tjoint))
    return tuple(out)


def _best(robot: Robot) -> TakeoffSpeed:
    speeds = takeoff_speeds(robot)
    if not speeds:
        raise TaskDefinitionError(f"jump: cannot estimate {robot.name}'s take-off speed (no crouch posture found)")
    return max(speeds, key=lambda s: s.speed)


@dataclass(frozen=True, slots=True, kw_only=True)
class PushOff:
    """The push-off the primitive plans for a take-off speed.

    Attributes:
        takeoff: The take-off posture estimate (:func:`takeoff_point`).
        depth: CoM drop at the bottom of the crouch [m].
        stroke: CoM rise from the bottom of the crouch to take-off [m].
        acceleration: Uniform upward CoM acceleration over the stroke [m/s^2] (inf without stroke).
        available: Static torque-limited acceleration at the bottom of the crouch [m/s^2].
        torque_joint: The joint whose torque limit bounds ``available``.
    """

    takeoff: TakeoffSpeed
    depth: float
    stroke: float
    acceleration: float
    available: float
    torque_joint: str


def push_off(robot: Robot, speed: float) -> PushOff:
    """Crouch depth, push stroke and the acceleration they need for a take-off ``speed`` [m/s]."""
    takeoff = takeoff_point(robot, speed)
    stroke = max(MIN_STROKE, speed * speed / (2.0 * PUSH_ACCELERATION * G))
    depth = min(takeoff.com_drop + stroke, robot.profile.squat_depth_max)
    done = depth - takeoff.com_drop
    acc = speed * speed / (2.0 * done) if done > 1e-3 else math.inf
    bottom = min(takeoff_speeds(robot), key=lambda s: abs(s.com_drop - depth))
    return PushOff(takeoff=takeoff, depth=depth, stroke=done, acceleration=acc,
                   available=bottom.push_acceleration, torque_joint=bottom.torque_joint)


def _feasible(robot: Robot, height: float) -> bool:
    v0 = math.sqrt(2.0 * G * height)
    if v0 > TAKEOFF_MARGIN * _best(robot).speed:
        return False
    p = push_off(robot, v0)
    return p.acceleration <= TORQUE_MARGIN * p.available


@functools.cache
def max_jump_height(robot: Robot) -> float:
    """Largest flight rise the primitive plans for ``robot`` [m] (before knot rounding; 5 mm grid).

    Bounded by the legs' joint speeds (take-off speed) and torques (push-off acceleration).
    """
    best = 0.0
    h = HEIGHT_STEP
    while h <= 1.0 and _feasible(robot, h):
        best = h
        h += HEIGHT_STEP
    return round(best, 3)


def check(params: dict, robot: Robot) -> None:
    """Refuse jumps beyond the legs' take-off speed or forward jumps beyond the longest step
    (:class:`tasks.exceptions.BeyondCapability`: infeasible, exit 4)."""
    h, fwd = params["height"], params["forward"]
    v0 = math.sqrt(2.0 * G * h)
    best = _best(robot)
    if max_jump_height(robot) < MIN_HEIGHT:
        raise BeyondCapability(
            f"{robot.name} cannot jump: its leg joint speeds and torques let its centre of mass rise at about "
            f"{best.speed:.2f} m/s at best (from a {best.com_drop:.2f} m crouch, {best.limiting_joint} at its "
            f"limit), not enough for a {MIN_HEIGHT:g} m jump with a safety margin"
        )
    if v0 > TAKEOFF_MARGIN * best.speed:
        raise BeyondCapability(
            f"jump height {h:g} m needs a take-off speed of {v0:.2f} m/s (sqrt(2 g h), a {flight_time(h):.2f} s "
            f"flight); {robot.name}'s leg joint speed limits let its centre of mass rise at about {best.speed:.2f} m/s "
            f"at best (from a {best.com_drop:.2f} m crouch, {best.limiting_joint} at its limit), enough for about "
            f"{best.speed ** 2 / (2 * G):.2f} m; with a safety margin, ask for at most {max_jump_height(robot):.2f} m"
        )
    p = push_off(robot, v0)
    if p.acceleration > TORQUE_MARGIN * p.available:
        raise BeyondCapability(
            f"jump height {h:g} m needs a take-off speed of {v0:.2f} m/s; from a {p.depth:.2f} m crouch the push "
            f"stroke of {p.stroke:.2f} m needs {p.acceleration:.1f} m/s^2 of upward acceleration, but {robot.name}'s "
            f"leg torques give at most about {TORQUE_MARGIN:g} x {p.available:.1f} m/s^2 there ({p.torque_joint} "
            f"limits it); ask for at most {max_jump_height(robot):.2f} m"
        )
    limit = robot.profile.step_length_max
    if fwd > limit + 1e-12 and limit <= max_forward(robot, h):
        raise BeyondCapability(
            f"jump forward {fwd:g} m is beyond {robot.name}'s {limit:.2f} m (its longest step); "
            f"ask for at most {limit:.2f} m"
        )
    speed = robot.profile.jump_forward_speed_max
    if fwd > 1e-12 and speed <= 0.0:
        raise BeyondCapability(
            f"{robot.name} cannot jump forward: its forward jumps are not certified in simulation (they fell); "
            f"jump in place, or step forward then jump"
        )
    if fwd > max_forward(robot, h) + 1e-12:
        T = flight_time(h)
        highest = max_jump_height(robot)
        raise BeyondCapability(
            f"jump forward {fwd:g} m with a {h:g} m rise (a {T:.2f} s flight) needs a forward take-off speed of "
            f"{fwd / T:.2f} m/s; {robot.name} lands a forward jump at up to {speed:g} m/s, so at most "
            f"{_cm(max_forward(robot, h)):.2f} m forward with that rise (with its highest jump, {highest:.2f} m: "
            f"{_cm(max_forward(robot, highest)):.2f} m)"
        )


def _cm(x: float) -> float:
    """``x`` rounded down to 1 cm [m]."""
    return math.floor(x * 100.0 + 1e-9) / 100.0


def max_forward(robot: Robot, height: float) -> float:
    """Longest forward jump with a flight rise of ``height`` [m]: the profile's
    ``jump_forward_speed_max`` over the flight (:func:`flight_time`), at most the longest step."""
    return min(robot.profile.step_length_max, robot.profile.jump_forward_speed_max * flight_time(height))


def limits(robot: Robot) -> dict[str, str]:
    """Robot-specific ranges of ``height`` and ``forward``."""
    highest = max_jump_height(robot)
    return {
        "height": f"at most {highest:.2f} m on {robot.name} (joint speeds and torques of its legs)",
        "forward": (f"at most {robot.profile.jump_forward_speed_max:g} m/s x the flight time on {robot.name}: "
                    f"{_cm(max_forward(robot, 0.05)):.2f} m with a 0.05 m rise, {_cm(max_forward(robot, highest)):.2f} m "
                    f"with its highest jump") if robot.profile.jump_forward_speed_max > 0 else f"0 on {robot.name} (no forward jumps)",
    }


def nominal_duration(params: dict, robot: Robot) -> float:
    """Crouch + push + flight + landing + recover [s]."""
    return CROUCH_TIME + PUSH_TIME + flight_time(params["height"]) + LAND_TIME + RECOVER_TIME


def takeoff_point(robot: Robot, speed: float) -> TakeoffSpeed:
    """The shallowest crouch whose straight-up speed covers ``speed / TAKEOFF_MARGIN`` (else the best)."""
    for s in takeoff_speeds(robot):
        if TAKEOFF_MARGIN * s.speed >= speed:
            return s
    return _best(robot)


def build(b: FragmentBuilder) -> Fragment:
    """Crouch, push off, flight (whole knots, never stretched), landing, recover."""
    robot, dt, h, fwd = b.robot, b.dt, b.params["height"], b.params["forward"]
    n_flight = max(MIN_FLIGHT_KNOTS, math.ceil(flight_time(h) / dt - 1e-9))
    T = n_flight * dt
    v0 = G * T / 2.0  # take-off speed of the rounded flight
    rise = G * T * T / 8.0
    n_crouch = max(2, round(CROUCH_TIME / dt))
    n_push = max(2, round(PUSH_TIME / dt))
    n_land = max(2, round(LAND_TIME / dt))
    n_recover = b.n_knots - (n_crouch + n_push + n_flight + n_land)
    if n_recover < 2:
        n_crouch -= 2 - n_recover
        n_recover = 2
    g = standing_geometry(robot)
    z0 = b.world_z(float(g.com[2]))
    push = push_off(robot, v0)
    takeoff, depth = push.takeoff, push.depth
    # knot boundaries, as nominal times the builder maps back onto exactly these knots
    bounds = np.cumsum([n_crouch, n_push, n_flight, n_land, n_recover])

    def tau(k: int) -> float:
        return float(k) * dt / b.scale

    heading = b.stance.heading()
    shift = heading.rotation @ np.array([fwd, 0.0, 0.0])
    landing = {}
    for side in ("left", "right"):
        pose = b.stance.sole(side)
        landing[side] = Pose(position=cast(Vec3, tuple(float(x) for x in np.asarray(pose.position) + shift)), rpy=pose.rpy)
    land_contacts = tuple(Contact(frame=robot.frame(f"{s}_foot"), placement=landing[s]) for s in ("left", "right"))
    end_stance = Stance(left=landing["left"], right=landing["right"])
    b.com_target("crouch", (None, None, z0 - depth), time=tau(bounds[0]), tolerance=CROUCH_TOLERANCE)
    # Spread the push over the push phase: soft CoM heights of a uniform acceleration from the
    # bottom of the crouch to the take-off height and speed. Without them the optimizer puts the
    # whole push into the last knot interval (about 2 g), which the spline reference between the
    # knots and the knee torques cannot follow.
    z_off = z0 - takeoff.com_drop
    stroke_done = max(depth - takeoff.com_drop, 1e-3)
    acc = v0 * v0 / (2.0 * stroke_done)
    t_acc = v0 / acc
    for j in range(1, n_push + 1):
        left = (n_push - j) * dt  # time to take-off
        if left >= t_acc:
            continue
        zj = z_off - v0 * left + 0.5 * acc * left * left
        b.com_target("take-off" if j == n_push else f"push {j}", (None, None, zj), time=tau(bounds[0] + j),
                     tolerance=PUSH_PROFILE_TOLERANCE)
    k_apex = bounds[1] + n_flight // 2
    t_apex = (n_flight // 2) * dt
    apex = z0 - takeoff.com_drop + v0 * t_apex - 0.5 * G * t_apex**2
    b.com_target("flight apex", (None, None, apex), time=tau(k_apex), tolerance=0.02,
                 priority=Priority.SOFT, weight=APEX_WEIGHT)
    home = end_stance.transform_from_standing(robot).act(g.com)
    b.com_target("landed and standing", (float(home[0]), float(home[1]), float(home[2])), time=tau(bounds[4]),
                 tolerance=END_TOLERANCE)
    # Hold the torso at its standing angles from the crouch to the end of the recovery. The
    # posture cost alone (a sum of squares over every joint) spreads the crouch over the legs
    # *and* the torso: on g1 the plan folded the waist (yaw 0.95, roll -0.5, pitch 0.5 rad) and
    # unfolded it during the push to raise the CoM, which needed 93 % of the waist's torque and
    # gave the body a pitch/roll angular momentum that the controller could not reproduce.
    q_stand = robot.q_standing
    for name in torso_joints(robot):
        jid = robot.model.getJointId(name)
        b.joint_targets.append(JointTarget(
            name=b.name(f"torso {name}"), joint=name, value=float(q_stand[robot.model.joints[jid].idx_q]),
            window=b.window(0.0, tau(bounds[4])), weight=TORSO_HOLD_WEIGHT))
    b.phase("crouch", tau(bounds[0]))
    b.phase("push off", tau(bounds[1]))
    b.phase("flight", tau(bounds[2]), (), swing_height=min(FLIGHT_CLEARANCE_MAX, rise / 3.0))
    b.phase("landing", tau(bounds[3]), land_contacts)
    b.phase("recover", tau(bounds[4]), land_contacts)
    b.end_stance = end_stance
    return b.finish(PARTS, dynamic=True)


def size_limits(params: dict, robot: Robot) -> dict[str, float]:
    """The highest jump the legs allow and the longest forward jump with the given rise."""
    return {"height": max_jump_height(robot), "forward": max_forward(robot, params["height"])}


PRIMITIVE = Primitive(name="jump", nominal_duration=nominal_duration, build=build, parts=lambda p: PARTS,
                      check=check, limits=limits, dynamic=True, size_limits=size_limits)
