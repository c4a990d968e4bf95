"""Numbers every view needs: resampled motions, geometry placements, CoM, ZMP, support polygons.

Everything here is a pure function of explicit objects (a :class:`robots.Robot`, arrays, a
:class:`planner.Plan`, a :class:`sim.Execution`); nothing draws and nothing is cached
between calls. The viewers (:mod:`viz.scene`) and the plots (:mod:`viz.plots`) share it so
that the HTML replay, the live viewer and the PNGs show the same numbers.

Conventions: world frame z-up, ground at z = 0, configurations in Pinocchio order with the
free-flyer quaternion stored (x, y, z, w), times in seconds.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from robots import Robot, points_in_world, polygon_margin, sole_corners
from robots import convex_hull as convex_hull_2d
from viz.exceptions import VizInputError

if TYPE_CHECKING:
    from sim.execution import Execution

GRAVITY = 9.81  # [m/s^2]


@dataclass(frozen=True, eq=False, kw_only=True)
class Motion:
    """A configuration trajectory on a time grid, with whatever else is known about it.

    Attributes:
        label: ``"planned"`` or ``"simulated"``.
        t: Times (T,) [s], increasing.
        q: Configurations (T, nq), Pinocchio order.
        v: Velocities (T, nv) or None.
        tau: Actuated joint torques (T, nv - 6) [N m] or None.
        forces: Contact force per frame name, (T, 3) in the world [N]; may be empty.
        objects: Movable scene object -> its pose on ``t`` (T, 7): centre position [m] then a unit
            quaternion (x, y, z, w); planned (:func:`planned_object_poses`) or simulated; may be empty.
    """

    label: str
    t: np.ndarray
    q: np.ndarray
    v: np.ndarray | None = None
    tau: np.ndarray | None = None
    forces: Mapping[str, np.ndarray] = field(default_factory=dict)
    objects: Mapping[str, np.ndarray] = field(default_factory=dict)

    @property
    def duration(self) -> float:
        """Length of the motion [s]."""
        return float(self.t[-1] - self.t[0]) if len(self.t) else 0.0


def _array(owner: str, name: str, value, ncols: int | None) -> np.ndarray:
    arr = np.asarray(value, dtype=float)
    if arr.ndim != 2 or (ncols is not None and arr.shape[1] != ncols) or arr.shape[0] == 0:
        want = f"(T, {ncols})" if ncols is not None else "(T, n)"
        raise VizInputError(f"{owner}: {name} must be a non-empty {want} array, got shape {arr.shape}")
    return arr


def plan_motion(robot: Robot, plan) -> Motion:
    """The planned motion of a :class:`planner.Plan` as a :class:`Motion`.

    Raises:
        VizInputError: the plan's arrays do not match the robot.
    """
    t = np.asarray(plan.t, dtype=float).reshape(-1)
    q = _array("plan", "q", plan.q, robot.nq)
    if len(t) != len(q):
        raise VizInputError(f"plan: t has {len(t)} knots but q has {len(q)} rows")
    v = _array("plan", "v", plan.v, robot.nv) if plan.v is not None and len(plan.v) else None
    forces = {k: np.asarray(f, dtype=float) for k, f in (plan.forces or {}).items()}
    objects = planned_object_poses(robot, getattr(plan, "spec", None), t, q)
    return Motion(label="planned", t=t, q=q, v=v, forces=forces, objects=objects)


def _rest_pose(obj) -> np.ndarray:
    """A scene object's pose (7,) where the scene puts it: position, quaternion (x, y, z, w)."""
    R = pin.rpy.rpyToMatrix(*(float(a) for a in obj.rpy))
    return np.concatenate([np.asarray(obj.position, dtype=float), pin.Quaternion(R).normalized().coeffs()])


