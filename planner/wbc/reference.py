"""Dense task references sampled from a Plan, for the whole-body controller.

A Plan lives on a coarse knot grid (``spec.dt`` ~ 0.05-0.1 s); the controller runs at 1 kHz.
:class:`PlanReference` turns the plan into smooth references on the controller's grid, once,
before the first tick, so that the tick itself only indexes arrays:

* configurations are interpolated with a C2 cubic spline in a chart: base position in the world,
  base rotation as a rotation vector relative to the first knot, joint positions. The spline's
  first and second derivatives give the velocity and acceleration feed-forward in Pinocchio's
  convention (base linear and angular velocity in the base frame);
* centre of mass, feet, hands and every frame a spec target names are evaluated on the dense
  configurations with Pinocchio: placement, velocity and classical acceleration (world-aligned);
* the active contact frames at each sample come from the spec's phases.

After the plan's end the last sample is held with zero velocity and acceleration.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from planner.results import Plan
from robots import Robot, points_in_world, sole_corners, support_polygon


def _skew_batch(w: np.ndarray) -> np.ndarray:
    out = np.zeros((*w.shape[:-1], 3, 3))
    out[..., 0, 1], out[..., 0, 2] = -w[..., 2], w[..., 1]
    out[..., 1, 0], out[..., 1, 2] = w[..., 2], -w[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -w[..., 1], w[..., 0]
    return out


def _exp3_and_jr(w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation matrices exp(w) and right Jacobians Jr(w) for a batch of rotation vectors (N, 3)."""
    theta = np.linalg.norm(w, axis=1)
    small = theta < 1e-6
    th = np.where(small, 1.0, theta)
    a = np.where(small, 1.0 - theta**2 / 6.0, np.sin(th) / th)
    b = np.where(small, 0.5 - theta**2 / 24.0, (1.0 - np.cos(th)) / th**2)
    c = np.where(small, 1.0 / 6.0 - theta**2 / 120.0, (th - np.sin(th)) / th**3)
    k = _skew_batch(w)
    k2 = k @ k
    eye = np.eye(3)
    rot = eye + a[:, None, None] * k + b[:, None, None] * k2
    jr = eye - b[:, None, None] * k + c[:, None, None] * k2
    return rot, jr


def _unwrap(w: np.ndarray, previous: np.ndarray) -> np.ndarray:
    """The rotation vector of the same rotation as ``w`` (``w + 2 pi m n``) closest to ``previous``.

    ``log3`` jumps from +pi to -pi when a base turns past a half turn from knot 0 (walking a
    circle); the spline of the chart must not. Returns ``w`` itself when no jump is needed.
    """
    theta = float(np.linalg.norm(w))
    if theta > 1e-9:
        axis = w / theta
    elif np.linalg.norm(previous) > 1e-9:
        axis = previous / np.linalg.norm(previous)
    else:
        return w
    m = round(float(axis @ (previous - w)) / (2.0 * np.pi))
    return w if m == 0 else w + 2.0 * np.pi * m * axis


@dataclass(frozen=True, eq=False)
class FrameTrack:
    """Reference of one frame on the dense grid (world-aligned).

    Attributes:
        frame_id: Pinocchio frame id.
        position: (N, 3) [m]. rotation: (N, 3, 3).
        velocity: (N, 6) linear + angular [m/s, rad/s].
        acceleration: (N, 6) classical linear + angular [m/s^2, rad/s^2].
    """

    frame_id: int
    position: np.ndarray
    rotation: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray


