"""Twin test of the planner's terms: every term kind's CasADi expression against an independent
numpy/Pinocchio computation of the same residual, and its CasADi Jacobian against central finite
differences of that numpy form, with the named tolerances below (issue 30, "Terms as classes":
the test that protects that refactor; a new kind fails :func:`test_every_kinematic_term_kind_of_the_planner_has_a_twin`
until it has a twin here).

* Kinematic kinds (contact, swing clearance, support polygon, CoM box, frame position and
  orientation targets hard and soft, base upright, CoM targets and centring, joint target, closed
  chain, self-collision, scene collision per shape, the joint torque margin against RNEA at rest):
  one term of a layout built from a small real
  Talos spec (stand, lift the right foot, stand; hand targets, CoM target and bounds, a joint
  target, two hands holding one box, a scene), through
  :func:`planner.trajopt.terms.stage_function`, at seeded random chart displacements ``dq``; the
  reference is Pinocchio on ``q_ref (+) dq``, its Jacobian central differences along the chart.
* Joint and velocity limits (variable bounds and linear rows) and the quadratic costs' operators
  against the model's limits and Pinocchio's ``difference``; the report's checks
  (:func:`planner.trajopt.checks.check_plan`) against the worst violation of the rows they
  stand for.
* The dynamic formulation: the per-knot physics (friction pyramid, Newton residual, angular
  momentum rate, sole corner heights), its rows over the whole grid (CoM dynamics, friction,
  angular momentum, ankle torques), the linearized whole-body momentum against Pinocchio's
  centroidal map, and the CoP of the corner forces against the soles shrunk by the margin.
* The payload has no CasADi form (a check on the plan, :mod:`planner.trajopt.payload`): its numpy
  torques against Pinocchio's RNEA with the object's weight as an external force.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest

from planner.trajopt.centroidal.nlp import sole_corner_heights
from planner.trajopt.centroidal.physics import (
    GRAVITY,
    angular_momentum_rate,
    com_acceleration,
    com_dynamics_residual,
    friction_pyramid,
)
from planner.trajopt.centroidal.torque import TorqueMarginTerm, joint_ids
from planner.trajopt.collision import Rows, sphere_sets, with_collision_terms
from planner.trajopt.kinds import ContactPositionTerm
from planner.trajopt.layout import Layout, make_layout, support_halfplanes, support_polygon
from planner.trajopt.payload import payload_torques
from planner.trajopt.scene_collision import SceneRows, obstacles, row_value, with_scene_terms
from planner.trajopt.symbolic import SymbolicKinematics, chart_to_configuration
from planner.trajopt.term import TERM_KINDS, NumericKinematics, StageKinematics, Term, kind_of_check
from planner.trajopt.terms import stage_function, term_kinds
from robots.contact import sole_corners
from tasks.scene import Scene, SceneObject
from tasks.specs import (
    CoMBounds,
    CoMTarget,
    Contact,
    FrameTarget,
    Grasp,
    JointTarget,
    Phase,
    Pose,
    Priority,
    TaskSpec,
)

# -- named tolerances ----------------------------------------------------------------------------
VALUE_TOL = 1e-9  # CasADi vs numpy/Pinocchio value: the same float64 arithmetic in another order
VALUE_RTOL = 1e-10  # relative part, for rows of large magnitude (scene rows, N and N m)
JAC_TOL = 1e-6  # CasADi Jacobian vs central differences, relative to max(1, |J|max)
FD_STEP = 1e-6  # central-difference step on each chart coordinate (or input) [m], [rad], [N]
DRAWS = 2  # random configurations per kind
DQ_SCALE = 0.2  # standard deviation of the chart displacement [m], [rad]
SEED = 20261128
MARGIN = 0.01  # [m] collision margin written into the collision and scene terms

FOOT_Y = 0.085  # [m] Talos's standing soles


SCENE = Scene(objects=(
    SceneObject(name="crate", shape="box", size=(0.3, 0.2, 0.25), position=(0.35, -0.4, 0.8), rpy=(0.2, -0.3, 0.5)),
    SceneObject(name="pipe", shape="cylinder", size=(0.06, 0.5), position=(0.3, -0.3, 1.0), rpy=(1.2, 0.1, 0.0)),
    SceneObject(name="ball", shape="sphere", size=(0.1,), position=(0.25, -0.45, 0.7)),
    SceneObject(name="box", shape="box", size=(0.2, 0.3, 0.2), position=(0.45, 0.0, 0.9),
                movable=True, mass=1.0),  # held in both hands
))

def _feet(*frames: str) -> tuple[Contact, ...]:
    y = {"left_foot": FOOT_Y, "right_foot": -FOOT_Y}
    return tuple(Contact(frame=f, placement=Pose(position=(0.0, y[f], 0.0))) for f in frames)


def _spec() -> TaskSpec:
    """A small Talos task with every kinematic term kind: stand, lift the right foot, stand again."""
    return TaskSpec(
        robot="talos",
        phases=(Phase(name="stand", duration=0.6, contacts=_feet("left_foot", "right_foot")),
                Phase(name="lift", duration=0.6, contacts=_feet("left_foot"), swing_height=0.05),
                Phase(name="land", duration=0.6, contacts=_feet("left_foot", "right_foot"))),
        targets=(
            FrameTarget(name="reach", frame="right_hand", position=(0.3, -0.3, 1.0), rpy=(0.0, -1.2, 0.0),
                        axes=(True, True, False), time=0.3),
            FrameTarget(name="soft reach", frame="left_hand", position=(0.3, 0.3, 0.9), rpy=(0.3, 0.0, 0.2),
                        time=0.3, priority=Priority.SOFT),
            FrameTarget(name="hold left", frame="left_hand", rpy=(0.0, -1.0, 0.0), time=1.35),
            FrameTarget(name="hold right", frame="right_hand", rpy=(0.0, -1.0, 0.3), time=1.35),
        ),
        com_targets=(CoMTarget(name="shift", position=(0.01, None, 0.8), time=0.3),
                     CoMTarget(name="soft shift", position=(None, 0.02, 0.85), time=0.45,
                               priority=Priority.SOFT)),
        com_bounds=(CoMBounds(name="balance", lower=(None, None, 0.7), upper=(0.1, None, None)),),
        joint_targets=(JointTarget(name="elbow", joint="arm_left_4_joint", value=-1.0, time=0.3),),
        grasps=(Grasp(name="box left", object="box", frame="left_hand", offset=(0.0, 0.0, -0.1), start=1.35),
                Grasp(name="box right", object="box", frame="right_hand", offset=(0.0, 0.0, -0.1), start=1.35)),
        dt=0.075,
        scene=SCENE,
    )


COLLISION_PAIRS = {("arm_left_5_link", "base_link"), ("gripper_left_base_link", "leg_right_3_link")}
SCENE_LINKS = ("arm_right_5", "arm_right_7", "gripper_right_base")
COLLISION_KNOT = 5
TORQUE_JOINTS = ("arm_left_2_joint", "arm_left_4_joint", "arm_right_1_joint", "torso_2_joint")


@pytest.fixture(scope="module")
def layout(talos) -> Layout:
    """The spec's layout, with self-collision and scene terms at one knot appended (the grasps name
    their hands by role, ``left_hand``: the scene rows' contact exclusions resolve it)."""
    lay = make_layout(_spec(), talos)
    kinematic = list(lay.terms)
    thigh = talos.frame_id("leg_left_3_link")  # a thigh held on a seat in position only (sit_down)
    kinematic.append(ContactPositionTerm.at(COLLISION_KNOT, thigh, "leg_left_3_link",
                                            pin.SE3(np.eye(3), np.array([-0.22, 0.085, 0.37])), "twin"))
    sets = sphere_sets(talos)
    lay = lay.with_terms([])
    index = [i for i, name in enumerate(sets.pair_names) if name in COLLISION_PAIRS]
    assert len(index) == len(COLLISION_PAIRS)
    ends = [sets.starts[pi + 1] if pi + 1 < len(sets.starts) else len(sets.sa) for pi in index]
    rows = Rows({pi: set(range(end - sets.starts[pi])) for pi, end in zip(index, ends, strict=True)},
                {pi: {COLLISION_KNOT} for pi in index})
    lay = with_collision_terms(lay, sets, rows, index, MARGIN)
    obs = obstacles(SCENE)
    arm = {s for s in range(len(sets.sphere_radius)) if sets.links[sets.sphere_owner[s]].startswith(SCENE_LINKS)}
    scene_rows = SceneRows(spheres={i: set(arm) for i in range(len(obs))},
                           knots={i: {COLLISION_KNOT} for i in range(len(obs))})
    lay = with_scene_terms(lay, sets, obs, scene_rows, list(range(len(obs))), MARGIN)
    arms = joint_ids(talos, TORQUE_JOINTS)  # a torque margin term, with a frozen rest of RNEA [N m]
    kinematic.append(TorqueMarginTerm.at(COLLISION_KNOT, talos, arms, 0.85, np.linspace(-3.0, 2.0, len(arms)), "twin"))
    return lay.with_terms([*kinematic, *lay.terms])