def planned_object_poses(robot: Robot, spec, t: np.ndarray, qs: np.ndarray) -> dict[str, np.ndarray]:
    """Where the plan puts each movable object of ``spec``'s scene at each knot (times ``t`` (T,)
    [s], configurations ``qs`` (T, nq)) (T, 7): position [m] and quaternion (x, y, z, w).

    An object stands where the scene puts it until a grasp of it (:class:`tasks.specs.Grasp`)
    starts; from that knot it moves with the holding frame, its centre at the grasp's ``offset`` in
    that frame and its orientation turned with the frame from the knot where the grasp starts; from
    the grasp's ``end`` (the release) it stays where the hand left it. A second grasp of the same
    object over the same window (both hands) follows the first. Objects that no grasp names stay put.

    Returns:
        Object name -> poses (T, 7); empty without a scene or movable objects.
    """
    scene = getattr(spec, "scene", None)
    if scene is None:
        return {}
    qs = np.asarray(qs, dtype=float)
    times = np.asarray(t, dtype=float).reshape(-1)
    if len(times) != len(qs):
        raise VizInputError(f"plan: t has {len(times)} knots but q has {len(qs)} rows")
    grasps = sorted(getattr(spec, "grasps", ()), key=lambda g: g.start)
    out: dict[str, np.ndarray] = {}
    model, data = robot.model, robot.data()
    for obj in scene.objects:
        if not obj.movable:
            continue
        pose = np.tile(_rest_pose(obj), (len(qs), 1))
        mine = [g for g in grasps if g.object == obj.name]
        seen: set[tuple[float, float | None]] = set()
        for g in mine:
            if (g.start, g.end) in seen:
                continue  # the other hand of a two-handed hold
            seen.add((g.start, g.end))
            k0 = _knot(times, g.start)
            k1 = len(qs) if g.end is None else _knot(times, g.end)
            if k0 >= len(qs):
                continue
            fid = model.getFrameId(g.frame)
            if fid >= len(model.frames):
                continue  # a frame this robot lacks: the object stays where it stands
            pin.framesForwardKinematics(model, data, qs[k0])
            rest = pose[k0]
            R_obj_in_hand = data.oMf[fid].rotation.T @ pin.Quaternion(rest[6], *rest[3:6]).toRotationMatrix()
            offset = np.asarray(g.offset, dtype=float)
            for k in range(k0, min(k1 + 1, len(qs))):
                pin.framesForwardKinematics(model, data, qs[k])
                M = data.oMf[fid]
                pose[k, :3] = M.act(offset)
                pose[k, 3:] = pin.Quaternion(M.rotation @ R_obj_in_hand).normalized().coeffs()
            pose[min(k1 + 1, len(qs)):] = pose[min(k1, len(qs) - 1)]
        out[obj.name] = pose
    return out


def _knot(times: np.ndarray, t: float) -> int:
    """The first knot at or after time ``t`` [s] (``len(times)`` when there is none)."""
    return int(np.searchsorted(times, t - 1e-9))


def execution_motion(robot: Robot, execution: Execution | None) -> Motion | None:
    """The simulated motion of an execution (a fresh run or one read back from a motion file).

    Returns:
        None when ``execution`` is None or holds no configurations.

    Raises:
        VizInputError: the arrays do not match the robot.
    """
    if execution is None or len(execution.q) == 0:
        return None
    t = np.asarray(execution.t, dtype=float).reshape(-1)
    q = _array("execution", "q", execution.q, robot.nq)
    if len(t) != len(q):
        raise VizInputError(f"execution: t has {len(t)} samples but q has {len(q)} rows")
    v, tau = execution.v, execution.tau
    try:
        objects = execution.object_poses()
    except ValueError as e:
        raise VizInputError(f"execution: {e}") from None
    return Motion(
        label="simulated",
        t=t,
        q=q,
        v=_array("execution", "v", v, robot.nv) if v is not None and len(v) else None,
        tau=_array("execution", "tau", tau, robot.nv - 6) if tau is not None and len(tau) else None,
        forces={k: np.asarray(f, dtype=float) for k, f in execution.contact_forces.items()},
        objects=objects,
    )


