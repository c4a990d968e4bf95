"""From a TaskSpec to a list of per-knot terms: the problem's layout, before any CasADi.

The transcription (docs/planner.md) uses a uniform knot grid ``t_k = k dt``, ``k = 0..N``.
The decision variables are the tangent displacements ``dq_k`` (nv) around the reference
``q_ref`` (the spec's start state, else the standing posture). Knots 0 and 1 are fixed at
``dq = 0`` (start at rest) and knot N repeats knot N-1 (end at rest), so the variables are
``dq_2 .. dq_{N-1}``.

Each spec item becomes :class:`Term`\\ s at knots. A term separates

* its *structure* (kind, knot, frame, axes, hard/soft: what the NLP graph looks like), which
  keys the solver cache, from
* its *values* (target positions, placements, polygon edges, weights as CasADi parameters;
  bounds as ``lbg``/``ubg``), which change from solve to solve without a rebuild.

One function per formulation piece (contacts, swing clearance, balance, frame targets, CoM
targets, joint targets) picks the knots; what one term at one knot is (its rows, expression, residual,
report and diagnosis) is its kind's class (:mod:`planner.trajopt.kinds`, ``docs/terms.md``). CoM dynamics with contact forces (``spec.dynamic``) add pieces with
their own variables through the formulation protocol (:mod:`planner.trajopt.formulation`):
:class:`Layout` is the kinematic formulation, ``planner.trajopt.centroidal.layout.DynamicLayout``
the dynamic one.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, NamedTuple, Self

import numpy as np
import pinocchio as pin

from planner.exceptions import SpecNotForRobot
from planner.trajopt.kinds import (
    CHAIN_ORIENTATION_TOLERANCE,  # noqa: F401 - re-exported: the layout's names before the kinds were classes
    CHAIN_TOLERANCE,  # noqa: F401
    HARD_EQUALITY_TOLERANCE,  # noqa: F401
    ClearanceTerm,
    ClosedChainTerm,
    CoMBoxTerm,
    CoMPositionTerm,
    ContactPositionTerm,
    ContactTerm,
    FrameOrientationTerm,
    FramePositionTerm,
    JointTargetTerm,
    SupportPolygonTerm,
    target_mode,
)
from planner.trajopt.layout_data import LayoutData
from planner.trajopt.term import Term, knots_of
from robots import Robot, halfplanes, sole_corners_in_world
from robots import support_polygon as polygon_of_soles
from tasks import CoMBounds, CoMTarget, Contact, FrameTarget, Grasp, JointTarget, Priority, TaskSpec

if TYPE_CHECKING:
    from planner.results import Check, Plan
    from planner.trajopt.settings import PlannerSettings

INF = math.inf
MIN_INTERVALS = 4  # the rest constraints use two knots at each end


@dataclass(frozen=True, eq=False)
class Layout(LayoutData):
    """The kinematic formulation of one spec on one robot: its data (:class:`LayoutData`, frozen) and
    the formulation protocol's methods (:class:`planner.trajopt.formulation.Formulation`)."""

    # -- the formulation protocol (planner.trajopt.formulation.Formulation) ------------------
    # The kinematic formulation: no variables, rows or parameters beyond the chart's; the
    # dynamic one (planner.trajopt.centroidal.layout.DynamicLayout) overrides every method.

    def extra_sizes(self) -> tuple[int, int]:
        """(variables, constraint rows) the formulation adds after the kinematic ones."""
        return 0, 0

    def extend_nlp(self, nlp: dict, derivatives: dict) -> tuple[dict, dict]:
        """The NLP ``{x, p, f, g}`` and its derivative functions, extended by the formulation."""
        return nlp, derivatives

    def extend_parameters(self, p: np.ndarray) -> np.ndarray:
        """The parameter vector, extended by the formulation."""
        return p

    def extend_bounds(self, lbx: np.ndarray, ubx: np.ndarray, lbg: np.ndarray,
                      ubg: np.ndarray) -> tuple[np.ndarray, ...]:
        """(lbx, ubx, lbg, ubg), extended by the formulation."""
        return lbx, ubx, lbg, ubg

    def initial_guess(self, settings: PlannerSettings | None = None) -> np.ndarray:
        """The solver's starting point: the nominal motion when ``settings.warm_start`` asks for it,
        else rest (``dq = 0``)."""
        if settings is not None and settings.solver.warm_start == "nominal":
            from planner.trajopt.nominal import nominal_motion

            return nominal_motion(self)[2:self.N].ravel()
        return np.zeros(self.robot.nv * (self.N - 2))

    def forces_of(self, x: np.ndarray) -> np.ndarray | None:
        """Contact-force variables of a solution ``x`` (None: the formulation has none)."""
        return None

    def plan_checks(self, q: np.ndarray, com: np.ndarray, forces: np.ndarray | None,
                    checks: list[Check], settings: PlannerSettings) -> list[Check]:
        """The constraint report of a plan, with the formulation's own checks."""
        return checks

    def plan_forces(self, forces: np.ndarray | None) -> tuple[dict, dict]:
        """(net force per contact frame for :attr:`Plan.forces`, extra entries for :attr:`Plan.extras`)."""
        return {}, {}

    def relinearized(self, dq: np.ndarray, x: np.ndarray, round_: int) -> Self | None:
        """The layout with rows re-linearized about a solution (``dq`` (N+1, nv), all variables ``x``)
        for solve ``round_ + 1`` (a new one, warm-started from the solution; this one is not changed),
        or None: no need. The kinematic formulation is exact: always None."""
        return None

    def diagnose(self, failed: Plan, relaxed: Callable[[], str]) -> str:
        """A failed plan in task terms; ``relaxed`` runs the generic diagnosis (hard targets relaxed
        into costs and solved again), which is the kinematic formulation's."""
        return relaxed()


