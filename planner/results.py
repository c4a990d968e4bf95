"""Planner results: the planned motion, solver statistics and the constraint report.

:class:`Check` (with :class:`CheckKind`) is also the record of the simulation's certificate
(``sim.certificate``): one check type for the planner's report and the certificate."""

from __future__ import annotations

import enum
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from tasks import TaskSpec


class SolveStatus(enum.Enum):
    """Outcome of a trajectory optimization; the value is the human-readable message."""

    SOLVED = "solved"
    SOLVED_INACCURATE = "solved to acceptable (not full) accuracy"
    INFEASIBLE = "the requested task is infeasible"
    MAX_ITERATIONS = "iteration limit reached"
    NUMERICAL_ERROR = "the solver reported a numerical failure"
    NOT_RUN = "the solver was not run"

    @property
    def ok(self) -> bool:
        """True for SOLVED and SOLVED_INACCURATE."""
        return self in (SolveStatus.SOLVED, SolveStatus.SOLVED_INACCURATE)


@dataclass(frozen=True, slots=True, kw_only=True)
class SolverStats:
    """How the solve went.

    Attributes:
        status: Mapped solver outcome.
        iterations: IPOPT iterations.
        build_time: Time to build (or load from cache) the NLP and solver [s].
        solve_time: Time inside the solver [s].
        cache: ``"built"`` (first ever), ``"disk"`` (loaded compiled code), ``"memory"`` (warm).
        objective: Final cost value.
        n_variables, n_constraints: Problem size.
        backend: ``"ipopt"``.
        raw_status: The backend's own status string.
        seed: Where the solve started when not from the task's own guess: ``"library (distance
            0.0300)"``, a stored solution of the same structure (:mod:`planner.trajopt.library`);
            empty otherwise.
    """

    status: SolveStatus
    iterations: int = 0
    build_time: float = 0.0
    solve_time: float = 0.0
    cache: str = "built"
    objective: float = float("nan")
    n_variables: int = 0
    n_constraints: int = 0
    backend: str = "ipopt"
    raw_status: str = ""
    seed: str = ""


