"""Fixtures of the viz tests: a synthetic plan (no solver), a real squat plan, an execution."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

SQUAT_DEPTH = 0.12  # [m] base drop of the synthetic squat
SYNTH_DURATION = 3.0  # [s]


def synthetic_plan(robot, *, duration: float = SYNTH_DURATION, dt: float = 0.05):
    """A Plan built directly: standing posture, base lowered and arms raised on a cosine."""
    from planner import Plan, SolverStats, SolveStatus
    from tasks.specs import Contact, FrameTarget, Phase, Pose, TaskSpec

    t = np.arange(0.0, duration + 1e-9, dt)
    s = 0.5 * (1.0 - np.cos(2.0 * np.pi * t / duration))
    q = np.tile(robot.q_standing, (len(t), 1))
    q[:, 2] -= SQUAT_DEPTH * s
    arm = [robot.model.joints[j].idx_q for j in range(2, robot.model.njoints)
           if any(k in robot.model.names[j] for k in ("arm_left_1", "arm_right_1", "shoulder_pitch"))]
    for i in arm:
        q[:, i] -= 0.8 * s
    v = np.zeros((len(t), robot.nv))  # joint velocities by finite differences (revolute joints)
    for k, i in enumerate(range(7, robot.nq)):
        v[:, 6 + k] = np.gradient(q[:, i], t)
    data = robot.data()
    com = np.array([pin.centerOfMass(robot.model, data, qk).copy() for qk in q])
    pin.framesForwardKinematics(robot.model, data, robot.q_standing)

    def placement(role: str) -> Pose:
        return Pose(position=tuple(float(x) for x in data.oMf[robot.frame_id(role)].translation))

    spec = TaskSpec(
        robot=robot.name,
        phases=(Phase(name="squat", duration=float(t[-1]),
                      contacts=(Contact(frame=robot.frame("left_foot"), placement=placement("left_foot")),
                                Contact(frame=robot.frame("right_foot"), placement=placement("right_foot")))),),
        targets=(FrameTarget(name="right hand mark", frame="right_hand", position=(0.35, -0.35, 1.1),
                             time=float(t[len(t) // 2])),),
        name="synthetic squat",
    )
    return Plan(robot=robot.name, spec=spec, t=t, q=q, v=v, a=np.zeros_like(v), com=com,
                stats=SolverStats(status=SolveStatus.SOLVED))


def synthetic_execution(robot, plan, *, rate: float = 200.0):
    """A :class:`sim.Execution` without a certificate (as a motion file without one reads back):
    the plan resampled at ``rate`` Hz, torques, sole forces."""
    from sim import Execution

    te = np.arange(0.0, float(plan.t[-1]) + 1e-9, 1.0 / rate)
    idx = np.minimum(np.searchsorted(plan.t, te), len(plan.t) - 1)
    qe = plan.q[idx].copy()
    ve = plan.v[idx].copy()
    n = robot.nv - 6
    tau = 0.5 * robot.torque_limits * np.sin(te[:, None] * (1.0 + np.arange(n)) * 0.3)
    half = robot.mass * 9.81 / 2.0
    forces = {
        robot.frame("left_foot"): np.column_stack([5 * np.sin(te), np.zeros_like(te), half + 30 * np.cos(te)]),
        robot.frame("right_foot"): np.column_stack([np.zeros_like(te), 4 + 0 * te, half - 30 * np.cos(te)]),
    }
    return Execution(t=te, q=qe, v=ve, tau=tau, certificate=None, contact_forces=forces)


@pytest.fixture(scope="session")
def synth_plan(talos):
    """Synthetic 3 s squat-like plan on Talos (no solver)."""
    return synthetic_plan(talos)


@pytest.fixture(scope="session")
def synth_execution(talos, synth_plan):
    """A fake execution for the synthetic plan."""
    return synthetic_execution(talos, synth_plan)


@pytest.fixture(scope="session")
def squat_plan(talos):
    """A real squat planned by planner.plan (skips if the planner is not available)."""
    trajopt = pytest.importorskip("planner")
    from tasks.actions import Action
    from tasks.compose import compile_actions

    spec = compile_actions([Action(name="squat")], talos)
    return trajopt.plan(spec, talos)


PICK_START = 1.0  # [s] the synthetic grasp starts here
CUP_OFFSET = (0.0, 0.0, -0.12)  # [m] the cup's centre in the hand frame while held
SIM_DROP = 0.03  # [m] the synthetic execution's cup hangs this much below the planned one


def synthetic_pick_up(robot, plan):
    """The synthetic plan with a scene (a fixed table, a movable cup where the right hand is at
    PICK_START, a movable box nobody holds) and a grasp of the cup by the right hand from PICK_START on."""
    import dataclasses

    from tasks.scene import Scene, SceneObject
    from tasks.specs import Grasp

    k0 = int(np.searchsorted(plan.t, PICK_START - 1e-9))
    data = robot.data()
    pin.framesForwardKinematics(robot.model, data, plan.q[k0])
    hand = robot.frame("right_hand")
    at = data.oMf[robot.frame_id("right_hand")].act(np.asarray(CUP_OFFSET))
    cup = SceneObject(name="cup", shape="cylinder", size=(0.08, 0.2), position=tuple(float(x) for x in at),
                      movable=True, mass=0.25, colour=(0.85, 0.1, 0.1, 1.0))
    box = SceneObject(name="box", shape="box", size=(0.2, 0.2, 0.2), position=(0.6, 0.6, 0.1), movable=True, mass=1.0)
    table = SceneObject(name="table", shape="box", size=(0.3, 0.3, 0.3), position=(0.9, -0.9, 0.15))
    grasp = Grasp(name="right hand holds the cup", object="cup", frame=hand, offset=CUP_OFFSET, start=float(plan.t[k0]))
    spec = dataclasses.replace(plan.spec, scene=Scene(name="a cup", objects=(table, cup, box)), grasps=(grasp,))
    return dataclasses.replace(plan, spec=spec)


def synthetic_pick_up_execution(robot, plan):
    """The synthetic execution of the pick-up plan with ``objects`` (the planned poses resampled,
    the cup SIM_DROP lower) and ``object_orientations``."""
    import dataclasses

    from viz import motion as vm

    ex = synthetic_execution(robot, plan)
    planned = vm.planned_object_poses(robot, plan.spec, plan.t, plan.q)
    objects, turns = {}, {}
    for name, poses in planned.items():
        sampled = vm.resample_poses(plan.t, poses, ex.t)
        if name == "cup":
            sampled[:, 2] -= SIM_DROP
        objects[name], turns[name] = sampled[:, :3], sampled[:, 3:]
    return dataclasses.replace(ex, objects=objects, object_orientations=turns)


@pytest.fixture(scope="session")
def pick_plan(talos, synth_plan):
    """The synthetic plan holding a cup in the right hand from PICK_START (no solver)."""
    return synthetic_pick_up(talos, synth_plan)


@pytest.fixture(scope="session")
def pick_execution(talos, pick_plan):
    """A fake execution of the pick-up plan with the objects' simulated poses."""
    return synthetic_pick_up_execution(talos, pick_plan)
