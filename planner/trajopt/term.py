"""One constraint or cost at one knot (:class:`Term`), the registry of term kinds, and the knots a
timed item applies to.

A term kind is a subclass of :class:`Term` (``docs/terms.md``): it names its ``kind`` (the key of
the registry :data:`TERM_KINDS` and the first entry of its ``structure``), lays out its rows (a
constructor classmethod: structure, parameters, bounds), and holds its CasADi expression
(:meth:`Term.expression`), its numpy residual (:meth:`Term.residual`, the twin the tests compare
with) and its diagnosis sentence (:meth:`Term.diagnosis`). The kinematic kinds live in
:mod:`planner.trajopt.kinds`; self-collision and scene collision beside their screening
(:mod:`planner.trajopt.collision`, :mod:`planner.trajopt.scene_collision`).

A leaf of ``planner.trajopt``: the modules that add terms to a layout (self-collision, scene
objects) import these without importing :mod:`planner.trajopt.layout`, whose kinematic initial
guess imports the nominal motion, which screens against the collision model.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
import pinocchio as pin

from planner.results import Check

if TYPE_CHECKING:
    from planner.results import CheckKind
    from robots.model import Robot

#: Every term kind by its ``kind``: filled when a subclass of :class:`Term` is defined.
TERM_KINDS: dict[str, type[Term]] = {}


@dataclass(eq=False)
class Term:
    """One constraint or cost at one knot; a subclass per kind (:data:`TERM_KINDS`).

    Attributes:
        kind: (class attribute) The kind's name: ``contact``, ``clearance``, ``polygon``,
            ``com_box``, ``frame_pos``, ``frame_rot``, ``com_pos``, ``joint``, ``frame_rel``
            (two hands holding one object: a closed chain), ``collision``, ``scene``.
        check_kinds: (class attribute) The report's checks that measure what the kind constrains
            (its diagnosis sentence is used for them).
        knot: Knot index (0..N).
        structure: Hashable description of the expression (no numeric values); its first entry
            is ``kind``. It keys the solver cache.
        params: Numeric parameters fed to the NLP (flattened).
        lower, upper: Bounds of the constraint rows (empty for a cost term).
        label: What the report calls it ("left_foot contact", "target 'reach'").
        item: The spec item it comes from (for diagnoses).
        phase: Name of the phase at this knot.
    """

    kind: ClassVar[str] = ""
    check_kinds: ClassVar[tuple[CheckKind, ...]] = ()

    knot: int
    structure: tuple
    params: np.ndarray = field(default_factory=lambda: np.zeros(0))
    lower: np.ndarray = field(default_factory=lambda: np.zeros(0))
    upper: np.ndarray = field(default_factory=lambda: np.zeros(0))
    label: str = ""
    item: object = None
    phase: str = ""

    def __init_subclass__(cls, **kwargs) -> None:
        super().__init_subclass__(**kwargs)
        if not cls.kind:
            return  # an abstract intermediate class
        known = TERM_KINDS.get(cls.kind)
        if known is not None and known.__qualname__ != cls.__qualname__:
            raise TypeError(f"term kind {cls.kind!r} is defined twice: {known.__qualname__} and {cls.__qualname__}")
        TERM_KINDS[cls.kind] = cls

    @property
    def is_cost(self) -> bool:
        """True when the term only adds to the cost."""
        return len(self.lower) == 0

    @property
    def n_rows(self) -> int:
        """Number of constraint rows."""
        return len(self.lower)

    def frames(self) -> tuple[int, ...]:
        """Frame ids whose placement the expression reads (computed once per stage)."""
        return ()

    def expression(self, p, kin: StageKinematics) -> tuple:
        """(constraint rows or None, cost) as CasADi SX of the stage's kinematics ``kin``, with
        ``p`` the symbol of this term's parameters (as many as :attr:`params`)."""
        raise NotImplementedError(f"term kind {self.kind!r} has no CasADi expression")

    def residual(self, kin: NumericKinematics) -> np.ndarray:
        """The same as :meth:`expression` in numpy at a configuration, with :attr:`params`: the
        rows (``n_rows``,) of a constraint, or ``[cost]`` of a cost term."""
        raise NotImplementedError(f"term kind {self.kind!r} has no numpy residual")

    @classmethod
    def report(cls, ctx: ReportContext) -> list[Check]:
        """The constraint report's checks of this kind for a plan (Pinocchio numerics on the plan's
        configurations, at every knot the spec item applies to, the fixed ones included): none by
        default (a cost, or a kind reported with another)."""
        return []

    @classmethod
    def diagnosis(cls, check: Check, phase: str, status: str) -> str:
        """A sentence for a failed plan whose worst violated check is ``check`` (one of
        :attr:`check_kinds`, or a check of no kind: the joint limits), in phase ``phase``, the
        solver having stopped with ``status``."""
        return (f"{check.name} violated by {check.violation:.3g} {check.unit} at t = {check.time:.2f} s in phase "
                f"{phase!r} ({status})")

    @classmethod
    def missed(cls, check: Check, gap: float, tolerance: float) -> str:
        """The relaxed diagnosis's sentence (:mod:`planner.trajopt.diagnose`): a hard target that the
        problem with its targets turned into heavy costs still misses by ``gap`` beyond its
        ``tolerance`` (``check`` measured on that relaxed solution)."""
        unit = "rad" if check.unit == "rad" else "m"
        return (f"{check.name} is {gap:.2f} {unit} beyond reach at t = {check.time:.2f} s "
                f"(closest {check.violation:.2f} {unit}, tolerance {tolerance:g} {unit})")