def placement_of(pose) -> pin.SE3:
    """pin.SE3 of a spec Pose (position + roll-pitch-yaw)."""
    return pin.SE3(pin.rpy.rpyToMatrix(*pose.rpy), np.array(pose.position, dtype=float))


def knot_grid(spec: TaskSpec) -> tuple[int, float, np.ndarray]:
    """Uniform grid over the horizon: (N intervals, dt [s], times (N+1,) [s])."""
    horizon = spec.horizon
    N = max(MIN_INTERVALS, int(round(horizon / spec.dt)))
    dt = horizon / N
    return N, dt, np.linspace(0.0, horizon, N + 1)


def start_configuration(spec: TaskSpec, robot: Robot) -> np.ndarray:
    """The configuration the motion starts from, at rest (nq,): the spec's start state, else the
    robot's standing posture (raises SpecNotForRobot when the start's size is not the robot's)."""
    if spec.start is None:
        return np.array(robot.q_standing, dtype=float)
    q = np.array(spec.start.q, dtype=float)
    if q.shape != (robot.model.nq,):
        raise SpecNotForRobot(f"the spec's start state has {q.size} numbers; {robot.name} has a configuration of "
                              f"{robot.model.nq} (base position, quaternion, {robot.model.nq - 7} joints)")
    return q


def make_layout(spec: TaskSpec, robot: Robot) -> Layout:
    """Lay the spec out on the knot grid (raises FrameNotFound for unknown frames).

    Raises:
        robots.FrameNotFound: a spec item names a frame the robot does not have.
        PlannerError: the spec asks for something the kinematic planner cannot model.
    """
    N, dt, t = knot_grid(spec)
    starts = spec.phase_start_times()
    phase_of_knot = [spec.phase_at(float(tk)) for tk in t]
    # Contacts per knot: the union of the phases touching the knot (a contact holds at both
    # ends of its phase), the later phase winning if a frame appears in both.
    contacts_at: list[dict[int, tuple[str, pin.SE3]]] = []
    for tk in t:
        active: dict[int, tuple[str, pin.SE3]] = {}
        for i, ph in enumerate(spec.phases):
            end = starts[i] + ph.duration
            if starts[i] - 1e-9 <= tk <= end + 1e-9:
                for c in ph.contacts:
                    active[robot.frame_id(c.frame)] = (c.frame, placement_of(c.placement))
        contacts_at.append(active)
    grid = Layout(robot=robot, spec=spec, N=N, dt=dt, t=t, phase_of_knot=phase_of_knot,
                  contacts_at=contacts_at, frame_ids=[], terms=(), q_ref=start_configuration(spec, robot))
    terms = [*contact_terms(grid), *swing_terms(grid), *regularization_terms(grid)]
    for bounds in spec.com_bounds:
        terms += balance_terms(grid, bounds)
    for target in spec.targets:
        terms += frame_target_terms(grid, target)
    for com_target in spec.com_targets:
        terms += com_target_terms(grid, com_target)
    for joint_target in spec.joint_targets:
        terms += joint_target_terms(grid, joint_target)
    terms += closed_chain_terms(grid.with_terms(terms))  # reads the targets' terms
    return replace(grid, terms=tuple(terms), frame_ids=sorted({f for t in terms for f in t.frames()}))


