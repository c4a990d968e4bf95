r"""Whole-body inverse-dynamics QP controller that tracks a Plan.

Every tick solves one quadratic program in the joint accelerations :math:`a` (nv) and the contact
forces :math:`f`: four corner forces per planar sole, 3D each, expressed in the sole frame.

Constraints:

* floating-base dynamics, the first six rows of :math:`M a + h = J_c^\top f`;
* stance contacts, :math:`J_c a + \dot J_c v = -K_p e - K_d \dot e` (6D per sole, in the sole
  frame; Baumgarte feedback pulls a drifting sole back to where it touched down);
* friction pyramids per corner, the contact model of :mod:`robots.contact`:
  :math:`|f_x|, |f_y| \le \mu' f_z` with :math:`\mu' = \mu/\sqrt 2` (the 4-edge pyramid inscribed
  in the Coulomb cone; hence :math:`f_z \ge 0`), which keeps the centre of pressure inside the
  sole rectangle;
* torque limits on the actuated rows, :math:`|M a + h - J_c^\top f|_{6:} \le \tau_{max}`.

Costs (weighted least squares on accelerations, PD + feed-forward from the plan): centre of
mass, centroidal angular momentum (the angular rows of Pinocchio's :math:`A_g`, tracking the
reference's :math:`h = A_g v`), base orientation, hands and every frame a spec target names,
swing feet, joint posture, plus small regularizations of :math:`a` and :math:`f`. A contact frame that is not in stance
has its force columns removed from the dynamics (the regularization then sets its forces to 0).

Contacts switch at the plan's times, except at the end of a flight (no planned contact): a sole
that reaches its landing height early is a stance sole from then on, and the CoM reference brakes
from the measured state; and in a flight the soles' references replay the plan's path from the
lift-off knot over the controller's (half a knot shorter) flight (``WbcSettings.early_touchdown``).

Numerics per tick: one ``computeAllTerms`` (mass matrix, nonlinear effects, joint Jacobians,
CoM Jacobian and the velocity-product accelerations), one ``centerOfMass`` at zero
acceleration for the CoM drift, and per frame a Jacobian and a drift read from the filled data.
The QP is a persistent dense proxsuite problem that is updated and warm-started from the
previous solution (docs/control.md). Any other backend name goes through ``qpsolvers``.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
import pinocchio as pin
import proxsuite

from planner.exceptions import ControllerError
from planner.results import Plan
from planner.wbc.kernel import ACTIVE_SET_SOLVED, FAST_SOLVED, tick_kernel
from planner.wbc.reference import PlanReference, flight_spans, landing_blend
from planner.wbc.settings import WbcSettings
from robots import Robot, pyramid_coefficient, pyramid_facets, sole_corners

INFINITY = 1e20  # proxsuite treats bounds this large as absent
_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
_ACCELERATION = pin.KinematicLevel.ACCELERATION
_SOLVED = proxsuite.proxqp.QPSolverOutput.PROXQP_SOLVED


EARLY_TOUCHDOWN_HEIGHT = 0.0005  # [m] a landing sole this close to its planned height is down (MuJoCo: in contact)
FLIGHT_TRAVEL = 0.005  # [m] a landing sole that moves more than this in a flight (a forward hop) gets:
FLIGHT_WINDOW = 0.3  # [s] before that flight and after its touch-down, the momentum task's flight_momentum_weight
EARLY_TOUCHDOWN_FRACTION = 0.25  # not in the first quarter of a flight (the sole is leaving then)
HAND_FORCE_UNIT = 0.25  # a hand contact's force variables in this share of the others' unit (leaning on a table)


def _flight_landings(active: np.ndarray) -> dict[int, tuple[int, int]]:
    """Sample -> (first sample, touch-down sample) of the flight it lies in (no active contact,
    between two stances)."""
    out: dict[int, tuple[int, int]] = {}
    flags = np.asarray(active, dtype=bool)
    air = [bool(flags.shape[1]) and not row.any() for row in flags]
    for a, k in flight_spans(air):
        for j in range(a, k):
            out[j] = (a, k)
    return out


def _flight_window(active: np.ndarray, span: int) -> np.ndarray:
    """Samples (n,) within ``span`` samples of a flight (no active contact, between two stances):
    from ``span`` before its first sample to ``span`` after its touch-down sample."""
    flags = np.asarray(active, dtype=bool)
    air = [bool(flags.shape[1]) and not row.any() for row in flags]
    out = np.zeros(len(flags), dtype=bool)
    for a, touch in flight_spans(air):
        out[max(a - span, 0) : touch + span + 1] = True
    return out


def _regions(ref: PlanReference, robot: Robot) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per contact frame of the spec with a 4-corner support region (a thigh on a seat): its corners
    in the frame (4, 3) and the rotation (3, 3) from the frame to its friction cone's frame (z: the
    surface normal, x: the frame's x made orthogonal to it), at the planned placement. The
    controller's corner forces of that contact are in the cone's frame, so its pyramids open about
    the surface normal, as the planner's (``planner.trajopt.centroidal.contact_geometry``)."""
    out: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for phase in ref.plan.spec.phases:
        for c in phase.contacts:
            if c.region is None or len(c.region) != 4:
                continue
            name = robot.model.frames[robot.frame_id(c.frame)].name
            R = pin.rpy.rpyToMatrix(*c.placement.rpy)
            z = np.asarray(c.normal if c.normal is not None else R[:, 2], dtype=float)
            z = z / np.linalg.norm(z)
            x = R[:, 0] - (R[:, 0] @ z) * z
            if np.linalg.norm(x) < 1e-6:
                x = R[:, 1] - (R[:, 1] @ z) * z
            x = x / np.linalg.norm(x)
            out[name] = (np.asarray(c.region, dtype=float), R.T @ np.column_stack([x, np.cross(z, x), z]))
    return out


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


