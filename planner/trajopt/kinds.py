"""The kinematic term kinds: one :class:`~planner.trajopt.term.Term` subclass per kind, each with
its layout rows (a constructor: structure, parameters, bounds), its CasADi expression, its numpy
residual and its diagnosis sentence (``docs/terms.md``).

Which knots a spec item puts its terms on is :mod:`planner.trajopt.layout`'s; what one term at one
knot is, is here. The self-collision and scene-collision kinds are in
:mod:`planner.trajopt.collision` and :mod:`planner.trajopt.scene_collision`.

Every parameter block stores a rotation matrix column-major (``R.T.ravel()``), as CasADi's
``reshape`` reads it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

import casadi as ca
import numpy as np
import pinocchio as pin

from planner.results import CheckKind
from planner.trajopt.symbolic import rotation_error
from planner.trajopt.term import (
    NumericKinematics,
    ReportContext,
    StageKinematics,
    Term,
    knots_of,
    worst_check,
)

if TYPE_CHECKING:
    from planner.results import Check
    from tasks import CoMBounds, CoMTarget, FrameTarget, Grasp, JointTarget

INF = math.inf
ORIENTATION_TRACE_MIN = 1.0  # trace(R_target^T R) of a hard orientation target: within 90 deg, not the flipped pi solution
HARD_EQUALITY_TOLERANCE = 1e-6  # [m] or [rad]: below it a hard target becomes an equality
BOX_SHRINK = 0.995  # hard targets: the NLP keeps the error this far inside the tolerance


def target_mode(soft: bool, tolerance: float) -> str:
    """``soft`` (a cost), ``eq`` (a hard target with a tolerance below
    :data:`HARD_EQUALITY_TOLERANCE`) or ``box`` (a hard target's rows in a box)."""
    if soft:
        return "soft"
    return "eq" if tolerance < HARD_EQUALITY_TOLERANCE else "box"


def target_upper(mode: str, n: int, tolerance: float) -> np.ndarray:
    """Row bounds of a hard target: |err_i| <= 0.995 tol / sqrt(n) (a box inside the ball)."""
    if mode == "soft":
        return np.zeros(0)
    if mode == "eq":
        return np.zeros(n)
    return np.full(n, BOX_SHRINK * tolerance / math.sqrt(n))


def _column_major(R: np.ndarray) -> np.ndarray:
    return np.asarray(R, dtype=float).T.ravel()


def _matrix(flat: np.ndarray) -> np.ndarray:
    """A rotation stored column-major, back as a matrix."""
    return np.asarray(flat, dtype=float).reshape(3, 3).T


def rotation_residual(R_target: np.ndarray, R: np.ndarray) -> np.ndarray:
    """The numpy twin of :func:`planner.trajopt.symbolic.rotation_error`: vee of the antisymmetric part
    of ``R_target^T R`` (sin(angle) times the axis) [rad]."""
    M = R_target.T @ R
    return 0.5 * np.array([M[2, 1] - M[1, 2], M[0, 2] - M[2, 0], M[1, 0] - M[0, 1]])


def _target_rows(err, mode: str, weight):
    """A target's (rows, 0) when hard, (None, weight |err|^2) when soft."""
    if mode in ("eq", "box"):
        return err, 0
    return None, weight * ca.sumsqr(err)


def _target_residual(err: np.ndarray, mode: str, weight: float) -> np.ndarray:
    if mode in ("eq", "box"):
        return err
    return np.array([weight * float(err @ err)])


class _OneFrame:
    """A term on one frame, the second entry of its structure (``(kind, frame id, ...)``)."""

    structure: tuple

    @property
    def frame_id(self) -> int:
        """The frame's id."""
        return self.structure[1]

    def frames(self) -> tuple[int, ...]:
        """The frame ids the expression reads."""
        return (self.frame_id,)


@dataclass(eq=False)
class ContactTerm(_OneFrame, Term):
    """A stance sole fixed in 6D to its placement: 3 position rows [m], 3 rotation rows [rad]
    (sin of the angle times the axis). Structure ``("contact", frame id)``; parameters the
    placement's position and rotation."""

    kind: ClassVar[str] = "contact"
    check_kinds: ClassVar[tuple[CheckKind, ...]] = (CheckKind.CONTACT_POSITION, CheckKind.CONTACT_ORIENTATION)

    @classmethod
    def at(cls, knot: int, frame_id: int, frame: str, placement: pin.SE3, phase: str) -> ContactTerm:
        """The term at ``knot``: its structure, parameters and row bounds."""
        return cls(knot=knot, structure=(cls.kind, frame_id),
                   params=np.concatenate([placement.translation, _column_major(placement.rotation)]),
                   lower=np.zeros(6), upper=np.zeros(6), label=f"{frame} contact", phase=phase)

    def expression(self, p, kin: StageKinematics) -> tuple:
        """(rows, cost) in CasADi (:meth:`Term.expression`)."""
        pos, R = kin.frames[self.frame_id]
        return ca.vertcat(pos - p[0:3], rotation_error(ca.reshape(p[3:12], 3, 3), R)), 0

    def residual(self, kin: NumericKinematics) -> np.ndarray:
        """The rows, or ``[cost]``, in numpy (:meth:`Term.residual`)."""
        oMf = kin.frame(self.frame_id)
        return np.concatenate([oMf.translation - self.params[0:3],
                               rotation_residual(_matrix(self.params[3:12]), oMf.rotation)])

    @classmethod
    def report(cls, ctx: ReportContext) -> list[Check]:
        """Per stance sole, the worst distance [m] and angle [rad] (``log3``) from its placement over
        every knot where it is in contact (the fixed knots included)."""
        names: dict[int, str] = {}
        pos_err: dict[int, list] = {}
        rot_err: dict[int, list] = {}
        t = ctx.lay.t
        for k, active in enumerate(ctx.lay.contacts_at):
            for fid, (frame, M) in active.items():
                names.setdefault(fid, frame)
                oMf = ctx.placements[k][fid]
                pos_err.setdefault(fid, []).append((np.linalg.norm(oMf.translation - M.translation), t[k]))
                rot_err.setdefault(fid, []).append((np.linalg.norm(pin.log3(M.rotation.T @ oMf.rotation)), t[k]))
        checks = []
        tolerance = ctx.settings.tolerances.contact
        position_only = {t.frame_id for t in ctx.lay.terms if isinstance(t, ContactPositionTerm)}
        for fid, frame in names.items():
            pe, rt = np.array(pos_err[fid]).T
            checks.append(worst_check(f"{frame} contact position", CheckKind.CONTACT_POSITION, pe, rt, tolerance,
                                      "m", frame))
            if fid in position_only:
                continue  # its orientation follows from the other contact's rows, to the solver's tolerance
            re, rt = np.array(rot_err[fid]).T
            checks.append(worst_check(f"{frame} contact orientation", CheckKind.CONTACT_ORIENTATION, re, rt,
                                      tolerance, "rad", frame))
        return checks


@dataclass(eq=False)
class ContactPositionTerm(ContactTerm):
    """A contact held in position only (3 rows [m]): one whose frame is fewer than 6 joints from
    another contact of the same knot (a thigh on a seat, 3 joints above its foot's sole). Its 6D
    rows would repeat that chain's (the foot fixes all but 3 of the thigh's degrees of freedom), and
    the solver, given redundant equalities, declared the sit infeasible; the orientation follows from
    the other contact and is reported with the soles' (:meth:`ContactTerm.report`). Structure
    ``("contact_position", frame id)``."""

    kind: ClassVar[str] = "contact_position"
    check_kinds: ClassVar[tuple[CheckKind, ...]] = ()

    @classmethod
    def at(cls, knot: int, frame_id: int, frame: str, placement: pin.SE3, phase: str) -> ContactPositionTerm:
        """The term at ``knot``: its structure, parameters and row bounds."""
        return cls(knot=knot, structure=(cls.kind, frame_id), params=np.array(placement.translation, dtype=float),
                   lower=np.zeros(3), upper=np.zeros(3), label=f"{frame} contact", phase=phase)

    def expression(self, p, kin: StageKinematics) -> tuple:
        """(rows, cost) in CasADi (:meth:`Term.expression`)."""
        pos, _ = kin.frames[self.frame_id]
        return pos - p[0:3], 0

    def residual(self, kin: NumericKinematics) -> np.ndarray:
        """The rows, or ``[cost]``, in numpy (:meth:`Term.residual`)."""
        return kin.frame(self.frame_id).translation - self.params[0:3]

    @classmethod
    def report(cls, ctx: ReportContext) -> list[Check]:
        """None of its own: :meth:`ContactTerm.report` covers every contact."""
        return []


@dataclass(eq=False)
class ClearanceTerm(_OneFrame, Term):
    """A foot off the ground above a height (its frame's z >= ``lower``) [m]: 0 at every swing knot,
    the phase's ``swing_height`` at its middle. Structure ``("clearance", frame id)``."""

    kind: ClassVar[str] = "clearance"
    check_kinds: ClassVar[tuple[CheckKind, ...]] = (CheckKind.SWING_CLEARANCE,)

    @classmethod
    def at(cls, knot: int, frame_id: int, height: float, label: str, phase: str) -> ClearanceTerm:
        """The term at ``knot``: its structure, parameters and row bounds."""
        return cls(knot=knot, structure=(cls.kind, frame_id), lower=np.array([height]), upper=np.array([INF]),
                   label=label, phase=phase)

    def expression(self, p, kin: StageKinematics) -> tuple:
        """(rows, cost) in CasADi (:meth:`Term.expression`)."""
        pos, _ = kin.frames[self.frame_id]
        return pos[2], 0

    def residual(self, kin: NumericKinematics) -> np.ndarray:
        """The rows, or ``[cost]``, in numpy (:meth:`Term.residual`)."""
        return np.array([kin.frame(self.frame_id).translation[2]])

    @classmethod
    def report(cls, ctx: ReportContext) -> list[Check]:
        """Per swinging foot, the worst depth [m] below its clearance over its terms."""
        clear: dict[str, list] = {}
        for term in ctx.lay.terms:
            if isinstance(term, cls):
                z = ctx.placements[term.knot][term.frame_id].translation[2]
                clear.setdefault(term.label.split()[0], []).append((term.lower[0] - z, ctx.lay.t[term.knot]))
        checks = []
        for frame, rows in clear.items():
            vals, times = np.array(rows).T
            checks.append(worst_check(f"{frame} clearance", CheckKind.SWING_CLEARANCE, vals, times,
                                      ctx.settings.tolerances.polygon, "m", frame))
        return checks


def _com_bound_sentence(check: Check, phase: str, status: str) -> str:
    return (f"CoM bound {check.subject!r} cannot hold in phase {phase!r}: the CoM ends {check.violation:.3f} m "
            f"outside at t = {check.time:.2f} s ({status})")


@dataclass(eq=False)
class SupportPolygonTerm(Term):
    """The CoM's ground projection inside the support polygon shrunk by a margin: ``A c_xy <= b``,
    padded to a fixed number of rows per number of soles (a padding row is ``0 <= 1``), so knots
    of one stance share one stage. Structure ``("polygon", rows)``; parameters ``A`` column-major."""

    kind: ClassVar[str] = "polygon"
    check_kinds: ClassVar[tuple[CheckKind, ...]] = (CheckKind.COM_SUPPORT_POLYGON,
                                                    CheckKind.COM_SUPPORT_POLYGON_AT_REST)

    @classmethod
    def at(cls, knot: int, A: np.ndarray, b: np.ndarray, rows: int, bounds: CoMBounds, phase: str) -> SupportPolygonTerm:
        """The term at ``knot``: its structure, parameters and row bounds."""
        A_pad = np.zeros((rows, 2))
        b_pad = np.full(rows, 1.0)
        A_pad[: len(A)] = A
        b_pad[: len(A)] = b - bounds.margin
        return cls(knot=knot, structure=(cls.kind, rows), params=A_pad.T.ravel(), lower=np.full(rows, -INF),
                   upper=b_pad, label=f"CoM bound {bounds.name!r} (support polygon)", item=bounds, phase=phase)

    def expression(self, p, kin: StageKinematics) -> tuple:
        """(rows, cost) in CasADi (:meth:`Term.expression`)."""
        A = ca.reshape(p, self.structure[1], 2)
        return ca.mtimes(A, kin.com[0:2]), 0

    def residual(self, kin: NumericKinematics) -> np.ndarray:
        """The rows, or ``[cost]``, in numpy (:meth:`Term.residual`)."""
        A = self.params.reshape(2, self.structure[1]).T
        return A @ kin.com[:2]

    @classmethod
    def report(cls, ctx: ReportContext) -> list[Check]:
        """Per CoM bound of the spec, over its knots (all of them, the fixed ones included): the worst
        distance [m] of the CoM outside its support polygon shrunk by the margin, then (the
        :class:`CoMBoxTerm` kind's check, reported here to keep each bound's two checks together)
        outside its box."""
        lay, com, t = ctx.lay, ctx.com, ctx.lay.t
        tolerance = ctx.settings.tolerances.polygon
        checks: list[Check] = []
        for bounds in lay.spec.com_bounds:
            ks = range(lay.N + 1) if bounds.window is None else knots_of(t, None, bounds.window, lay.N)
            poly, box = [], []
            for k in ks:
                if bounds.support_polygon:
                    planes = ctx.halfplanes(k)
                    if planes is not None:
                        A, b = planes
                        poly.append((float(np.max(A @ com[k, :2] - (b - bounds.margin))), t[k]))
                viol = 0.0
                for i in range(3):
                    lo, hi = bounds.lower[i], bounds.upper[i]
                    if lo is not None:
                        viol = max(viol, lo - com[k, i])
                    if hi is not None:
                        viol = max(viol, com[k, i] - hi)
                box.append((viol, t[k]))
            if bounds.support_polygon and poly:
                vals, times = np.array(poly).T
                checks.append(worst_check(f"CoM bound {bounds.name!r} support polygon", CheckKind.COM_SUPPORT_POLYGON,
                                          vals, times, tolerance, "m", bounds.name))
            if any(x is not None for x in (*bounds.lower, *bounds.upper)) and box:
                vals, times = np.array(box).T
                checks.append(worst_check(f"CoM bound {bounds.name!r} box", CheckKind.COM_BOX, vals, times, tolerance,
                                          "m", bounds.name))
        return checks

    diagnosis = staticmethod(_com_bound_sentence)


@dataclass(eq=False)
class CoMBoxTerm(Term):
    """The CoM inside the box of a CoM bound, on the axes it bounds [m]. Structure
    ``("com_box", axes)``."""

    kind: ClassVar[str] = "com_box"
    check_kinds: ClassVar[tuple[CheckKind, ...]] = (CheckKind.COM_BOX,)

    @classmethod
    def at(cls, knot: int, bounds: CoMBounds, axes: tuple[bool, ...], phase: str) -> CoMBoxTerm:
        """The term at ``knot``: its structure, parameters and row bounds."""
        lo = np.array([-INF if v is None else v for v, a in zip(bounds.lower, axes, strict=True) if a])
        hi = np.array([INF if v is None else v for v, a in zip(bounds.upper, axes, strict=True) if a])
        return cls(knot=knot, structure=(cls.kind, axes), lower=lo, upper=hi,
                   label=f"CoM bound {bounds.name!r} (box)", item=bounds, phase=phase)

    @property
    def axes(self) -> list[int]:
        """The axes the term acts on."""
        return [i for i, a in enumerate(self.structure[1]) if a]

    def expression(self, p, kin: StageKinematics) -> tuple:
        """(rows, cost) in CasADi (:meth:`Term.expression`)."""
        return kin.com[self.axes], 0

    def residual(self, kin: NumericKinematics) -> np.ndarray:
        """The rows, or ``[cost]``, in numpy (:meth:`Term.residual`)."""
        return kin.com[self.axes]

    diagnosis = staticmethod(_com_bound_sentence)


class _Target(Term):
    """A target: hard (rows in a box, or equalities) or soft (a weighted cost); ``mode`` is the
    last entry of its structure."""

    @property
    def mode(self) -> str:
        """``soft``, ``eq`` or ``box``."""
        return self.structure[-1]

    @property
    def hard(self) -> bool:
        """True for a constraint, False for a cost."""
        return self.mode != "soft"


@dataclass(eq=False)
class FramePositionTerm(_OneFrame, _Target):
    """A frame's position on the target's axes [m]. Structure ``("frame_pos", frame id, axes,
    mode)``; parameters the position and the weight."""

    kind: ClassVar[str] = "frame_pos"
    check_kinds: ClassVar[tuple[CheckKind, ...]] = (CheckKind.TARGET_POSITION,)

    @classmethod
    def at(cls, knot: int, frame_id: int, target: FrameTarget, scale: float, phase: str) -> FramePositionTerm:
        """The term at ``knot``: its structure, parameters and row bounds."""
        from tasks import Priority

        assert target.position is not None
        mode = target_mode(target.priority is Priority.SOFT, target.tolerance)
        upper = target_upper(mode, sum(target.axes), target.tolerance)
        return cls(knot=knot, structure=(cls.kind, frame_id, target.axes, mode),
                   params=np.array([*target.position, target.weight * scale]), lower=-upper, upper=upper,
                   label=f"{target.frame} target {target.name!r}", item=target, phase=phase)

    @property
    def axes(self) -> tuple[bool, ...]:
        """The axes the term acts on."""
        return self.structure[2]

    def expression(self, p, kin: StageKinematics) -> tuple:
        """(rows, cost) in CasADi (:meth:`Term.expression`)."""
        pos, _ = kin.frames[self.frame_id]
        err = (pos - p[0:3])[[i for i, a in enumerate(self.axes) if a]]
        return _target_rows(err, self.mode, p[3])

    def residual(self, kin: NumericKinematics) -> np.ndarray:
        """The rows, or ``[cost]``, in numpy (:meth:`Term.residual`)."""
        err = (kin.frame(self.frame_id).translation - self.params[0:3])[np.array(self.axes)]
        return _target_residual(err, self.mode, self.params[3])

    @classmethod
    def report(cls, ctx: ReportContext) -> list[Check]:
        """Per frame target of the spec, over its knots (the fixed ones included): the worst position
        error [m] on its axes, then (the :class:`FrameOrientationTerm` kind's check, reported here to
        keep a target's two checks together) the worst angle [rad] (``log3``). A soft target's
        tolerance is infinite: it is reported, never failed."""
        from tasks import Priority

        lay, t = ctx.lay, ctx.lay.t
        checks = []
        for target in lay.spec.targets:
            fid = lay.robot.frame_id(target.frame)
            ks = knots_of(t, target.time, target.window, lay.N)
            tol_scale = 1.0 if target.priority is Priority.HARD else math.inf
            if target.position is not None:
                axes = np.array(target.axes)
                errs = [np.linalg.norm((ctx.placements[k][fid].translation - np.array(target.position))[axes])
                        for k in ks]
                checks.append(worst_check(f"{target.frame} target {target.name!r}", CheckKind.TARGET_POSITION,
                                          np.array(errs), t[ks], target.tolerance * tol_scale + 1e-9, "m", target.name))
            if target.rpy is not None:
                R_t = pin.rpy.rpyToMatrix(*target.rpy)
                errs = [np.linalg.norm(pin.log3(R_t.T @ ctx.placements[k][fid].rotation)) for k in ks]
                checks.append(worst_check(f"{target.frame} orientation target {target.name!r}",
                                          CheckKind.TARGET_ORIENTATION, np.array(errs), t[ks],
                                          target.orientation_tolerance * tol_scale + 1e-9, "rad", target.name))
        return checks


@dataclass(eq=False)
class FrameOrientationTerm(_OneFrame, _Target):
    """A frame's orientation [rad] (sin of the angle times the axis): a target's, or the base
    upright (a cost). Structure ``("frame_rot", frame id, mode)``; parameters the rotation and the
    weight."""

    kind: ClassVar[str] = "frame_rot"
    check_kinds: ClassVar[tuple[CheckKind, ...]] = (CheckKind.TARGET_ORIENTATION,)

    @classmethod
    def at(cls, knot: int, frame_id: int, rotation: np.ndarray, mode: str, weight: float, tolerance: float,
           label: str, phase: str, item: object = None) -> FrameOrientationTerm:
        """The term at ``knot``: its structure, parameters and row bounds."""
        upper = target_upper(mode, 3, math.sin(min(tolerance, math.pi / 2)))
        lower = -upper
        if mode != "soft":  # the sine rows vanish at pi too: trace(R_t^T R) = 1 + 2 cos(angle) >= 1 keeps it within 90 deg
            lower, upper = np.append(lower, ORIENTATION_TRACE_MIN), np.append(upper, math.inf)
        return cls(knot=knot, structure=(cls.kind, frame_id, mode), params=np.array([*_column_major(rotation), weight]),
                   lower=lower, upper=upper, label=label, item=item, phase=phase)

    def expression(self, p, kin: StageKinematics) -> tuple:
        """(rows, cost) in CasADi (:meth:`Term.expression`)."""
        _, R = kin.frames[self.frame_id]
        R_t = ca.reshape(p[0:9], 3, 3)
        rows, cost = _target_rows(rotation_error(R_t, R), self.mode, p[9])
        if rows is None:
            return rows, cost
        return ca.vertcat(rows, ca.trace(ca.mtimes(R_t.T, R))), cost

    def residual(self, kin: NumericKinematics) -> np.ndarray:
        """The rows, or ``[cost]``, in numpy (:meth:`Term.residual`)."""
        R_t, R = _matrix(self.params[0:9]), kin.frame(self.frame_id).rotation
        out = _target_residual(rotation_residual(R_t, R), self.mode, self.params[9])
        return out if self.mode == "soft" else np.append(out, np.trace(R_t.T @ R))


@dataclass(eq=False)
class CoMPositionTerm(_Target):
    """The CoM on the target's axes [m]: a CoM target's, or the CoM centring (a cost). Structure
    ``("com_pos", axes, mode)``; parameters the position (0 on a free axis) and the weight."""

    kind: ClassVar[str] = "com_pos"
    check_kinds: ClassVar[tuple[CheckKind, ...]] = (CheckKind.COM_TARGET,)

    @classmethod
    def at(cls, knot: int, axes: tuple[bool, ...], goal, mode: str, weight: float, upper: np.ndarray, label: str,
           phase: str, item: object = None) -> CoMPositionTerm:
        """The term at ``knot``: its structure, parameters and row bounds."""
        return cls(knot=knot, structure=(cls.kind, axes, mode), params=np.array([*goal, weight]),
                   lower=-upper, upper=upper, label=label, item=item, phase=phase)

    @classmethod
    def of_target(cls, knot: int, target: CoMTarget, n_knots: int, phase: str) -> CoMPositionTerm:
        """The term of a CoM target at ``knot`` (its weight shared by ``n_knots`` knots)."""
        from tasks import Priority

        axes = tuple(v is not None for v in target.position)
        mode = target_mode(target.priority is Priority.SOFT, target.tolerance)
        return cls.at(knot, axes, [0.0 if v is None else v for v in target.position], mode, target.weight / n_knots,
                      target_upper(mode, sum(axes), target.tolerance), f"CoM target {target.name!r}", phase,
                      item=target)

    @property
    def axes(self) -> tuple[bool, ...]:
        """The axes the term acts on."""
        return self.structure[1]

    def expression(self, p, kin: StageKinematics) -> tuple:
        """(rows, cost) in CasADi (:meth:`Term.expression`)."""
        err = (kin.com - p[0:3])[[i for i, a in enumerate(self.axes) if a]]
        return _target_rows(err, self.mode, p[3])

    def residual(self, kin: NumericKinematics) -> np.ndarray:
        """The rows, or ``[cost]``, in numpy (:meth:`Term.residual`)."""
        err = (kin.com - self.params[0:3])[np.array(self.axes)]
        return _target_residual(err, self.mode, self.params[3])

    @classmethod
    def report(cls, ctx: ReportContext) -> list[Check]:
        """Per CoM target of the spec, the worst error [m] on its axes over its knots (the CoM
        centring is a cost: not reported)."""
        from tasks import Priority

        lay, com, t = ctx.lay, ctx.com, ctx.lay.t
        checks = []
        for com_target in lay.spec.com_targets:
            ks = knots_of(t, com_target.time, com_target.window, lay.N)
            axes = np.array([v is not None for v in com_target.position])
            goal = np.array([0.0 if v is None else v for v in com_target.position])
            errs = [np.linalg.norm((com[k] - goal)[axes]) for k in ks]
            tol = com_target.tolerance if com_target.priority is Priority.HARD else math.inf
            checks.append(worst_check(f"CoM target {com_target.name!r}", CheckKind.COM_TARGET, np.array(errs), t[ks],
                                      tol + 1e-9, "m", com_target.name))
        return checks


@dataclass(eq=False)
class JointTargetTerm(Term):
    """A one-dof joint's angle towards a value, as the cost ``w (q_j - value)^2``. Structure
    ``("joint", tangent index)``; parameters the value [rad] and the weight."""

    kind: ClassVar[str] = "joint"

    @classmethod
    def at(cls, knot: int, idx_v: int, target: JointTarget, n_knots: int, phase: str) -> JointTargetTerm:
        """The term at ``knot``: its structure, parameters and row bounds."""
        return cls(knot=knot, structure=(cls.kind, idx_v), params=np.array([target.value, target.weight / n_knots]),
                   label=f"joint target {target.name!r}", item=target, phase=phase)

    @property
    def idx_v(self) -> int:
        """The joint's tangent index."""
        return self.structure[1]

    def expression(self, p, kin: StageKinematics) -> tuple:
        """(rows, cost) in CasADi (:meth:`Term.expression`)."""
        value = kin.q_ref[self.idx_v + 1] + kin.dq[self.idx_v]  # one-dof joints: idx_q = idx_v + 1
        return None, p[1] * (value - p[0]) ** 2

    def residual(self, kin: NumericKinematics) -> np.ndarray:
        """The rows, or ``[cost]``, in numpy (:meth:`Term.residual`)."""
        return np.array([self.params[1] * (kin.q[self.idx_v + 1] - self.params[0]) ** 2])


CHAIN_TOLERANCE = 0.003  # [m]: the held object's centre as placed by one hand vs by the other
CHAIN_ORIENTATION_TOLERANCE = 0.02  # [rad]: the hands' relative orientation vs at the grasp


@dataclass(eq=False)
class ClosedChainTerm(Term):
    """Two hands holding one object: the object's centre as placed by one hand (its grasp offset)
    is where the other places it (3 rows [m]) and, when the grasp fixes it, the hands' relative
    orientation (3 rows [rad]). Structure ``("frame_rel", frame a, frame b, oriented)``;
    parameters both offsets and the relative rotation."""

    kind: ClassVar[str] = "frame_rel"

    @classmethod
    def at(cls, knot: int, frame_a: int, frame_b: int, a: Grasp, b: Grasp, relative: np.ndarray | None,
           phase: str) -> ClosedChainTerm:
        """The term at ``knot``: its structure, parameters and row bounds."""
        upper = target_upper("box", 3, CHAIN_TOLERANCE)
        if relative is not None:
            upper = np.concatenate([upper, target_upper("box", 3, math.sin(CHAIN_ORIENTATION_TOLERANCE))])
        params = np.array([*a.offset, *b.offset, *_column_major(np.eye(3) if relative is None else relative)])
        return cls(knot=knot, structure=(cls.kind, frame_a, frame_b, relative is not None), params=params,
                   lower=-upper, upper=upper, item=a, phase=phase,
                   label=f"both hands hold the {a.object} (closed chain)")

    @property
    def pair(self) -> tuple[int, int]:
        """The two hands' frame ids."""
        return self.structure[1], self.structure[2]

    def frames(self) -> tuple[int, ...]:
        """The frame ids the expression reads."""
        return self.pair

    def expression(self, p, kin: StageKinematics) -> tuple:
        """(rows, cost) in CasADi (:meth:`Term.expression`)."""
        (pa, Ra), (pb, Rb) = (kin.frame(f) for f in self.pair)
        rows = [pa + ca.mtimes(Ra, p[0:3]) - pb - ca.mtimes(Rb, p[3:6])]
        if self.structure[3]:
            rows.append(rotation_error(ca.reshape(p[6:15], 3, 3), ca.mtimes(Ra.T, Rb)))
        return ca.vertcat(*rows), 0

    def residual(self, kin: NumericKinematics) -> np.ndarray:
        """The rows, or ``[cost]``, in numpy (:meth:`Term.residual`)."""
        Ma, Mb = (kin.frame(f) for f in self.pair)
        rows = [Ma.act(self.params[0:3]) - Mb.act(self.params[3:6])]
        if self.structure[3]:
            rows.append(rotation_residual(_matrix(self.params[6:15]), Ma.rotation.T @ Mb.rotation))
        return np.concatenate(rows)