def resample_poses(t: np.ndarray, poses: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Poses (T, 7) given at times ``t`` (T,) [s] sampled at ``times`` (F,) [s] (clamped to the ends):
    positions linear, quaternions spherical (shortest arc) between the two neighbours."""
    t = np.asarray(t, dtype=float)
    poses = np.asarray(poses, dtype=float)
    out = np.empty((len(times), 7))
    if len(t) == 1:
        out[:] = poses[0]
        return out
    idx = np.clip(np.searchsorted(t, times, side="right") - 1, 0, len(t) - 2)
    for i, (k, s) in enumerate(zip(idx, times, strict=True)):
        h = t[k + 1] - t[k]
        a = float(np.clip((s - t[k]) / h, 0.0, 1.0)) if h > 0 else 0.0
        out[i, :3] = (1.0 - a) * poses[k, :3] + a * poses[k + 1, :3]
        q0 = pin.Quaternion(poses[k, 6], *poses[k, 3:6]).normalized()
        q1 = pin.Quaternion(poses[k + 1, 6], *poses[k + 1, 3:6]).normalized()
        out[i, 3:] = q0.slerp(a, q1).coeffs()
    return out


def resample(robot: Robot, motion: Motion, fps: float) -> tuple[np.ndarray, np.ndarray]:
    """Configurations on a uniform grid of ``fps`` frames per second.

    Interpolation is geodesic on the configuration manifold (``pin.interpolate``), so the
    base rotation stays a unit quaternion. The last sample is always the motion's end.

    Args:
        robot: The robot of the motion.
        motion: The motion to sample.
        fps: Frames per second [1/s], > 0.

    Returns:
        ``(times, qs)``: times (F,) [s] starting at 0, configurations (F, nq).
    """
    t, q = motion.t, motion.q
    if len(t) == 1:
        return np.zeros(1), q.copy()
    t0 = float(t[0])
    n = max(2, int(np.floor((t[-1] - t0) * fps + 1e-9)) + 1)
    times = np.linspace(0.0, (n - 1) / fps, n)
    if times[-1] < t[-1] - t0 - 1e-9:
        times = np.append(times, t[-1] - t0)
    times = np.minimum(times, t[-1] - t0)
    qs = np.empty((len(times), q.shape[1]))
    idx = np.clip(np.searchsorted(t - t0, times, side="right") - 1, 0, len(t) - 2)
    for i, (k, s) in enumerate(zip(idx, times, strict=True)):
        h = t[k + 1] - t[k]
        alpha = float(np.clip((s - (t[k] - t0)) / h, 0.0, 1.0)) if h > 0 else 0.0
        qs[i] = pin.interpolate(robot.model, q[k], q[k + 1], alpha)
    return times, qs


def geometry_placements(robot: Robot, qs: np.ndarray) -> np.ndarray:
    """Rigid world placement of every visual geometry at every configuration.

    The mesh scale is NOT included (it may be negative: 13 Talos meshes are mirrored), so
    each 4x4 is a proper rigid transform whose rotation converts to a quaternion.

    Returns:
        Array (n_geometries, F, 4, 4), geometries in ``robot.visual_model`` order.
    """
    model, data = robot.model, robot.data()
    gmodel = robot.visual_model
    gdata = pin.GeometryData(gmodel)
    out = np.empty((len(gmodel.geometryObjects), len(qs), 4, 4))
    for f, q in enumerate(qs):
        pin.forwardKinematics(model, data, q)
        pin.updateGeometryPlacements(model, data, gmodel, gdata)
        for g in range(len(gmodel.geometryObjects)):
            out[g, f] = gdata.oMg[g].homogeneous
    return out


def com_trajectory(robot: Robot, qs: np.ndarray) -> np.ndarray:
    """Centre of mass (F, 3) [m] of each configuration."""
    model, data = robot.model, robot.data()
    return np.array([pin.centerOfMass(model, data, q).copy() for q in qs])


def frame_trajectory(robot: Robot, qs: np.ndarray, frame: str) -> np.ndarray:
    """World position (F, 3) [m] of a frame (name or role) at each configuration."""
    model, data = robot.model, robot.data()
    fid = robot.frame_id(frame)
    out = np.empty((len(qs), 3))
    for i, q in enumerate(qs):
        pin.framesForwardKinematics(model, data, q)
        out[i] = data.oMf[fid].translation
    return out


def zmp_from_com(t: np.ndarray, com: np.ndarray) -> np.ndarray:
    """Zero-moment point (T, 2) on flat ground from the CoM trajectory [m].

    Cart-table model (rate of angular momentum neglected):
    :math:`p = c_{xy} - c_z \\ddot c_{xy} / (\\ddot c_z + g)`, with :math:`\\ddot c` from
    second-order finite differences on the (possibly non-uniform) grid. Where the vertical
    acceleration cancels gravity (flight), the ZMP is undefined and returned as NaN.
    """
    t = np.asarray(t, dtype=float)
    com = np.asarray(com, dtype=float)
    if len(t) < 3:
        return com[:, :2].copy()
    vel = np.gradient(com, t, axis=0)
    acc = np.gradient(vel, t, axis=0)
    denom = acc[:, 2] + GRAVITY
    with np.errstate(divide="ignore", invalid="ignore"):
        zmp = com[:, :2] - (com[:, 2] / denom)[:, None] * acc[:, :2]
    zmp[denom < 0.1 * GRAVITY] = np.nan
    return zmp


def _contact_xy(robot: Robot, frame: str) -> np.ndarray:
    side = robot.foot_side(robot.profile.frame(frame) or frame)
    if side is not None:
        return sole_corners(robot.profile.sole, side)[:, :2]
    return 0.025 * np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], dtype=float)


def contact_sole_corners(robot: Robot, q: np.ndarray, frame: str) -> np.ndarray:
    """Corners (4, 3) of the contact surface of ``frame`` at configuration ``q``, in the world [m].

    Feet use the profile's sole rectangle; any other contact frame gets a 5 cm square.
    """
    data = robot.data()
    pin.framesForwardKinematics(robot.model, data, q)
    xy = _contact_xy(robot, frame)
    return points_in_world(np.column_stack([xy, np.zeros(len(xy))]), data.oMf[robot.frame_id(frame)])


def contact_corners_at_placement(robot: Robot, contact) -> np.ndarray:
    """Corners (4, 3) of a spec :class:`tasks.specs.Contact` at its requested placement [m]."""
    R = pin.rpy.rpyToMatrix(*(float(a) for a in contact.placement.rpy))
    p = np.asarray(contact.placement.position, dtype=float)
    xy = _contact_xy(robot, contact.frame)
    return points_in_world(np.column_stack([xy, np.zeros(len(xy))]), pin.SE3(R, p))


@dataclass(frozen=True, kw_only=True)
class SupportPhase:
    """The support polygon of one phase of a plan.

    Attributes:
        name: Phase name.
        start, end: Phase interval [s].
        frames: Contact frames active in the phase.
        soles: Corners (4, 3) of each active contact surface [m], keyed by frame.
        polygon: Counter-clockwise convex hull (H, 2) of all soles [m]; empty in flight.
    """

    name: str
    start: float
    end: float
    frames: tuple[str, ...]
    soles: Mapping[str, np.ndarray]
    polygon: np.ndarray


def support_phases(robot: Robot, plan) -> list[SupportPhase]:
    """Support polygon of every phase of ``plan``, from the contact placements of its spec."""
    spec = plan.spec
    out = []
    for phase, start in zip(spec.phases, spec.phase_start_times(), strict=True):
        end = start + phase.duration
        frames = tuple(c.frame for c in phase.contacts)
        soles = {c.frame: contact_corners_at_placement(robot, c) for c in phase.contacts}
        pts = np.vstack(list(soles.values())) if soles else np.zeros((0, 3))
        hull = convex_hull_2d(pts) if len(pts) else np.zeros((0, 2))
        out.append(SupportPhase(name=phase.name, start=start, end=end, frames=frames, soles=soles,
                                polygon=hull))
    return out


def point_in_polygon_margin(point: np.ndarray, polygon: np.ndarray) -> float:
    """Signed distance [m] of a 2D point inside a convex CCW polygon (> 0 inside)."""
    return polygon_margin(polygon, point)
