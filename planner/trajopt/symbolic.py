"""CasADi SX kinematics built from a Pinocchio model, over the tangent-displacement chart.

The pip wheels of Pinocchio have no ``pinocchio.casadi``, so this module rebuilds forward
kinematics as a pure function of the model (docs/planner.md): it walks ``parents`` and
``jointPlacements`` as rotation/translation pairs, ``oMi[i] = oMi[parent] * jointPlacements[i] *
jMq``, frames through ``frames[f].parentJoint``, and the centre of mass as
``sum(m_i * oMi * lever_i) / M``.

The chart: a configuration is a reference ``q_ref`` (nq) plus a tangent displacement ``dq``
(nv). One-dof joints move by ``q_ref + dq``; the free flyer's position is ``p_ref + R_ref dv``
and its rotation ``R_ref exp3(w)``. No quaternion, no norm constraint; joint limits become
bounds on ``dq``, and at ``dq = 0`` the Jacobians equal Pinocchio's tangent Jacobians (base
velocity in the base frame). :func:`chart_to_configuration` and :func:`configuration_to_chart`
convert numerically.
"""

from __future__ import annotations

import hashlib
from collections import OrderedDict
from dataclasses import dataclass

import casadi as ca
import numpy as np
import pinocchio as pin

from planner.exceptions import UnsupportedModel

EXP3_TAYLOR_THRESHOLD = 1e-6  # [rad^2], below it exp3 uses its Taylor series

_AXES = {"X": (1.0, 0.0, 0.0), "Y": (0.0, 1.0, 0.0), "Z": (0.0, 0.0, 1.0)}


def _skew(w):
    return ca.vertcat(
        ca.horzcat(0, -w[2], w[1]),
        ca.horzcat(w[2], 0, -w[0]),
        ca.horzcat(-w[1], w[0], 0),
    )


def exp3(w):
    """Rotation matrix of the rotation vector ``w`` [rad], smooth at 0 (Taylor branch)."""
    theta2 = ca.dot(w, w)
    small = theta2 < EXP3_TAYLOR_THRESHOLD
    safe2 = ca.if_else(small, 1.0, theta2)
    theta = ca.sqrt(safe2)
    a = ca.if_else(small, 1 - theta2 / 6 + theta2**2 / 120, ca.sin(theta) / theta)
    b = ca.if_else(small, 0.5 - theta2 / 24 + theta2**2 / 720, (1 - ca.cos(theta)) / safe2)
    K = _skew(w)
    return ca.SX.eye(3) + a * K + b * ca.mtimes(K, K)


def _axis_rotation(axis: np.ndarray, angle):
    """Rotation of ``angle`` about the unit ``axis`` (constant), Rodrigues."""
    x, y, z = (float(a) for a in axis)
    c, s = ca.cos(angle), ca.sin(angle)
    t = 1 - c
    if (x, y, z) == (1.0, 0.0, 0.0):
        return ca.vertcat(ca.horzcat(1, 0, 0), ca.horzcat(0, c, -s), ca.horzcat(0, s, c))
    if (x, y, z) == (0.0, 1.0, 0.0):
        return ca.vertcat(ca.horzcat(c, 0, s), ca.horzcat(0, 1, 0), ca.horzcat(-s, 0, c))
    if (x, y, z) == (0.0, 0.0, 1.0):
        return ca.vertcat(ca.horzcat(c, -s, 0), ca.horzcat(s, c, 0), ca.horzcat(0, 0, 1))
    return ca.vertcat(
        ca.horzcat(c + x * x * t, x * y * t - z * s, x * z * t + y * s),
        ca.horzcat(y * x * t + z * s, c + y * y * t, y * z * t - x * s),
        ca.horzcat(z * x * t - y * s, z * y * t + x * s, c + z * z * t),
    )


@dataclass(frozen=True)
class _JointInfo:
    kind: str  # "freeflyer", "revolute", "prismatic"
    idx_q: int
    idx_v: int
    axis: np.ndarray | None