_FAST_TICK = TickInfo(True, 0, "solved without active inequalities")


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
        # the centroidal map and its time variation get their own Data: on a Data that
        # computeAllTerms has filled, pin 4.1's computeCentroidalMapTimeVariation returns a
        # wrong dA_g (it accumulates, like data.dhg; the test checks against finite differences)
        self._data_mom = robot.model.createData()
        nv = self.model.nv
        self.nv = nv
        self.nu = nv - 6
        self.torque_limits = robot.torque_limits * self.settings.torque_scale
        self._neg_torque_limits = -self.torque_limits
        # force variables are scaled so that one unit is the per-corner share of the weight
        self._f_scale = robot.mass * 9.81 / 8.0  # [N]
        # the contact model's pyramid (robots.contact): |fx|, |fy| <= mu' fz, mu' = mu / sqrt(2)
        self._mu_contact = robot.profile.friction_coefficient * self.settings.friction_scale
        self._mu = float(pyramid_coefficient(self._mu_contact))  # mu', the kernel's per-axis bound
        self._com_drift = self.settings.com_drift
        # pin.difference is computed inside the compiled kernel for a free flyer + 1-dof joints
        self._simple_joints = self.model.nq == nv + 1
        self._tol = self.settings.eps_abs
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
        self.fast_ticks = 0  # ticks solved exactly without proxsuite (no active inequality)
        self.active_set_ticks = 0  # ticks solved without proxsuite, some inequalities active

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
        self._x: np.ndarray | None = None
        self._prev_tau = np.zeros(self.nu)
        self._q0 = np.array(q, dtype=float)
        self.failures = 0
        self.fast_ticks = 0
        self.active_set_ticks = 0
        self.last = None

    # ------------------------------------------------------------------ problem layout
    def _build_layout(self, ref: PlanReference) -> None:
        s = self.settings
        model, nv = self.model, self.nv
        self._contacts = list(ref.contact_frames)
        nc = len(self._contacts)
        # the pyramids: the profile's friction, or a contact's lower one (a 0.6 table under talos's 0.7, a sole
        # on an icy slope: tasks.terrain.with_surface_friction)
        mu = min([self.robot.profile.friction_coefficient, *(c.friction_coefficient for p in ref.plan.spec.phases
                                                               for c in p.contacts if c.friction_coefficient)])
        self._mu_contact = mu * s.friction_scale
        self._mu = float(pyramid_coefficient(self._mu_contact))
        self.n = nv + 12 * nc
        self.n_eq = 6 + 6 * nc
        self.n_in = 16 * nc + self.nu
        # corner geometry (sole frame, pulled cop_margin inside) and the force -> wrench map G0 (6 x 12)
        g0s = []
        regions = _regions(ref, self.robot)
        # a region contact on another body part (a thigh on a seat, 3 joints above its held sole): its
        # forces act at its corners, its position is tracked as a stiff task, its orientation is free
        self._position_only = [i for i, name in enumerate(self._contacts)
                               if self.robot.foot_side(name) is None and name in regions]
        hands = {int(j) for r in ("left_hand", "right_hand") if self.robot.has_role(r)
                 for j in model.subtrees[model.frames[self.robot.frame_id(r)].parentJoint]}
        # a hand's force unit is HAND_FORCE_UNIT of the others': the regularization (alike for every
        # corner force) costs its newtons 1 / HAND_FORCE_UNIT^2 times more, so the weight stays on the feet
        self._f_scales = np.array([self._f_scale * (HAND_FORCE_UNIT if self.robot.foot_side(name) is None
                                                    and model.frames[model.getFrameId(name)].parentJoint in hands else 1.0)
                                   for name in self._contacts])
        for name, unit in zip(self._contacts, self._f_scales, strict=True):
            foot = self.robot.foot_side(name)
            corners = sole_corners(self.robot.profile.sole, foot or "left", margin=s.cop_margin)
            cone = np.eye(3)  # the corner forces' frame in the contact frame (a sole: the same)
            if foot is None and name in regions:  # a region on another body part (a thigh on a seat)
                corners, cone = regions[name]
            g0 = np.zeros((6, 12))
            for k, c in enumerate(corners):
                g0[:3, 3 * k : 3 * k + 3] = cone
                g0[3:, 3 * k : 3 * k + 3] = pin.skew(c) @ cone
            g0s.append(g0 * unit)
        self._g0_arr = np.array(g0s).reshape(nc, 6, 12)  # the kernel's corner-force -> wrench maps
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
        # CoM rows, then 6 rows per frame (linear, angular; world-aligned), then the centroidal
        # angular momentum (3 rows, A_g / m) when its task is on
        n_mom = 3 if s.momentum_weight > 0 else 0
        nrow = 3 + 6 * nf + n_mom
        self._nrow = nrow
        self._mom_rows = slice(3 + 6 * nf, nrow) if n_mom else None
        self._inv_mass = 1.0 / self.robot.mass
        self._frame_rows = [
            (fid, slice(3 + 6 * i, 9 + 6 * i), i) for i, fid in enumerate(self._frame_ids)
        ]
        self._hom = np.zeros((nf, 4, 4))
        self._build_references(ref, n_mom)
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
        if n_mom:  # no position error: kp 0, the momentum gain is the row's damping (_set_active)
            kp[3 + 6 * nf :], w[3 + 6 * nf :] = 0.0, s.momentum_weight
        self._kp_task, self._sqrt_w_task = kp, np.sqrt(w)
        self._J = np.zeros((nrow, nv))
        self._drift = np.zeros(nrow)
        self._a_des = np.zeros(nrow)
        self._dq_post = np.zeros(nv)
        self._pos = np.zeros((1 + nf, 3))
        self._rots = np.zeros((nf, 3, 3))
        self._anchor_pos = np.zeros((nf, 3))
        self._anchor_rot = np.tile(np.eye(3), (nf, 1, 1))
        self._active_key: int | None = None
        self._active_flags: tuple[bool, ...] | None = None
        self._last_rots = np.zeros((nf, 3, 3))
        self._build_qp(ref)

    def _build_references(self, ref: PlanReference, n_mom: int) -> None:
        """The reference grid, its contact patterns and flights, and the stacked task references
        (:meth:`_build_layout`); ``n_mom``: the momentum rows (0 or 3)."""
        s = self.settings
        # the reference grid (PlanReference.index inlined in the tick) and its contact patterns
        self._t0 = float(ref.plan.t[0])
        self._inv_dt = 1.0 / ref.dt
        self._n_ref = ref.n
        flags, inverse = np.unique(ref.active, axis=0, return_inverse=True)
        self._patterns = [int(p) for p in np.asarray(inverse).reshape(-1)]
        self._pattern_flags = [tuple(bool(a) for a in row) for row in flags]
        self._landings = _flight_landings(ref.active) if s.early_touchdown else {}
        self._early: tuple[bool, ...] | None = None  # soles already down in the current flight
        # stacked references on the dense grid (n, ...): positions (CoM first), rotations, velocities, accelerations
        self._ref_pos = np.concatenate(
            [ref.com[:, None, :]] + [ref.frames[nm].position[:, None, :] for nm in self._frames],
            axis=1,
        )
        self._ref_rot = np.stack([ref.frames[nm].rotation for nm in self._frames], axis=1)
        # the momentum rows' "velocity" is h / m and their "acceleration" dh/dt / m
        mom_vel = [ref.angular_momentum * self._inv_mass] if n_mom else []
        mom_acc = [ref.angular_momentum_rate * self._inv_mass] if n_mom else []
        self._ref_vel = np.concatenate(
            [ref.com_velocity] + [ref.frames[nm].velocity for nm in self._frames] + mom_vel, axis=1
        )
        self._ref_acc = np.concatenate(
            [ref.com_acceleration] + [ref.frames[nm].acceleration for nm in self._frames] + mom_acc,
            axis=1,
        )
        if s.early_touchdown:
            self._retime_flights(ref, nc_frames=len(self._contacts))
        # flights in which a landing sole travels: a window around them for the momentum weight
        self._near_flight = np.zeros(ref.n, dtype=bool)
        self._travel_flight = np.zeros(ref.n, dtype=bool)
        span = int(round(FLIGHT_WINDOW * self._inv_dt))
        for a, touch in set(self._landings.values()):
            lands = self._pattern_flags[self._patterns[touch]]
            travel = max((float(np.linalg.norm(self._ref_pos[touch, 1 + i, :2] - self._ref_pos[a - 1, 1 + i, :2]))
                          for i, on in enumerate(lands) if on), default=0.0)
            if travel > FLIGHT_TRAVEL:
                self._near_flight[max(a - span, 0) : touch + span + 1] = True
                self._travel_flight[a:touch] = True
        self._mom_near: bool | None = None
        # every flight (a jump, a hop): FLIGHT_WINDOW before it and after its touch-down, the CoM rows
        # weigh flight_com_weight (the push-off and the landing follow the plan's momentum, not the CoM)
        self._near_any_flight = _flight_window(ref.active, span)
        self._com_near: bool | None = None
        self._tick_k = 0

    def _build_qp(self, ref: PlanReference) -> None:
        """The QP's constant matrices, regularisation, posture gains and work buffers
        (:meth:`_build_layout`)."""
        s = self.settings
        nv, nc = self.nv, len(self._contacts)
        # constant matrices
        self.H = np.zeros((self.n, self.n))
        self.g = np.zeros(self.n)
        self.A = np.zeros((self.n_eq, self.n))
        self.b = np.zeros(self.n_eq)
        self.C = np.zeros((self.n_in, self.n))
        self.l = np.full(self.n_in, -INFINITY)
        self.u = np.zeros(self.n_in)
        pyramid = pyramid_facets(self._mu_contact)
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
        self.H[np.diag_indices(self.n)] = self._reg  # the force block keeps it; the a block is rewritten
        self._force_reg = float(self._reg[-1]) if nc else 1.0
        self._Ha = np.zeros((nv, nv))
        self._ga = np.zeros(nv)
        self._xbuf = np.zeros(self.n)
        self._taubuf = np.zeros(self.nu)
        self._fast_path = bool(s.fast_path and s.backend == "proxsuite" and not self._position_only)
        self._active_iters = int(s.active_set_iterations) if self._fast_path else 0
        self._info = np.zeros(2, dtype=np.int64)
        self._l_tau = self.l[16 * nc :]
        self._u_tau = self.u[16 * nc :]
        self._layout = tuple(self._contacts)
        self._qp = None
        self._x = np.zeros(self.n)
        self._S = np.zeros((nv, 12 * nc))
        self._stance = np.zeros(0, dtype=np.int64)  # indices of the stance contacts

    def _retime_flights(self, ref: PlanReference, nc_frames: int) -> None:
        """The soles' references in each flight start when the controller's flight does.

        The plan's sole leaves the floor at the lift-off knot, but the controller's stance lasts
        half a knot longer (the reference's take-off, :mod:`planner.wbc.reference`): at the
        switch the swing reference was already that far up and ahead, with its velocity, and the
        sole started the flight behind it (G1's forward hop: 1 cm ahead and 1.3 cm up, 0.4 m/s).
        The plan's sole path from the lift-off knot to the touch-down is replayed over the
        controller's flight instead (time-compressed: velocities scaled by the ratio,
        accelerations by its square); the touch-down time and pose are unchanged.
        """
        knots = np.asarray(ref.plan.t, dtype=float)
        for a, touch in sorted(set(self._landings.values())):
            t_a = self._t0 + a / self._inv_dt
            before = knots[knots <= t_a + 1e-9]
            if not len(before):
                continue
            a0 = int(round((float(before[-1]) - self._t0) * self._inv_dt))
            if not 0 <= a0 < a:
                continue
            ratio = (touch - a0) / (touch - a)
            src = a0 + (np.arange(a, touch + 1) - a) * ratio  # fractional source samples
            lo = np.minimum(np.floor(src).astype(int), touch - 1)
            w = (src - lo)[:, None]
            near = np.round(src).astype(int)
            for i in range(nc_frames):
                cols = slice(3 + 6 * i, 9 + 6 * i)
                pos = self._ref_pos[:, 1 + i]
                vel, acc = self._ref_vel[:, cols], self._ref_acc[:, cols]
                new_pos = (1 - w) * pos[lo] + w * pos[lo + 1]
                new_vel = ((1 - w) * vel[lo] + w * vel[lo + 1]) * ratio
                new_acc = ((1 - w) * acc[lo] + w * acc[lo + 1]) * ratio**2
                self._ref_rot[a : touch + 1, i] = self._ref_rot[near, i]
                self._ref_pos[a : touch + 1, 1 + i] = new_pos
                self._ref_vel[a : touch + 1, cols] = new_vel
                self._ref_acc[a : touch + 1, cols] = new_acc

    def _set_active(self, active: tuple[bool, ...], key: int, ref: PlanReference) -> None:
        """Gains, weights, masks and feed-forward terms for a new set of stance contacts."""
        s = self.settings
        nc, nrow = len(self._contacts), self._nrow
        on = np.zeros(nrow, dtype=bool)
        for i, a in enumerate(active):
            if a:
                on[3 + 6 * i : 9 + 6 * i] = True
        kp = np.where(on, s.contact_kp, self._kp_task)
        w_task = self._sqrt_w_task
        if nc and not any(active) and self._travel_flight[self._tick_k]:  # the soles must travel in a short flight
            kp, w_task = kp.copy(), w_task.copy()
            for i in range(nc):
                kp[3 + 6 * i : 9 + 6 * i] = s.flight_foot_kp
        self._kp_rows = kp
        self._kd_rows = 2.0 * np.sqrt(kp)
        if self._mom_rows is not None:
            self._kd_rows[self._mom_rows] = s.momentum_kp
        mask = (~on).astype(float)  # stance rows track the anchor at rest
        self._feedforward = (self._ref_acc + self._kd_rows * self._ref_vel) * mask
        self._w_rows = np.where(on, 0.0, w_task)
        self._mom_near = None  # the momentum weight is set by the tick (_momentum_window)
        self._com_near = None  # and the CoM weight
        self._stance_rows = on[3 : 3 + 6 * nc].astype(float)
        for i in self._position_only:  # its forces act, its place is a stiff task (not a constraint: with the
            # soles' rows and the pelvis between the two hips, hard rows were rank-deficient and the QP failed)
            self._stance_rows[6 * i : 6 * i + 6] = 0.0
            if active[i]:
                self._w_rows[3 + 6 * i : 6 + 6 * i] = self._sqrt_w_task[3 + 6 * i : 6 + 6 * i]
        self._frame_active = np.zeros(len(self._frames), dtype=bool)
        self._frame_active[:nc] = active
        self._stance = np.array([i for i, a in enumerate(active) if a], dtype=np.int64)
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
                :class:`~planner.wbc.reference.PlanReference`.

        Returns:
            Actuated joint torques (nv - 6,) [N m], within the torque limits.
        """
        ref = reference if isinstance(reference, PlanReference) else self.reference_for(reference)
        if self._layout is None or self._layout != ref.contact_frames:
            if self._q0 is None:
                self.reset(q, v)
            self._build_layout(ref)
        model, data = self.model, self.data
        k = int((t - self._t0) * self._inv_dt + 0.5)  # PlanReference.index, inlined
        k = 0 if k < 0 else (self._n_ref - 1 if k >= self._n_ref else k)

        J, drift, pos, hom = self._J, self._drift, self._pos, self._hom
        self._task_kinematics(q, v)
        self._contact_pattern(k, v, ref)
        if self._near_flight[k] != self._mom_near or self._near_any_flight[k] != self._com_near:
            self._flight_weights(k)
        q_ref = ref.q[k]
        dq_post = self._dq_post
        if not self._simple_joints:
            dq_post[:] = pin.difference(model, q, q_ref)
        # data.M.T: symmetric (computeAllTerms fills it whole): the C-ordered view is faster
        status = tick_kernel(
            data.M.T, data.nle, J, drift, v, q, q_ref, dq_post, hom, self._ref_pos[k], self._ref_rot[k],
            self._feedforward[k], self._anchor_pos, self._anchor_rot, self._frame_active, self._kp_rows,
            self._kd_rows, self._w_rows, self._post_feedforward[k], self._kp_post, self._kd_post, self._diag_a,
            self._diag_a_total, self._g0_arr, self._stance, self._force_reg, self._mu, self.torque_limits,
            self._tol, self._fast_path, self._active_iters, pos, self._rots, self._Ha, self._ga, self._S,
            self._a_des, self._xbuf, self._taubuf, self._info,
        )
        if status == FAST_SOLVED or status == ACTIVE_SET_SOLVED:
            tau = self._taubuf.copy()
            self._prev_tau = tau
            self._x = self._xbuf.copy()
            self._last_rots = self._rots.copy()
            if status == FAST_SOLVED:
                self.fast_ticks += 1
                self.last = _FAST_TICK
            else:
                self.active_set_ticks += 1
                its, n_rows = int(self._info[0]), int(self._info[1])
                self.last = TickInfo(True, its, f"solved with {n_rows} inequality rows active")
            return tau
        return self._full_qp()

    def _task_kinematics(self, q: np.ndarray, v: np.ndarray) -> None:
        """Pinocchio's part of a tick: the mass matrix and nonlinear effects, and the task rows'
        Jacobians and drifts (CoM, momentum, frames), the CoM and the frames' placements."""
        model, data = self.model, self.data
        J, drift, pos, hom = self._J, self._drift, self._pos, self._hom
        mom = self._mom_rows
        if mom is not None:  # angular rows of A_g and dA_g v
            dmom = self._data_mom
            dag = pin.computeCentroidalMapTimeVariation(model, dmom, q, v)
            J[mom] = dmom.Ag[3:] * self._inv_mass
            drift[mom] = (dag[3:] @ v) * self._inv_mass
        pin.computeAllTerms(model, data, q, v)
        J[:3] = data.Jcom
        if self._com_drift:  # CoM position and its drift J'v in one call
            # (computeAllTerms also fills data.dhg, but pin 4.1 accumulates it over calls); its forward
            # pass left the kinematics at zero acceleration in data.v, data.a: the CoM pass alone reads
            # them (equal, bit for bit, to centerOfMass(q, v, 0), which ran the forward pass again)
            pos[0] = pin.centerOfMass(model, data, _ACCELERATION, False)
            drift[:3] = data.acom[0]
        else:
            pos[0] = data.com[0]
        # frames: getFrameJacobian also updates data.oMf[fid]
        for fid, rows, i in self._frame_rows:
            J[rows] = pin.getFrameJacobian(model, data, fid, _LWA)
            drift[rows] = pin.getFrameClassicalAcceleration(model, data, fid, _LWA).vector
            hom[i] = data.oMf[fid].homogeneous

    def _contact_pattern(self, k: int, v: np.ndarray, ref: PlanReference) -> None:
        """The stance soles at sample ``k`` (an early touch-down included); a sole that touches down
        is held where it touched."""
        pattern = self._patterns[k]
        landing = self._landings.get(k)
        if landing is None:
            self._early = None
        else:
            pattern = self._touchdown(k, landing, v, pattern)
        self._tick_k = k
        if pattern != self._active_key:
            active = self._pattern_flags[pattern] if pattern >= 0 else self._early
            assert active is not None
            was = self._active_flags
            for i, a in enumerate(active):
                if a and not (was is not None and was[i]):
                    self._anchor_pos[i] = self._hom[i, :3, 3]  # the sole is held where it touched down
                    self._anchor_rot[i] = self._hom[i, :3, :3]
            self._set_active(active, pattern, ref)

    def _full_qp(self) -> np.ndarray:
        """The full QP (proxsuite), when the compiled equality-only solve and its active set did not
        solve the tick; on a failure the last torques are held (and counted)."""
        data = self.data
        rots = self._rots
        nv = self.nv
        M, h = data.M, data.nle
        self._fill_qp(M, h)
        x, ok, iterations, status = self._solve()
        if ok:
            tau = M[6:] @ x[:nv] + h[6:] - self._S[6:] @ x[nv:]
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

    def _flight_weights(self, k: int) -> None:
        """The momentum rows' and the CoM rows' weights at sample ``k`` (near a flight or not)."""
        s = self.settings
        if self._near_flight[k] != self._mom_near:
            self._mom_near = bool(self._near_flight[k])
            if self._mom_rows is not None:
                self._w_rows[self._mom_rows] = np.sqrt(s.flight_momentum_weight if self._mom_near else s.momentum_weight)
        if self._near_any_flight[k] != self._com_near:
            self._com_near = bool(self._near_any_flight[k])
            self._w_rows[:3] = np.sqrt(s.flight_com_weight if self._com_near else s.com_weight)

    def _touchdown(self, k: int, landing: tuple[int, int], v: np.ndarray, pattern: int) -> int:
        """The contact pattern of flight sample ``k``: a sole that lands before the planned
        touch-down is a stance sole from then on (key ``-1 - mask`` for such a pattern).

        A sole counts as down once the flight's first ``EARLY_TOUCHDOWN_FRACTION`` has passed, it
        is within ``EARLY_TOUCHDOWN_HEIGHT`` of its height at the planned touch-down and not rising.
        """
        start, touch = landing
        if k - start < EARLY_TOUCHDOWN_FRACTION * (touch - start):
            return pattern
        planned = self._pattern_flags[self._patterns[touch]]
        down = list(self._early) if self._early is not None else [False] * len(planned)
        for i, lands in enumerate(planned):
            if lands and not down[i]:
                z, z_land = self._hom[i, 2, 3], self._ref_pos[touch, 1 + i, 2]
                vz = float(self._J[5 + 6 * i] @ v)  # frame i's linear z row (LOCAL_WORLD_ALIGNED)
                down[i] = bool(z <= z_land + EARLY_TOUCHDOWN_HEIGHT and vz <= 0.0)
        if not any(down):
            return pattern
        if self._early is None:
            self._absorb_landing(k, touch, v)
        self._early = tuple(down)
        return -1 - sum(1 << i for i, d in enumerate(down) if d)

    def _absorb_landing(self, k: int, touch: int, v: np.ndarray) -> None:
        """After an early touch-down at sample ``k``: the CoM reference from the measured CoM and
        its velocity back onto the plan's (:func:`planner.wbc.reference.landing_blend`: the fall
        stopped at a bounded acceleration, the soles kept loaded), instead of falling ballistically
        onto the sole until the planned touch-down and then braking at once (a step of ~20 m/s^2
        in the asked CoM acceleration, which rolled and slid G1's hopping foot)."""
        if k >= self._n_ref - 1:
            return
        ts = np.arange(self._n_ref - k) / self._inv_dt
        b, pos, vel, acc = landing_blend(ts, self._pos[0], self._J[:3] @ v, self._ref_pos[k:, 0], self._ref_vel[k:, :3])
        end = k + b
        self._ref_pos[k : end + 1, 0] = pos
        self._ref_vel[k : end + 1, :3] = vel
        self._ref_acc[k : end + 1, :3] = acc

    def _fill_qp(self, M: np.ndarray, h: np.ndarray) -> None:
        """The full QP's matrices from the kernel's outputs (when an inequality is active)."""
        nv = self.nv
        S = self._S
        self.H[:nv, :nv] = self._Ha
        self.g[:nv] = self._ga
        A, b = self.A, self.b
        nsr = 6 * len(self._contacts)
        A[6:, :nv] = self._J[3 : 3 + nsr] * self._stance_rows[:, None]
        b[6:] = self._a_des[3 : 3 + nsr] * self._stance_rows
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

    def angular_momentum_task(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        r"""The last tick's angular-momentum rows, all times the robot's mass.

        Returns:
            ``A`` (3, nv): the angular rows of the centroidal momentum matrix :math:`A_g(q)`;
            ``drift`` (3,): :math:`\dot A_g v`; ``desired`` (3,): the rate of centroidal angular
            momentum the task asks for, :math:`\dot h_{ref} + K (h_{ref} - h)` [N m].
        """
        if self._mom_rows is None:
            raise ControllerError("the angular-momentum task is off (WbcSettings.momentum_weight = 0)")
        rows, m = self._mom_rows, self.robot.mass
        return self._J[rows] * m, self._drift[rows] * m, (self._a_des[rows] + self._drift[rows]) * m

    def acceleration(self) -> np.ndarray:
        """Joint accelerations of the last QP solution (nv,)."""
        assert self._x is not None, "no tick yet"
        return self._x[: self.nv].copy()

    def corner_forces(self) -> dict[str, np.ndarray]:
        """Corner forces (4, 3) of every contact frame in its sole frame, last QP solution [N]."""
        assert self._x is not None, "no tick yet"
        f = self._x[self.nv :] * np.repeat(self._f_scales, 12)
        return {
            name: f[12 * i : 12 * i + 12].reshape(4, 3).copy()
            for i, name in enumerate(self._contacts)
        }

    def contact_jacobian_transpose(self) -> np.ndarray:
        """:math:`J_c^\\top` mapping the stacked corner forces to generalized forces, last tick (nv, 12 nc)."""
        return self._S / np.repeat(self._f_scales, 12)

    def contact_forces(self) -> dict[str, np.ndarray]:
        """Net force of each stance contact in the world from the last tick's QP (3,) [N]."""
        out: dict[str, np.ndarray] = {}
        if self._x is None:
            return out
        f = self._x[self.nv :] * np.repeat(self._f_scales, 12)
        for i in self._stance.tolist():
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
