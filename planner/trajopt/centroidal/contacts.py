"""Contact geometry: the sole corners, normal and friction of each contact, per knot."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, cast

import numpy as np
import pinocchio as pin

from planner.exceptions import PlannerError
from robots.contact import sole_corners
from robots.model import Robot
from tasks.specs import Contact, Pose, TaskSpec, Vec3

if TYPE_CHECKING:
    from planner.trajopt.layout import Layout

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
    """

    frame: str
    rotation: np.ndarray
    position: np.ndarray
    points_in_world: np.ndarray
    points_in_frame: np.ndarray
    friction_coefficient: float

    @property
    def n_points(self) -> int:
        """Number of force points (4 for a sole, 1 for a point contact)."""
        return int(self.points_in_world.shape[0])

    @property
    def normal(self) -> np.ndarray:
        """Contact normal in the world (3,)."""
        return self.rotation[:, 2]


def contact_geometry(contact: Contact, robot: Robot, *, cop_margin: float = 0.0) -> ContactGeometry:
    """Bind a spec :class:`~tasks.specs.Contact` to ``robot``: frame name, corners, friction.

    A foot frame (the robot's ``left_foot``/``right_foot``) gets the four corners of the profile's
    sole rectangle (mirrored for the right foot), moved inward by ``cop_margin``; any other frame
    is a point contact at its origin.

    Args:
        contact: The spec contact (frame by name or role, placement, optional friction).
        robot: The robot it applies to.
        cop_margin: Inward margin of the sole rectangle that the centre of pressure keeps [m].

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
    if side is None:
        local = np.zeros((1, 3))
    else:
        sole = robot.profile.sole
        if 2 * cop_margin >= min(sole.x_max - sole.x_min, sole.y_max - sole.y_min):
            raise PlannerError(
                f"CoP margin {cop_margin:g} m leaves no area of {robot.name}'s "
                f"{sole.x_max - sole.x_min:.3f} x {sole.y_max - sole.y_min:.3f} m sole"
            )
        local = sole_corners(sole, side, margin=cop_margin)
    mu = contact.friction_coefficient or robot.profile.friction_coefficient
    return ContactGeometry(
        frame=frame,
        rotation=rotation,
        position=position,
        points_in_world=local @ rotation.T + position,
        points_in_frame=local,
        friction_coefficient=float(mu),
    )


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
    bound = [tuple(contact_geometry(c, robot, cop_margin=cop_margin) for c in p.contacts) for p in spec.phases]
    return tuple(bound[spec.phase_at(float(tk))] for tk in t)


def _geometry_values(c: ContactGeometry) -> np.ndarray:
    return np.concatenate([c.points_in_world.ravel(), c.rotation.ravel(order="F"), [c.friction_coefficient]])


# ---------------------------------------------------------------------------------------------
# Integration with the trajectory NLP (planner.trajopt)
# ---------------------------------------------------------------------------------------------


def layout_contacts(lay: Layout, *, cop_margin: float = 0.0) -> tuple[tuple[ContactGeometry, ...], ...]:
    """Per knot of a :class:`planner.trajopt.layout.Layout`, the contacts it holds, as geometry.

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
            contact = Contact(
                frame=robot.model.frames[fid].name,
                placement=Pose(position=cast(Vec3, tuple(float(x) for x in M.translation)),
                               rpy=cast(Vec3, tuple(float(x) for x in pin.rpy.matrixToRpy(M.rotation)))),
                friction_coefficient=mus.get(fid),
            )
            geos.append(contact_geometry(contact, robot, cop_margin=cop_margin))
        out.append(tuple(geos))
    return tuple(out)


def contact_geometry_points(robot: Robot, frame: str) -> np.ndarray | None:
    """The full (unshrunk) sole rectangle corners (4, 2) of a foot frame in its frame, None otherwise."""
    side = robot.foot_side(frame)
    if side is None:
        return None
    return sole_corners(robot.profile.sole, side)[:, :2]