def joint_infos(model: pin.Model) -> list[_JointInfo | None]:
    """Per-joint kind/indices/axis (index 0, the universe, is None).

    Raises:
        UnsupportedModel: a joint type other than free flyer, revolute or prismatic (X, Y, Z or
            unaligned) appears.
    """
    out: list[_JointInfo | None] = [None]
    for i in range(1, model.njoints):
        j = model.joints[i]
        name = j.shortname()
        if name == "JointModelFreeFlyer":
            if i != 1 or model.parents[i] != 0:
                raise UnsupportedModel(f"joint {model.names[i]!r}: a free flyer is only supported as the root joint")
            out.append(_JointInfo("freeflyer", j.idx_q, j.idx_v, None))
        elif name in ("JointModelRX", "JointModelRY", "JointModelRZ"):
            out.append(_JointInfo("revolute", j.idx_q, j.idx_v, np.array(_AXES[name[-1]])))
        elif name == "JointModelRevoluteUnaligned":
            out.append(_JointInfo("revolute", j.idx_q, j.idx_v, np.array(j.extract().axis, dtype=float)))
        elif name in ("JointModelPX", "JointModelPY", "JointModelPZ"):
            out.append(_JointInfo("prismatic", j.idx_q, j.idx_v, np.array(_AXES[name[-1]])))
        elif name == "JointModelPrismaticUnaligned":
            out.append(_JointInfo("prismatic", j.idx_q, j.idx_v, np.array(j.extract().axis, dtype=float)))
        else:
            raise UnsupportedModel(
                f"joint {model.names[i]!r} has type {name}, which the planner does not support "
                "(supported: free flyer root, revolute and prismatic joints about X, Y, Z or a fixed axis)"
            )
    if len(out) < 2 or out[1] is None or out[1].kind != "freeflyer":
        raise UnsupportedModel("the planner needs a model whose root joint is a free flyer")
    return out


def model_hash(model: pin.Model) -> str:
    """A hash of everything the kinematics depends on (tree, placements, inertias, frames)."""
    h = hashlib.sha256()
    h.update(repr((model.nq, model.nv, model.njoints, list(model.parents))).encode())
    for i in range(model.njoints):
        h.update(model.joints[i].shortname().encode())
        h.update(np.asarray(model.jointPlacements[i].homogeneous).tobytes())
        h.update(np.array([model.inertias[i].mass, *model.inertias[i].lever]).tobytes())
        j = model.joints[i]
        if j.shortname().endswith("Unaligned"):
            h.update(np.asarray(j.extract().axis, dtype=float).tobytes())
    for f in model.frames:
        h.update(f.name.encode())
        h.update(repr(int(f.parentJoint)).encode())
        h.update(np.asarray(f.placement.homogeneous).tobytes())
    h.update(np.asarray(model.lowerPositionLimit).tobytes())
    h.update(np.asarray(model.upperPositionLimit).tobytes())
    h.update(np.asarray(model.velocityLimit).tobytes())
    return h.hexdigest()[:16]


