r"""Whole-body inverse-dynamics QP controller that tracks a Plan.

Every tick solves one quadratic program in the joint accelerations :math:`a` (nv) and the contact
forces :math:`f`: four corner forces per planar sole, 3D each, expressed in the sole frame.

Constraints:

* floating-base dynamics, the first six rows of :math:`M a + h = J_c^\top f`;
* stance contacts, :math:`J_c a + \dot J_c v = -K_p e - K_d \dot e` (6D per sole, in the sole
  frame; Baumgarte feedback pulls a drifting sole back to where it touched down);
* friction pyramids per corner, :math:`|f_x|, |f_y| \le \mu f_z` (hence :math:`f_z \ge 0`),
  which keeps the centre of pressure inside the sole rectangle;
* torque limits on the actuated rows, :math:`|M a + h - J_c^\top f|_{6:} \le \tau_{max}`.

Costs (weighted least squares on accelerations, PD + feed-forward from the plan): centre of
mass, base orientation, hands and every frame a spec target names, swing feet, joint posture,
plus small regularizations of :math:`a` and :math:`f`. A contact frame that is not in stance
has its force columns removed from the dynamics (the regularization then sets its forces to 0).

Numerics per tick: one ``computeAllTerms`` (mass matrix, nonlinear effects, joint Jacobians,
CoM Jacobian and the velocity-product accelerations), one ``centerOfMass`` at zero
acceleration for the CoM drift, and per frame a Jacobian and a drift read from the filled data.
The QP is a persistent dense proxsuite problem that is updated and warm-started from the
previous solution (DESIGN.md section 4). Any other backend name goes through ``qpsolvers``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
import pinocchio as pin
import proxsuite

from planner.exceptions import PlannerError
from planner.plan import Plan
from planner.wbc_reference import PlanReference
from robots.model import Robot

INFINITY = 1e20  # proxsuite treats bounds this large as absent
_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
_SOLVED = proxsuite.proxqp.QPSolverOutput.PROXQP_SOLVED
_VEE_A = np.array([7, 2, 3])  # flattened (R^T R_ref) entries (2,1), (0,2), (1,0)
_VEE_B = np.array([5, 6, 1])  # and (1,2), (2,0), (0,1): vee(R - R^T) / 2 = sin(angle) * axis


class ControllerError(PlannerError):
    """The whole-body controller was misconfigured (unknown backend, bad reference)."""


@dataclass(frozen=True, slots=True, kw_only=True)
class WbcSettings:
    """Weights, gains and solver options of the whole-body controller.

    Gains are stiffnesses [1/s^2]; each damping is :math:`2\\sqrt{K_p}` (critical).

    Attributes:
        backend: ``"proxsuite"`` (persistent dense solver, warm-started) or a ``qpsolvers``
            solver name (``"proxqp"``, ``"daqp"``, ``"quadprog"``, ``"osqp"``...).
        dt: Controller period [s]; the reference is sampled on this grid.
        com_weight, hand_weight, foot_weight, base_weight, posture_weight: Task weights [-].
        orientation_factor: Orientation rows of frame tasks get ``weight * orientation_factor``.
        force_weight: Regularization of corner forces [1/N^2].
        acceleration_weight: Regularization of accelerations [-].
        com_kp, frame_kp, foot_kp, base_kp, posture_kp: PD stiffnesses [1/s^2].
        contact_kp: Baumgarte stiffness on stance-sole drift [1/s^2].
        friction_scale: Fraction of the friction coefficient the controller may use [-].
        cop_margin: The corner forces act this far inside the sole rectangle, which keeps the centre
            of pressure off the sole's edges [m].
        torque_scale: Fraction of each torque limit the controller may use [-]. 0.97 by
            default: the certificate flags torques above 98 % of the limit as saturation, and a
            jump's push-off uses every newton-metre the QP allows (100 % with 1.0).
        com_drift: Include the CoM velocity-product term (one extra Pinocchio call, ~7 us).
        eps_abs: QP absolute tolerance. max_iter, max_iter_in: proxsuite outer / inner iteration caps
            (they bound the cost of a failing tick).
        dense_backend: proxsuite dense factorization: ``Automatic``, ``PrimalDualLDLT`` or ``PrimalLDLT``.
    """

    backend: str = "proxsuite"
    dt: float = 0.001
    com_weight: float = 10.0
    hand_weight: float = 1.0
    foot_weight: float = 10.0
    base_weight: float = 1.0
    posture_weight: float = 1e-3
    orientation_factor: float = 0.1
    force_weight: float = 1e-7
    acceleration_weight: float = 1e-6
    com_kp: float = 100.0
    frame_kp: float = 400.0
    foot_kp: float = 200.0
    base_kp: float = 100.0
    posture_kp: float = 100.0
    contact_kp: float = 10.0
    friction_scale: float = 0.9
    cop_margin: float = 0.0
    torque_scale: float = 0.97
    com_drift: bool = True
    eps_abs: float = 1e-6
    max_iter: int = 50
    max_iter_in: int = 1500
    dense_backend: str = "Automatic"

    def __post_init__(self) -> None:
        for name in (
            "com_weight",
            "hand_weight",
            "foot_weight",
            "base_weight",
            "posture_weight",
            "orientation_factor",
            "force_weight",
            "acceleration_weight",
            "com_kp",
            "frame_kp",
            "foot_kp",
            "base_kp",
            "posture_kp",
            "contact_kp",
        ):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise ControllerError(
                    f"WbcSettings.{name} must be a finite number >= 0, got {value!r}"
                )
        if not (self.force_weight > 0 and self.acceleration_weight > 0):
            raise ControllerError("WbcSettings: force_weight and acceleration_weight must be > 0")
        if not 0 < self.friction_scale <= 1 or not 0 < self.torque_scale:
            raise ControllerError(
                "WbcSettings: friction_scale must be in (0, 1] and torque_scale > 0"
            )
        if not self.dt > 0:
            raise ControllerError(f"WbcSettings.dt must be > 0 s, got {self.dt!r}")


class TickInfo(NamedTuple):
    """What the last tick did.

    Attributes:
        ok: The QP solved (otherwise the previous torque was reused).
        iterations: QP iterations.
        status: Backend status (a proxsuite ``QPSolverOutput`` or a text).
    """

    ok: bool
    iterations: int
    status: Any


class WholeBodyController:
    """Inverse-dynamics QP controller (see the module docstring).

    Args:
        robot: The robot to control (its Pinocchio model is used read-only).
        settings: Weights, gains and backend.

    Example:
        >>> ctrl = WholeBodyController(robot)
        >>> ctrl.reset(q, v)
        >>> tau = ctrl.compute(t, q, v, plan)  # (nv - 6,) [N m]
    """

    def __init__(self, robot: Robot, settings: WbcSettings | None = None) -> None:
        self.robot = robot
        self.settings = settings if settings is not None else WbcSettings()
        self.model = robot.model
        self.data = robot.model.createData()
        nv = self.model.nv
        self.nv = nv
        self.nu = nv - 6
        self.torque_limits = robot.torque_limits * self.settings.torque_scale
        self._neg_torque_limits = -self.torque_limits
        # force variables are scaled so that one unit is the per-corner share of the weight
        self._f_scale = robot.mass * 9.81 / 8.0  # [N]
        mu = robot.profile.friction_coefficient * self.settings.friction_scale
        self._mu = mu
        self._zero_a = np.zeros(nv)
        backend = self.settings.backend
        if backend != "proxsuite":
            import qpsolvers

            if backend not in qpsolvers.available_solvers:
                raise ControllerError(
                    f"QP backend {backend!r} is not installed; available: proxsuite, "
                    f"{', '.join(qpsolvers.available_solvers)} (install e.g. the 'daqp' or 'quadprog' package)"
                )
        self._reference: PlanReference | None = None
        self._reference_key: int | None = None
        self._layout: tuple[str, ...] | None = None
        self._qp: Any = None
        self._q0: np.ndarray | None = None
        self._prev_tau = np.zeros(self.nu)
        self.last: TickInfo | None = None
        self.failures = 0

    # ------------------------------------------------------------------ reference handling
    def reference_for(self, plan: Plan) -> PlanReference:
        """The dense reference of ``plan`` (built once per plan, then reused)."""
        if (
            self._reference is None
            or self._reference_key != id(plan)
            or self._reference.plan is not plan
        ):
            self._reference = PlanReference(plan, self.robot, dt=self.settings.dt)
            self._reference_key = id(plan)
        return self._reference

    def reset(self, q: np.ndarray, v: np.ndarray) -> None:
        """Forget the solver state and contact anchors; the next tick starts from ``q``, ``v``.

        Args:
            q: Configuration (nq,), Pinocchio order.
            v: Velocity (nv,).
        """
        self._qp = None
        self._layout = None
        self._x = None
        self._prev_tau = np.zeros(self.nu)
        self._q0 = np.array(q, dtype=float)
        self.failures = 0
        self.last = None

    # ------------------------------------------------------------------ problem layout
    def _build_layout(self, ref: PlanReference) -> None:
        s = self.settings
        model, nv = self.model, self.nv
        self._contacts = list(ref.contact_frames)
        nc = len(self._contacts)
        self.n = nv + 12 * nc
        self.n_eq = 6 + 6 * nc
        self.n_in = 16 * nc + self.nu
        # corner geometry (sole frame, pulled cop_margin inside) and the force -> wrench map G0 (6 x 12)
        g0s = []
        for name in self._contacts:
            side = self.robot.foot_side(name) or "left"
            corners = np.array([[x, y, 0.0] for x, y in self.robot.profile.sole.corners(side)])
            centre = corners.mean(axis=0)
            half = np.abs(corners - centre).max(axis=0)
            shrink = np.clip((half - s.cop_margin) / np.where(half > 0, half, 1.0), 0.0, 1.0)
            corners = centre + (corners - centre) * shrink
            g0 = np.zeros((6, 12))
            for k, c in enumerate(corners):
                g0[:3, 3 * k : 3 * k + 3] = np.eye(3)
                g0[3:, 3 * k : 3 * k + 3] = pin.skew(c)
            g0s.append(g0 * self._f_scale)
        self._g0s = g0s
        # frames: contact frames first (stance rows), then hands and spec target frames
        hand_names = [
            self.robot.frame(r) for r in ("left_hand", "right_hand") if self.robot.has_role(r)
        ]
        target_names = [
            model.frames[self.robot.frame_id(t.frame)].name for t in ref.plan.spec.targets
        ]
        others = [
            nm for nm in dict.fromkeys([*hand_names, *target_names]) if nm not in self._contacts
        ]
        self._frames = [*self._contacts, *others]
        self._frame_ids = [model.getFrameId(nm) for nm in self._frames]
        nf = len(self._frames)
        nrow = 3 + 6 * nf  # CoM rows, then 6 rows per frame (linear, angular; world-aligned)
        self._nrow = nrow
        # stacked references on the dense grid (n, ...): positions (CoM first), rotations, velocities, accelerations
        self._ref_pos = np.concatenate(
            [ref.com[:, None, :]] + [ref.frames[nm].position[:, None, :] for nm in self._frames],
            axis=1,
        )
        self._ref_rot = np.stack([ref.frames[nm].rotation for nm in self._frames], axis=1)
        self._ref_vel = np.concatenate(
            [ref.com_velocity] + [ref.frames[nm].velocity for nm in self._frames], axis=1
        )
        self._ref_acc = np.concatenate(
            [ref.com_acceleration] + [ref.frames[nm].acceleration for nm in self._frames], axis=1
        )
        # per-row gains and weights of the tracking tasks
        kp = np.empty(nrow)
        w = np.empty(nrow)
        kp[:3], w[:3] = s.com_kp, s.com_weight
        for i, nm in enumerate(self._frames):
            rows = slice(3 + 6 * i, 9 + 6 * i)
            is_contact = nm in self._contacts
            kp[rows] = s.foot_kp if is_contact else s.frame_kp
            wt = s.foot_weight if is_contact else s.hand_weight
            w[rows] = [wt] * 3 + [wt * s.orientation_factor] * 3
        self._kp_task, self._sqrt_w_task = kp, np.sqrt(w)
        self._J = np.zeros((nrow, nv))
        self._drift = np.zeros(nrow)
        self._err = np.zeros(nrow)
        self._err_frames = self._err[3:].reshape(nf, 6)
        self._pos = np.zeros((1 + nf, 3))
        self._rots = np.zeros((nf, 3, 3))
        self._anchor_pos = np.zeros((nf, 3))
        self._anchor_rot = np.tile(np.eye(3), (nf, 1, 1))
        self._active_key: bytes | None = None
        self._active_flags: tuple[bool, ...] | None = None
        self._target_pos = np.zeros((nf, 3))
        self._target_rot = np.zeros((nf, 3, 3))
        self._last_rots = np.zeros((nf, 3, 3))
        self._T = np.zeros((nrow, nv))
        # constant matrices
        self.H = np.zeros((self.n, self.n))
        self.g = np.zeros(self.n)
        self.A = np.zeros((self.n_eq, self.n))
        self.b = np.zeros(self.n_eq)
        self.C = np.zeros((self.n_in, self.n))
        self.l = np.full(self.n_in, -INFINITY)
        self.u = np.zeros(self.n_in)
        mu = self._mu
        pyramid = np.array([[1.0, 0.0, -mu], [-1.0, 0.0, -mu], [0.0, 1.0, -mu], [0.0, -1.0, -mu]])
        for i in range(nc):
            for k in range(4):
                r0 = 16 * i + 4 * k
                c0 = nv + 12 * i + 3 * k
                self.C[r0 : r0 + 4, c0 : c0 + 3] = pyramid
        self._tau_rows = slice(16 * nc, 16 * nc + self.nu)
        self._reg = np.concatenate(
            [
                np.full(nv, s.acceleration_weight),
                np.full(12 * nc, s.force_weight * self._f_scale**2),
            ]
        )
        # posture weights on the actuated joints, base orientation on the angular base rows
        self._diag_a = np.zeros(nv)
        self._diag_a[3:6] = s.base_weight
        self._diag_a[6:] = s.posture_weight
        self._diag_a_total = self._diag_a + self._reg[:nv]
        self._kp_post = np.zeros(nv)
        self._kp_post[3:6] = s.base_kp
        self._kp_post[6:] = s.posture_kp
        self._kd_post = 2.0 * np.sqrt(self._kp_post)
        self._post_feedforward = ref.a + self._kd_post * ref.v
        self.H[np.diag_indices(self.n)] = (
            self._reg
        )  # the force block keeps it; the a block is rewritten
        self._h_diag_a = self.H.reshape(-1)[: nv * (self.n + 1) : self.n + 1]
        self._l_tau = self.l[16 * nc :]
        self._u_tau = self.u[16 * nc :]
        self._G = np.zeros((6, 12))
        self._layout = tuple(self._contacts)
        self._qp = None
        self._x = np.zeros(self.n)
        self._S = np.zeros((nv, 12 * nc))
        self._stance: list[int] = []

    def _set_active(self, active: tuple[bool, ...], key: bytes, ref: PlanReference) -> None:
        """Gains, weights, masks and feed-forward terms for a new set of stance contacts."""
        s = self.settings
        nc, nrow = len(self._contacts), self._nrow
        on = np.zeros(nrow, dtype=bool)
        for i, a in enumerate(active):
            if a:
                on[3 + 6 * i : 9 + 6 * i] = True
        kp = np.where(on, s.contact_kp, self._kp_task)
        self._kp_rows = kp
        self._kd_rows = 2.0 * np.sqrt(kp)
        mask = (~on).astype(float)  # stance rows track the anchor at rest
        self._feedforward = (self._ref_acc + self._kd_rows * self._ref_vel) * mask
        self._w_rows = np.where(on, 0.0, self._sqrt_w_task)
        self._stance_rows = on[3 : 3 + 6 * nc].astype(float)
        self._frame_active = np.zeros(len(self._frames), dtype=bool)
        self._frame_active[:nc] = active
        self._stance = [i for i, a in enumerate(active) if a]
        for i, a in enumerate(active):
            if not a:
                self._S[:, 12 * i : 12 * i + 12] = 0.0
        self._active_key = key
        self._active_flags = active

    # ------------------------------------------------------------------ the tick
    def compute(
        self, t: float, q: np.ndarray, v: np.ndarray, reference: Plan | PlanReference
    ) -> np.ndarray:
        """Joint torques for the current state.

        Args:
            t: Time since the start of the plan [s].
            q: Measured configuration (nq,), Pinocchio order, quaternion (x, y, z, w).
            v: Measured velocity (nv,), Pinocchio convention.
            reference: The Plan to track (its dense reference is built on first use), or a
                :class:`~planner.wbc_reference.PlanReference`.

        Returns:
            Actuated joint torques (nv - 6,) [N m], within the torque limits.
        """
        ref = reference if isinstance(reference, PlanReference) else self.reference_for(reference)
        if self._layout is None or self._layout != ref.contact_frames:
            if self._q0 is None:
                self.reset(q, v)
            self._build_layout(ref)
        model, data, nv = self.model, self.data, self.nv
        k = ref.index(t)

        pin.computeAllTerms(model, data, q, v)
        M = data.M
        h = data.nle
        J, drift, pos, rots = self._J, self._drift, self._pos, self._rots
        # ---- CoM rows
        J[:3] = data.Jcom
        if self.settings.com_drift:  # CoM position and its drift J'v in one call
            pos[0] = pin.centerOfMass(model, data, q, v, self._zero_a)
            drift[:3] = data.acom[0]
        else:
            pos[0] = data.com[0]
        # ---- frame rows (world-aligned): Jacobian, drift J'v, placement
        for i, fid in enumerate(self._frame_ids):
            placement = pin.updateFramePlacement(model, data, fid)
            J[3 + 6 * i : 9 + 6 * i] = pin.getFrameJacobian(model, data, fid, _LWA)
            drift[3 + 6 * i : 9 + 6 * i] = pin.getFrameClassicalAcceleration(
                model, data, fid, _LWA
            ).vector
            pos[1 + i] = placement.translation
            rots[i] = placement.rotation
        key = ref.active[k].tobytes()
        if key != self._active_key:
            active = tuple(bool(a) for a in ref.active[k])
            was = self._active_flags
            for i, a in enumerate(active):
                if a and not (was is not None and was[i]):
                    self._anchor_pos[i] = pos[1 + i]  # the sole is held where it touched down
                    self._anchor_rot[i] = rots[i]
            self._set_active(active, key, ref)
        target_pos, target_rot = self._target_pos, self._target_rot
        np.copyto(target_pos, self._ref_pos[k, 1:])
        np.copyto(target_rot, self._ref_rot[k])
        if self._stance:
            np.copyto(target_pos, self._anchor_pos, where=self._frame_active[:, None])
            np.copyto(target_rot, self._anchor_rot, where=self._frame_active[:, None, None])
        # ---- errors: CoM, positions, orientations (small-angle, sin-axis form, world-aligned)
        err = self._err
        err[:3] = self._ref_pos[k, 0] - pos[0]
        ef = self._err_frames
        ef[:, :3] = target_pos - pos[1:]
        rel = (rots.transpose(0, 2, 1) @ target_rot).reshape(-1, 9)
        w = rel[:, _VEE_A] - rel[:, _VEE_B]
        ef[:, 3:] = 0.5 * np.matmul(rots, w[:, :, None])[:, :, 0]
        a_des = self._feedforward[k] + self._kp_rows * err - self._kd_rows * (J @ v) - drift
        # ---- stance contacts: equality rows and force map
        A, b, S = self.A, self.b, self._S
        nsr = 6 * len(self._contacts)
        A[6:, :nv] = J[3 : 3 + nsr] * self._stance_rows[:, None]
        b[6:] = a_des[3 : 3 + nsr] * self._stance_rows
        G = self._G
        for i in self._stance:
            rot = rots[i]
            G[:3] = rot @ self._g0s[i][:3]
            G[3:] = rot @ self._g0s[i][3:]
            S[:, 12 * i : 12 * i + 12] = J[3 + 6 * i : 9 + 6 * i].T @ G
        # ---- tracking tasks (rows of stance contacts have weight 0)
        wr = self._w_rows
        T = self._T
        np.multiply(wr[:, None], J, out=T)
        r = wr * a_des
        # ---- posture + base orientation (diagonal terms)
        a_post = (
            self._post_feedforward[k]
            + self._kp_post * pin.difference(model, q, ref.q[k])
            - self._kd_post * v
        )
        # ---- QP matrices
        H, g = self.H, self.g
        H[:nv, :nv] = T.T @ T
        self._h_diag_a += self._diag_a_total
        g[:nv] = -(T.T @ r) - self._diag_a * a_post
        # dynamics rows (floating base)
        A[:6, :nv] = M[:6]
        A[:6, nv:] = -S[:6]
        b[:6] = -h[:6]
        # torque rows
        tau_rows = self._tau_rows
        C = self.C
        C[tau_rows, :nv] = M[6:]
        C[tau_rows, nv:] = -S[6:]
        np.subtract(-self.torque_limits, h[6:], out=self._l_tau)
        np.subtract(self.torque_limits, h[6:], out=self._u_tau)

        x, ok, iterations, status = self._solve()
        if ok:
            tau = M[6:] @ x[:nv] + h[6:] - S[6:] @ x[nv:]
            np.minimum(tau, self.torque_limits, out=tau)
            np.maximum(tau, self._neg_torque_limits, out=tau)
            self._prev_tau = tau
            self._x = x
        else:
            self.failures += 1
            tau = self._prev_tau.copy()
            self._qp = None  # cold start (and a fresh preconditioner) on the next tick
        self._last_rots = rots.copy()
        self.last = TickInfo(ok, iterations, status)
        return tau

    def acceleration(self) -> np.ndarray:
        """Joint accelerations of the last QP solution (nv,)."""
        return self._x[: self.nv].copy()

    def corner_forces(self) -> dict[str, np.ndarray]:
        """Corner forces (4, 3) of every contact frame in its sole frame, last QP solution [N]."""
        f = self._x[self.nv :] * self._f_scale
        return {
            name: f[12 * i : 12 * i + 12].reshape(4, 3).copy()
            for i, name in enumerate(self._contacts)
        }

    def contact_jacobian_transpose(self) -> np.ndarray:
        """:math:`J_c^\\top` mapping the stacked corner forces to generalized forces, last tick (nv, 12 nc)."""
        return self._S / self._f_scale

    def contact_forces(self) -> dict[str, np.ndarray]:
        """Net force of each stance contact in the world from the last tick's QP (3,) [N]."""
        out = {}
        if self._x is None:
            return out
        f = self._x[self.nv :] * self._f_scale
        for i in self._stance:
            out[self._contacts[i]] = self._last_rots[i] @ f[12 * i : 12 * i + 12].reshape(4, 3).sum(
                axis=0
            )
        return out

    def _new_qp(self) -> Any:
        s = self.settings
        qp = proxsuite.proxqp.dense.QP(
            self.n,
            self.n_eq,
            self.n_in,
            False,
            proxsuite.proxqp.dense.HessianType.Dense,
            getattr(proxsuite.proxqp.dense.DenseBackend, s.dense_backend),
        )
        qp.settings.eps_abs = s.eps_abs
        qp.settings.eps_rel = 0.0
        qp.settings.max_iter = s.max_iter
        qp.settings.max_iter_in = s.max_iter_in
        qp.settings.verbose = False
        qp.settings.initial_guess = proxsuite.proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
        qp.init(self.H, self.g, self.A, self.b, self.C, self.l, self.u)
        return qp

    def _solve(self) -> tuple[np.ndarray, bool, int, Any]:
        s = self.settings
        if s.backend == "proxsuite":
            fresh = self._qp is None
            if fresh:
                self._qp = self._new_qp()
            else:
                self._qp.update(
                    self.H,
                    self.g,
                    self.A,
                    self.b,
                    self.C,
                    self.l,
                    self.u,
                    update_preconditioner=False,
                )
            self._qp.solve()
            res = self._qp.results  # one access: each one copies the whole results object
            info = res.info
            status = info.status
            x = res.x
            ok = status == _SOLVED and bool(np.isfinite(x).all())
            iterations = int(info.iter)
            if not ok and not fresh:
                # a warm start from a far-away point can make proxsuite declare a feasible QP
                # infeasible: retry cold, with a fresh preconditioner, before giving up
                self._qp = self._new_qp()
                self._qp.solve()
                res = self._qp.results
                status, x = res.info.status, res.x
                ok = status == _SOLVED and bool(np.isfinite(x).all())
                iterations += int(res.info.iter)
            return x.copy(), ok, iterations, status
        import qpsolvers

        finite_l = self.l > -INFINITY / 2
        G = np.vstack([self.C, -self.C[finite_l]])
        hvec = np.concatenate([self.u, -self.l[finite_l]])
        x = qpsolvers.solve_qp(
            self.H, self.g, G, hvec, self.A, self.b, solver=s.backend, initvals=self._x
        )
        if x is None or not np.all(np.isfinite(x)):
            return np.zeros(self.n), False, 0, "failed"
        return x, True, 0, "solved"
