"""Constraint report and prechecks, with Pinocchio numerics (independent of CasADi).

* :func:`check_plan`: every constraint group's worst violation over the horizon, its unit
  and time (stance soles, swing clearance, CoM support polygon and box, frame and CoM
  targets, joint position and velocity limits).
* :func:`precheck`: contradictions visible before solving (a first phase whose contacts are
  not where the robot stands, a support polygon narrower than twice the margin, a CoM box
  that misses the polygon, a target before the robot can move).
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from planner.results import Check, CheckKind
from planner.trajopt.collision import SelfCollisionTerm
from planner.trajopt.kinds import (
    ClearanceTerm,
    CoMPositionTerm,
    ContactTerm,
    FramePositionTerm,
    SupportPolygonTerm,
)
from planner.trajopt.layout import (
    Layout,
    halfplanes,
    knots_of,
    placement_of,
    support_halfplanes,
    support_polygon,
)
from planner.trajopt.scene_collision import SceneCollisionTerm
from planner.trajopt.settings import PlannerSettings
from planner.trajopt.term import ReportContext, Term, worst_check
from tasks import Priority

START_TOLERANCE = 1e-3  # [m], [rad]: first-phase contacts vs the standing soles


def finite_differences(model: pin.Model, q: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Velocities and accelerations consistent with ``q`` on the manifold.

    ``v_k = difference(q_k, q_{k+1}) / dt`` and ``a_k = (v_{k+1} - v_k) / dt`` (explicit Euler:
    ``q_{k+1} = integrate(q_k, v_k dt)``, ``v_{k+1} = v_k + a_k dt``); the last entries are 0.
    """
    T = len(q)
    v = np.zeros((T, model.nv))
    for k in range(T - 1):
        v[k] = pin.difference(model, q[k], q[k + 1]) / dt
    a = np.zeros((T, model.nv))
    a[:-1] = (v[1:] - v[:-1]) / dt
    return v, a


#: The term kinds whose checks the report lists before the joint limits, in this order (the CoM
#: bound's box is reported with its polygon, a frame target's orientation with its position).
REPORTED_BEFORE_LIMITS: tuple[type[Term], ...] = (ContactTerm, ClearanceTerm, SupportPolygonTerm, FramePositionTerm,
                                                  CoMPositionTerm)
#: ... and after them.
REPORTED_AFTER_LIMITS: tuple[type[Term], ...] = (SelfCollisionTerm, SceneCollisionTerm)


def check_plan(lay: Layout, q: np.ndarray, v: np.ndarray, com: np.ndarray,
               settings: PlannerSettings) -> list[Check]:
    """Every constraint group's worst violation, evaluated with Pinocchio at the knots: each term
    kind's checks (:meth:`planner.trajopt.term.Term.report`), and the joint position and velocity
    limits (bounds on the variables and rows of the transcription, not terms)."""
    robot, spec, t = lay.robot, lay.spec, lay.t
    model, data = robot.model, robot.data()
    used = sorted({fid for active in lay.contacts_at for fid in active}
                  | {term.frame_id for term in lay.terms if isinstance(term, ClearanceTerm)}
                  | {robot.frame_id(target.frame) for target in spec.targets})
    placements: list[dict[int, pin.SE3]] = []  # per knot, the placements of the frames checked
    for qk in q:
        pin.forwardKinematics(model, data, qk)
        placements.append({fid: pin.updateFramePlacement(model, data, fid).copy() for fid in used})
    ctx = ReportContext(lay=lay, q=q, v=v, com=com, settings=settings, placements=placements,
                        halfplanes=lambda k: support_halfplanes(lay, k))
    checks = [c for kind in REPORTED_BEFORE_LIMITS for c in kind.report(ctx)]
    # joint limits
    lower = np.asarray(model.lowerPositionLimit, dtype=float)[7:]
    upper = np.asarray(model.upperPositionLimit, dtype=float)[7:]
    lower = np.where(np.abs(lower) < 1e10, lower, -np.inf)
    upper = np.where(np.abs(upper) < 1e10, upper, np.inf)
    viol = np.maximum(lower - q[:, 7:], q[:, 7:] - upper).max(axis=1)
    checks.append(worst_check("joint position limits", CheckKind.JOINT_POSITION_LIMITS, viol, t,
                              settings.tolerances.limit, "rad"))
    vmax = np.asarray(model.velocityLimit, dtype=float)[6:]
    vmax = np.where((vmax > 0) & (vmax < 1e10), vmax, np.inf)
    vviol = (np.abs(v[:, 6:]) - vmax).max(axis=1)
    checks.append(worst_check("joint velocity limits", CheckKind.JOINT_VELOCITY_LIMITS, vviol, t,
                              settings.tolerances.limit / lay.dt, "rad/s"))
    return checks + [c for kind in REPORTED_AFTER_LIMITS for c in kind.report(ctx)]


def _has_point(A: np.ndarray, b: np.ndarray) -> bool:
    """True when ``{x in R^2 : A x <= b}`` is non-empty (a bounded region has a vertex where two
    boundary lines cross, so checking every crossing is exact)."""
    n = len(A)
    for i in range(n):
        for j in range(i + 1, n):
            M = np.array([A[i], A[j]])
            if abs(np.linalg.det(M)) < 1e-12:
                continue
            x = np.linalg.solve(M, np.array([b[i], b[j]]))
            if np.all(A @ x <= b + 1e-12):
                return True
    return False