class SymbolicKinematics:
    """Forward kinematics of a Pinocchio model as CasADi SX expressions of ``(q_ref, dq)``.

    Args:
        model: A Pinocchio model whose root joint is a free flyer.

    Raises:
        UnsupportedModel: the model has a joint type this module cannot express.
    """

    def __init__(self, model: pin.Model) -> None:
        self.model = model
        self.joints = joint_infos(model)
        self.nq, self.nv = model.nq, model.nv
        self.mass = float(sum(model.inertias[i].mass for i in range(model.njoints)))

    def joint_placements(self, q_ref, dq) -> list[tuple]:
        """World placements ``(R, p)`` of every joint (index 0 = universe) at ``q_ref (+) dq``.

        For SX symbols of the full sizes (how the planner calls it), the placements come from one
        SX Function of the model built once per process (:func:`_placements_function`) and
        evaluated on ``q_ref, dq``: the same operations on the same operands as walking the tree
        here, but in CasADi's C++ instead of ~5,000 Python-level SX operations (a dynamic plan
        builds its kinematics ~28 times, ~1 s of a first-ever build)."""
        if (isinstance(q_ref, ca.SX) and isinstance(dq, ca.SX) and q_ref.shape == (self.nq, 1)
                and dq.shape == (self.nv, 1)):
            fn = _placements_function(self.model)
            outs = fn(q_ref, dq)
            if not isinstance(outs, (list, tuple)):
                outs = [outs]
            placements: list[tuple] = [(ca.SX.eye(3), ca.SX.zeros(3))]
            placements += [(outs[2 * k], outs[2 * k + 1]) for k in range(len(outs) // 2)]
            return placements
        return self.walk(q_ref, dq)

    def walk(self, q_ref, dq) -> list[tuple]:
        """:meth:`joint_placements` by walking the tree in Python (any argument types)."""
        model = self.model
        out: list[tuple] = [(ca.SX.eye(3), ca.SX.zeros(3))]
        for i in range(1, model.njoints):
            info = self.joints[i]
            assert info is not None  # only index 0, the universe, is None
            if info.kind == "freeflyer":
                R_ref = _quat_to_matrix(q_ref[info.idx_q + 3: info.idx_q + 7])
                p = q_ref[info.idx_q: info.idx_q + 3] + ca.mtimes(R_ref, dq[info.idx_v: info.idx_v + 3])
                R = ca.mtimes(R_ref, exp3(dq[info.idx_v + 3: info.idx_v + 6]))
                jR, jp = R, p
            elif info.kind == "revolute":
                assert info.axis is not None  # revolute and prismatic joints have an axis
                jR = _axis_rotation(info.axis, q_ref[info.idx_q] + dq[info.idx_v])
                jp = ca.SX.zeros(3)
            else:  # prismatic
                jR = ca.SX.eye(3)
                jp = ca.DM(info.axis) * (q_ref[info.idx_q] + dq[info.idx_v])
            M = model.jointPlacements[i]
            Rp, pp = out[model.parents[i]]
            # oMi = oMparent * parentMi(placement) * jMq
            R_pl = ca.mtimes(Rp, ca.DM(M.rotation))
            p_pl = pp + ca.mtimes(Rp, ca.DM(M.translation))
            out.append((ca.mtimes(R_pl, jR), p_pl + ca.mtimes(R_pl, jp)))
        return out

    def frame_placement(self, oMi: list[tuple], frame_id: int) -> tuple:
        """World placement ``(R, p)`` of a frame given the joint placements."""
        f = self.model.frames[frame_id]
        R, p = oMi[f.parentJoint]
        return ca.mtimes(R, ca.DM(f.placement.rotation)), p + ca.mtimes(R, ca.DM(f.placement.translation))

    def com(self, oMi: list[tuple]):
        """Centre of mass in the world (3,) [m]."""
        acc = ca.SX.zeros(3)
        for i in range(1, self.model.njoints):
            inertia = self.model.inertias[i]
            if inertia.mass == 0.0:
                continue
            R, p = oMi[i]
            acc += inertia.mass * (p + ca.mtimes(R, ca.DM(inertia.lever)))
        return acc / self.mass

    def function(self, frame_ids: list[int], name: str = "fk") -> ca.Function:
        """CasADi Function ``(q_ref[nq], dq[nv]) -> (com[3], p_0[3], R_0[3x3], p_1, R_1, ...)``."""
        q_ref = ca.SX.sym("q_ref", self.nq)
        dq = ca.SX.sym("dq", self.nv)
        oMi = self.joint_placements(q_ref, dq)
        outs = [self.com(oMi)]
        names = ["com"]
        for k, fid in enumerate(frame_ids):
            R, p = self.frame_placement(oMi, fid)
            outs += [p, R]
            names += [f"p{k}", f"R{k}"]
        return ca.Function(name, [q_ref, dq], outs, ["q_ref", "dq"], names)


PLACEMENTS_CACHE_SIZE = 8
_PLACEMENTS: OrderedDict[str, ca.Function] = OrderedDict()


def kinematic_key(model: pin.Model) -> str:
    """A hash of what the joint placements depend on: the tree, the joint types, indices, axes and
    placements (cheaper than :func:`model_hash`: no frames, inertias or limits)."""
    h = hashlib.sha256()
    h.update(repr((model.nq, model.nv, model.njoints, list(model.parents))).encode())
    for i in range(model.njoints):
        j = model.joints[i]
        h.update(repr((j.shortname(), j.idx_q, j.idx_v)).encode())
        h.update(np.asarray(model.jointPlacements[i].homogeneous).tobytes())
        if j.shortname().endswith("Unaligned"):
            h.update(np.asarray(j.extract().axis, dtype=float).tobytes())
    return h.hexdigest()[:16]


def _placements_function(model: pin.Model) -> ca.Function:
    """SX Function ``(q_ref[nq], dq[nv]) -> (R_1, p_1, ..., R_n, p_n)`` of the joints' world
    placements, built once per model structure and process (a small LRU keyed by
    :func:`kinematic_key`)."""
    key = kinematic_key(model)
    hit = _PLACEMENTS.get(key)
    if hit is not None:
        _PLACEMENTS.move_to_end(key)
        return hit
    q_ref, dq = ca.SX.sym("q_ref", model.nq), ca.SX.sym("dq", model.nv)
    outs = [x for R, p in SymbolicKinematics(model).walk(q_ref, dq)[1:] for x in (R, p)]
    fn = ca.Function("placements_" + key, [q_ref, dq], outs)
    _PLACEMENTS[key] = fn
    while len(_PLACEMENTS) > PLACEMENTS_CACHE_SIZE:
        _PLACEMENTS.popitem(last=False)
    return fn


def _quat_to_matrix(quat):
    """Rotation matrix of a quaternion (x, y, z, w) (assumed unit) as SX."""
    x, y, z, w = quat[0], quat[1], quat[2], quat[3]
    return ca.vertcat(
        ca.horzcat(1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)),
        ca.horzcat(2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)),
        ca.horzcat(2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)),
    )