def _use(lay: Layout, k: int) -> bool:
    """Constraints live on variable knots only (knots 0, 1 are fixed; N repeats N-1)."""
    return 2 <= k <= lay.N - 1


def contact_terms(lay: Layout) -> list[Term]:
    """Stance soles fixed in 6D to their placement: 3 position rows [m] + 3 rotation rows [rad]."""
    out: list[Term] = []
    for k in range(lay.N + 1):
        if not _use(lay, k):
            continue
        for fid, (frame, M) in lay.contacts_at[k].items():
            near = 6 if lay.robot.foot_side(lay.robot.model.frames[fid].name) else min(
                (_chain_joints(lay.robot, fid, other) for other in lay.contacts_at[k] if other != fid), default=6)
            kind = ContactPositionTerm if near < 6 else ContactTerm  # a sole keeps its 6 rows
            out.append(kind.at(k, fid, frame, M, lay.phase_name(k)))
    return out


def _chain_joints(robot: Robot, a: int, b: int) -> int:
    """The one-dof joints on the kinematic path between frames ``a`` and ``b`` (a thigh and its foot: 3)."""
    model = robot.model
    sa = set(model.supports[model.frames[a].parentJoint])
    sb = set(model.supports[model.frames[b].parentJoint])
    return sum(model.joints[j].nv == 1 for j in sa ^ sb)


def swing_terms(lay: Layout) -> list[Term]:
    """Feet off the ground stay above it; at a phase's middle they clear ``swing_height`` [m]."""
    out: list[Term] = []
    spec, robot = lay.spec, lay.robot
    contact_frames = {robot.frame_id(f): f for f in spec.contact_frames()}
    starts = spec.phase_start_times()
    for fid, frame in contact_frames.items():
        for k in range(lay.N + 1):
            if not _use(lay, k) or fid in lay.contacts_at[k]:
                continue
            out.append(ClearanceTerm.at(k, fid, 0.0, f"{frame} above ground", lay.phase_name(k)))
        for i, ph in enumerate(spec.phases):
            if any(robot.frame_id(c.frame) == fid for c in ph.contacts) or ph.swing_height <= 0:
                continue
            k = int(round((starts[i] + 0.5 * ph.duration) / lay.dt))
            if not _use(lay, k) or fid in lay.contacts_at[k]:
                continue
            out.append(ClearanceTerm.at(k, fid, ph.swing_height, f"{frame} swing clearance", ph.name))
    return out


COM_CENTERING_WEIGHT = 20.0  # [1/m^2 per s]: CoM ground projection towards the support centre
BASE_UPRIGHT_WEIGHT = 2.0  # [1/rad^2 per s]: base orientation towards upright, yaw of the feet


