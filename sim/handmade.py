"""Hand-made plans built by numeric inverse kinematics, without the trajectory optimizer.

They serve as controller tests and benchmarks that do not depend on the planner: standing
still, a slow squat (CoM lowered with both soles fixed), an arm motion (a hand raised and
brought back) and deliberately broken plans (a stance foot dragged sideways). Each knot is
solved by damped Gauss-Newton from the previous one: both soles held in 6D, the CoM
horizontal position held (or moved), the base orientation held, a hand moved, and a small
pull towards the standing posture. Velocities and accelerations are central finite
differences; the plan starts and ends at rest.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import cast

import numpy as np
import pinocchio as pin

from planner import Plan, SolverStats, SolveStatus
from robots import Robot
from tasks import CoMBounds, CoMTarget, Contact, FrameTarget, Phase, Pose, Priority, TaskSpec, Vec3

Offset = Callable[[float], np.ndarray]


def smooth_bump(duration: float) -> Callable[[float], float]:
    """0 -> 1 -> 0 over ``duration`` [s], with zero slope at both ends."""
    return lambda t: 0.5 * (1.0 - np.cos(2.0 * np.pi * min(max(t / duration, 0.0), 1.0)))


def _pose_of(placement: pin.SE3) -> Pose:
    rpy = pin.rpy.matrixToRpy(placement.rotation)
    return Pose(
        position=cast(Vec3, tuple(float(x) for x in placement.translation)),
        rpy=cast(Vec3, tuple(float(x) for x in rpy)),
    )


def ik_plan(
    robot: Robot,
    *,
    duration: float,
    dt: float = 0.05,
    com_offset: Offset | None = None,
    hand_offsets: dict[str, Offset] | None = None,
    foot_offsets: dict[str, Offset] | None = None,
    targets: tuple[FrameTarget, ...] = (),
    com_targets: tuple[CoMTarget, ...] = (),
    name: str = "handmade",
    q_start: np.ndarray | None = None,
    phases: tuple[tuple[str, float, tuple[str, ...]], ...] | None = None,
) -> Plan:
    """A plan by numeric IK over a uniform grid (double support unless ``phases`` say otherwise).

    Args:
        robot: The robot.
        duration: Length [s].
        dt: Knot spacing [s].
        com_offset: CoM displacement from its start as a function of time [m].
        hand_offsets: Hand role -> displacement of that hand from its start [m].
        foot_offsets: Foot role -> displacement of that sole from its start [m] (the spec still
            holds the foot in contact: a deliberately inconsistent plan).
        targets: Frame targets to put in the spec.
        com_targets: CoM targets to put in the spec.
        name: Spec name.
        q_start: Start configuration (default: the robot's standing posture).
        phases: ``(name, duration [s], foot roles in contact)`` per phase; the durations must add
            up to ``duration``. Default: one double-support phase. The IK always holds both soles
            at their start placement plus ``foot_offsets``.

    Returns:
        A Plan with ``SolveStatus.SOLVED`` statistics.
    """
    model, data = robot.model, robot.data()
    q = np.array(robot.q_standing if q_start is None else q_start, dtype=float)
    hand_offsets = hand_offsets or {}
    foot_offsets = foot_offsets or {}
    pin.framesForwardKinematics(model, data, q)
    feet = {role: robot.frame_id(role) for role in ("left_foot", "right_foot")}
    foot0 = {role: data.oMf[fid].copy() for role, fid in feet.items()}
    hands = {role: robot.frame_id(role) for role in hand_offsets}
    hand0 = {role: data.oMf[fid].translation.copy() for role, fid in hands.items()}
    com0 = pin.centerOfMass(model, data, q).copy()
    rot0 = pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix()
    q_posture = q.copy()
    n = int(round(duration / dt)) + 1
    times = dt * np.arange(n)
    qs = np.empty((n, model.nq))
    for k, t in enumerate(times):
        for _ in range(30):
            pin.computeJointJacobians(model, data, q)
            pin.updateFramePlacements(model, data)
            errs, jacs = [], []
            for role, fid in feet.items():
                target = foot0[role].copy()
                if role in foot_offsets:
                    target.translation = target.translation + foot_offsets[role](t)
                cur = data.oMf[fid]
                err = pin.log6(target.actInv(cur)).vector
                J = pin.Jlog6(target.actInv(cur)) @ pin.getFrameJacobian(
                    model, data, fid, pin.LOCAL
                )
                errs.append(30.0 * err)
                jacs.append(30.0 * J)
            com = pin.centerOfMass(model, data, q)
            com_target = com0 + (com_offset(t) if com_offset is not None else 0.0)
            errs.append(3.0 * (com - com_target))
            jacs.append(3.0 * pin.jacobianCenterOfMass(model, data, q))
            for role, fid in hands.items():
                p = data.oMf[fid].translation
                errs.append(3.0 * (p - hand0[role] - hand_offsets[role](t)))
                jacs.append(
                    3.0 * pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)[:3]
                )
            rot = pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix()
            errs.append(pin.log3(rot0.T @ rot))
            jb = np.zeros((3, model.nv))
            jb[:, 3:6] = np.eye(3)
            jacs.append(jb)
            errs.append(0.03 * pin.difference(model, q_posture, q)[6:])
            jacs.append(np.hstack([np.zeros((model.nv - 6, 6)), 0.03 * np.eye(model.nv - 6)]))
            e = np.concatenate(errs)
            J = np.vstack(jacs)
            step = -np.linalg.solve(J.T @ J + 1e-8 * np.eye(model.nv), J.T @ e)
            q = pin.integrate(model, q, step)
            if np.linalg.norm(step) < 1e-10:
                break
        q = np.clip(q, model.lowerPositionLimit, model.upperPositionLimit) if model.nq > 7 else q
        qs[k] = q
    return _finish_plan(robot, data, times, qs, foot0, phases, targets=targets, com_targets=com_targets,
                        dt=dt, name=name)


def _finish_plan(robot: Robot, data: pin.Data, times: np.ndarray, qs: np.ndarray, foot0: dict[str, pin.SE3],
                 phases: tuple[tuple[str, float, tuple[str, ...]], ...] | None, *,
                 targets: tuple[FrameTarget, ...], com_targets: tuple[CoMTarget, ...], dt: float,
                 name: str) -> Plan:
    """The plan of :func:`ik_plan` from its IK configurations ``qs`` at ``times``: velocities and
    accelerations by central differences, the CoM, and the spec of ``phases``."""
    model = robot.model
    vs, acc = central_differences(model, qs, dt)
    coms = np.array([pin.centerOfMass(model, data, qk) for qk in qs])
    if phases is None:
        phases = (("stand", float(times[-1]), ("left_foot", "right_foot")),)
    spec_phases = tuple(
        Phase(
            name=label,
            duration=float(length),
            contacts=tuple(Contact(frame=role, placement=_pose_of(foot0[role])) for role in roles),
        )
        for label, length, roles in phases
    )
    spec = TaskSpec(
        robot=robot.name,
        phases=spec_phases,
        targets=targets,
        com_targets=com_targets,
        com_bounds=(CoMBounds(),),
        dt=dt,
        name=name,
    )
    return Plan(
        robot=robot.name,
        spec=spec,
        t=times,
        q=qs,
        v=vs,
        a=acc,
        com=coms,
        stats=SolverStats(status=SolveStatus.SOLVED, backend="handmade-ik"),
    )


def standing_plan(robot: Robot, *, duration: float = 2.0, dt: float = 0.05) -> Plan:
    """Stand still in the standing posture for ``duration`` [s]."""
    return ik_plan(robot, duration=duration, dt=dt, name="stand")


def squat_plan(
    robot: Robot, *, depth: float = 0.15, duration: float = 3.0, dt: float = 0.05
) -> Plan:
    """Lower the CoM by ``depth`` [m] and come back up, soles fixed; a CoMTarget asks for the bottom."""
    bump = smooth_bump(duration)
    com_z = pin.centerOfMass(robot.model, robot.data(), robot.q_standing)[2]
    bottom = CoMTarget(
        name="squat bottom",
        position=(None, None, float(com_z - depth)),
        time=0.5 * duration,
        tolerance=0.01,
    )
    return ik_plan(
        robot,
        duration=duration,
        dt=dt,
        com_offset=lambda t: np.array([0.0, 0.0, -depth * bump(t)]),
        com_targets=(bottom,),
        name="squat",
    )


def joint_plan(
    robot: Robot,
    joints: dict[str, float],
    *,
    duration: float = 3.0,
    dt: float = 0.05,
    name: str = "joints",
) -> Plan:
    """Move the named joints from the standing posture to ``joints`` [rad] and back (a smooth
    bump), holding every other joint and the base: a plan that ignores balance and collisions
    (for tests that need a motion the planner would refuse, such as a forearm through the pelvis).
    """
    model = robot.model
    goal = np.array(robot.q_standing, dtype=float)
    for joint, value in joints.items():
        if not model.existJointName(joint):
            raise KeyError(f"robot {robot.name!r} has no joint {joint!r}")
        goal[model.joints[model.getJointId(joint)].idx_q] = value
    goal = np.clip(goal, model.lowerPositionLimit, model.upperPositionLimit)
    bump = smooth_bump(duration)
    draft = ik_plan(robot, duration=duration, dt=dt, name=name)  # standing: its spec and timing
    qs = np.array([pin.interpolate(model, robot.q_standing, goal, bump(t)) for t in draft.t])
    vs, acc = central_differences(model, qs, dt)
    data = robot.data()
    coms = np.array([pin.centerOfMass(model, data, q) for q in qs])
    return dataclasses.replace(draft, q=qs, v=vs, a=acc, com=coms)


def arm_plan(
    robot: Robot,
    *,
    side: str = "right",
    offset: tuple[float, float, float] = (0.15, 0.0, 0.25),
    duration: float = 3.0,
    dt: float = 0.05,
    tolerance: float = 0.02,
) -> Plan:
    """Move one hand by ``offset`` [m] and back; a FrameTarget asks for the top at mid-motion."""
    bump = smooth_bump(duration)
    role = f"{side}_hand"
    shift = np.array(offset, dtype=float)
    draft = ik_plan(
        robot, duration=duration, dt=dt, hand_offsets={role: lambda t: shift * bump(t)}, name="arm"
    )
    mid = len(draft.t) // 2
    data = robot.data()
    pin.framesForwardKinematics(robot.model, data, draft.q[mid])
    top = data.oMf[robot.frame_id(role)].translation
    target = FrameTarget(
        name=f"{side} hand up",
        frame=role,
        position=cast(Vec3, tuple(float(x) for x in top)),
        time=float(draft.t[mid]),
        tolerance=tolerance,
        priority=Priority.HARD,
    )
    spec = TaskSpec(
        robot=draft.spec.robot,
        phases=draft.spec.phases,
        targets=(target,),
        com_bounds=draft.spec.com_bounds,
        dt=draft.spec.dt,
        name="arm",
    )
    return Plan(
        robot=draft.robot,
        spec=spec,
        t=draft.t,
        q=draft.q,
        v=draft.v,
        a=draft.a,
        com=draft.com,
        stats=draft.stats,
    )


def foot_lift_plan(
    robot: Robot,
    *,
    side: str = "right",
    height: float = 0.05,
    shift: float = 0.07,
    dt: float = 0.05,
) -> Plan:
    """Shift the CoM over one foot, lift the other ``height`` [m] and put it back, shift back.

    Phases: 1.5 s weight shift (double support), 1.5 s lift (single support), 1.5 s shift back.
    The CoM goes ``shift`` [m] towards the stance foot, whose centre is 0.085 m off on Talos.
    """
    stance, swing = ("left_foot", "right_foot") if side == "right" else ("right_foot", "left_foot")
    sign = 1.0 if side == "right" else -1.0
    t1, t2, t3 = 1.5, 3.0, 4.5

    def com(t: float) -> np.ndarray:
        if t < t1:
            s_ = 0.5 * (1.0 - np.cos(np.pi * t / t1))
        elif t < t2:
            s_ = 1.0
        else:
            s_ = 0.5 * (1.0 + np.cos(np.pi * min((t - t2) / (t3 - t2), 1.0)))
        return np.array([0.0, sign * shift * s_, 0.0])

    def foot(t: float) -> np.ndarray:
        s_ = 0.0 if not t1 <= t <= t2 else 0.5 * (1.0 - np.cos(2.0 * np.pi * (t - t1) / (t2 - t1)))
        return np.array([0.0, 0.0, height * s_])

    both = ("left_foot", "right_foot")
    return ik_plan(
        robot,
        duration=t3,
        dt=dt,
        com_offset=com,
        foot_offsets={swing: foot},
        name=f"lift {swing}",
        phases=(
            ("shift", t1, both),
            (f"lift {swing}", t2 - t1, (stance,)),
            ("shift back", t3 - t2, both),
        ),
    )


def with_torque_limits(robot: Robot, scale: float) -> Robot:
    """A copy of ``robot`` whose joint torque limits are multiplied by ``scale`` (for what-if checks)."""
    model = pin.Model(robot.model)
    model.effortLimit = np.array(robot.model.effortLimit) * scale
    return dataclasses.replace(robot, model=model, _frame_ids={})


def feet_apart_plan(
    robot: Robot, *, distance: float = 0.25, duration: float = 2.0, dt: float = 0.05
) -> Plan:
    """An infeasible plan: the right sole is dragged ``distance`` [m] outwards while it is in stance."""
    ramp = lambda t: 0.5 * (1.0 - np.cos(np.pi * min(t / duration, 1.0)))  # noqa: E731
    return ik_plan(
        robot,
        duration=duration,
        dt=dt,
        foot_offsets={"right_foot": lambda t: np.array([0.0, -distance * ramp(t), 0.0])},
        com_offset=lambda t: np.array([0.0, -0.5 * distance * ramp(t), 0.0]),
        name="feet apart",
    )


def central_differences(model: pin.Model, qs: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Velocities and accelerations of configurations ``qs`` (n, nq) sampled every ``dt`` [s] by
    central differences on the configuration manifold (``pin.difference``); zero at both ends (a
    motion from and to rest)."""
    n = len(qs)
    vs = np.zeros((n, model.nv))
    for k in range(1, n - 1):
        vs[k] = pin.difference(model, qs[k - 1], qs[k + 1]) / (2 * dt)
    acc = np.zeros((n, model.nv))
    acc[1:-1] = (vs[2:] - vs[:-2]) / (2 * dt)
    return vs, acc