def rotation_error(R_target, R):
    """3-vector rotation error: vee of the antisymmetric part of ``R_target^T R`` [rad]."""
    M = ca.mtimes(R_target.T, R)
    return 0.5 * ca.vertcat(M[2, 1] - M[1, 2], M[0, 2] - M[2, 0], M[1, 0] - M[0, 1])


# -- numeric chart conversions ------------------------------------------------------------


def chart_to_configuration(model: pin.Model, q_ref: np.ndarray, dq: np.ndarray) -> np.ndarray:
    """Configuration ``q_ref (+) dq`` in the chart of this module (nq,)."""
    q = np.array(q_ref, dtype=float).copy()
    R_ref = pin.Quaternion(q_ref[3:7]).matrix()
    q[0:3] = q_ref[0:3] + R_ref @ dq[0:3]
    R = R_ref @ pin.exp3(np.asarray(dq[3:6], dtype=float))
    q[3:7] = pin.Quaternion(R).coeffs()
    q[7:] = q_ref[7:] + dq[6:]
    return q


def configuration_to_chart(model: pin.Model, q_ref: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Inverse of :func:`chart_to_configuration` (nv,)."""
    dq = np.zeros(model.nv)
    R_ref = pin.Quaternion(q_ref[3:7]).matrix()
    R = pin.Quaternion(q[3:7]).matrix()
    dq[0:3] = R_ref.T @ (q[0:3] - q_ref[0:3])
    dq[3:6] = pin.log3(R_ref.T @ R)
    dq[6:] = q[7:] - q_ref[7:]
    return dq