def _with_box(A: np.ndarray, b: np.ndarray, lower, upper) -> tuple[np.ndarray, np.ndarray]:
    """``A x <= b`` with the rows of the xy box ``lower <= x <= upper`` appended."""
    return (np.vstack([A, [[-1.0, 0.0], [1.0, 0.0], [0.0, -1.0], [0.0, 1.0]]]),
            np.concatenate([b, [-lower[0], upper[0], -lower[1], upper[1]]]))


def _polygon_room(A: np.ndarray, b: np.ndarray, lower=None, upper=None) -> float:
    """Radius of the largest disc inside ``A x <= b`` (and the xy box) [m]; -inf when empty."""
    if lower is not None:
        A, b = _with_box(A, b, lower, upper)
    if not _has_point(A, b):
        return -math.inf
    lo, hi = 0.0, 10.0
    for _ in range(40):  # bisection on the inward offset [m]
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if _has_point(A, b - mid) else (lo, mid)
    return lo


def precheck(lay: Layout) -> str:
    """A task-level explanation of a contradiction visible before solving, or ``""``."""
    robot, spec = lay.robot, lay.spec
    data = robot.data()
    pin.framesForwardKinematics(robot.model, data, lay.q_ref)
    first = spec.phases[0]
    for c in first.contacts:
        fid = robot.frame_id(c.frame)
        M = placement_of(c.placement)
        oMf = data.oMf[fid]
        dp = float(np.linalg.norm(oMf.translation - M.translation))
        dr = float(np.linalg.norm(pin.log3(M.rotation.T @ oMf.rotation)))
        if dp > START_TOLERANCE or dr > START_TOLERANCE:
            where = ", ".join(f"{x:.3f}" for x in oMf.translation)
            return (f"contact {c.frame} in the first phase {first.name!r} is {dp:.3f} m / {dr:.3f} rad away from "
                    f"where the robot starts standing (foot at [{where}] m); the first phase's contacts must match "
                    "the standing posture")
    com0 = np.array(pin.centerOfMass(robot.model, data, lay.q_ref))
    for bounds in spec.com_bounds:
        ks = range(lay.N + 1) if bounds.window is None else knots_of(lay.t, None, bounds.window, lay.N)
        seen_phases = set()
        for k in ks:
            phase = lay.phase_name(k)
            for i in range(3):
                lo, hi = bounds.lower[i], bounds.upper[i]
                axis = "xyz"[i]
                if k < 2 and ((lo is not None and com0[i] < lo - 1e-9) or (hi is not None and com0[i] > hi + 1e-9)):
                    return (f"CoM bound {bounds.name!r} cannot hold at the start (t = {lay.t[k]:.2f} s, phase "
                            f"{phase!r}): the standing CoM {axis} = {com0[i]:.3f} m is outside "
                            f"[{_fmt(lo)}, {_fmt(hi)}] m")
            if not bounds.support_polygon or phase in seen_phases:
                continue
            seen_phases.add(phase)
            hull = support_polygon(lay, k)
            if len(hull) < 3:
                continue
            A, b = halfplanes(hull)
            if not _has_point(A, b - bounds.margin):  # no room (the width only for the message)
                width = 2 * _polygon_room(A, b)
                return (f"CoM bound {bounds.name!r} cannot hold in phase {phase!r}: the support polygon is "
                        f"{width:.3f} m wide, and the margin {bounds.margin:.3f} m on each side leaves no room")
            if any(bounds.lower[i] is not None or bounds.upper[i] is not None for i in range(2)):
                lo_xy = [-1e3 if v is None else v for v in bounds.lower[:2]]
                hi_xy = [1e3 if v is None else v for v in bounds.upper[:2]]
                if not _has_point(*_with_box(A, b - bounds.margin, lo_xy, hi_xy)):
                    return (f"CoM bound {bounds.name!r} cannot hold in phase {phase!r}: its box "
                            f"x [{_fmt(bounds.lower[0])}, {_fmt(bounds.upper[0])}] m, y [{_fmt(bounds.lower[1])}, "
                            f"{_fmt(bounds.upper[1])}] m does not overlap the support polygon shrunk by "
                            f"{bounds.margin:.3f} m")
    for target in spec.targets:
        ks = knots_of(lay.t, target.time, target.window, lay.N)
        if target.priority is Priority.HARD and target.position is not None and all(k < 2 for k in ks):
            p = data.oMf[robot.frame_id(target.frame)].translation
            err = float(np.linalg.norm((p - np.array(target.position))[np.array(target.axes)]))
            if err > target.tolerance:
                return (f"{target.frame} target {target.name!r} at t = {lay.t[ks[0]]:.2f} s comes before the robot "
                        f"can move (first motion at t = {lay.t[2]:.2f} s); it is {err:.3f} m away at the start")
    return ""


def _fmt(v) -> str:
    return "-inf" if v is None else f"{v:.3f}"