class CheckKind(enum.Enum):
    """What a :class:`Check` checks; code finds checks by kind (and subject), never by name.

    The planner's report (a constraint group's worst violation over the horizon):
    ``CONTACT_POSITION``, ``CONTACT_ORIENTATION``, ``SWING_CLEARANCE`` (subject: the frame),
    ``COM_SUPPORT_POLYGON``, ``COM_SUPPORT_POLYGON_AT_REST``, ``COM_BOX`` (subject: the bound's
    name), ``TARGET_POSITION``, ``TARGET_ORIENTATION``, ``COM_TARGET`` (subject: the target's name),
    ``JOINT_POSITION_LIMITS``, ``JOINT_VELOCITY_LIMITS``; a dynamic plan adds ``COM_DYNAMICS``,
    ``FRICTION_CONE``, ``CENTRE_OF_PRESSURE`` (subject: the frame), ``FORCE_WITHOUT_CONTACT``,
    ``SWING_SOLE_CORNERS``, and the plan's own full dynamics recomputed with RNEA:
    ``FULL_DYNAMICS_ZMP`` (its ZMP in the support polygon) and ``FULL_DYNAMICS_WRENCH`` (the
    planned contact moment against the one the motion needs), ``ANKLE_TORQUE`` (subject: the
    ankle joint; the planned forces' moment about it against its bound); every plan adds ``SELF_COLLISION``
    (subject: the closest link pair, ``a/b``), and a plan with a scene ``SCENE_COLLISION`` (subject:
    the closest link and object, ``link/object``).

    The simulation's certificate: ``BASE_HEIGHT``, ``BASE_TILT``, ``UNPLANNED_CONTACTS``,
    ``FOOT_PLACEMENT``, ``FOOT_SLIP`` (subject: ``left_foot``/``right_foot``, or the frame),
    ``PEAK_TORQUE``, ``QP_FAILURES``, ``COM_TRACKING``, ``HAND_TRACKING`` (subject: the hand's
    role), and ``TARGET_POSITION`` (there its orientation must also be within its tolerance +
    0.1 rad) and ``COM_TARGET`` as measured in the simulation, ``SELF_COLLISION`` (shared with the
    planner's report) and ``SCENE_COLLISION`` (subject there: the closest pair in words, "left
    forearm / pelvis"). A plan with grasps adds ``PAYLOAD_TORQUE`` (subject: the grasp), its
    certificate ``OBJECT_GRASP``, ``OBJECT_LIFT``, ``OBJECT_HELD`` (held to the end: still in the
    hand), ``OBJECT_PLACE``, ``OBJECT_OFFER`` (held out for a hand-over),
    ``OBJECT_PUSH`` (moved by a push; subject: the object),
    ``OBJECT_MOVED`` and ``OBJECT_TIPPED`` (the objects no hand holds). A plan with a support-region
    contact on an object (a thigh on a seat, :mod:`sim.seat`) adds ``SEAT_PLACEMENT``, ``SEAT_SLIP``
    and ``SEAT_CONTACT`` (subject: the contact frame; ``others``: no other link touches the seat). The intent lines
    (:mod:`sim.intent`): ``INTENT_CONTACTS`` (a sole's lift-offs and touch-downs as planned;
    subject: the foot), ``INTENT_FLIGHT`` (both soles off the floor for a jump's or hop's flights),
    ``INTENT_AMPLITUDE`` (a shift, turn or rise relative to the plan), ``INTENT_STEPS`` (step
    lengths and turn angles), ``INTENT_WORDS`` (what the action's word means: the clap's hands
    meet, the salute's hand at the head, the point's direction). ``SELF_COLLISION_MESH``: every
    pair of links on the URDF meshes (coal; :mod:`sim.meshcheck`).

    ``ESTOP``: the run was stopped by the E-stop (subject: the trigger; docs/safety.md).

    ``RECORDED``: a check read back from a motion file, whose report stores no kind.
    """

    CONTACT_POSITION = "contact_position"
    CONTACT_ORIENTATION = "contact_orientation"
    SWING_CLEARANCE = "swing_clearance"
    COM_SUPPORT_POLYGON = "com_support_polygon"
    COM_SUPPORT_POLYGON_AT_REST = "com_support_polygon_at_rest"
    COM_BOX = "com_box"
    TARGET_POSITION = "target_position"
    TARGET_ORIENTATION = "target_orientation"
    COM_TARGET = "com_target"
    JOINT_POSITION_LIMITS = "joint_position_limits"
    JOINT_VELOCITY_LIMITS = "joint_velocity_limits"
    COM_DYNAMICS = "com_dynamics"
    FRICTION_CONE = "friction_cone"
    CENTRE_OF_PRESSURE = "centre_of_pressure"
    FORCE_WITHOUT_CONTACT = "force_without_contact"
    SWING_SOLE_CORNERS = "swing_sole_corners"
    FULL_DYNAMICS_ZMP = "full_dynamics_zmp"
    FULL_DYNAMICS_WRENCH = "full_dynamics_wrench"
    ANKLE_TORQUE = "ankle_torque"
    SELF_COLLISION = "self_collision"
    BASE_HEIGHT = "base_height"
    BASE_TILT = "base_tilt"
    UNPLANNED_CONTACTS = "unplanned_contacts"
    FOOT_PLACEMENT = "foot_placement"
    FOOT_SLIP = "foot_slip"
    PEAK_TORQUE = "peak_torque"
    QP_FAILURES = "qp_failures"
    COM_TRACKING = "com_tracking"
    HAND_TRACKING = "hand_tracking"
    SCENE_COLLISION = "scene_collision"
    PAYLOAD_TORQUE = "payload_torque"
    OBJECT_GRASP = "object_grasp"
    OBJECT_LIFT = "object_lift"
    OBJECT_HELD = "object_held"
    OBJECT_PLACE = "object_place"
    OBJECT_OFFER = "object_offer"
    OBJECT_PUSH = "object_push"
    OBJECT_MOVED = "object_moved"
    INTENT_CONTACTS = "intent_contacts"
    INTENT_FLIGHT = "intent_flight"
    INTENT_AMPLITUDE = "intent_amplitude"
    INTENT_STEPS = "intent_steps"
    INTENT_WORDS = "intent_words"
    SELF_COLLISION_MESH = "self_collision_mesh"
    OBJECT_TIPPED = "object_tipped"
    SEAT_PLACEMENT = "seat_placement"
    SEAT_SLIP = "seat_slip"
    SEAT_CONTACT = "seat_contact"
    ESTOP = "estop"
    RECORDED = "recorded"


