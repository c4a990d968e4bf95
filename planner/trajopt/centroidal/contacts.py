"""Contact geometry: the sole corners, normal and friction of each contact, per knot."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import cast

import numpy as np
import pinocchio as pin

from planner.exceptions import PlannerError
from planner.trajopt.layout_data import LayoutData
from robots import Robot, sole_corners
from tasks import Contact, Pose, TaskSpec, Vec3

# ---------------------------------------------------------------------------------------------
# Ankle joints
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True, kw_only=True)
class AnkleAxis:
    """One ankle joint of a foot, seen from its sole frame (fixed per robot, at the standing posture).

    With the foot's own inertia and weight neglected, the joint's torque is the moment of the
    sole's contact forces about this axis: ``tau = a . sum_i (r_i - o) x f_i``
    (``r_i`` the force points and ``f_i`` the forces, all in the sole frame).

    Attributes:
        joint: Pinocchio joint name (``right_ankle_pitch_joint``).
        axis: Unit joint axis in the sole frame (3,) [-].
        origin: Joint origin in the sole frame (3,) [m] (its z: the ankle's height above the sole).
        effort: The joint's torque limit (``model.effortLimit``) [N m].
    """

    joint: str
    axis: np.ndarray
    origin: np.ndarray
    effort: float

    def levers(self, points: np.ndarray) -> np.ndarray:
        """(n, 3) vectors ``l_i = a x (r_i - o)``: the torque is ``sum_i l_i . f_i`` (sole frame) [m]."""
        return np.cross(self.axis, np.asarray(points, dtype=float) - self.origin)


def ankle_axes(robot: Robot, frame: str) -> tuple[AnkleAxis, ...]:
    """The ankle joints of a sole frame, found from the kinematic chain, at the standing posture.

    From the joint that moves the sole frame's link up the chain, the revolute one-degree joints
    whose axis lies in the sole plane (pitch, roll), at most two, stopping at the first other
    joint or at an axis parallel to one already taken (G1: ``*_ankle_roll_joint`` then
    ``*_ankle_pitch_joint``, the knee's pitch axis ends the search; Talos: ``leg_*_6_joint``,
    ``leg_*_5_joint``). Their axes and origins are expressed in the sole frame at
    ``robot.q_standing`` (the parent joint's axis moves in that frame with the child's angle:
    neglected, the ankle roll stays small on flat ground). A joint without a finite positive
    effort limit is skipped (nothing to bound).

    Args:
        robot: The robot.
        frame: The sole frame's name.

    Returns:
        The ankle axes, nearest the sole first (empty: none found).
    """
    model = robot.model
    data = model.createData()
    q = robot.q_standing
    pin.computeJointJacobians(model, data, q)
    pin.framesForwardKinematics(model, data, q)
    fid = robot.frame_id(frame)
    oMs = data.oMf[fid]
    out: list[AnkleAxis] = []
    seen: list[np.ndarray] = []
    j = int(model.frames[fid].parentJoint)
    while j > 0 and len(seen) < 2:
        jm = model.joints[j]
        if jm.nv != 1:
            break
        S = pin.getJointJacobian(model, data, j, pin.LOCAL)[:, jm.idx_v]  # the joint's own motion, in its frame
        if np.linalg.norm(S[:3]) > 1e-9 or abs(np.linalg.norm(S[3:]) - 1.0) > 1e-9:
            break  # not a revolute joint about its origin
        axis = oMs.rotation.T @ (data.oMi[j].rotation @ S[3:])
        if abs(axis[2]) > 0.5 or any(abs(float(axis @ a)) > 0.9 for a in seen):
            break  # a yaw joint, or a second pitch (the knee): the ankle ends here
        seen.append(axis)
        effort = float(model.effortLimit[jm.idx_v])
        if np.isfinite(effort) and effort > 0.0:
            out.append(AnkleAxis(joint=str(model.names[j]), axis=axis, origin=np.array(oMs.actInv(data.oMi[j].translation)),
                                 effort=effort))
        j = int(model.parents[j])
    return tuple(out)


# ---------------------------------------------------------------------------------------------
# Contact geometry
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True, kw_only=True)
class ContactGeometry:
    """A contact bound to a robot: where its force points are and how its cone is oriented.

    Attributes:
        frame: Pinocchio frame name of the contact (the key of ``Plan.forces``).
        rotation: Contact frame orientation in the world (3, 3); column 2 is the normal.
        position: Contact frame origin in the world (3,) [m].
        points_in_world: Force application points (n, 3) [m]: the sole corners (n = 4) of a
            foot, the frame origin (n = 1) of a point contact.
        points_in_frame: The same points in the contact frame (n, 3) [m].
        friction_coefficient: Coulomb friction coefficient [-].
        ankle: The foot's ankle joints (:func:`ankle_axes`; empty for a point contact).
    """

    frame: str
    rotation: np.ndarray
    position: np.ndarray
    points_in_world: np.ndarray
    points_in_frame: np.ndarray
    friction_coefficient: float
    ankle: tuple[AnkleAxis, ...] = ()
    _levers: np.ndarray | None = field(default=None, init=False, repr=False, compare=False)

    def ankle_levers(self) -> np.ndarray:
        """(n_ankle, n_points, 3) levers of the force points about each ankle axis, in the contact frame [m]
        (computed on first use, then kept: read-only)."""
        if self._levers is None:
            levers = np.array([a.levers(self.points_in_frame) for a in self.ankle]).reshape(len(self.ankle),
                                                                                            self.n_points, 3)
            levers.setflags(write=False)
            object.__setattr__(self, "_levers", levers)  # a cache of a frozen record's function
        assert self._levers is not None
        return self._levers

    def ankle_torques(self, forces: np.ndarray) -> np.ndarray:
        """Moment (n_ankle,) of world point forces (n_points, 3) about each ankle axis [N m]: with the
        foot's inertia and weight neglected, the joint's torque is its opposite."""
        local = np.asarray(forces, dtype=float) @ self.rotation  # rows R^T f_i
        return np.einsum("jic,ic->j", self.ankle_levers(), local)

    @property
    def n_points(self) -> int:
        """Number of force points (4 for a sole, 1 for a point contact)."""
        return int(self.points_in_world.shape[0])

    @property
    def normal(self) -> np.ndarray:
        """Contact normal in the world (3,)."""
        return self.rotation[:, 2]


def contact_geometry(contact: Contact, robot: Robot, *, cop_margin: float = 0.0,
                     ankles: dict[str, tuple[AnkleAxis, ...]] | None = None) -> ContactGeometry:
    """Bind a spec :class:`~tasks.specs.Contact` to ``robot``: frame name, corners, friction.

    A foot frame (the robot's ``left_foot``/``right_foot``) gets the four corners of the profile's
    sole rectangle (mirrored for the right foot), moved inward by ``cop_margin``; any other frame
    is a point contact at its origin.

    Args:
        contact: The spec contact (frame by name or role, placement, optional friction).
        robot: The robot it applies to.
        cop_margin: Inward margin of the sole rectangle that the centre of pressure keeps [m].
        ankles: A cache frame -> :func:`ankle_axes` shared between calls (filled here).

    Returns:
        The bound geometry.

    Raises:
        PlannerError: ``cop_margin`` leaves no sole area.
        robots.exceptions.FrameNotFound: the frame does not exist on the robot.
    """
    fid = robot.frame_id(contact.frame)
    frame = robot.model.frames[fid].name
    rotation = pin.rpy.rpyToMatrix(*contact.placement.rpy)
    position = np.asarray(contact.placement.position, dtype=float)
    side = robot.foot_side(frame)
    ankle: tuple[AnkleAxis, ...] = ()
    if side is None:
        local = np.zeros((1, 3))
    else:
        ankles = {} if ankles is None else ankles
        if frame not in ankles:
            ankles[frame] = ankle_axes(robot, frame)
        ankle = ankles[frame]
        sole = robot.profile.sole
        if 2 * cop_margin >= min(sole.x_max - sole.x_min, sole.y_max - sole.y_min):
            raise PlannerError(
                f"CoP margin {cop_margin:g} m leaves no area of {robot.name}'s "
                f"{sole.x_max - sole.x_min:.3f} x {sole.y_max - sole.y_min:.3f} m sole"
            )
        local = sole_corners(sole, side, margin=cop_margin)
    mu = contact.friction_coefficient or robot.profile.friction_coefficient
    world = local @ rotation.T + position
    if contact.region is not None:  # a support region on another body part: its corners are the force points
        world = np.asarray(contact.region, dtype=float) @ rotation.T + position
    if contact.normal is not None:  # the cone opens about the surface's normal, not the frame's z axis
        rotation = normal_frame(np.asarray(contact.normal, dtype=float), rotation[:, 0])
    return ContactGeometry(
        frame=frame,
        rotation=rotation,
        position=position,
        points_in_world=world,
        points_in_frame=(world - position) @ rotation,
        friction_coefficient=float(mu),
        ankle=ankle,
    )


def normal_frame(normal: np.ndarray, x_hint: np.ndarray) -> np.ndarray:
    """A rotation (3, 3) whose z axis is the unit ``normal`` and whose x axis is ``x_hint`` made
    orthogonal to it (the world x or y axis when the hint is along the normal)."""
    z = normal / np.linalg.norm(normal)
    for hint in (x_hint, np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])):
        x = hint - (hint @ z) * z
        if np.linalg.norm(x) > 1e-6:
            x = x / np.linalg.norm(x)
            return np.column_stack([x, np.cross(z, x), z])
    raise AssertionError("unreachable: two orthogonal hints cannot both be along the normal")  # pragma: no cover


def contacts_per_knot(spec: TaskSpec, robot: Robot, t: Sequence[float] | np.ndarray, *, cop_margin: float = 0.0) -> tuple[tuple[ContactGeometry, ...], ...]:
    """Active contacts of ``spec`` at each knot time (the later phase at a phase boundary).

    Args:
        spec: The task.
        robot: The robot.
        t: Knot times [s].
        cop_margin: Inward sole margin [m].

    Returns:
        One tuple of bound contacts per knot.
    """
    ankles: dict[str, tuple[AnkleAxis, ...]] = {}
    bound = [tuple(contact_geometry(c, robot, cop_margin=cop_margin, ankles=ankles) for c in p.contacts)
             for p in spec.phases]
    return tuple(bound[spec.phase_at(float(tk))] for tk in t)


def _geometry_values(c: ContactGeometry, *, ankle: bool = False) -> np.ndarray:
    """Parameter values of one contact: world points, rotation (column-major), friction, then
    (``ankle``) its ankle levers (n_ankle, n_points, 3) row-major."""
    parts: list[np.ndarray] = [c.points_in_world.ravel(), c.rotation.ravel(order="F"), np.array([c.friction_coefficient])]
    if ankle:
        parts.append(c.ankle_levers().ravel())
    return np.concatenate(parts)


# ---------------------------------------------------------------------------------------------
# Integration with the trajectory NLP (planner.trajopt)
# ---------------------------------------------------------------------------------------------


def layout_contacts(lay: LayoutData, *, cop_margin: float = 0.0) -> tuple[tuple[ContactGeometry, ...], ...]:
    """Per knot of a :class:`planner.trajopt.layout_data.LayoutData`, the contacts it holds, as geometry.

    A contact holds at both ends of its phase (the layout's ``contacts_at``), so forces may act
    at the knot where a foot lifts off or touches down. The friction coefficient is the spec
    contact's own, else the robot profile's.

    Args:
        lay: The layout.
        cop_margin: Inward sole margin for the centre of pressure [m].

    Returns:
        One tuple of contacts per knot (0..N).
    """
    robot, spec = lay.robot, lay.spec
    starts = spec.phase_start_times()
    ankles: dict[str, tuple[AnkleAxis, ...]] = {}
    bound: dict[tuple, ContactGeometry] = {}  # a contact held over many knots is bound once
    out = []
    for k, active in enumerate(lay.contacts_at):
        tk = float(lay.t[k])
        mus: dict[int, float | None] = {}
        for i, ph in enumerate(spec.phases):
            if starts[i] - 1e-9 <= tk <= starts[i] + ph.duration + 1e-9:
                for c in ph.contacts:
                    mus[robot.frame_id(c.frame)] = c.friction_coefficient
        geos = []
        for fid, (_frame, M) in active.items():
            position = cast(Vec3, tuple(float(x) for x in M.translation))
            rpy = cast(Vec3, tuple(float(x) for x in pin.rpy.matrixToRpy(M.rotation)))
            key = (fid, position, rpy, mus.get(fid))
            if key not in bound:
                contact = Contact(frame=robot.model.frames[fid].name, placement=Pose(position=position, rpy=rpy),
                                  friction_coefficient=mus.get(fid))
                bound[key] = contact_geometry(contact, robot, cop_margin=cop_margin, ankles=ankles)
            geos.append(bound[key])
        out.append(tuple(geos))
    return tuple(out)


def contact_geometry_points(robot: Robot, frame: str) -> np.ndarray | None:
    """The full (unshrunk) sole rectangle corners (4, 2) of a foot frame in its frame, None otherwise."""
    side = robot.foot_side(frame)
    if side is None:
        return None
    return sole_corners(robot.profile.sole, side)[:, :2]