@dataclass(frozen=True, eq=False)
class ReportContext:
    """What the report's checks of a plan read (:func:`planner.trajopt.checks.check_plan`).

    Attributes:
        lay: The layout (kinematic or dynamic).
        q: Configurations (N+1, nq).
        v: Velocities (N+1, nv).
        com: CoM positions (N+1, 3) [m].
        settings: The planner settings (tolerances).
        placements: Per knot, the world placements of the frames the checks use.
        halfplanes: Knot -> ``(A, b)`` of its support polygon, or None (``layout.support_halfplanes``).
    """

    lay: Any
    q: np.ndarray
    v: np.ndarray
    com: np.ndarray
    settings: Any
    placements: list[dict[int, pin.SE3]]
    halfplanes: Callable[[int], tuple[np.ndarray, np.ndarray] | None]


def worst_check(name: str, kind: CheckKind, values: np.ndarray, times: np.ndarray, tolerance: float, unit: str,
                subject: str = "") -> Check:
    """The check of a group of violations: its worst value (at least 0) and its time."""
    if len(values) == 0:
        return Check.constraint(name=name, kind=kind, violation=0.0, tolerance=tolerance, unit=unit, time=0.0,
                                subject=subject)
    i = int(np.argmax(values))
    return Check.constraint(name=name, kind=kind, violation=float(max(values[i], 0.0)), tolerance=tolerance,
                            unit=unit, time=float(times[i]), subject=subject)


def kind_of_check(kind: CheckKind) -> type[Term]:
    """The term kind whose rows a report check measures (:class:`Term` itself for a check no term
    kind claims: joint limits, the dynamic formulation's)."""
    return next((cls for cls in TERM_KINDS.values() if kind in cls.check_kinds), Term)


class StageKinematics:
    """The symbolic kinematics of one stage (CasADi SX of ``dq`` around ``q_ref``), shared by its
    terms: the CoM, the placements of the frames the terms read, and the joint placements
    (computed on first use when the caller did not give them).

    Args:
        robot: The robot.
        q_ref: Reference configuration symbol (nq).
        dq: Chart displacement symbol (nv).
        com: CoM expression (3).
        frames: Frame id -> (position, rotation) expressions.
        joints: The joint placements ``oMi`` [(R, p)], or None.
    """

    def __init__(self, robot: Robot, q_ref, dq, com, frames: dict, joints: list | None = None) -> None:
        self.robot, self.q_ref, self.dq, self.com, self.frames = robot, q_ref, dq, com, frames
        self._joints = joints

    @property
    def joints(self) -> list:
        """World placements ``(R, p)`` of every joint (built on first use)."""
        if self._joints is None:
            from planner.trajopt.symbolic import SymbolicKinematics

            self._joints = SymbolicKinematics(self.robot.model).joint_placements(self.q_ref, self.dq)
        return self._joints

    def frame(self, frame_id: int) -> tuple:
        """(position, rotation) of a frame: from the stage's frames, or from the joint placements."""
        if frame_id in self.frames:
            return self.frames[frame_id]
        from planner.trajopt.symbolic import SymbolicKinematics

        return SymbolicKinematics(self.robot.model).frame_placement(self.joints, frame_id)[::-1]


class NumericKinematics:
    """Pinocchio's forward kinematics of one configuration, for the numpy residuals.

    Args:
        model: The Pinocchio model.
        q: Configuration (nq).
    """

    def __init__(self, model: pin.Model, q: np.ndarray) -> None:
        self.model, self.q = model, np.asarray(q, dtype=float)
        self.data = model.createData()
        pin.forwardKinematics(model, self.data, self.q)
        self._com: np.ndarray | None = None

    def frame(self, frame_id: int) -> pin.SE3:
        """World placement of a frame."""
        return pin.updateFramePlacement(self.model, self.data, frame_id)

    def joint(self, joint_id: int) -> pin.SE3:
        """World placement of a joint."""
        return self.data.oMi[joint_id]

    @property
    def com(self) -> np.ndarray:
        """Centre of mass in the world (3,) [m]."""
        if self._com is None:
            self._com = np.array(pin.centerOfMass(self.model, self.data, self.q, False))
        return self._com


def knots_of(layout_t: np.ndarray, time: float | None, window, N: int) -> list[int]:
    """Knots where a timed item applies: nearest to ``time``, every knot in ``window``, or N."""
    dt = layout_t[1] - layout_t[0]
    if window is not None:
        ks = [k for k in range(N + 1) if window[0] - 1e-9 <= layout_t[k] <= window[1] + 1e-9]
        if not ks:
            ks = [int(round(0.5 * (window[0] + window[1]) / dt))]
        return ks
    if time is None:
        return [N]
    return [min(N, max(0, int(round(time / dt))))]