def regularization_terms(lay: Layout) -> list[Term]:
    """Soft terms that pick the natural motion among the many the constraints allow.

    The posture cost acts on the joints only, so without these the floating base is free, and a
    symmetric request (a squat) can be met more cheaply by rolling the pelvis onto one leg: the
    CoM then sits on the edge of the support polygon, where the plan is kinematically valid but
    the controller cannot track it (its ZMP leaves the soles). Two costs prevent that:

    * the CoM ground projection is pulled towards the centroid of the support polygon;
    * the base is pulled upright, with the mean yaw of the active soles.

    Both are weighted per second of motion, so they do not depend on the knot spacing; hard
    targets (a CoM shift for ``lean``, one-foot balance) override them.
    """
    out: list[Term] = []
    robot = lay.robot
    base = robot.frame_id("base")
    base_rotation = _standing_base_rotation(lay)  # the same at every knot
    for k in lay.variable_knots:
        hull = support_polygon(lay, k)
        if len(hull) >= 3:
            centre = hull.mean(axis=0)
            out.append(CoMPositionTerm.at(k, (True, True, False), [centre[0], centre[1], 0.0], "soft",
                                                COM_CENTERING_WEIGHT * lay.dt, np.zeros(0), "CoM centring (cost)",
                                                lay.phase_name(k)))
        yaws = [math.atan2(M.rotation[1, 0], M.rotation[0, 0]) for M in
                (M for fid, (_, M) in lay.contacts_at[k].items() if robot.foot_side(robot.model.frames[fid].name))]
        if yaws:
            yaw = math.atan2(sum(math.sin(y) for y in yaws), sum(math.cos(y) for y in yaws))
            R = pin.rpy.rpyToMatrix(0.0, 0.0, yaw) @ base_rotation
            out.append(FrameOrientationTerm.at(k, base, R, "soft", BASE_UPRIGHT_WEIGHT * lay.dt, 0.0,
                                                     "base upright (cost)", lay.phase_name(k)))
    return out


def _standing_base_rotation(lay: Layout) -> np.ndarray:
    """Base orientation at the standing posture with the feet's yaw removed (iCub's base is yawed)."""
    data = lay.robot.data()
    pin.framesForwardKinematics(lay.robot.model, data, lay.q_ref)
    feet = [data.oMf[lay.robot.frame_id(f"{s}_foot")].rotation for s in ("left", "right")]
    yaw = math.atan2(sum(R[1, 0] for R in feet), sum(R[0, 0] for R in feet))
    return pin.rpy.rpyToMatrix(0.0, 0.0, -yaw) @ data.oMf[lay.robot.frame_id("base")].rotation


def support_polygon(lay: LayoutData, k: int) -> np.ndarray:
    """Corners (M, 2) of the support polygon at knot ``k`` [m], counter-clockwise.

    Inside a phase it is the convex hull of the phase's soles. On a boundary knot, where a foot
    lifts off or touches down, the CoM must already (or still) be over the soles of the phase
    with fewer feet, so the smaller of the two hulls is used (a phase in flight has none).
    """
    entry = _support_entry(lay, k)
    return np.zeros((0, 2)) if entry is None else entry.hull


def support_halfplanes(lay: LayoutData, k: int) -> tuple[np.ndarray, np.ndarray] | None:
    """``halfplanes(support_polygon(lay, k))`` (read-only arrays), None when that polygon has fewer
    than 3 corners; computed once per phase."""
    entry = _support_entry(lay, k)
    return None if entry is None else entry.planes


class _PhasePolygon(NamedTuple):
    start: float  # [s]
    end: float  # [s]
    hull: np.ndarray  # (M, 2), read-only
    area: float  # [m^2]
    planes: tuple[np.ndarray, np.ndarray] | None  # halfplanes(hull) (read-only), None: < 3 corners


def _support_entry(lay: LayoutData, k: int) -> _PhasePolygon | None:
    """The smallest support polygon of the phases that hold at knot ``k`` (None: no sole)."""
    tk = lay.t[k]
    hulls = [p for p in _phase_polygons(lay) if p.start - 1e-9 <= tk <= p.end + 1e-9]
    if not hulls:
        return None
    return min(hulls, key=lambda h: h.area)


def _phase_polygons(lay: LayoutData) -> list[_PhasePolygon]:
    """The phases of ``lay.spec`` with soles, in order: their time spans and sole polygons,
    computed once per layout and spec (:func:`support_polygon` asks for them at every knot,
    several times over a plan)."""
    return lay.memo("phase_polygons", lambda: _build_phase_polygons(lay))