# -- independent numpy/Pinocchio forms ------------------------------------------------------------


class Kinematics(NamedTuple):
    """Pinocchio's forward kinematics of one configuration."""

    model: pin.Model
    data: pin.Data
    q: np.ndarray

    def frame(self, fid: int) -> pin.SE3:
        return pin.updateFramePlacement(self.model, self.data, fid)

    def com(self) -> np.ndarray:
        return np.array(pin.centerOfMass(self.model, self.data, self.q, False))


def _kinematics(robot, q: np.ndarray) -> Kinematics:
    model = robot.model
    data = model.createData()
    pin.forwardKinematics(model, data, q)
    return Kinematics(model, data, q)


def _rotation_error(R_target: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Rotation rows independently: sin(angle) * axis of R_t^T R from its unit quaternion (w, v),
    2 w v (smooth at every angle, the same for q and -q; no log3 near pi)."""
    quat = pin.Quaternion(R_target.T @ R)
    return 2.0 * quat.w * np.array([quat.x, quat.y, quat.z])


def _target_rotation(term: Term) -> np.ndarray:
    return _target_rpy_matrix(term.item) if term.item is not None else _params_rotation(term.params[0:9])


def _params_rotation(flat: np.ndarray) -> np.ndarray:
    return np.asarray(flat, dtype=float).reshape(3, 3).T  # stored column-major


def _target_rpy_matrix(target) -> np.ndarray:
    return pin.rpy.rpyToMatrix(*target.rpy)


def _contact_ref(lay: Layout, term: Term, kin: Kinematics) -> np.ndarray:
    frame, M = lay.contacts_at[term.knot][term.structure[1]]
    oMf = kin.frame(term.structure[1])
    return np.concatenate([oMf.translation - M.translation, _rotation_error(M.rotation, oMf.rotation)])


def _contact_position_ref(lay: Layout, term: Term, kin: Kinematics) -> np.ndarray:
    return kin.frame(term.structure[1]).translation - np.array([-0.22, 0.085, 0.37])  # the fixture's seat place


def _clearance_ref(lay: Layout, term: Term, kin: Kinematics) -> np.ndarray:
    return np.array([kin.frame(term.structure[1]).translation[2]])


def _polygon_ref(lay: Layout, term: Term, kin: Kinematics) -> np.ndarray:
    planes = support_halfplanes(lay, term.knot)
    assert planes is not None
    A = np.zeros((term.structure[1], 2))
    A[: len(planes[0])] = planes[0]
    return A @ kin.com()[:2]


def _com_box_ref(lay: Layout, term: Term, kin: Kinematics) -> np.ndarray:
    return kin.com()[np.array(term.structure[1])]


def _soft(err: np.ndarray, term: Term) -> np.ndarray:
    """A soft term's cost: weight |err|^2, the weight being the term's (spec weight / knots)."""
    return np.array([term.params[-1] * float(err @ err)])


def _frame_pos_ref(lay: Layout, term: Term, kin: Kinematics) -> np.ndarray:
    target = term.item
    err = (kin.frame(term.structure[1]).translation - np.array(target.position))[np.array(target.axes)]
    return _soft(err, term) if term.structure[-1] == "soft" else err


def _frame_rot_ref(lay: Layout, term: Term, kin: Kinematics) -> np.ndarray:
    R_t = _target_rotation(term)
    R = kin.frame(term.structure[1]).rotation
    err = _rotation_error(R_t, R)
    if term.structure[-1] == "soft":
        return _soft(err, term)
    angle = float(np.linalg.norm(pin.log3(R_t.T @ R)))  # a hard target's last row: 1 + 2 cos(angle), >= 1 within 90 deg
    return np.append(err, 1.0 + 2.0 * np.cos(angle))


def _com_pos_ref(lay: Layout, term: Term, kin: Kinematics) -> np.ndarray:
    if term.item is None:  # the CoM centring cost: towards the support polygon's centroid
        goal = np.array([*support_polygon_centre(lay, term.knot), 0.0])
        axes = np.array([True, True, False])
    else:
        goal = np.array([0.0 if v is None else v for v in term.item.position])
        axes = np.array([v is not None for v in term.item.position])
    err = (kin.com() - goal)[axes]
    return _soft(err, term) if term.structure[-1] == "soft" else err


def support_polygon_centre(lay: Layout, k: int) -> np.ndarray:
    return support_polygon(lay, k).mean(axis=0)


def _torque_margin_ref(lay: Layout, term: Term, kin: Kinematics) -> np.ndarray:
    """Pinocchio's RNEA at rest (the gravity torques), plus the frozen rest where it loads the joint
    (upper rows) or where it pulls the other way (lower rows), over the limits."""
    model = kin.model
    idx = [model.joints[j].idx_v for j in term.structure[1]]
    tau = pin.rnea(model, model.createData(), kin.q, np.zeros(model.nv), np.zeros(model.nv))[idx]
    rest = term.params
    limits = model.effortLimit[idx]
    return np.concatenate([(tau + np.where(rest > 0, rest, 0.0)) / limits, (tau + np.where(rest < 0, rest, 0.0)) / limits])


def _joint_ref(lay: Layout, term: Term, kin: Kinematics) -> np.ndarray:
    target = term.item
    jid = kin.model.getJointId(target.joint)
    value = kin.q[kin.model.joints[jid].idx_q]
    return np.array([term.params[1] * (value - target.value) ** 2])


def _frame_rel_ref(lay: Layout, term: Term, kin: Kinematics) -> np.ndarray:
    a, b = (g for g in lay.spec.grasps if g.object == term.item.object)
    Ma, Mb = kin.frame(term.structure[1]), kin.frame(term.structure[2])
    rows = [Ma.act(np.array(a.offset)) - Mb.act(np.array(b.offset))]
    if term.structure[3]:
        hold = {t.frame: _target_rpy_matrix(t) for t in lay.spec.targets if t.name.startswith("hold")}
        R_rel = hold[a.frame].T @ hold[b.frame]
        rows.append(_rotation_error(R_rel, Ma.rotation.T @ Mb.rotation))
    return np.concatenate(rows)


def _collision_ref(lay: Layout, term: Term, kin: Kinematics) -> np.ndarray:
    sets = sphere_sets(lay.robot)
    _, ja, jb, _, _, chosen = term.structure
    a, b = (int(x) for x in sets.pairs[sets.pair_names.index(term.item)])
    wa = np.array([kin.data.oMi[ja].act(c) for c in sets.centres[a]])
    wb = np.array([kin.data.oMi[jb].act(c) for c in sets.centres[b]])
    return np.array([float(np.dot(wa[i] - wb[j], wa[i] - wb[j])) for i, j in chosen])


def _scene_ref(lay: Layout, term: Term, kin: Kinematics) -> np.ndarray:
    sets = sphere_sets(lay.robot)
    (ob,) = (o for o in obstacles(SCENE) if o.key == term.item)
    chosen = [s for s in range(len(sets.sphere_radius))
              if sets.links[sets.sphere_owner[s]].startswith(SCENE_LINKS)]
    assert len(chosen) == term.n_rows  # no sphere excluded by a planned contact at this knot
    out = []
    for s in chosen:
        centre = kin.data.oMi[int(sets.joints[sets.sphere_owner[s]])].act(sets.sphere_local[s])
        u = ob.rotation.T @ (centre - ob.position)
        a = ob.inflated(np.array([sets.sphere_radius[s] + MARGIN]))[0]
        out.append(float(row_value(ob.shape, u, a)))
    return np.array(out)


class Kind(NamedTuple):
    """One term kind: which term of the layout it picks, and its numpy form."""

    select: Callable[[Term], bool]
    reference: Callable[[Layout, Term, Kinematics], np.ndarray]
    cost: bool = False  # the term adds to the cost (output 1) instead of rows (output 0)


def _named(kind: str, mode: str | None = None, item=None):
    def select(t: Term) -> bool:
        return (t.kind == kind and (mode is None or t.structure[-1] == mode)
                and (item is None or item(t.item)))
    return select


KINDS: dict[str, Kind] = {
    "contact (foot placement)": Kind(_named("contact"), _contact_ref),
    "contact (position only: a thigh on a seat)": Kind(_named("contact_position"), _contact_position_ref),
    "swing clearance": Kind(lambda t: t.kind == "clearance" and t.lower[0] > 0, _clearance_ref),
    "CoM support polygon (two soles)": Kind(lambda t: t.kind == "polygon" and t.structure[1] == 8, _polygon_ref),
    "CoM support polygon (one sole)": Kind(lambda t: t.kind == "polygon" and t.structure[1] == 4, _polygon_ref),
    "CoM bounds box": Kind(_named("com_box"), _com_box_ref),
    "frame target position (hard)": Kind(_named("frame_pos", "box"), _frame_pos_ref),
    "frame target position (soft)": Kind(_named("frame_pos", "soft"), _frame_pos_ref, cost=True),
    "frame target orientation (hard)": Kind(
        _named("frame_rot", "box", lambda item: item is not None and item.name == "reach"), _frame_rot_ref),
    "frame target orientation (soft)": Kind(
        _named("frame_rot", "soft", lambda item: item is not None), _frame_rot_ref, cost=True),
    "base upright (cost)": Kind(_named("frame_rot", "soft", lambda item: item is None), _frame_rot_ref, cost=True),
    "CoM target (hard)": Kind(_named("com_pos", "box", lambda item: item is not None), _com_pos_ref),
    "CoM target (soft)": Kind(_named("com_pos", "soft", lambda item: item is not None), _com_pos_ref, cost=True),
    "CoM centring (cost)": Kind(_named("com_pos", "soft", lambda item: item is None), _com_pos_ref, cost=True),
    "joint target": Kind(_named("joint"), _joint_ref, cost=True),
    "closed chain (two hands)": Kind(lambda t: t.kind == "frame_rel" and t.structure[3], _frame_rel_ref),
    "self-collision spheres": Kind(_named("collision"), _collision_ref),
    "torque margin (arms, torso)": Kind(_named("torque_margin"), _torque_margin_ref),
    "scene collision (box)": Kind(lambda t: t.kind == "scene" and t.structure[1] == "box", _scene_ref),
    "scene collision (cylinder)": Kind(lambda t: t.kind == "scene" and t.structure[1] == "cylinder", _scene_ref),
    "scene collision (sphere)": Kind(lambda t: t.kind == "scene" and t.structure[1] == "sphere", _scene_ref),
}


def _assert_jacobian(J: np.ndarray, fd: np.ndarray, what: str) -> None:
    scale = max(1.0, float(np.abs(J).max()))
    worst = float(np.abs(J - fd).max())
    assert worst <= JAC_TOL * scale, f"{what}: |J - FD| = {worst:.3e} > {JAC_TOL:g} x {scale:.3g}"


def _central_differences(f: Callable[[np.ndarray], np.ndarray], x: np.ndarray) -> np.ndarray:
    cols = []
    for i in range(len(x)):
        e = np.zeros(len(x))
        e[i] = FD_STEP
        cols.append((f(x + e) - f(x - e)) / (2 * FD_STEP))
    return np.array(cols).T


@pytest.mark.parametrize("name", list(KINDS))
def test_kinematic_term_matches_its_numpy_twin(layout, talos, name):
    """The stage function of one term equals its numpy/Pinocchio form at random configurations,
    and CasADi's Jacobian of it equals central differences of the numpy form along the chart."""
    kind = KINDS[name]
    index = next((i for i, t in enumerate(layout.terms) if kind.select(t)), None)
    assert index is not None, f"the spec has no {name} term"
    term = layout.terms[index]
    fn = stage_function(layout, [index], "twin")
    out = 1 if kind.cost else 0
    model, q_ref = talos.model, layout.q_ref
    dq_sym = ca.SX.sym("dq", talos.nv)
    expr = fn(dq_sym, q_ref, term.params)[out]
    jac = ca.Function("twin_jacobian", [dq_sym], [ca.jacobian(expr, dq_sym)])

    def numpy_form(dq: np.ndarray) -> np.ndarray:
        return np.asarray(kind.reference(layout, term, _kinematics(talos, chart_to_configuration(model, q_ref, dq))),
                          dtype=float).ravel()

    rng = np.random.default_rng(SEED)
    for _ in range(DRAWS):
        dq = rng.normal(scale=DQ_SCALE, size=talos.nv)
        value = np.asarray(fn(dq, q_ref, term.params)[out], dtype=float).ravel()
        want = numpy_form(dq)
        assert value.shape == want.shape and len(want) == (1 if kind.cost else term.n_rows)
        np.testing.assert_allclose(value, want, rtol=VALUE_RTOL, atol=VALUE_TOL, err_msg=name)
        _assert_jacobian(np.asarray(jac(dq)), _central_differences(numpy_form, dq), name)
        # the kind's own numpy residual is this independent form too
        own = term.residual(NumericKinematics(model, chart_to_configuration(model, q_ref, dq)))
        np.testing.assert_allclose(own, want, rtol=VALUE_RTOL, atol=VALUE_TOL, err_msg=name)


EXAMPLES_PER_KIND = 3  # terms of distinct structure checked per kind


def _examples(lay: Layout, cls: type[Term]) -> list[int]:
    """Indices of up to EXAMPLES_PER_KIND terms of ``cls`` with distinct structures (and both cost
    and constraint variants when the kind has both)."""
    seen: dict[tuple, int] = {}
    for i, t in enumerate(lay.terms):
        if type(t) is cls:
            seen.setdefault((t.structure, t.is_cost), i)
    by_role: dict[bool, list[int]] = {}
    for (_, is_cost), i in seen.items():
        by_role.setdefault(is_cost, []).append(i)
    picked = [ids[0] for ids in by_role.values()]
    picked += [i for i in seen.values() if i not in picked]
    return picked[:EXAMPLES_PER_KIND]


@pytest.mark.parametrize("kind", sorted(term_kinds()))
def test_every_term_kinds_casadi_expression_matches_its_numpy_residual(layout, talos, kind):
    """Each registered term kind (:data:`planner.trajopt.term.TERM_KINDS`): its CasADi expression
    (through the NLP's stage function) equals its own numpy residual at random configurations, for
    terms of several structures, and the CasADi Jacobian along the chart equals central differences
    of the numpy residual."""
    cls = term_kinds()[kind]
    model, q_ref = talos.model, layout.q_ref
    examples = _examples(layout, cls)
    assert examples, f"the twin layout has no {kind!r} term"
    rng = np.random.default_rng(SEED)
    for index in examples:
        term = layout.terms[index]
        fn = stage_function(layout, [index], "twin_" + kind)
        out = 1 if term.is_cost else 0
        dq_sym = ca.SX.sym("dq", talos.nv)
        jac = ca.Function("twin_jacobian", [dq_sym], [ca.jacobian(fn(dq_sym, q_ref, term.params)[out], dq_sym)])

        def residual(dq: np.ndarray, term=term) -> np.ndarray:
            return term.residual(NumericKinematics(model, chart_to_configuration(model, q_ref, dq)))

        for _ in range(DRAWS):
            dq = rng.normal(scale=DQ_SCALE, size=talos.nv)
            value = np.asarray(fn(dq, q_ref, term.params)[out], dtype=float).ravel()
            want = residual(dq)
            assert want.shape == (1 if term.is_cost else term.n_rows,), (kind, want.shape)
            np.testing.assert_allclose(value, want, rtol=VALUE_RTOL, atol=VALUE_TOL, err_msg=f"{kind} {term.label}")
            _assert_jacobian(np.asarray(jac(dq)), _central_differences(residual, dq), f"{kind} {term.label}")


def test_every_term_kind_of_the_planner_has_a_twin(layout):
    """Every registered term kind appears in the twin layout, is twinned above against an
    independent numpy form, and defines its own CasADi expression and numpy residual: a new kind
    fails here until it gets its twin."""
    kinds = term_kinds()
    assert {"contact", "clearance", "polygon", "com_box", "frame_pos", "frame_rot", "com_pos", "joint",
            "frame_rel", "collision", "scene"} <= set(kinds), set(kinds)
    for name, cls in kinds.items():
        assert cls.kind == name and issubclass(cls, Term)
        assert cls.expression is not Term.expression and cls.residual is not Term.residual, name
    twinned = {t.kind for t in layout.terms if any(k.select(t) for k in KINDS.values())}
    assert twinned == {t.kind for t in layout.terms} == set(kinds)
    assert all(type(t) is kinds[t.kind] for t in layout.terms)


def test_a_new_term_kind_is_one_class(layout, talos):
    """What docs/terms.md tells a newcomer: a subclass of Term with a ``kind``, an expression and a
    residual is registered on definition and goes through the NLP's stage function with the other
    terms of its knot; a second class of the same kind name is refused."""
    base = talos.frame_id("base")

    class BaseHeight(Term):  # the base's height above a value [m]
        kind = "test_base_height"

        def frames(self) -> tuple[int, ...]:
            return (base,)

        def expression(self, p, kin: StageKinematics) -> tuple:
            return kin.frames[base][0][2] - p[0], 0

        def residual(self, kin: NumericKinematics) -> np.ndarray:
            return np.array([kin.frame(base).translation[2] - self.params[0]])

    try:
        assert TERM_KINDS["test_base_height"] is BaseHeight
        with pytest.raises(TypeError, match="defined twice"):
            type("Another", (Term,), {"kind": "test_base_height"})
        term = BaseHeight(knot=COLLISION_KNOT, structure=("test_base_height",), params=np.array([0.9]),
                          lower=np.zeros(1), upper=np.array([np.inf]))
        ids = [i for i, t in enumerate(layout.terms) if t.knot == COLLISION_KNOT and not t.is_cost][:3]
        lay = layout.with_terms([*(layout.terms[i] for i in ids), term])
        fn = stage_function(lay, list(range(len(lay.terms))), "twin_new_kind")
        dq = np.random.default_rng(SEED).normal(scale=DQ_SCALE, size=talos.nv)
        kin = NumericKinematics(talos.model, chart_to_configuration(talos.model, layout.q_ref, dq))
        p = np.concatenate([t.params for t in lay.terms])
        g = np.asarray(fn(dq, layout.q_ref, p)[0], dtype=float).ravel()
        want = np.concatenate([t.residual(kin) for t in lay.terms])
        np.testing.assert_allclose(g, want, rtol=VALUE_RTOL, atol=VALUE_TOL)
    finally:
        TERM_KINDS.pop("test_base_height", None)


def test_the_reports_checks_find_their_kinds_diagnosis(talos):
    """A failed plan's sentence comes from the term kind whose rows its worst check measures: the CoM
    bound kinds speak of the bound, a check no kind claims (joint limits) gets the generic sentence."""
    from planner.results import Check, CheckKind

    def check(kind: CheckKind, name: str, subject: str = "") -> Check:
        return Check.constraint(name=name, kind=kind, violation=0.04, tolerance=1e-3, unit="m", time=1.2,
                                subject=subject)

    assert kind_of_check(CheckKind.COM_BOX) is term_kinds()["com_box"]
    assert kind_of_check(CheckKind.COM_SUPPORT_POLYGON_AT_REST) is term_kinds()["polygon"]
    assert kind_of_check(CheckKind.SELF_COLLISION) is term_kinds()["collision"]
    assert kind_of_check(CheckKind.JOINT_POSITION_LIMITS) is Term
    bound = check(CheckKind.COM_BOX, "CoM bound 'balance' box", "balance")
    assert kind_of_check(bound.kind).diagnosis(bound, "lift", "infeasible") == (
        "CoM bound 'balance' cannot hold in phase 'lift': the CoM ends 0.040 m outside at t = 1.20 s (infeasible)")
    limits = check(CheckKind.JOINT_POSITION_LIMITS, "joint position limits")
    assert kind_of_check(limits.kind).diagnosis(limits, "lift", "infeasible") == (
        "joint position limits violated by 0.04 m at t = 1.20 s in phase 'lift' (infeasible)")


# -- the dynamic formulation's per-knot expressions ------------------------------------------------


def _rotation(rng: np.random.Generator) -> np.ndarray:
    return pin.exp3(rng.normal(scale=0.4, size=3))


def _dynamic_case(name: str, rng: np.random.Generator):
    """(CasADi function of x, numpy function of x, x) for one dynamic expression."""
    x_sym = ca.SX.sym("x", 0)
    if name == "friction pyramid":
        R = _rotation(rng)
        x = np.concatenate([rng.normal(size=3) * 200.0 + np.array([0, 0, 400.0]), [0.7]])  # force [N], mu
        x_sym = ca.SX.sym("x", 4)
        expr = friction_pyramid(x_sym[0:3], R, x_sym[3])

        def numpy_form(x):
            t1, t2, n = R[:, 0], R[:, 1], R[:, 2]
            f, mu = x[0:3], x[3] / math.sqrt(2.0)
            fn = n @ f
            return np.array([fn, mu * fn - t1 @ f, mu * fn + t1 @ f, mu * fn - t2 @ f, mu * fn + t2 @ f])
    elif name == "Newton residual (CoM dynamics)":
        mass, dt = 90.0, 0.05
        x = np.concatenate([rng.normal(size=9) * 0.05 + np.tile([0, 0, 0.9], 3), rng.normal(size=3) * 300.0])
        x_sym = ca.SX.sym("x", 12)
        expr = com_dynamics_residual(mass, com_acceleration(x_sym[0:3], x_sym[3:6], x_sym[6:9], dt), x_sym[9:12])

        def numpy_form(x):
            acc = (x[0:3] - 2 * x[3:6] + x[6:9]) / dt**2
            return mass * acc - mass * np.array([0.0, 0.0, -9.81]) - x[9:12]
    else:  # angular-momentum rate about the CoM from point forces
        points = rng.normal(size=(4, 3)) * 0.1
        x = np.concatenate([[0.0, 0.0, 0.9] + rng.normal(size=3) * 0.05, rng.normal(size=12) * 100.0])
        x_sym = ca.SX.sym("x", 15)
        expr = angular_momentum_rate(x_sym[0:3], points, [x_sym[3 + 3 * i: 6 + 3 * i] for i in range(4)])

        def numpy_form(x):
            com, forces = x[0:3], x[3:].reshape(4, 3)
            return sum((np.cross(p - com, f) for p, f in zip(points, forces, strict=True)), np.zeros(3))
    fn = ca.Function("f", [x_sym], [expr, ca.jacobian(expr, x_sym)])
    return fn, numpy_form, x


@pytest.mark.parametrize("name", ["friction pyramid", "Newton residual (CoM dynamics)", "angular-momentum rate"])
def test_dynamic_expression_matches_its_numpy_twin(name):
    assert np.allclose(GRAVITY, [0.0, 0.0, -9.81])
    rng = np.random.default_rng(SEED)
    for _ in range(DRAWS):
        fn, numpy_form, x = _dynamic_case(name, rng)
        value, J = (np.asarray(v, dtype=float) for v in fn(x))
        np.testing.assert_allclose(value.ravel(), numpy_form(x), rtol=VALUE_RTOL, atol=VALUE_TOL, err_msg=name)
        _assert_jacobian(J, _central_differences(numpy_form, x), name)


def test_sole_corner_heights_match_pinocchio(talos):
    """The dynamic formulation's sole corner heights (the swing floor and the corner forces' lever
    arms) against Pinocchio's foot placements, and their Jacobian against central differences."""
    model, q_ref = talos.model, np.array(talos.q_standing)
    kin = SymbolicKinematics(model)
    dq_sym = ca.SX.sym("dq", talos.nv)
    expr = sole_corner_heights(kin, kin.joint_placements(q_ref, dq_sym), talos)
    fn = ca.Function("h", [dq_sym], [expr, ca.jacobian(expr, dq_sym)])

    def numpy_form(dq):
        k = _kinematics(talos, chart_to_configuration(model, q_ref, dq))
        return np.array([k.frame(talos.frame_id(f"{side}_foot")).act(c)[2]
                         for side in ("left", "right") for c in sole_corners(talos.profile.sole, side)])

    rng = np.random.default_rng(SEED)
    for _ in range(DRAWS):
        dq = rng.normal(scale=DQ_SCALE, size=talos.nv)
        value, J = (np.asarray(v, dtype=float) for v in fn(dq))
        np.testing.assert_allclose(value.ravel(), numpy_form(dq), rtol=VALUE_RTOL, atol=VALUE_TOL)
        _assert_jacobian(J, _central_differences(numpy_form, dq), "sole corner heights")


def test_payload_torques_match_rnea_with_the_objects_weight(talos):
    """The payload check's static torques (numpy: g(q) + J_p^T m g) equal Pinocchio's inverse
    dynamics at rest with the object's weight applied as an external force on the hand's joint."""
    model, q_ref = talos.model, np.array(talos.q_standing)
    frame, offset, mass = "right_hand", np.array([0.05, 0.0, -0.1]), 2.5
    fid = talos.frame_id(frame)
    joint = model.frames[fid].parentJoint
    rng = np.random.default_rng(SEED)
    for _ in range(DRAWS):
        q = chart_to_configuration(model, q_ref, rng.normal(scale=DQ_SCALE, size=talos.nv))
        data = model.createData()
        pin.framesForwardKinematics(model, data, q)
        point = data.oMf[fid].act(offset)  # the object's centre in the world
        oMj = data.oMi[joint]
        weight = pin.Force(np.array([0.0, 0.0, -mass * 9.81]), np.cross(point, [0.0, 0.0, -mass * 9.81]))
        fext = [pin.Force.Zero() for _ in range(model.njoints)]
        fext[joint] = oMj.actInv(weight)  # a world wrench about the origin, in the joint's frame
        tau = pin.rnea(model, data, q, np.zeros(model.nv), np.zeros(model.nv), pin.StdVec_Force(fext))
        np.testing.assert_allclose(payload_torques(talos, q, frame, offset, mass), tau[6:], rtol=1e-9, atol=1e-9)


# -- joint limits, velocity limits and the quadratic costs' operators -----------------------------


def test_joint_and_velocity_limits_match_the_models_limits(layout, talos):
    """Joint limits are variable bounds and velocity limits linear rows of the NLP: at random
    trajectories, each joint's distance to its bounds equals its distance to Pinocchio's position
    limits on ``q``, and the velocity rows equal Pinocchio's ``difference`` between knots (the
    report's velocities, :func:`planner.trajopt.checks.finite_differences`, times dt) with bounds
    ``velocityLimit dt``; the smoothness operator gives second differences and the posture operator
    the joint part of the chart."""
    from planner.trajopt.checks import finite_differences
    from planner.trajopt.transcription import _quadratic_operators, bounds, make_nlp_layout

    model, nv, N, q_ref = talos.model, talos.nv, layout.N, layout.q_ref
    nl = make_nlp_layout(layout)
    lbx, ubx, lbg, ubg = bounds(layout, nl)
    A, P, D = (np.asarray(ca.DM(op).full()) for op in _quadratic_operators(layout))
    lower, upper = model.lowerPositionLimit[7:], model.upperPositionLimit[7:]
    finite = (np.abs(lower) < 1e10) & (np.abs(upper) < 1e10)
    vj = nl.velocity_joints
    assert len(vj) > 20 and finite.sum() > 20
    n_vel = len(vj) * (N - 2)
    np.testing.assert_allclose(ubg[nl.n_g_kin - n_vel: nl.n_g_kin], np.tile(model.velocityLimit[vj], N - 2) * layout.dt,
                               rtol=VALUE_RTOL, atol=VALUE_TOL)
    rng = np.random.default_rng(SEED)
    for _ in range(DRAWS):
        x = rng.normal(scale=DQ_SCALE, size=nv * (N - 2))
        dq = np.vstack([np.zeros((2, nv)), x.reshape(N - 2, nv), x[-nv:]])  # knots 0, 1 at rest; N = N - 1
        q = np.array([chart_to_configuration(model, q_ref, d) for d in dq])
        for k in range(2, N):
            xk, lo, hi = x[(k - 2) * nv: (k - 1) * nv], lbx[(k - 2) * nv: (k - 1) * nv], ubx[(k - 2) * nv: (k - 1) * nv]
            np.testing.assert_allclose((xk - lo)[6:][finite], (q[k, 7:] - lower)[finite], atol=VALUE_TOL)
            np.testing.assert_allclose((hi - xk)[6:][finite], (upper - q[k, 7:])[finite], atol=VALUE_TOL)
        v, _ = finite_differences(model, q, layout.dt)
        np.testing.assert_allclose(D @ x, (v[1:N - 1, vj] * layout.dt).ravel(), rtol=VALUE_RTOL, atol=VALUE_TOL)
        second = dq[2:N + 1] - 2 * dq[1:N] + dq[0:N - 1]  # knots 1..N-1
        np.testing.assert_allclose(A @ x, second.ravel(), atol=VALUE_TOL)
        np.testing.assert_allclose(P @ x, dq[2:N + 1, 6:].ravel(), atol=VALUE_TOL)


def test_momentum_linearization_matches_pinocchios_centroidal_momentum(layout, talos):
    """The dynamic formulation's angular-momentum rows enter linearized (no symbolic A_g): at a
    random iterate, ``b + P dq_j + Q dq_{j+1}`` equals the exact interval momentum there
    (Pinocchio's centroidal map at the interval's midpoint, the report's form,
    :func:`interval_momentum`), and ``[P Q]`` equals central differences of the interval momentum
    with the map frozen at that midpoint (the linearization's definition, module docstring)."""
    from planner.trajopt.centroidal.layout import to_dynamic_layout
    from planner.trajopt.centroidal.momentum import interval_linearization, interval_momentum

    dyn = to_dynamic_layout(layout)
    model, nv, N, dt, q_ref = talos.model, talos.nv, dyn.N, float(dyn.dt), dyn.q_ref
    weight = talos.mass * 9.81
    rng = np.random.default_rng(SEED)
    dq = rng.normal(scale=DQ_SCALE / 4, size=(N + 1, nv))
    b, P, Q = interval_linearization(dyn, dq)
    q = np.array([chart_to_configuration(model, q_ref, d) for d in dq])
    exact = interval_momentum(talos, q, dt) / weight
    for j in (3, N // 2):
        np.testing.assert_allclose(b[j] + P[j] @ dq[j] + Q[j] @ dq[j + 1], exact[j], rtol=VALUE_RTOL, atol=VALUE_TOL)
        data = model.createData()
        v = pin.difference(model, q[j], q[j + 1]) / dt
        A = pin.computeCentroidalMap(model, data, pin.integrate(model, q[j], 0.5 * dt * v))[3:] / weight

        def frozen(pair: np.ndarray, j=j, A=A) -> np.ndarray:  # A_g frozen at the iterate's midpoint
            qa, qb = (chart_to_configuration(model, q_ref, d) for d in (pair[:nv], pair[nv:]))
            return A @ pin.difference(model, qa, qb) / dt

        fd = _central_differences(frozen, np.concatenate([dq[j], dq[j + 1]]))
        _assert_jacobian(np.hstack([P[j], Q[j]]), fd, f"momentum interval {j}")


# -- the report's checks measure what the rows constrain ------------------------------------------


def _all_rows(lay: Layout, dq: np.ndarray) -> dict[int, np.ndarray]:
    """Every constraint term's rows (CasADi, the NLP's stage functions) at chart displacements
    ``dq`` (N+1, nv), by term index."""
    from planner.trajopt.terms import stage_groups

    out: dict[int, np.ndarray] = {}
    for n, (_sig, knots, term_lists) in enumerate(stage_groups(lay)):
        fn = stage_function(lay, term_lists[0], f"twin_stage_{n}")
        for k, ids in zip(knots, term_lists, strict=True):
            p = np.concatenate([lay.terms[i].params for i in ids]) if ids else np.zeros(0)
            g = np.asarray(fn(dq[k], lay.q_ref, p)[0], dtype=float).ravel()
            offset = 0
            for i in ids:
                out[i] = g[offset: offset + lay.terms[i].n_rows]
                offset += lay.terms[i].n_rows
    return out


def test_report_checks_measure_the_rows(layout, talos):
    """On a random trajectory (rest at both ends), each check of the report (Pinocchio numerics,
    :func:`planner.trajopt.checks.check_plan`) equals the worst violation of the NLP's rows that
    constrain the same thing: contact position |rows 0:3|, contact orientation asin|rows 3:6|, swing
    clearance, support polygon, CoM box, frame and CoM target |rows|."""
    from planner.trajopt.checks import check_plan, finite_differences
    from planner.trajopt.settings import PlannerSettings

    model, nv, N = talos.model, talos.nv, layout.N
    rng = np.random.default_rng(SEED)
    dq = np.zeros((N + 1, nv))
    dq[2:N] = rng.normal(scale=DQ_SCALE / 2, size=(N - 2, nv))
    dq[N] = dq[N - 1]
    q = np.array([chart_to_configuration(model, layout.q_ref, d) for d in dq])
    v, _ = finite_differences(model, q, layout.dt)
    data = model.createData()
    com = np.array([pin.centerOfMass(model, data, qk) for qk in q])
    rows = _all_rows(layout, dq)
    checks = {c.name: c for c in check_plan(layout, q, v, com, PlannerSettings())}
    terms = layout.terms

    def worst(select: Callable[[Term], bool], measure: Callable[[Term, np.ndarray], float]) -> float:
        values = [measure(t, rows[i]) for i, t in enumerate(terms) if select(t) and i in rows]
        assert values
        return max(0.0, max(values))

    def upper_violation(t: Term, g: np.ndarray) -> float:
        return float(np.max(np.maximum(t.lower - g, g - t.upper)))

    want = {
        "left_foot contact position": worst(
            lambda t: t.kind == "contact" and t.label.startswith("left_foot"), lambda t, g: float(np.linalg.norm(g[:3]))),
        "left_foot contact orientation": worst(
            lambda t: t.kind == "contact" and t.label.startswith("left_foot"),
            lambda t, g: math.asin(min(1.0, float(np.linalg.norm(g[3:])))),
        ),
        "right_foot clearance": worst(lambda t: t.kind == "clearance", upper_violation),
        "CoM bound 'balance' support polygon": worst(lambda t: t.kind == "polygon", upper_violation),
        "CoM bound 'balance' box": worst(lambda t: t.kind == "com_box", upper_violation),
        "right_hand target 'reach'": worst(
            lambda t: t.kind == "frame_pos" and t.item is not None and t.item.name == "reach",
            lambda t, g: float(np.linalg.norm(g))),
        "CoM target 'shift'": worst(
            lambda t: t.kind == "com_pos" and t.item is not None and t.item.name == "shift",
            lambda t, g: float(np.linalg.norm(g))),
    }
    for name, value in want.items():
        assert value > 1e-3, f"{name}: the random trajectory does not test it ({value})"
        assert math.isclose(checks[name].violation, value, rel_tol=VALUE_RTOL, abs_tol=VALUE_TOL), \
            (name, checks[name].violation, value)


# -- the dynamic formulation's rows on a whole grid -----------------------------------------------

FD_COLUMNS = 60  # random columns of the centroidal rows' Jacobian checked by central differences


def _edges(R: np.ndarray, mu: float) -> np.ndarray:
    """The 4 inner-pyramid edges (mu', mu', 1), (-mu', mu', 1), (-mu', -mu', 1), (mu', -mu', 1) in the world."""
    m = mu / math.sqrt(2.0)
    return R @ np.array([[m, -m, -m, m], [m, m, -m, -m], [1.0, 1.0, 1.0, 1.0]])


@pytest.mark.parametrize("edges", [True, False], ids=["friction edges", "force components"])
def test_centroidal_rows_match_numpy(layout, talos, edges):
    """The dynamic formulation's rows over the grid (CoM dynamics with contact forces, friction
    pyramid, angular momentum of the corner forces, ankle torques) equal numpy's, block by block, at
    random CoM trajectories and force variables, and their Jacobian equals central differences of
    the numpy form (a seeded sample of columns). The force readout the plan reports
    (``generators``) is the map the rows use."""
    from planner.trajopt.centroidal.layout import to_dynamic_layout
    from planner.trajopt.centroidal.pattern import centroidal_function
    from planner.trajopt.centroidal.settings import CentroidalSettings

    dyn = to_dynamic_layout(layout)
    settings = CentroidalSettings(friction_edges=edges)
    cf = centroidal_function(dyn, settings=settings)
    terms = cf.terms
    N, dt, n = dyn.N, float(dyn.dt), terms.n_variables
    g_unit = GRAVITY / np.linalg.norm(GRAVITY)
    kinds = {b.name.rsplit(" ", 1)[0] if b.name.startswith(("ankle", "friction")) else b.name
             for b in terms.constraints}
    assert kinds == {"CoM dynamics", "angular momentum", "ankle torque"} | (set() if edges else {"friction"}), kinds

    def forces(u: np.ndarray, k: int) -> list[tuple[object, np.ndarray]]:
        out = []
        for c in terms.contacts[k]:
            idx = terms.force_index[k][c.frame]
            E = _edges(c.rotation, c.friction_coefficient) if edges else np.eye(3)
            out.append((c, u[idx] @ E.T))  # (n_points, 3) in body weights
        return out

    def numpy_form(x: np.ndarray) -> np.ndarray:
        C, u = x[: 3 * (N + 1)].reshape(N + 1, 3), x[3 * (N + 1):]
        rows = []
        for block in terms.constraints:
            k = block.knot
            fk = forces(u, k)
            if block.name == "CoM dynamics":
                total = sum((f.sum(axis=0) for _, f in fk), np.zeros(3))
                rows.append((C[k + 1] - 2 * C[k] + C[k - 1]) / dt**2 / 9.81 - g_unit - total)
            elif block.name == "angular momentum":
                rows.append(-sum((np.cross(p - C[k], fi) for c, f in fk for p, fi in
                                  zip(c.points_in_world, f, strict=True)), np.zeros(3)))
            elif block.name.startswith("ankle torque"):
                (c, f), = ((c, f) for c, f in fk if block.name.endswith(c.frame))
                rows.append(c.ankle_torques(f))  # the report's form, in body weights x m
            else:
                assert block.name.startswith("friction")
                (c, f), = ((c, f) for c, f in fk if block.name.endswith(c.frame))
                mu = c.friction_coefficient / math.sqrt(2.0)
                t1, t2, nrm = c.rotation.T
                rows += [np.array([nrm @ fi, mu * nrm @ fi - t1 @ fi, mu * nrm @ fi + t1 @ fi,
                                   mu * nrm @ fi - t2 @ fi, mu * nrm @ fi + t2 @ fi]) for fi in f]
        return np.concatenate(rows)

    for k, per_frame in enumerate(terms.generators):
        for c in terms.contacts[k]:
            if c.frame in per_frame:
                want = _edges(c.rotation, c.friction_coefficient) if edges else np.eye(3)
                np.testing.assert_allclose(per_frame[c.frame], want, atol=VALUE_TOL)
    Cs, us = ca.SX.sym("C", 3, N + 1), ca.SX.sym("u", n)
    g = cf.function(Cs, us, terms.parameter_values, dt)[0]
    xs = ca.vertcat(ca.vec(Cs), us)  # column-major C: knot by knot
    fn = ca.Function("centroidal_twin", [xs], [g, ca.jacobian(g, xs)])
    rng = np.random.default_rng(SEED)
    for _ in range(DRAWS):
        C = np.array([0.0, 0.0, 0.85]) + rng.normal(scale=0.05, size=(N + 1, 3))
        u = rng.uniform(0.0, 0.1, size=n) if edges else rng.normal(scale=0.1, size=n)
        x = np.concatenate([C.ravel(), u])
        value, J = (np.asarray(v.full() if hasattr(v, "full") else v, dtype=float) for v in fn(x))
        np.testing.assert_allclose(value.ravel(), numpy_form(x), rtol=VALUE_RTOL, atol=VALUE_TOL)
        cols = rng.choice(len(x), size=FD_COLUMNS, replace=False)
        fd = np.array([(numpy_form(x + FD_STEP * e) - numpy_form(x - FD_STEP * e)) / (2 * FD_STEP)
                       for e in np.eye(len(x))[cols]]).T
        _assert_jacobian(J[:, cols], fd, "centroidal rows")


def test_cop_of_the_corner_forces_stays_in_the_sole_shrunk_by_the_margin(layout, talos):
    """CoP/support in the dynamic formulation is no row: the corner forces' points are the soles'
    corners moved inward by ``cop_margin`` (here: against the sole rectangle and the stance
    placements of the spec), so non-negative edge weights put each foot's CoP inside the shrunk
    sole (the report's :func:`cop_violation` is 0), and the readout's corner forces are the edges'."""
    from planner.trajopt.centroidal.checks import cop_violation
    from planner.trajopt.centroidal.layout import to_dynamic_layout
    from planner.trajopt.centroidal.pattern import centroidal_function
    from planner.trajopt.centroidal.settings import CentroidalSettings

    settings = CentroidalSettings()
    dyn = to_dynamic_layout(layout)
    terms = centroidal_function(dyn, settings=settings).terms
    sole, margin = talos.profile.sole, settings.cop_margin
    rng = np.random.default_rng(SEED)
    u = rng.uniform(0.0, 1.0, size=terms.n_variables) ** 8  # a few dominant corners: CoPs near the edges
    corner = terms.corner_forces(u)
    seen = 0
    for k, contacts in enumerate(terms.contacts):
        if not 1 <= k <= dyn.N - 1:
            continue
        for c in contacts:
            side = "left" if c.frame == talos.model.frames[talos.frame_id("left_foot")].name else "right"
            placement = next(ct.placement for ph in dyn.spec.phases for ct in ph.contacts
                             if talos.frame_id(ct.frame) == talos.frame_id(c.frame))
            R, p = pin.rpy.rpyToMatrix(*placement.rpy), np.array(placement.position)
            np.testing.assert_allclose(c.points_in_frame, sole_corners(sole, side, margin=margin), atol=VALUE_TOL)
            np.testing.assert_allclose(c.points_in_world, c.points_in_frame @ R.T + p, atol=VALUE_TOL)
            idx = terms.force_index[k][c.frame]
            f = u[idx] @ _edges(c.rotation, c.friction_coefficient).T * terms.weight  # [N]
            np.testing.assert_allclose(corner[c.frame][k], f, rtol=VALUE_RTOL, atol=VALUE_TOL)
            local = f @ R  # rows R^T f_i
            cop = (c.points_in_frame[:, :2] * local[:, 2:3]).sum(axis=0) / local[:, 2].sum()
            x = (sole.x_min + margin, sole.x_max - margin)
            y_left = (sole.y_min + margin, sole.y_max - margin)
            y = y_left if side == "left" else (-y_left[1], -y_left[0])
            assert cop_violation(cop[None], x, y)[0] <= VALUE_TOL, (k, c.frame, cop, x, y)
            seen += 1
    assert seen > 20
