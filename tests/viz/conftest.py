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


def synthetic_execution(robot, plan, *, rate: float = 200.0) -> dict:
    """exec_* arrays like a motion file's: plan resampled at ``rate`` Hz, torques, sole forces."""
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
    return {"exec_t": te, "exec_q": qe, "exec_v": ve, "exec_tau": tau, "contact_forces": forces}


@pytest.fixture(scope="session")
def synth_plan(talos):
    """Synthetic 3 s squat-like plan on Talos (no solver)."""
    return synthetic_plan(talos)


@pytest.fixture(scope="session")
def synth_execution(talos, synth_plan):
    """A fake execution (arrays) for the synthetic plan."""
    return synthetic_execution(talos, synth_plan)


@pytest.fixture(scope="session")
def squat_plan(talos):
    """A real squat planned by planner.plan (skips if the planner is not available)."""
    trajopt = pytest.importorskip("planner")
    from tasks.actions import Action
    from tasks.compose import compile_actions

    spec = compile_actions([Action(name="squat")], talos)
    return trajopt.plan(spec, talos)
