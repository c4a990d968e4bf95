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

from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from scipy.interpolate import CubicSpline

from planner.plan import Plan
from robots.model import Robot


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


class PlanReference:
    """A Plan resampled on the controller's grid (see the module docstring).

    Args:
        plan: The planned motion.
        robot: The robot it was planned for.
        dt: Controller period [s].
        frames: Extra frames (names or roles) to track besides feet, hands and spec targets.

    Attributes:
        dt, n: Sample period [s] and number of samples.
        q, v, a: (n, nq), (n, nv), (n, nv) references.
        com, com_velocity, com_acceleration: (n, 3).
        frames: Frame name -> :class:`FrameTrack` (feet, hands, target frames).
        contact_frames: Every contact frame name of the spec, in order.
        active: (n, len(contact_frames)) booleans, contact active at the sample.
        duration: Plan duration [s].
    """

    def __init__(
        self, plan: Plan, robot: Robot, *, dt: float = 0.001, frames: tuple[str, ...] = ()
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
            chart[k, 3:6] = pin.log3(rel)
            chart[k, 6:] = knots_q[k, 7:]
            dchart[k, :3] = rot @ knots_v[k, :3]
            dchart[k, 3:6] = pin.Jlog3(rel) @ knots_v[k, 3:6]
            dchart[k, 6:] = knots_v[k, 6:] if model.nq - 7 == model.nv - 6 else 0.0
        if nk >= 2:
            spline = CubicSpline(plan.t, chart, bc_type=((1, dchart[0]), (1, dchart[-1])), axis=0)
            c, dc, ddc = spline(times), spline(times, 1), spline(times, 2)
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

        data = model.createData()
        com = np.empty((n, 3))
        dcom = np.empty((n, 3))
        ddcom = np.empty((n, 3))
        pos = np.empty((len(ids), n, 3))
        rots = np.empty((len(ids), n, 3, 3))
        vel = np.empty((len(ids), n, 6))
        acc = np.empty((len(ids), n, 6))
        lwa = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
        for i in range(n):
            pin.centerOfMass(model, data, q[i], v[i], a[i])  # also forward kinematics to 2nd order
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
        self.com, self.com_velocity, self.com_acceleration = com, dcom, ddcom
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

        active = np.zeros((n, len(self.contact_frames)), dtype=bool)
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
                active[mask, self.contact_frames.index(name)] = True
        self.active = active
        self.times = times

    def index(self, t: float) -> int:
        """Sample index of time ``t`` [s] (clamped to the plan; the last sample after the end)."""
        k = int(round((t - float(self.plan.t[0])) / self.dt))
        return 0 if k < 0 else (self.n - 1 if k >= self.n else k)
