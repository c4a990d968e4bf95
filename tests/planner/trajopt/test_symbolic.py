"""Symbolic (CasADi SX) kinematics against Pinocchio, and against finite differences on the manifold."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest

from planner.exceptions import UnsupportedModel
from planner.trajopt.symbolic import (
    SymbolicKinematics,
    chart_to_configuration,
    configuration_to_chart,
    exp3,
    joint_infos,
)
from tests.tolerances import FD_ATOL, FD_STEP, SYMBOLIC_ATOL

N_CONFIGURATIONS = 50
ROLES = ("left_foot", "right_foot", "left_hand", "right_hand", "base", "torso")


def _random_configurations(model, rng, n):
    lo = np.clip(model.lowerPositionLimit, -np.pi, np.pi)
    hi = np.clip(model.upperPositionLimit, -np.pi, np.pi)
    lo[:3], hi[:3] = -1.0, 1.0
    out = []
    for _ in range(n):
        q = lo + rng.random(model.nq) * (hi - lo)
        q[3:7] = rng.normal(size=4)
        q[3:7] /= np.linalg.norm(q[3:7])
        out.append(q)
    return out


def _kinematics_function(robot):
    """(q_ref, dq) -> com, then per role frame: p, vec(R), J_p = dp/ddq, J_R = dvec(R)/ddq."""
    kin = SymbolicKinematics(robot.model)
    q_ref, dq = ca.SX.sym("q_ref", robot.nq), ca.SX.sym("dq", robot.nv)
    oMi = kin.joint_placements(q_ref, dq)
    com = kin.com(oMi)
    outs = [com, ca.jacobian(com, dq)]
    for role in ROLES:
        R, p = kin.frame_placement(oMi, robot.frame_id(role))
        outs += [p, ca.vec(R), ca.jacobian(p, dq), ca.jacobian(ca.vec(R), dq)]
    return ca.Function("kin", [q_ref, dq], outs)


def _angular_jacobian(R: np.ndarray, dR: np.ndarray) -> np.ndarray:
    """World angular Jacobian from d vec(R) / d dq: column j = vee(dR_j R^T)."""
    cols = []
    for j in range(dR.shape[1]):
        W = dR[:, j].reshape(3, 3, order="F") @ R.T
        cols.append([W[2, 1], W[0, 2], W[1, 0]])
    return np.array(cols).T


def test_placements_com_and_jacobians_match_pinocchio(any_robot, rng):
    """At 50 random configurations (dq != 0 in the chart) frame placements and CoM match Pinocchio
    to 1e-9, and at dq = 0 the frame/CoM Jacobians equal Pinocchio's tangent Jacobians."""
    robot = any_robot
    model, data = robot.model, robot.data()
    fn = _kinematics_function(robot)
    worst = 0.0
    for q_ref in _random_configurations(model, rng, N_CONFIGURATIONS):
        dq = 0.3 * rng.normal(size=model.nv)
        out = [np.array(x) for x in fn(q_ref, dq)]
        q = chart_to_configuration(model, q_ref, dq)
        pin.framesForwardKinematics(model, data, q)
        com = pin.centerOfMass(model, data, q)
        worst = max(worst, np.abs(out[0].ravel() - com).max())
        for i, role in enumerate(ROLES):
            M = data.oMf[robot.frame_id(role)]
            p, R = out[2 + 4 * i].ravel(), out[3 + 4 * i].reshape(3, 3, order="F")
            worst = max(worst, np.abs(p - M.translation).max(), np.abs(R - M.rotation).max())
        # Jacobians at dq = 0 (the chart's tangent equals Pinocchio's)
        out0 = [np.array(x) for x in fn(q_ref, np.zeros(model.nv))]
        pin.computeJointJacobians(model, data, q_ref)
        pin.updateFramePlacements(model, data)
        J_com = pin.jacobianCenterOfMass(model, data, q_ref)
        worst = max(worst, np.abs(out0[1] - J_com).max())
        for i, role in enumerate(ROLES):
            J = pin.getFrameJacobian(model, data, robot.frame_id(role), pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
            R0 = out0[3 + 4 * i].reshape(3, 3, order="F")
            worst = max(worst, np.abs(out0[4 + 4 * i] - J[:3]).max(),
                        np.abs(_angular_jacobian(R0, out0[5 + 4 * i]) - J[3:]).max())
    assert worst < SYMBOLIC_ATOL, f"{robot.name}: worst difference {worst:.2e}"


def test_jacobians_match_finite_differences_on_the_manifold(talos, rng):
    """The symbolic position Jacobian at dq = 0 equals central differences along pin.integrate."""
    model = talos.model
    fn = _kinematics_function(talos)
    (q,) = _random_configurations(model, rng, 1)
    out0 = [np.array(x) for x in fn(q, np.zeros(model.nv))]
    zero = np.zeros(model.nv)
    for j in rng.choice(model.nv, size=12, replace=False):
        e = np.zeros(model.nv)
        e[j] = FD_STEP
        plus = [np.array(x) for x in fn(pin.integrate(model, q, e), zero)]
        minus = [np.array(x) for x in fn(pin.integrate(model, q, -e), zero)]
        fd_com = (plus[0] - minus[0]).ravel() / (2 * FD_STEP)
        assert np.abs(fd_com - out0[1][:, j]).max() < FD_ATOL
        for i in range(len(ROLES)):
            fd = (plus[2 + 4 * i] - minus[2 + 4 * i]).ravel() / (2 * FD_STEP)
            assert np.abs(fd - out0[4 + 4 * i][:, j]).max() < FD_ATOL


def test_chart_round_trip(talos, rng):
    """configuration_to_chart inverts chart_to_configuration (rotations below pi)."""
    for q_ref in _random_configurations(talos.model, rng, 5):
        dq = 0.5 * rng.normal(size=talos.nv)
        q = chart_to_configuration(talos.model, q_ref, dq)
        assert np.abs(configuration_to_chart(talos.model, q_ref, q) - dq).max() < 1e-12


def test_exp3_is_exact_near_zero_and_far_from_it():
    """exp3 matches Pinocchio on both sides of its Taylor threshold."""
    w = ca.SX.sym("w", 3)
    f = ca.Function("exp3", [w], [exp3(w)])
    for scale in (0.0, 1e-9, 1e-4, 9e-4, 1.1e-3, 0.5, 3.0):
        v = scale * np.array([0.3, -0.5, 0.8])
        assert np.abs(np.array(f(v)) - pin.exp3(v)).max() < 1e-14


def test_unsupported_joint_type_is_refused():
    """A spherical joint raises UnsupportedModel naming the joint and its type."""
    model = pin.Model()
    root = model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), "root")
    model.addJoint(root, pin.JointModelSpherical(), pin.SE3.Identity(), "ball")
    with pytest.raises(UnsupportedModel, match="ball.*JointModelSpherical"):
        joint_infos(model)


def test_model_without_free_flyer_is_refused():
    """A fixed-base model raises UnsupportedModel."""
    model = pin.Model()
    model.addJoint(0, pin.JointModelRX(), pin.SE3.Identity(), "hinge")
    with pytest.raises(UnsupportedModel, match="free flyer"):
        joint_infos(model)