def _build_phase_polygons(lay: LayoutData) -> list[_PhasePolygon]:
    spec, robot = lay.spec, lay.robot
    out: list[_PhasePolygon] = []
    for start, phase in zip(spec.phase_start_times(), spec.phases, strict=True):
        soles = []
        for c in phase.contacts:
            side = robot.foot_side(robot.model.frames[robot.frame_id(c.frame)].name)
            if side is None:
                if region_supports(c):  # a thigh on a seat: its support region bears weight
                    soles.append(np.asarray(c.region, dtype=float) @ placement_of(c.placement).rotation.T
                                 + np.asarray(c.placement.position, dtype=float))
                continue  # a hand or other point contact: not part of the sole polygon
            soles.append(sole_corners_in_world(robot.profile.sole, side, placement_of(c.placement)))
        if soles:
            hull = polygon_of_soles(soles)
            planes = halfplanes(hull) if len(hull) >= 3 else None
            for a in (hull, *(planes or ())):
                a.setflags(write=False)  # shared by every knot of the phase
            out.append(_PhasePolygon(start, start + phase.duration, hull, _polygon_area(hull), planes))
    return out


SUPPORT_NORMAL_COS = math.cos(math.radians(30))  # a region on a surface tilted at most this much bears weight


def region_supports(contact: Contact) -> bool:
    """A contact with a support region on a surface facing up (its normal, or its placement's z axis,
    within 30 deg of vertical): its corners join the soles' support polygon."""
    if contact.region is None:
        return False
    n = contact.normal if contact.normal is not None else tuple(pin.rpy.rpyToMatrix(*contact.placement.rpy)[:, 2])
    return float(n[2]) >= SUPPORT_NORMAL_COS


def _polygon_area(hull: np.ndarray) -> float:
    x, y = hull[:, 0], hull[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))


POLYGON_ROWS = {1: 4, 2: 8}  # padded number of rows by number of active soles


def balance_terms(lay: Layout, bounds: CoMBounds) -> list[Term]:
    """CoM ground projection inside the support polygon shrunk by the margin, plus the box."""
    out: list[Term] = []
    ks = range(lay.N + 1) if bounds.window is None else knots_of(lay.t, None, bounds.window, lay.N)
    axes = tuple(lo is not None or hi is not None for lo, hi in zip(bounds.lower, bounds.upper, strict=True))
    for k in ks:
        if not _use(lay, k):
            continue
        if bounds.support_polygon:
            planes = support_halfplanes(lay, k)
            if planes is not None:
                A, b = planes
                n_feet = sum(1 for fid in lay.contacts_at[k] if lay.robot.foot_side(lay.robot.model.frames[fid].name))
                rows = max(POLYGON_ROWS.get(n_feet, 4 * n_feet), len(A))
                out.append(SupportPolygonTerm.at(k, A, b, rows, bounds, lay.phase_name(k)))
        if any(axes):
            out.append(CoMBoxTerm.at(k, bounds, axes, lay.phase_name(k)))
    return out


def frame_target_terms(lay: Layout, target: FrameTarget) -> list[Term]:
    """Frame position/orientation targets at their knots, hard (ball constraint) or soft (cost)."""
    out: list[Term] = []
    fid = lay.robot.frame_id(target.frame)
    ks = sorted({lay.free_knot(k) for k in knots_of(lay.t, target.time, target.window, lay.N)})
    for kk in ks:
        k = kk
        if kk < 2:
            continue  # fixed start knots: checked in the report only
        scale = 1.0 / len(ks)
        if target.position is not None:
            out.append(FramePositionTerm.at(kk, fid, target, scale, lay.phase_name(k)))
        if target.rpy is not None:
            mode = _mode(target.priority, target.orientation_tolerance)
            out.append(FrameOrientationTerm.at(
                kk, fid, pin.rpy.rpyToMatrix(*target.rpy), mode, target.weight * scale, target.orientation_tolerance,
                f"{target.frame} orientation target {target.name!r}", lay.phase_name(k), item=target))
    return out


def com_target_terms(lay: Layout, target: CoMTarget) -> list[Term]:
    """CoM position targets (per axis) at their knots, hard or soft."""
    out: list[Term] = []
    ks = sorted({lay.free_knot(k) for k in knots_of(lay.t, target.time, target.window, lay.N)})
    for kk in ks:
        if kk < 2:
            continue
        out.append(CoMPositionTerm.of_target(kk, target, len(ks), lay.phase_name(kk)))
    return out


