"""Fragments and the builder that primitives use to write them.

A :class:`Fragment` is one action compiled into spec pieces on the absolute time line of
the final :class:`~tasks.specs.TaskSpec`: consecutive phases starting at ``t0`` and the
targets that belong to them. :mod:`tasks.compose` concatenates and overlays fragments.

All times are placed on the knot grid of the spec (multiples of ``dt``): a primitive
describes its motion in *nominal* seconds, the :class:`FragmentBuilder` stretches it to the
fragment's duration (overlays are stretched to the longest action of their group) and snaps
every phase boundary and target time to a knot, so the planner never has to round.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import cast

import numpy as np
import pinocchio as pin

from robots import Robot
from tasks.actions import Action
from tasks.exceptions import TaskDefinitionError
from tasks.primitives.geometry import Stance, StandingGeometry, _clean, standing_geometry
from tasks.specs import (
    CoMBounds,
    CoMTarget,
    Contact,
    FrameTarget,
    Grasp,
    JointTarget,
    OptVec3,
    Phase,
    Priority,
    Push,
)

DEFAULT_DT = 0.075  # [s] knot spacing of compiled specs (the TaskSpec default)
TIME_DIGITS = 9  # times are rounded to 1 ns so that sums of knots compare exactly

# Body parts an action can drive; two overlaid actions must not share one.
PARTS = ("legs", "com", "torso", "head", "left_arm", "right_arm")


def knot_time(k: int, dt: float) -> float:
    """Time of knot ``k`` [s], rounded to :data:`TIME_DIGITS`."""
    return round(k * dt, TIME_DIGITS)


def to_knot(t: float, dt: float) -> int:
    """Index of the knot at time ``t`` (which must be on the grid)."""
    k = round(t / dt)
    if abs(k * dt - t) > 1e-6:
        raise TaskDefinitionError(f"time {t:g} s is not on the knot grid of dt = {dt:g} s")
    return int(k)


@dataclass(frozen=True, slots=True, kw_only=True)
class Fragment:
    """One action compiled to spec pieces, on the absolute time line.

    Attributes:
        action: The action it came from.
        label: Prefix of every target name (``"2 wave"``).
        t0: Start time [s] (on the knot grid).
        phases: Consecutive phases from ``t0``; their durations sum to ``duration``.
        targets, com_targets, com_bounds, joint_targets: Spec items with absolute times.
        parts: Body parts the action drives (see :data:`PARTS`).
        changes_contacts: True when the phases differ from standing on both feet.
        dynamic: Needs the planner's CoM dynamics (steps, jumps).
        end_stance: Where the feet are at the end.
        grasps: Objects a hand takes (or lets go of) in this action.
        pushes: Objects a hand pushes in this action (the certificate checks how far they moved).
        holds: Names of targets that stay held after the action, until the next action that
            drives one of its parts or moves the feet (or the end of the motion): a held object.
        end_contacts: Contacts besides the soles held after the action, until the next one (the
            thighs on a seat after ``sit_down``): the standing phases between and after keep them.
    """

    action: Action
    label: str
    t0: float
    phases: tuple[Phase, ...]
    targets: tuple[FrameTarget, ...] = ()
    com_targets: tuple[CoMTarget, ...] = ()
    com_bounds: tuple[CoMBounds, ...] = ()
    joint_targets: tuple[JointTarget, ...] = ()
    parts: frozenset[str] = frozenset()
    changes_contacts: bool = False
    dynamic: bool = False
    end_stance: Stance
    grasps: tuple[Grasp, ...] = ()
    holds: tuple[str, ...] = ()
    pushes: tuple[Push, ...] = ()
    end_contacts: tuple[Contact, ...] = ()

    @property
    def duration(self) -> float:
        """Length [s]."""
        return round(sum(p.duration for p in self.phases), TIME_DIGITS)

    @property
    def t_end(self) -> float:
        """End time [s]."""
        return round(self.t0 + self.duration, TIME_DIGITS)


@dataclass(frozen=True, slots=True, kw_only=True)
class Primitive:
    """A registered motion primitive: how long it takes and how it compiles.

    Attributes:
        name: Registry name (``squat``).
        nominal_duration: ``(params, robot) -> seconds`` at the requested speed.
        build: ``(builder) -> Fragment``: writes phases and targets through the builder.
        parts: ``(params) -> body parts`` the action drives.
        check: ``(params, robot) -> None``: robot-specific range checks (TaskDefinitionError).
        limits: ``(robot) -> {param: description}`` robot-specific limits for ``wbmp actions``.
        available: False for primitives registered before their implementation lands.
        size_limits: ``(params, robot) -> {param: largest value}`` for the sizes (lengths,
            depths, heights, angles) the robot bounds, given the other parameters (a step's
            length depends on its direction); :func:`fit_defaults` keeps unstated sizes within them.
    """

    name: str
    nominal_duration: Callable[[dict, Robot], float]
    build: Callable[[FragmentBuilder], Fragment]
    parts: Callable[[dict], frozenset[str]]
    check: Callable[[dict, Robot], None] = lambda params, robot: None
    limits: Callable[[Robot], dict[str, str]] = lambda robot: {}
    available: bool = True
    dynamic: bool = False
    size_limits: Callable[[dict, Robot], dict[str, float]] = lambda params, robot: {}


class FragmentBuilder:
    """Writes one fragment. Primitives give times in nominal seconds from their own start.

    Attributes:
        action, params, robot: The action, its resolved parameters and the robot.
        geometry: The robot's standing numbers.
        stance: Where the robot stands at the start.
        scale: Stretch factor from nominal to actual time (>= 1).
        nominal: Nominal duration [s].
    """

    def __init__(self, action: Action, robot: Robot, *, t0: float, dt: float, nominal: float,
                 duration: float | None, stance: Stance, label: str) -> None:
        self.action = action
        self.params = dict(action.params)
        self.robot = robot
        self.geometry: StandingGeometry = standing_geometry(robot)
        self.stance = stance
        self.dt = dt
        self.label = label
        self.k0 = to_knot(t0, dt)
        self.nominal = nominal
        total = nominal if duration is None else max(duration, nominal)
        self.n_knots = max(1, math.ceil(total / dt - 1e-9))
        self.scale = self.n_knots * dt / nominal
        self._transform = stance.transform_from_standing(robot)
        self._phases: list[tuple[str, int, tuple[Contact, ...], float]] = []
        self.targets: list[FrameTarget] = []
        self.com_targets: list[CoMTarget] = []
        self.com_bounds: list[CoMBounds] = []
        self.joint_targets: list[JointTarget] = []
        self.grasps: list[Grasp] = []
        self.holds: list[str] = []
        self.pushes: list[Push] = []
        self.end_stance = stance
        self.end_contacts: tuple[Contact, ...] = ()

    # --- time ---------------------------------------------------------------------------
    def knot(self, tau: float) -> int:
        """Absolute knot index of nominal time ``tau`` [s] from the fragment start."""
        k = round(tau * self.scale / self.dt)
        return self.k0 + min(max(k, 0), self.n_knots)

    def t(self, tau: float) -> float:
        """Absolute time [s] of nominal time ``tau``, snapped to the knot grid."""
        return knot_time(self.knot(tau), self.dt)

    def window(self, tau0: float, tau1: float) -> tuple[float, float]:
        """Absolute (t_start, t_end) [s] of a nominal window."""
        return (self.t(tau0), self.t(tau1))

    @property
    def t0(self) -> float:
        """Absolute start time [s]."""
        return knot_time(self.k0, self.dt)

    @property
    def t_end(self) -> float:
        """Absolute end time [s]."""
        return knot_time(self.k0 + self.n_knots, self.dt)

    # --- geometry -----------------------------------------------------------------------
    def world(self, point_in_standing) -> tuple[float, float, float]:
        """A standing-frame point carried to the current stance (world) [m]."""
        return _clean(self._transform.act(np.asarray(point_in_standing, dtype=float)))

    def world_rotation(self, rotation_in_standing: np.ndarray) -> tuple[float, float, float]:
        """A standing-frame orientation carried to the current stance, as rpy [rad]."""
        return _clean(pin.rpy.matrixToRpy(self._transform.rotation @ rotation_in_standing))

    def world_z(self, z_in_standing: float) -> float:
        """A standing height carried to the current stance [m]."""
        return float(z_in_standing + self._transform.translation[2])

    def contacts(self, sides: Iterable[str] = ("left", "right")) -> tuple[Contact, ...]:
        """Contacts of the given soles at their current placements."""
        return tuple(Contact(frame=self.robot.frame(f"{s}_foot"), placement=self.stance.sole(s)) for s in sides)

    # --- writing ------------------------------------------------------------------------
    def phase(self, name: str, tau_end: float, contacts: tuple[Contact, ...] | None = None, *,
              swing_height: float = 0.05) -> None:
        """Append a phase that ends at nominal time ``tau_end`` (both feet down by default)."""
        contacts = self.contacts() if contacts is None else contacts
        self._phases.append((name, self.knot(tau_end), contacts, swing_height))

    def name(self, what: str) -> str:
        """A target name unique within the spec: ``"<label>: <what>"``."""
        return f"{self.label}: {what}"

    def frame_target(self, what: str, role: str, *, position=None, rpy=None, axes=(True, True, True),
                     time: float | None = None, window: tuple[float, float] | None = None,
                     tolerance: float = 0.01, orientation_tolerance: float = 0.05,
                     priority: Priority = Priority.HARD, weight: float = 100.0, touch: str | None = None,
                     meets: str | None = None) -> None:
        """Add a :class:`FrameTarget`; ``time``/``window`` in nominal seconds, values in world."""
        self.targets.append(FrameTarget(
            name=self.name(what), frame=self.robot.frame(role), position=position, rpy=rpy,
            axes=tuple(axes), time=None if time is None else self.t(time),
            window=None if window is None else self.window(*window), tolerance=tolerance,
            orientation_tolerance=orientation_tolerance, priority=priority, weight=weight, touch=touch,
            meets=None if meets is None else self.robot.frame(meets),
        ))

    def com_target(self, what: str, position, *, time: float | None = None,
                   window: tuple[float, float] | None = None, tolerance: float = 0.01,
                   priority: Priority = Priority.HARD, weight: float = 100.0) -> None:
        """Add a :class:`CoMTarget`; ``time``/``window`` in nominal seconds."""
        self.com_targets.append(CoMTarget(
            name=self.name(what), position=cast(OptVec3, tuple(None if v is None else float(v) for v in position)),
            time=None if time is None else self.t(time),
            window=None if window is None else self.window(*window),
            tolerance=tolerance, priority=priority, weight=weight,
        ))

    def finish(self, parts: frozenset[str], *, dynamic: bool = False) -> Fragment:
        """The fragment written so far (its last phase must end at the nominal duration)."""
        if not self._phases:
            raise TaskDefinitionError(f"{self.action.name}: the primitive wrote no phase")
        phases, k = [], self.k0
        for i, (name, k_end, contacts, swing) in enumerate(self._phases):
            if i == len(self._phases) - 1:
                k_end = self.k0 + self.n_knots
            if k_end <= k:
                raise TaskDefinitionError(
                    f"{self.action.name}: phase {name!r} is shorter than one knot (dt = {self.dt:g} s); "
                    "use a longer duration"
                )
            phases.append(Phase(name=f"{self.label}: {name}", duration=knot_time(k_end - k, self.dt),
                                contacts=contacts, swing_height=swing))
            k = k_end
        standing = self.contacts()
        changes = any(p.contacts != standing for p in phases) or self.end_stance != self.stance
        return Fragment(
            action=self.action, label=self.label, t0=self.t0, phases=tuple(phases),
            targets=tuple(self.targets), com_targets=tuple(self.com_targets),
            com_bounds=tuple(self.com_bounds), joint_targets=tuple(self.joint_targets),
            parts=frozenset(parts), changes_contacts=changes, dynamic=dynamic, end_stance=self.end_stance,
            grasps=tuple(self.grasps), holds=tuple(self.holds), pushes=tuple(self.pushes),
            end_contacts=self.end_contacts,
        )


FIT_GRID = {"m": 0.01, "rad": 0.01}  # a fitted default is the limit rounded down to this grid


def fit_defaults(primitive: Primitive, action: Action, robot: Robot) -> Action:
    """``action`` with every size it did not state chosen within ``robot``'s limits.

    A parameter in ``action.defaulted`` whose registry default is beyond the robot's limit
    (:attr:`Primitive.size_limits`, given the other parameters) becomes that limit, rounded down
    to :data:`FIT_GRID` (1 cm, 0.01 rad): "take two steps to the left" on g1 steps 0.10 m, its
    longest side step, where the registry says 0.15 m. A limit below the parameter's minimum is
    left alone (the primitive's check then says why the robot cannot do the action), and a stated
    value is never changed (beyond the limit, the check refuses it and names the limit).
    """
    from tasks.actions import get_action

    if not action.defaulted:
        return action
    params = dict(action.params)
    limits = primitive.size_limits(params, robot)
    changed = False
    for name, limit in limits.items():
        value = params.get(name)
        if name not in action.defaulted or not isinstance(value, float) or abs(value) <= limit + 1e-12:
            continue
        schema = get_action(action.name).param(name)
        grid = FIT_GRID.get(schema.unit, 0.01)
        fitted = math.floor(limit / grid + 1e-9) * grid
        fitted = round(fitted, 9)
        if schema.minimum is not None and fitted < max(schema.minimum, 0.0) - 1e-12:
            continue
        params[name] = math.copysign(fitted, value)
        changed = True
    if not changed:
        return action
    return Action(name=action.name, params=params, overlay=action.overlay, defaulted=action.defaulted)


def rest_targets(b: FragmentBuilder, roles: Iterable[str], *, tau: float) -> None:
    """Soft targets that bring frames back to their standing positions at nominal time ``tau``."""
    for role in roles:
        b.frame_target(f"{role.replace('_', ' ')} back at rest", role,
                       position=b.world(b.geometry.position(role)), time=tau,
                       tolerance=0.02, priority=Priority.SOFT, weight=100.0)


def arms_of(arm: str) -> tuple[str, ...]:
    """('left',), ('right',) or ('left', 'right') for an ``arm`` parameter."""
    return ("left", "right") if arm == "both" else (arm,)


__all__ = [
    "DEFAULT_DT",
    "PARTS",
    "Fragment",
    "FragmentBuilder",
    "Primitive",
    "arms_of",
    "fit_defaults",
    "knot_time",
    "rest_targets",
    "to_knot",
]
