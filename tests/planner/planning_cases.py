"""Specs used by the planner tests, and an independent Pinocchio check of a plan against its spec."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
from scipy.spatial import ConvexHull

from tasks.specs import CoMBounds, CoMTarget, Contact, FrameTarget, Phase, Pose, TaskSpec
from tests.tolerances import CONTACT_POS_ATOL, CONTACT_ROT_ATOL

LIMIT_ATOL = 1e-6  # [rad] joint position limits in a plan (IPOPT bound relaxation ~1e-8)
VELOCITY_ATOL = 1e-5  # [rad/s] finite-difference velocity limits in a plan
POLYGON_ATOL = 1e-6  # [m] CoM ground projection inside the shrunk support polygon


def standing(robot):
    """(data at q_standing, CoM at q_standing)."""
    data = robot.data()
    pin.framesForwardKinematics(robot.model, data, robot.q_standing)
    return data, np.array(pin.centerOfMass(robot.model, data, robot.q_standing))


def feet(robot) -> tuple[Contact, Contact]:
    """Both soles held where they stand."""
    data, _ = standing(robot)

    def pose(role):
        M = data.oMf[robot.frame_id(role)]
        return Pose(position=tuple(float(x) for x in M.translation),
                    rpy=tuple(float(x) for x in pin.rpy.matrixToRpy(M.rotation)))

    return (Contact(frame="left_foot", placement=pose("left_foot")),
            Contact(frame="right_foot", placement=pose("right_foot")))


def squat_spec(robot, depth: float, *, duration: float = 3.0, dt: float = 0.075, margin: float = 0.02) -> TaskSpec:
    """Lower the CoM by ``depth`` [m] at mid-motion and stand up again."""
    _, com = standing(robot)
    return TaskSpec(
        robot=robot.name, name="squat", dt=dt,
        phases=(Phase(name="squat", duration=duration, contacts=feet(robot)),),
        com_targets=(CoMTarget(name="bottom", position=(None, None, float(com[2]) - depth), time=duration / 2),),
        com_bounds=(CoMBounds(name="balance", margin=margin),),
    )


def reach_spec(robot, offset, *, duration: float = 3.0, time: float = 1.5, tolerance: float = 0.01,
               absolute=None) -> TaskSpec:
    """Right hand to its standing position + ``offset`` [m] (or to ``absolute``) at ``time``."""
    data, _ = standing(robot)
    hand = data.oMf[robot.frame_id("right_hand")].translation
    goal = np.array(absolute, dtype=float) if absolute is not None else hand + np.array(offset)
    return TaskSpec(
        robot=robot.name, name="reach",
        phases=(Phase(name="stand", duration=duration, contacts=feet(robot)),),
        targets=(FrameTarget(name="reach", frame="right_hand", position=tuple(float(x) for x in goal), time=time,
                             tolerance=tolerance),),
    )


def assert_plan_meets_spec(plan, robot, spec) -> dict[str, float]:
    """Check a plan with Pinocchio numerics only; returns the worst errors found."""
    model, data = robot.model, robot.data()
    dt = plan.dt
    worst = {"contact_pos": 0.0, "contact_rot": 0.0, "polygon": -np.inf, "target": 0.0}
    assert np.allclose(plan.q[0], robot.q_standing, atol=1e-12), "the motion must start standing"
    assert np.allclose(plan.t, np.linspace(0.0, spec.horizon, len(plan.t))), "uniform grid over the horizon"
    assert np.abs(plan.v[0]).max() < 1e-9 and np.abs(plan.v[-2:]).max() < 1e-9, "start and end at rest"
    for k in range(len(plan.t) - 1):  # v consistent with q on the manifold
        q_next = pin.integrate(model, plan.q[k], plan.v[k] * dt)
        assert np.abs(pin.difference(model, q_next, plan.q[k + 1])).max() < 1e-9
    lower, upper = model.lowerPositionLimit[7:], model.upperPositionLimit[7:]
    vmax = np.array(model.velocityLimit[6:])
    vmax[vmax <= 0] = np.inf  # a zero limit in a URDF means "not given" (Romeo's fingers)
    margin = min(b.margin for b in spec.com_bounds)
    starts = spec.phase_start_times()
    for k, (tk, q) in enumerate(zip(plan.t, plan.q, strict=True)):
        pin.framesForwardKinematics(model, data, q)
        active = [c for i, ph in enumerate(spec.phases)
                  if starts[i] - 1e-9 <= tk <= starts[i] + ph.duration + 1e-9 for c in ph.contacts]
        corners = []
        for c in active:
            oMf = data.oMf[robot.frame_id(c.frame)]
            goal = pin.SE3(pin.rpy.rpyToMatrix(*c.placement.rpy), np.array(c.placement.position))
            worst["contact_pos"] = max(worst["contact_pos"], np.linalg.norm(oMf.translation - goal.translation))
            worst["contact_rot"] = max(worst["contact_rot"],
                                       np.linalg.norm(pin.log3(goal.rotation.T @ oMf.rotation)))
            side = "left" if c.frame == "left_foot" else "right"
            corners.append(robot.sole_corners_in_world(q, side)[:, :2])
        com = pin.centerOfMass(model, data, q)
        assert np.allclose(com, plan.com[k], atol=1e-12)
        hull = ConvexHull(np.vstack(corners))
        # equations: n . x + d <= 0 inside, n unit
        inside = -(hull.equations[:, :2] @ com[:2] + hull.equations[:, 2])  # distance to each edge
        worst["polygon"] = max(worst["polygon"], float(margin - inside.min()))
        assert np.all(q[7:] >= lower - LIMIT_ATOL) and np.all(q[7:] <= upper + LIMIT_ATOL), f"limits at t={tk}"
        assert np.all(np.abs(plan.v[k, 6:]) <= vmax + VELOCITY_ATOL), f"velocity limits at t={tk}"
    assert worst["contact_pos"] < CONTACT_POS_ATOL
    assert worst["contact_rot"] < CONTACT_ROT_ATOL
    assert worst["polygon"] < POLYGON_ATOL, f"CoM leaves the shrunk polygon by {worst['polygon']:.2e} m"
    for target in spec.targets:
        k = int(round(target.time / dt))
        pin.framesForwardKinematics(model, data, plan.q[k])
        err = np.linalg.norm(data.oMf[robot.frame_id(target.frame)].translation - np.array(target.position))
        worst["target"] = max(worst["target"], err)
        assert err <= target.tolerance, f"{target.name}: {err:.4f} m from the target"
    for target in spec.com_targets:
        k = int(round(target.time / dt))
        err = abs(plan.com[k, 2] - target.position[2])
        worst["target"] = max(worst["target"], err)
        assert err <= target.tolerance
    return worst