def joint_target_terms(lay: Layout, target: JointTarget) -> list[Term]:
    """Joint angle targets as weighted costs."""
    out: list[Term] = []
    model = lay.robot.model
    if not model.existJointName(target.joint):
        raise SpecNotForRobot(
            f"joint target {target.name!r}: robot {lay.robot.name!r} has no joint {target.joint!r}"
        )
    jid = model.getJointId(target.joint)
    if model.joints[jid].nv != 1:
        raise SpecNotForRobot(f"joint target {target.name!r}: joint {target.joint!r} is not a one-dof joint")
    iv = model.joints[jid].idx_v
    ks = sorted({lay.free_knot(k) for k in knots_of(lay.t, target.time, target.window, lay.N)})
    for kk in ks:
        if kk < 2:
            continue
        out.append(JointTargetTerm.at(kk, iv, target, len(ks), lay.phase_name(kk)))
    return out


def held_together(spec: TaskSpec) -> list[tuple[Grasp, Grasp]]:
    """Pairs of grasps in which two hands hold one object together (same object and start and end)."""
    gs = spec.grasps
    return [(a, b) for i, a in enumerate(gs) for b in gs[i + 1:]
            if a.object == b.object and a.frame != b.frame and abs(a.start - b.start) < 1e-9 and a.end == b.end]


def grasp_relative_rotation(lay: Layout, a: Grasp, b: Grasp) -> np.ndarray | None:
    """``R_a^T R_b`` of the two hands at the grasp: from their HARD orientation targets at its start
    (None: either hand has none there)."""
    ka = knots_of(lay.t, a.start, None, lay.N)[0]
    rot: dict[str, np.ndarray] = {}
    for target in lay.spec.targets:
        if target.rpy is None or target.priority is not Priority.HARD or target.frame not in (a.frame, b.frame):
            continue
        if ka in knots_of(lay.t, target.time, target.window, lay.N):
            rot.setdefault(target.frame, pin.rpy.rpyToMatrix(*target.rpy))
    if a.frame not in rot or b.frame not in rot:
        return None
    return rot[a.frame].T @ rot[b.frame]


def closed_chain_terms(lay: Layout) -> list[Term]:
    """(``lay``: the layout with every other term.) Two hands holding one object form a closed chain: at every knot of the shared hold, the
    object's centre as placed by one hand (its grasp offset) is where the other places it (3 rows
    [m]), and the hands' relative orientation stays what their targets give at the grasp (3 rows,
    when both have one there). Stage-wise: both frames at the same knot. A knot where both hands
    already have HARD position and orientation targets (the press, the lift, the put-down: placed
    in the chain by the grasp) gets none: its rows would repeat the targets' (a degenerate NLP that
    IPOPT left infeasible); the chain holds the hands between them."""
    out: list[Term] = []
    posed: dict[int, set[tuple[str, int]]] = {}
    for t in lay.terms:
        if (isinstance(t, FrameOrientationTerm) or (isinstance(t, FramePositionTerm) and all(t.axes))) and t.hard:
            posed.setdefault(t.knot, set()).add((t.kind, t.frame_id))
    for a, b in held_together(lay.spec):
        fa, fb = lay.robot.frame_id(a.frame), lay.robot.frame_id(b.frame)
        R_rel = grasp_relative_rotation(lay, a, b)
        end = lay.spec.horizon if a.end is None else a.end
        ks = sorted({lay.free_knot(k) for k in knots_of(lay.t, None, (a.start, end), lay.N)})
        targeted = {(cls.kind, f) for cls in (FramePositionTerm, FrameOrientationTerm) for f in (fa, fb)}
        for k in ks:
            if not _use(lay, k) or (R_rel is not None and targeted <= posed.get(k, set())):
                continue
            out.append(ClosedChainTerm.at(k, fa, fb, a, b, R_rel, lay.phase_name(k)))
    return out


def _mode(priority: Priority, tolerance: float) -> str:
    return target_mode(priority is Priority.SOFT, tolerance)