@dataclass(frozen=True, slots=True, kw_only=True)
class Check:
    """One check with its number and verdict: a constraint group of the planner's report, or a
    physical check of the simulation's certificate.

    A planner check (:meth:`constraint`) has ``value`` = the group's worst violation (>= 0) and
    ``limit`` = the accepted violation; ``violation`` and ``tolerance`` name them so.

    Attributes:
        name: What was checked, in words ("left_foot contact position", "base height",
            "target 'wave #1'"); shown and stored, never parsed.
        kind: What was checked, for code (:class:`CheckKind`).
        value: The measured worst value [unit].
        limit: The accepted bound [unit].
        unit: ``m``, ``rad``, ``rad/s``, ``N``, ``%``, ``count``...
        time: Time of the worst value (or of the first violation) [s].
        ok: Verdict.
        message: The failure in words (empty when ok, and for the planner's checks).
        upper: True when ``value`` must stay <= ``limit``, False when it must stay >= ``limit``.
        subject: The spec item, frame or role checked (a target's or bound's name, a frame,
            ``left_foot``); empty when the check is about the whole robot.

    ``kind`` and ``subject`` do not take part in equality: a check read back from a motion file
    (which stores neither) equals the one that was written.
    """

    name: str
    kind: CheckKind = field(compare=False)
    value: float
    limit: float
    unit: str
    time: float
    ok: bool
    message: str = ""
    upper: bool = True
    subject: str = field(default="", compare=False)

    @classmethod
    def constraint(cls, *, name: str, kind: CheckKind, violation: float, tolerance: float, unit: str,
                   time: float, subject: str = "") -> Check:
        """A constraint group's check: ok when its worst ``violation`` is within ``tolerance``."""
        return cls(name=name, kind=kind, value=violation, limit=tolerance, unit=unit, time=time,
                   ok=bool(violation <= tolerance), subject=subject)

    @property
    def violation(self) -> float:
        """A constraint group's worst violation (``value``) [unit]."""
        return self.value

    @property
    def tolerance(self) -> float:
        """A constraint group's accepted violation (``limit``) [unit]."""
        return self.limit

    def to_dict(self) -> dict[str, Any]:
        """The certificate's JSON form of the check (NaN/inf become None)."""
        return {
            "name": self.name,
            "value": _json_float(self.value),
            "limit": _json_float(self.limit),
            "unit": self.unit,
            "ok": bool(self.ok),
            "time": _json_float(self.time),
            "message": self.message,
            "upper": self.upper,
        }


#: The planner report's name for :class:`Check` (kept for existing imports).
ConstraintCheck = Check


def _json_float(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


@dataclass(frozen=True, eq=False, kw_only=True)
class Plan:
    """A planned whole-body motion on a uniform time grid.

    Attributes:
        robot: Robot name.
        spec: The TaskSpec it satisfies.
        t: Knot times (T,) [s].
        q: Configurations (T, nq), Pinocchio order, free-flyer quaternion (x, y, z, w).
        v: Velocities (T, nv) [m/s, rad/s], Pinocchio convention (base linear/angular in the
            base frame).
        a: Accelerations (T, nv).
        com: Centre of mass (T, 3) [m].
        forces: Contact force per contact frame (T, 3) in the world [N], for dynamic plans
            (zero while the contact is inactive); empty for kinematic plans.
        stats: Solver statistics.
        checks: Constraint report, one entry per group.
        diagnosis: Task-level explanation of a failure (empty when ok).
    """

    robot: str
    spec: TaskSpec
    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    com: np.ndarray
    forces: Mapping[str, np.ndarray] = field(default_factory=dict)
    stats: SolverStats
    checks: tuple[Check, ...] = ()
    diagnosis: str = ""
    extras: Mapping[str, Any] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        """Solver succeeded and every constraint group is within tolerance."""
        return self.stats.status.ok and all(c.ok for c in self.checks)

    @property
    def dt(self) -> float:
        """Knot spacing [s]."""
        return float(self.t[1] - self.t[0]) if len(self.t) > 1 else 0.0

    def active_contacts(self, k: int) -> tuple[str, ...]:
        """Contact frames active at knot ``k``."""
        return tuple(c.frame for c in self.spec.phases[self.spec.phase_at(float(self.t[k]))].contacts)

    def summary(self) -> str:
        """A short multi-line table of the solve and the constraint report."""
        s = self.stats
        lines = [
            f"plan: {s.status.value} in {s.iterations} iterations "
            f"(build {s.build_time:.2f} s [{s.cache}], solve {s.solve_time:.2f} s), "
            f"{len(self.t)} knots over {self.t[-1]:.2f} s, {s.n_variables} variables, {s.n_constraints} constraints",
        ]
        if s.seed:
            lines.append(f"  started from a stored solution of this structure: {s.seed}")
        for c in self.checks:
            mark = "ok  " if c.ok else "FAIL"
            lines.append(f"  {mark} {c.name:<40} {c.violation:10.2e} {c.unit:<6} (tol {c.tolerance:.0e}, t = {c.time:.2f} s)")
        if self.diagnosis:
            lines.append(f"  diagnosis: {self.diagnosis}")
        return "\n".join(lines)