def _dense_motion(plan: Plan, model: pin.Model, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """q, v, a at ``times``: a clamped cubic spline through the knots in chart coordinates (base
    position in the world, rotation vector w.r.t. knot 0, joints), at rest at the end."""
    n = len(times)
    knots_q = np.asarray(plan.q, dtype=float)
    knots_v = np.asarray(plan.v, dtype=float)
    nk = len(plan.t)

    # chart coordinates at the knots: base position (world), rotation vector w.r.t. knot 0, joints
    rot0 = pin.Quaternion(
        knots_q[0, 6], knots_q[0, 3], knots_q[0, 4], knots_q[0, 5]
    ).toRotationMatrix()
    chart = np.empty((nk, 6 + model.nq - 7))
    dchart = np.empty_like(chart)
    for k in range(nk):
        quat = pin.Quaternion(knots_q[k, 6], knots_q[k, 3], knots_q[k, 4], knots_q[k, 5])
        quat.normalize()
        rot = quat.toRotationMatrix()
        rel = rot0.T @ rot
        chart[k, :3] = knots_q[k, :3]
        w = pin.log3(rel)
        unwrapped = _unwrap(w, chart[k - 1, 3:6]) if k else w
        chart[k, 3:6] = unwrapped
        chart[k, 6:] = knots_q[k, 7:]
        dchart[k, :3] = rot @ knots_v[k, :3]
        if unwrapped is w:
            dchart[k, 3:6] = pin.Jlog3(rel) @ knots_v[k, 3:6]
        else:  # beyond a half turn from knot 0: d/dt of the unwrapped vector, Jr(w)^+ omega
            dchart[k, 3:6] = np.linalg.pinv(_exp3_and_jr(unwrapped[None])[1][0], rcond=1e-6) @ knots_v[k, 3:6]
        dchart[k, 6:] = knots_v[k, 6:] if model.nq - 7 == model.nv - 6 else 0.0
    if nk >= 2:
        c, dc, ddc = clamped_cubic_spline(np.asarray(plan.t, dtype=float), chart, dchart[0], dchart[-1], times)
    else:
        c, dc, ddc = (
            chart.repeat(n, axis=0),
            np.zeros((n, chart.shape[1])),
            np.zeros((n, chart.shape[1])),
        )

    rot_rel, jr = _exp3_and_jr(c[:, 3:6])
    rot = rot0[None] @ rot_rel
    q = np.empty((n, model.nq))
    q[:, :3] = c[:, :3]
    quats = np.array([pin.Quaternion(r).coeffs() for r in rot])  # (x, y, z, w)
    q[:, 3:7] = quats
    q[:, 7:] = c[:, 6:]
    omega = np.einsum("nij,nj->ni", jr, dc[:, 3:6])
    lin = np.einsum("nji,nj->ni", rot, dc[:, :3])  # R^T p'
    v = np.empty((n, model.nv))
    v[:, :3], v[:, 3:6], v[:, 6:] = lin, omega, dc[:, 6:]
    a = np.empty((n, model.nv))
    a[:, :3] = np.einsum("nji,nj->ni", rot, ddc[:, :3]) - np.cross(omega, lin)
    a[:, 3:6] = np.einsum("nij,nj->ni", jr, ddc[:, 3:6])
    a[:, 6:] = ddc[:, 6:]
    # hold the end at rest
    v[-1] = 0.0
    a[-1] = 0.0
    return q, v, a


def _dense_kinematics(model: pin.Model, q: np.ndarray, v: np.ndarray, a: np.ndarray, ids: list[int]) -> tuple[
        np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per sample: the CoM and its two derivatives, the placement (position, rotation), velocity and
    classical acceleration (LOCAL_WORLD_ALIGNED) of the frames ``ids``, the rate of centroidal
    momentum and the angular momentum; the last sample at rest."""
    n = len(q)
    data = model.createData()
    com = np.empty((n, 3))
    dcom = np.empty((n, 3))
    ddcom = np.empty((n, 3))
    pos = np.empty((len(ids), n, 3))
    rots = np.empty((len(ids), n, 3, 3))
    vel = np.empty((len(ids), n, 6))
    acc = np.empty((len(ids), n, 6))
    dmom = np.empty((n, 6))  # rate of centroidal momentum (linear, angular about the CoM)
    hang = np.empty((n, 3))  # centroidal angular momentum A_g(q) v, angular rows
    lwa = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
    acceleration = pin.KinematicLevel.ACCELERATION
    for i in range(n):
        # CoM, its derivatives and forward kinematics to 2nd order, plus the momentum rate
        dmom[i] = pin.computeCentroidalMomentumTimeVariation(model, data, q[i], v[i], a[i])
        hang[i] = data.hg.angular
        # the call above ran the forward pass to 2nd order (data.v, data.a): the CoM pass alone
        pin.centerOfMass(model, data, acceleration, False)
        com[i], dcom[i], ddcom[i] = data.com[0], data.vcom[0], data.acom[0]
        for j, fid in enumerate(ids):
            placement = pin.updateFramePlacement(model, data, fid)
            pos[j, i] = placement.translation
            rots[j, i] = placement.rotation
            vel[j, i] = pin.getFrameVelocity(model, data, fid, lwa).vector
            acc[j, i] = pin.getFrameClassicalAcceleration(model, data, fid, lwa).vector
    vel[:, -1] = 0.0
    acc[:, -1] = 0.0
    dcom[-1] = 0.0
    ddcom[-1] = 0.0
    return com, dcom, ddcom, pos, rots, vel, acc, dmom, hang


def _contact_activity(plan: Plan, robot: Robot, contact_frames: tuple[str, ...], times: np.ndarray) -> np.ndarray:
    """(n, len(contact_frames)) booleans: the plan's contact active at each of ``times`` (a phase
    holds from its start to just before its end, the last one to the end)."""
    model = robot.model
    n = len(times)
    active = np.zeros((n, len(contact_frames)), dtype=bool)
    spec = plan.spec
    starts = spec.phase_start_times()
    for p, phase in enumerate(spec.phases):
        t_start = starts[p]
        t_end = t_start + phase.duration
        mask = (
            (times >= t_start - 1e-9) & (times < t_end - 1e-9)
            if p < len(spec.phases) - 1
            else times >= t_start - 1e-9
        )
        for contact in phase.contacts:
            name = model.frames[robot.frame_id(contact.frame)].name
            active[mask, contact_frames.index(name)] = True
    return active


class PlanReference:
    """A Plan resampled on the controller's grid (see the module docstring).

    Args:
        plan: The planned motion.
        robot: The robot it was planned for.
        dt: Controller period [s].
        frames: Extra frames (names or roles) to track besides feet, hands and spec targets.

    Attributes:
        dt, n: Sample period [s] and number of samples.
        zmp_margin: When not None, the CoM reference is made dynamically feasible: where the
            plan's ZMP (full dynamics: CoM acceleration and the rate of angular momentum)
            comes closer than ``zmp_margin`` [m] to the support polygon's edge, or leaves it,
            the ZMP is projected into the polygon shrunk by the margin and the CoM path is
            re-solved from it (see :func:`balance_com`). The plan's own CoM stays in
            ``plan_com``.
        zmp_scale: For kinematic plans (``spec.dynamic`` False: planned without any dynamics,
            meant to be quasi-static), the ZMP is further kept inside the support polygon
            scaled by this factor about its centre, so that in double support both soles keep
            a share of the weight; a sole that carries nothing slides or yaws under the arm's
            reaction moments. This applies only where the plan's CoM is itself inside the scaled
            polygon (a lean keeps its static offset). 1 turns this off.
        q, v, a: (n, nq), (n, nv), (n, nv) references.
        com, com_velocity, com_acceleration: (n, 3), the CoM reference the controller tracks.
        plan_com: (n, 3) the plan's CoM (equal to ``com`` when the plan's ZMP needs no change).
        angular_momentum, angular_momentum_rate: (n, 3) the reference's centroidal angular
            momentum :math:`A_g(q) v` (angular rows, about the CoM, world axes) [kg m^2/s] and
            its rate [N m] (Pinocchio's ``computeCentroidalMomentumTimeVariation``).
        zmp: (n, 2) the plan's ZMP (full dynamics) [m]; zmp_shift: (n, 2) how far the balance
            filter moved it [m] (zero where the plan was feasible with the margin).
        frames: Frame name -> :class:`FrameTrack` (feet, hands, target frames).
        contact_frames: Every contact frame name of the spec, in order.
        active: (n, len(contact_frames)) booleans, contact active at the sample.
        duration: Plan duration [s].
    """

    def __init__(
        self,
        plan: Plan,
        robot: Robot,
        *,
        dt: float = 0.001,
        frames: tuple[str, ...] = (),
        zmp_margin: float | None = 0.02,
        zmp_scale: float = 0.35,
    ) -> None:
        model = robot.model
        self.plan = plan
        self.dt = float(dt)
        self.duration = float(plan.t[-1] - plan.t[0])
        t0 = float(plan.t[0])
        n = int(round(self.duration / self.dt)) + 1
        self.n = n
        times = t0 + self.dt * np.arange(n)
        times[-1] = min(times[-1], float(plan.t[-1]))
        nk = len(plan.t)
        q, v, a = _dense_motion(plan, model, times)
        self.q, self.v, self.a = q, v, a

        names: list[str] = []
        for role in ("left_foot", "right_foot", "left_hand", "right_hand"):
            if robot.has_role(role):
                names.append(robot.frame(role))
        for target in plan.spec.targets:
            names.append(model.frames[robot.frame_id(target.frame)].name)
        self.contact_frames = tuple(
            model.frames[robot.frame_id(f)].name for f in plan.spec.contact_frames()
        )
        names.extend(self.contact_frames)
        for extra in frames:
            names.append(model.frames[robot.frame_id(extra)].name)
        names = list(dict.fromkeys(names))
        ids = [robot.frame_id(nm) for nm in names]

        com, dcom, ddcom, pos, rots, vel, acc, dmom, hang = _dense_kinematics(model, q, v, a, ids)
        self.plan_com = com.copy()
        self.angular_momentum = hang
        self.angular_momentum_rate = dmom[:, 3:].copy()
        self.frames = {
            nm: FrameTrack(
                frame_id=fid,
                position=pos[j],
                rotation=rots[j],
                velocity=vel[j],
                acceleration=acc[j],
            )
            for j, (nm, fid) in enumerate(zip(names, ids, strict=True))
        }

        active = _contact_activity(plan, robot, self.contact_frames, times)
        self.active = active
        self.times = times
        if plan.spec.dynamic and active.shape[1]:
            # the plan's last stance knot before a flight pushes for half a knot interval after it
            knot_dt = float(np.min(np.diff(plan.t))) if nk >= 2 else 0.0
            _ballistic_flights(times, active, com, dcom, ddcom, hold=int(round(0.5 * knot_dt / self.dt)))
            self.plan_com = com.copy()

        # ZMP of the dense reference (flat ground): c - (c_z F_xy + (-N_y, N_x)) / F_z
        mass = float(sum(inertia.mass for inertia in model.inertias[1:]))
        # in a ballistic flight F_z = 0: no ZMP (nothing to project either); report the CoM there
        fz = mass * (ddcom[:, 2] + 9.81)
        loaded = np.abs(fz) > 1e-6 * mass * 9.81
        safe = np.where(loaded, fz, 1.0)
        ang = np.stack([-dmom[:, 4], dmom[:, 3]], axis=1) / safe[:, None]
        self.zmp = np.where(
            loaded[:, None], com[:, :2] - com[:, 2:3] * ddcom[:, :2] * mass / safe[:, None] + ang, com[:, :2]
        )
        self.zmp_shift = np.zeros((n, 2))
        self.com, self.com_velocity, self.com_acceleration = com, dcom, ddcom
        if zmp_margin is not None and n >= 3:
            scale = 1.0 if plan.spec.dynamic else float(zmp_scale)
            zmp_target = self.zmp.copy()
            for rows, verts in support_polygons(robot, self, margin=zmp_margin):
                zmp_target[rows] = project_into_polygon(self.zmp[rows], verts)
            if scale < 1.0:  # only where the plan's CoM itself is inside the scaled polygon
                for rows, verts in support_polygons(robot, self, margin=zmp_margin, scale=scale):
                    inside = np.all(project_into_polygon(com[rows, :2], verts) == com[rows, :2], axis=1)
                    rows = rows[inside]
                    zmp_target[rows] = project_into_polygon(self.zmp[rows], verts)
            shift = zmp_target - self.zmp
            if np.abs(shift).max() > 1e-6:
                new = com.copy()
                new[:, :2] = balance_com(com, shift, self.dt)
                new_vel = np.zeros((n, 3))
                new_acc = np.zeros((n, 3))
                new_vel[1:-1] = (new[2:] - new[:-2]) / (2.0 * self.dt)
                new_acc[1:-1] = (new[2:] - 2.0 * new[1:-1] + new[:-2]) / self.dt**2
                new_vel[:, 2], new_acc[:, 2] = dcom[:, 2], ddcom[:, 2]
                new_vel[-1] = 0.0
                new_acc[-1] = 0.0
                self.com, self.com_velocity, self.com_acceleration = new, new_vel, new_acc
                self.zmp_shift = shift

    def index(self, t: float) -> int:
        """Sample index of time ``t`` [s] (clamped to the plan; the last sample after the end)."""
        k = int(round((t - float(self.plan.t[0])) / self.dt))
        return 0 if k < 0 else (self.n - 1 if k >= self.n else k)


FLIGHT_BLEND = 0.15  # [s] push-off and landing blends around a ballistic flight (the landing's at least)
LANDING_BRAKE = 1.0  # [g] the landing blend first stops the CoM's fall at this upward acceleration (the soles carry 2 x the weight)
LANDING_UNLOAD = 0.3  # [g] then it decelerates the CoM downwards at most this much: the soles keep 70 % of the weight
LANDING_BLEND_MAX = 0.6  # [s] the longest landing blend
_LANDING_STEP = 0.01  # [s] the landing blend's lengths tried
_G = 9.81  # [m/s^2]


def landing_blend(ts: np.ndarray, p1: np.ndarray, v1: np.ndarray, ref_pos: np.ndarray,
                  ref_vel: np.ndarray) -> tuple[int, np.ndarray, np.ndarray, np.ndarray]:
    r"""The CoM after a touch-down, from ``(p1, v1)`` back onto the reference: ``(b, pos, vel, acc)``
    for the samples ``0..b`` of ``ts`` (times from the touch-down, ``ts[0] = 0``; ``ref_pos``,
    ``ref_vel`` (n, 3) the reference on them).

    Vertically, the fall first stops at a constant upward acceleration of ``LANDING_BRAKE`` g, then
    a cubic Hermite from rest at that bottom rejoins the reference at sample ``b``: the shortest
    blend (at least ``FLIGHT_BLEND``, at most ``LANDING_BLEND_MAX``, in 10 ms steps) whose
    downward acceleration (linear on a cubic: extreme at its ends) stays within ``LANDING_UNLOAD``
    g, so the soles stay loaded. Horizontally one cubic Hermite over ``[0, ts[b]]`` (over 0.15 s
    only, with the dip capped at 2-3 cm, G1's forward hops slipped 10.4 mm: docs/control.md).

    A single 0.15 s Hermite from talos's 0.72 m/s touch-down of a 5 cm jump to the plan's knots,
    already 3 cm higher, asked for +2.4 g at touch-down and -1.3 g at its end: the soles cannot
    pull, both unloaded to 4 % of the weight 0.15 s after landing, and pushed 20 N s at the
    touch-down on a floor at 0.7 x mu, the right sole rolled 7 degrees onto its edge and slid 10 mm.
    """
    n = len(ts)
    brake = LANDING_BRAKE * _G
    vz1 = float(v1[2])
    t_stop = max(-vz1, 0.0) / brake
    z_bottom = float(p1[2]) + vz1 * t_stop + 0.5 * brake * t_stop**2
    v_start = max(vz1, 0.0)
    dt = float(ts[1] - ts[0]) if n > 1 else _LANDING_STEP
    step = max(1, int(round(_LANDING_STEP / dt)))
    first = min(int(np.searchsorted(ts, max(FLIGHT_BLEND, t_stop + _LANDING_STEP) - 1e-9)), n - 1)
    last = min(int(np.searchsorted(ts, LANDING_BLEND_MAX + 1e-9)), n - 1)
    b = last
    for k in range(first, last + 1, step):
        h = float(ts[k]) - t_stop
        rise = float(ref_pos[k, 2]) - z_bottom
        vb = float(ref_vel[k, 2])
        a_start = 6.0 * rise / h**2 - (4.0 * v_start + 2.0 * vb) / h
        a_end = -6.0 * rise / h**2 + (2.0 * v_start + 4.0 * vb) / h
        if min(a_start, a_end) >= -LANDING_UNLOAD * _G:
            b = k
            break
    tt = ts[: b + 1]
    pos, vel, acc = _hermite(0.0, float(ts[b]), p1, v1, ref_pos[b], ref_vel[b], tt)
    braking = tt < t_stop
    pos[braking, 2] = float(p1[2]) + vz1 * tt[braking] + 0.5 * brake * tt[braking] ** 2
    vel[braking, 2] = vz1 + brake * tt[braking]
    acc[braking, 2] = brake
    rest = ~braking
    if rest.any() and float(ts[b]) > t_stop:
        zp, zv, za = _hermite(t_stop, float(ts[b]), [z_bottom], [v_start], ref_pos[b, 2:3], ref_vel[b, 2:3], tt[rest])
        pos[rest, 2], vel[rest, 2], acc[rest, 2] = zp[:, 0], zv[:, 0], za[:, 0]
    return b, pos, vel, acc


def solve_tridiagonal(ab: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Solve a diagonally dominant tridiagonal system in ``scipy.linalg.solve_banded((1, 1), ab,
    rhs)``'s banded form (``ab[0, 1:]`` the super-diagonal, ``ab[1]`` the diagonal, ``ab[2, :-1]``
    the sub-diagonal; ``rhs`` (n,) or (n, k)) by elimination without pivoting (Thomas), which
    is stable for the strictly diagonally dominant systems of this module; ``scipy.linalg``
    costs ~0.2 s to import."""
    n = ab.shape[1]
    upper, diag, lower = ab[0], ab[1], ab[2]
    c = np.empty(n)
    d = np.array(rhs, dtype=float)
    c[0] = upper[1] / diag[0] if n > 1 else 0.0
    d[0] = d[0] / diag[0]
    for i in range(1, n):
        denom = diag[i] - lower[i - 1] * c[i - 1]
        if i < n - 1:
            c[i] = upper[i + 1] / denom
        d[i] = (d[i] - lower[i - 1] * d[i - 1]) / denom
    for i in range(n - 2, -1, -1):
        d[i] = d[i] - c[i] * d[i + 1]
    return d


def clamped_cubic_spline(t: np.ndarray, y: np.ndarray, d_start: np.ndarray, d_end: np.ndarray,
                         times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    r"""The C2 cubic spline through ``(t, y)`` with the first derivatives ``d_start``, ``d_end`` at
    its ends, and its first and second derivatives, at ``times``.

    What ``scipy.interpolate.CubicSpline(t, y, bc_type=((1, d_start), (1, d_end)), axis=0)``
    gives, without importing ``scipy.interpolate`` (~0.4 s of every simulated ``wbmp solve``):
    the knot slopes ``m`` solve the tridiagonal system of second-derivative continuity
    :math:`h_i m_{i-1} + 2 (h_{i-1} + h_i) m_i + h_{i-1} m_{i+1} = 3 (h_i \delta_{i-1} + h_{i-1} \delta_i)`,
    then each interval is the cubic Hermite piece of its end values and slopes (times outside
    ``t`` use the end pieces).

    Args:
        t: (n,) increasing knot times [s], n >= 2.
        y: (n, d) values.
        d_start, d_end: (d,) first derivatives at ``t[0]`` and ``t[-1]``.
        times: (m,) evaluation times [s].

    Returns:
        ``(value, first derivative, second derivative)``, each (m, d).
    """
    y = np.asarray(y, dtype=float)
    h = np.diff(t)
    delta = (y[1:] - y[:-1]) / h[:, None]
    n = len(t)
    m = np.empty_like(y)
    m[0], m[-1] = d_start, d_end
    if n > 2:
        ab = np.zeros((3, n - 2))
        ab[0, 1:] = h[:-2]  # super-diagonal: h_{i-1} of row i (multiplies m_{i+1})
        ab[1] = 2.0 * (h[:-1] + h[1:])
        ab[2, :-1] = h[2:]  # sub-diagonal: h_i of row i (multiplies m_{i-1})
        rhs = 3.0 * (h[1:, None] * delta[:-1] + h[:-1, None] * delta[1:])
        rhs[0] -= h[1] * m[0]
        rhs[-1] -= h[-2] * m[-1]
        m[1:-1] = solve_tridiagonal(ab, rhs)
    k = np.clip(np.searchsorted(t, times, side="right") - 1, 0, n - 2)
    hk = h[k][:, None]
    c2 = (3.0 * delta[k] - 2.0 * m[k] - m[k + 1]) / hk
    c3 = (m[k] + m[k + 1] - 2.0 * delta[k]) / hk**2
    x = (np.asarray(times, dtype=float) - t[k])[:, None]
    value = y[k] + x * (m[k] + x * (c2 + x * c3))
    first = m[k] + x * (2.0 * c2 + 3.0 * x * c3)
    second = 2.0 * c2 + 6.0 * x * c3
    return value, first, second


def _hermite(t0: float, t1: float, p0, v0, p1, v1, t: np.ndarray):
    """Cubic Hermite segment on [t0, t1]: position, velocity, acceleration at ``t`` (n, 3)."""
    h = t1 - t0
    s = ((t - t0) / h)[:, None]
    p0, v0, p1, v1 = (np.asarray(x, dtype=float)[None, :] for x in (p0, v0, p1, v1))
    pos = (2 * s**3 - 3 * s**2 + 1) * p0 + (s**3 - 2 * s**2 + s) * h * v0 + (-2 * s**3 + 3 * s**2) * p1 \
        + (s**3 - s**2) * h * v1
    vel = ((6 * s**2 - 6 * s) * p0 + (3 * s**2 - 4 * s + 1) * h * v0 + (-6 * s**2 + 6 * s) * p1
           + (3 * s**2 - 2 * s) * h * v1) / h
    acc = ((12 * s - 6) * p0 + (6 * s - 4) * h * v0 + (-12 * s + 6) * p1 + (6 * s - 2) * h * v1) / h**2
    return pos, vel, acc



def flight_spans(airborne) -> list[tuple[int, int]]:
    """(first airborne sample, touch-down sample) of each flight between two stances: a run of
    airborne samples with a sample on the ground before and after it."""
    out, n, k = [], len(airborne), 0
    while k < n:
        if not airborne[k]:
            k += 1
            continue
        a = k
        while k < n and airborne[k]:
            k += 1
        if a > 0 and k < n:
            out.append((a, k))
    return out

def _ballistic_flights(times: np.ndarray, active: np.ndarray, com: np.ndarray, dcom: np.ndarray,
                       ddcom: np.ndarray, hold: int = 0) -> None:
    r"""Make the CoM reference of every flight (no active contact) ballistic, in place.

    A dynamic plan's flight knots follow :math:`\ddot c = g` exactly, but the C2 spline through
    the knots smooths the take-off velocity jump over the neighbouring intervals: the spline
    reached only 0.75 of the 1.1 m/s take-off speed of a 5 cm jump when the contacts switched
    off, and bent the flight (accelerations from -15.7 to +7.7 m/s^2) where no force can act.
    The flight becomes the parabola through the take-off and touch-down knots; a cubic blend
    over ``FLIGHT_BLEND`` before take-off reaches the ballistic take-off velocity, and one after
    touch-down absorbs the landing velocity back onto the spline.

    ``hold`` samples (half a knot interval): the stance before a flight lasts this much longer
    (``active`` is changed in place) and the take-off blend ends there. The plan's CoM dynamics
    are central differences at the knots, so the last stance knot's force acts on the interval
    around it, half of which lies after the phase's switch; the parabola through the flight's
    knots (the last stance knot, the flight knots and the touch-down knot) leaves that knot at
    a speed the push cannot reach by then. Measured on g1's 5 cm jump: the parabola needs
    1.36 m/s at the switch, half a knot later 0.99 m/s; the push stroke's CoM rises 9 cm in the
    0.15 s before the switch (0.61 m/s on average from 0.55 m/s), so the blend to the switch
    first decelerated (-8 m/s^2, the soles nearly unloaded) and then asked for 2.5 g: the
    tracked body took off with 3x the planned pitch momentum and fell on landing.
    """
    n = len(times)
    airborne = np.asarray(~active.any(axis=1), dtype=bool)
    g = np.array([0.0, 0.0, -9.81])
    for i0, i1 in flight_spans(airborne):  # the lift-off knot (first sample without contact), the touch-down knot
        t0, t1 = times[i0], times[i1]
        T = t1 - t0
        v_off = (com[i1] - com[i0]) / T - 0.5 * g * T
        tt = (times[i0 : i1 + 1] - t0)[:, None]
        c0 = com[i0].copy()
        c1 = com[i1].copy()
        com[i0 : i1 + 1] = c0 + v_off * tt + 0.5 * g * tt**2
        dcom[i0 : i1 + 1] = v_off + g * tt
        ddcom[i0 : i1 + 1] = g
        v_land = v_off + g * T
        h = min(hold, (i1 - i0) // 2)  # the real take-off: h samples after the switch
        if h > 0:
            active[i0 : i0 + h] = active[i0 - 1]
        it = i0 + h
        b0 = int(np.searchsorted(times, times[it] - FLIGHT_BLEND))
        if b0 < it:
            seg = slice(b0, it)  # ends where the flight starts (same position and velocity)
            com[seg], dcom[seg], ddcom[seg] = _hermite(times[b0], times[it], com[b0], dcom[b0], com[it],
                                                       dcom[it], times[seg])
        if i1 < n - 1:
            b, pos, vel, acc = landing_blend(times[i1:] - t1, c1, v_land, com[i1:], dcom[i1:])
            seg = slice(i1, i1 + b + 1)
            com[seg], dcom[seg], ddcom[seg] = pos, vel, acc


def support_polygons(
    robot: Robot, ref: PlanReference, *, margin: float = 0.0, scale: float = 1.0
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Support polygons of a reference: runs of samples with the same stance contacts.

    Each sole rectangle is shrunk by ``margin`` [m] on every side before the convex hull is
    taken; the hull is then scaled by ``scale`` about its vertex centroid.

    Returns:
        ``(sample indices, counter-clockwise vertices (V, 2) [m])`` per run; runs without a
        stance contact, or with a degenerate polygon, are left out.
    """
    out: list[tuple[np.ndarray, np.ndarray]] = []
    if ref.active.shape[1] == 0:
        return out
    change = np.nonzero(np.any(ref.active[1:] != ref.active[:-1], axis=1))[0] + 1
    bounds = [0, *change.tolist(), ref.n]
    local = {}
    for name in ref.contact_frames:
        side = robot.foot_side(name) or "left"
        sole = robot.profile.sole
        m = min(margin, 0.45 * (sole.x_max - sole.x_min), 0.45 * (sole.y_max - sole.y_min))
        local[name] = sole_corners(sole, side, margin=m)
    for lo, hi in itertools.pairwise(bounds):
        mid = (lo + hi) // 2
        pts = [
            points_in_world(local[name], pin.SE3(ref.frames[name].rotation[mid], ref.frames[name].position[mid]))
            for c, name in enumerate(ref.contact_frames)
            if ref.active[lo, c]
        ]
        verts = support_polygon(pts)
        if len(verts) < 3:  # no stance contact, or a degenerate polygon (a line)
            continue
        centre = verts.mean(axis=0)
        out.append((np.arange(lo, hi), centre + scale * (verts - centre)))
    return out


def project_into_polygon(points: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """Nearest points of a convex polygon (counter-clockwise ``vertices`` (V, 2)) to ``points`` (N, 2)."""
    a = vertices
    b = np.roll(vertices, -1, axis=0)
    edge = b - a
    normal = np.stack([edge[:, 1], -edge[:, 0]], axis=1)  # outward for a counter-clockwise polygon
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    outside = ((points[:, None, :] - a[None]) * normal[None]).sum(axis=2) > 0.0  # (N, V)
    out = points.copy()
    bad = outside.any(axis=1)
    if not bad.any():
        return out
    p = points[bad]
    s = ((p[:, None, :] - a[None]) * edge[None]).sum(axis=2) / (edge * edge).sum(axis=1)[None]
    s = np.clip(s, 0.0, 1.0)
    cand = a[None] + s[:, :, None] * edge[None]  # (M, V, 2)
    d = np.linalg.norm(cand - p[:, None, :], axis=2)
    out[bad] = cand[np.arange(len(p)), np.argmin(d, axis=1)]
    return out


def balance_com(com: np.ndarray, zmp_shift: np.ndarray, dt: float) -> np.ndarray:
    r"""Horizontal CoM path whose ZMP is the plan's moved by ``zmp_shift``, same first and last CoM.

    The ZMP depends on the CoM through :math:`p = c - k \ddot c + o` per horizontal axis
    (:math:`k = c_z / (g + \ddot c_z)` from the plan, ``o`` the angular-momentum part, kept from
    the plan). Moving ``p`` by ``zmp_shift`` is the linear boundary-value problem
    :math:`c - k \ddot c = c_{plan} - k \ddot c_{plan} + \Delta p`, solved on the sample grid
    with central second differences (a tridiagonal, diagonally dominant system). A zero shift
    returns the plan's CoM.

    Args:
        com: (n, 3) the plan's CoM [m].
        zmp_shift: (n, 2) wanted change of the ZMP [m].
        dt: Sample period [s].

    Returns:
        (n, 2) horizontal CoM [m].
    """
    n = len(com)
    ddz = np.zeros(n)
    ddz[1:-1] = (com[2:, 2] - 2.0 * com[1:-1, 2] + com[:-2, 2]) / dt**2
    k = com[:, 2] / (9.81 + ddz) / dt**2
    rhs = com[:, :2] + zmp_shift
    rhs[1:-1] -= k[1:-1, None] * (com[2:, :2] - 2.0 * com[1:-1, :2] + com[:-2, :2])
    ab = np.zeros((3, n - 2))
    ab[0, 1:] = -k[1:-2]
    ab[1] = 1.0 + 2.0 * k[1:-1]
    ab[2, :-1] = -k[2:-1]
    r = rhs[1:-1].copy()
    r[0] += k[1] * com[0, :2]
    r[-1] += k[-2] * com[-1, :2]
    out = com[:, :2].copy()
    out[1:-1] = solve_tridiagonal(ab, r)
    return out
