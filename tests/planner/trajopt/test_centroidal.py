"""CoM dynamics with contact forces: CasADi expressions against numpy, and small solves."""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest

from planner.exceptions import PlannerError
from planner.trajopt.centroidal import (
    GRAVITY,
    CentroidalSettings,
    angular_momentum_rate,
    build_centroidal,
    build_centroidal_for_spec,
    center_of_pressure,
    com_acceleration,
    com_dynamics_residual,
    contact_geometry,
    contacts_per_knot,
    cop_violation,
    friction_pyramid,
    friction_violation,
    pyramid_edges,
)
from tasks.specs import Contact, Phase, Pose, TaskSpec
from tests.tolerances import SYMBOLIC_ATOL


def _feet(robot, *, yaw: float = 0.0) -> tuple[Contact, Contact]:
    data = robot.data()
    pin.framesForwardKinematics(robot.model, data, robot.q_standing)
    out = []
    for side in ("left", "right"):
        p = data.oMf[robot.frame_id(f"{side}_foot")].translation
        out.append(Contact(frame=f"{side}_foot", placement=Pose(position=tuple(float(x) for x in p), rpy=(0.0, 0.0, yaw))))
    return tuple(out)


def _rot(rng) -> np.ndarray:
    return pin.rpy.rpyToMatrix(*rng.uniform(-0.6, 0.6, 3))


def test_sole_corners_match_the_robot(talos, g1):
    """Margin 0: the force points are the robot's sole corners at the standing posture."""
    for robot in (talos, g1):
        for side, contact in zip(("left", "right"), _feet(robot), strict=True):
            geo = contact_geometry(contact, robot)
            assert geo.frame == robot.frame(f"{side}_foot")
            assert geo.n_points == 4
            np.testing.assert_allclose(geo.points_in_world, robot.sole_corners_in_world(robot.q_standing, side), atol=1e-9)
            assert geo.friction_coefficient == robot.profile.friction_coefficient


def test_cop_margin_shrinks_the_sole(talos):
    """A 1 cm margin moves every corner 1 cm inward in x and y; an oversized margin is refused."""
    contact = _feet(talos)[0]
    full = contact_geometry(contact, talos).points_in_frame
    shrunk = contact_geometry(contact, talos, cop_margin=0.01).points_in_frame
    np.testing.assert_allclose(np.abs(full[:, :2] - shrunk[:, :2]), 0.01, atol=1e-12)
    with pytest.raises(PlannerError, match="leaves no area"):
        contact_geometry(contact, talos, cop_margin=0.07)


def test_point_contact_and_friction_override(talos):
    """A non-foot frame is a single point at its origin; the contact's own mu wins over the profile's."""
    c = Contact(frame="right_hand", placement=Pose(position=(0.3, -0.3, 0.8)), friction_coefficient=0.3)
    geo = contact_geometry(c, talos)
    assert geo.n_points == 1
    np.testing.assert_allclose(geo.points_in_world, [[0.3, -0.3, 0.8]])
    assert geo.friction_coefficient == 0.3


@pytest.mark.parametrize("inner", [True, False])
def test_friction_pyramid_against_numpy(rng, inner):
    """The CasADi rows equal the numpy formula; all rows >= 0 exactly inside the pyramid."""
    f = ca.SX.sym("f", 3)
    for _ in range(50):
        R = _rot(rng)
        mu = float(rng.uniform(0.2, 1.2))
        fun = ca.Function("pyr", [f], [friction_pyramid(f, R, mu, inner=inner)])
        force = rng.normal(size=3) * 100 + R[:, 2] * 150
        got = np.array(fun(force)).ravel()
        local = R.T @ force
        mp = mu / math.sqrt(2) if inner else mu
        ref = np.array([local[2], mp * local[2] - local[0], mp * local[2] + local[0], mp * local[2] - local[1], mp * local[2] + local[1]])
        np.testing.assert_allclose(got, ref, atol=SYMBOLIC_ATOL)
        inside = local[2] >= 0 and abs(local[0]) <= mp * local[2] and abs(local[1]) <= mp * local[2]
        assert inside == bool(np.all(got >= 0))
        if inner and inside:
            assert friction_violation(force, R, mu) == 0.0  # the inner pyramid is inside the cone


@pytest.mark.parametrize("inner", [True, False])
def test_pyramid_edges_span_exactly_the_pyramid(rng, inner):
    """Non-negative edge weights give forces inside the pyramid; forces on its faces need zero weights.

    The CasADi edges equal the numpy ones; with the inner pyramid every edge lies on the Coulomb
    cone (tangential = mu * normal), so no combination leaves the cone.
    """
    f = ca.SX.sym("f", 3)
    R_sym = ca.SX.sym("R", 3, 3)
    mu_sym = ca.SX.sym("mu")
    edges_fun = ca.Function("edges", [R_sym, mu_sym], [pyramid_edges(R_sym, mu_sym, inner=inner)])
    for _ in range(30):
        R = _rot(rng)
        mu = float(rng.uniform(0.2, 1.2))
        E = pyramid_edges(R, mu, inner=inner)
        np.testing.assert_allclose(np.array(edges_fun(R, mu)), E, atol=SYMBOLIC_ATOL)
        local = R.T @ E
        mp = mu / math.sqrt(2) if inner else mu
        np.testing.assert_allclose(np.abs(local[:2]), mp, atol=1e-12)  # corners of the square
        np.testing.assert_allclose(local[2], 1.0, atol=1e-12)
        rows = ca.Function("pyr", [f], [friction_pyramid(f, R, mu, inner=inner)])
        for lam in rng.uniform(0.0, 100.0, size=(10, 4)):
            assert np.array(rows(E @ lam)).min() >= -1e-9
            if inner:
                assert friction_violation(E @ lam, R, mu) <= 1e-9
        # a force on a face of the pyramid (|t1.f| = mu' n.f) is reached with two edges only
        face = R @ np.array([mp, 0.3 * mp, 1.0]) * 50.0
        lam, *_ = np.linalg.lstsq(E, face, rcond=None)
        lam_nonneg = np.linalg.solve(E[:, [0, 3]].T @ E[:, [0, 3]], E[:, [0, 3]].T @ face)
        assert lam_nonneg.min() >= 0.0
        np.testing.assert_allclose(E[:, [0, 3]] @ lam_nonneg, face, atol=1e-9)


def test_angular_momentum_rate_against_numpy(rng):
    """sum (p_i - c) x f_i, symbolic vs numpy, and its Jacobian w.r.t. the CoM vs the analytic one."""
    c = ca.SX.sym("c", 3)
    fs = [ca.SX.sym(f"f{i}", 3) for i in range(4)]
    points = rng.normal(size=(4, 3))
    expr = angular_momentum_rate(c, points, fs)
    fun = ca.Function("ldot", [c, *fs], [expr, ca.jacobian(expr, c)])
    for _ in range(20):
        cv = rng.normal(size=3)
        fv = rng.normal(size=(4, 3)) * 50
        val, jac = fun(cv, *fv)
        ref = sum(np.cross(p - cv, f) for p, f in zip(points, fv, strict=True))
        np.testing.assert_allclose(np.array(val).ravel(), ref, atol=SYMBOLIC_ATOL)
        total = fv.sum(axis=0)  # d/dc of -c x F = F x dc -> skew(F)
        skew = np.array([[0, -total[2], total[1]], [total[2], 0, -total[0]], [-total[1], total[0], 0]])
        np.testing.assert_allclose(np.array(jac), skew, atol=SYMBOLIC_ATOL)


def test_com_acceleration_is_exact_on_parabolas(rng):
    """The central difference is exact for constant acceleration; the residual is m(c'' - g) - F."""
    a = rng.normal(size=3)
    dt = 0.05
    c = [0.5 * a * (k * dt) ** 2 + 0.3 * k * dt for k in range(3)]
    np.testing.assert_allclose(com_acceleration(*c, dt), a, atol=1e-9)
    m = 90.0
    np.testing.assert_allclose(com_dynamics_residual(m, a, m * (a - GRAVITY)), 0.0, atol=1e-9)
    np.testing.assert_allclose(com_dynamics_residual(m, GRAVITY, np.zeros(3)), 0.0, atol=1e-12)  # free fall


def _solve_forces(terms, com_values, com_syms):
    """Minimize the centroidal cost over the forces for a fixed numeric CoM trajectory."""
    g, lbg, ubg = terms.g()
    subs = ca.vertcat(*com_syms, terms.parameters)
    fix = ca.vertcat(*[ca.DM(c) for c in com_values], ca.DM(terms.parameter_values))
    g = ca.substitute(g, subs, fix)
    cost = ca.substitute(ca.SX(terms.cost), subs, fix)
    solver = ca.nlpsol("s", "ipopt", {"x": terms.variables, "f": cost, "g": g},
                       {"print_time": False, "ipopt": {"print_level": 0, "sb": "yes", "tol": 1e-10}})
    sol = solver(x0=terms.initial, lbx=terms.lower, ubx=terms.upper, lbg=lbg, ubg=ubg)
    return solver.stats(), np.array(sol["x"]).ravel()


@pytest.mark.parametrize("edges", [True, False])
def test_standing_forces_carry_the_weight_and_put_the_cop_under_the_com(talos, edges):
    """Static CoM over the feet: forces sum to m g, friction holds, and the net CoP is the CoM
    projection, with forces parametrized by pyramid edges or by their components."""
    feet = tuple(contact_geometry(c, talos) for c in _feet(talos))
    T = 5
    com_syms = [ca.SX.sym(f"c{k}", 3) for k in range(T)]
    c0 = np.array([0.03, 0.02, 0.87])
    terms = build_centroidal(com_syms, 0.1, [feet] * T, talos.mass,
                             settings=CentroidalSettings(whole_body_momentum=False, angular_momentum_weight=100.0, force_weight=1e-6, cop_margin=0.0,
                                                         friction_edges=edges))
    # 3 interior knots x 2 feet x 4 corners x (4 edge weights or 3 components)
    assert terms.n_variables == 3 * 2 * 4 * (4 if edges else 3)
    # dynamics (+ pyramid rows) + 2 ankle-torque rows per foot
    assert len(terms.g()[1]) == 3 * (3 + (0 if edges else 2 * 4 * 5) + 2 * 2)
    assert terms.dynamics_knots == (1, 2, 3)
    stats, x = _solve_forces(terms, [c0] * T, com_syms)
    assert stats["success"]
    forces = terms.forces(x)
    corners = terms.corner_forces(x)
    total = forces[feet[0].frame] + forces[feet[1].frame]
    np.testing.assert_allclose(total[1:-1], np.tile(-talos.mass * GRAVITY, (3, 1)), rtol=1e-7, atol=1e-6)
    np.testing.assert_allclose(total[[0, -1]], 0.0)  # no dynamics, no forces at the end knots
    points = np.vstack([f.points_in_world for f in feet])
    stacked = np.concatenate([corners[f.frame] for f in feet], axis=1)  # (T, 8, 3)
    fz = stacked[1:-1, :, 2]
    cop = fz @ points[:, :2] / fz.sum(axis=1, keepdims=True)
    np.testing.assert_allclose(cop, np.tile(c0[:2], (3, 1)), atol=1e-5)
    for f in feet:
        assert friction_violation(corners[f.frame][1:-1], f.rotation, f.friction_coefficient).max() <= 1e-6
        assert corners[f.frame][1:-1, :, 2].min() >= -1e-8


def test_com_outside_the_support_needs_angular_momentum(talos):
    """With the CoM 0.3 m ahead of the toes, the forces cannot have a zero moment about it."""
    feet = tuple(contact_geometry(c, talos) for c in _feet(talos))
    T = 3
    com_syms = [ca.SX.sym(f"c{k}", 3) for k in range(T)]
    terms = build_centroidal(com_syms, 0.1, [feet] * T, talos.mass, settings=CentroidalSettings(whole_body_momentum=False, force_weight=0.0))
    stats, x = _solve_forces(terms, [np.array([0.4, 0.0, 0.87])] * T, com_syms)
    assert stats["success"]
    corners = terms.corner_forces(x)
    pts = np.vstack([f.points_in_world for f in feet])
    fk = np.concatenate([corners[f.frame][1] for f in feet])
    ldot = sum(np.cross(p - [0.4, 0.0, 0.87], f) for p, f in zip(pts, fk, strict=True))
    # best case: all weight at the toes, 0.3 m short of the CoM -> |L'| >= m g (0.4 - 0.1)
    assert abs(ldot[1]) >= talos.mass * 9.81 * 0.3 * (1 - 1e-5)  # IPOPT lands ~1e-7 below


def test_flight_has_no_force_and_needs_a_ballistic_com(talos):
    """Flight knots get no variables; their dynamics rows vanish only for free fall."""
    feet = tuple(contact_geometry(c, talos) for c in _feet(talos))
    T, dt = 6, 0.05
    sets = [feet, feet, (), (), feet, feet]
    com_syms = [ca.SX.sym(f"c{k}", 3) for k in range(T)]
    terms = build_centroidal(com_syms, dt, sets, talos.mass)
    assert set(terms.force_index[2]) == set() and set(terms.force_index[3]) == set()
    assert set(terms.force_index[1]) == {f.frame for f in feet}
    dyn = [b for b in terms.constraints if b.name == "CoM dynamics" and b.knot in (2, 3)]
    assert not ca.depends_on(ca.vertcat(*[b.expr for b in dyn]), terms.parameters)
    fun = ca.Function("dyn", com_syms, [ca.vertcat(*[b.expr for b in dyn])])
    ballistic = [np.array([0.0, 0.0, 0.9 + 1.0 * k * dt]) + 0.5 * GRAVITY * (k * dt) ** 2 for k in range(T)]
    np.testing.assert_allclose(np.array(fun(*ballistic)).ravel(), 0.0, atol=1e-9)
    hovering = [np.array([0.0, 0.0, 0.9])] * T
    np.testing.assert_allclose(np.array(fun(*hovering)).ravel(), [0, 0, 1, 0, 0, 1], atol=1e-9)  # 1 g short


def test_spec_grid_follows_the_phases(talos):
    """build_centroidal_for_spec: contact sets per knot from the phases, the later phase at a boundary."""
    feet = _feet(talos)
    spec = TaskSpec(robot="talos", phases=(
        Phase(name="push", duration=0.2, contacts=feet),
        Phase(name="flight", duration=0.2),
        Phase(name="land", duration=0.2, contacts=feet),
    ), dt=0.05, dynamic=True)
    t = np.linspace(0.0, 0.6, 13)
    sets = contacts_per_knot(spec, talos, t)
    assert [len(s) for s in sets] == [2, 2, 2, 2, 0, 0, 0, 0, 2, 2, 2, 2, 2]
    com = [ca.SX.sym(f"c{k}", 3) for k in range(13)]
    terms = build_centroidal_for_spec(spec, talos, t, com)
    assert terms.n_variables == (3 + 4) * 2 * 4 * 4  # knots 1-3 and 8-11 carry two soles (4 edges each)
    with pytest.raises(PlannerError, match="uniform"):
        build_centroidal_for_spec(spec, talos, np.array([0.0, 0.1, 0.15, 0.6]), com[:4])


def test_numeric_cop_and_friction_checks(talos):
    """center_of_pressure / cop_violation / friction_violation on hand-made forces."""
    geo = contact_geometry(_feet(talos)[0], talos)
    f = np.zeros((3, 4, 3))
    f[0, :, 2] = 100.0  # uniform: CoP at the sole centre
    f[1, 1, 2] = 100.0  # all on the front-right corner (x_max, y_min)
    cop = center_of_pressure(geo.points_in_frame, f, geo.rotation)
    np.testing.assert_allclose(cop[0], geo.points_in_frame[:, :2].mean(axis=0), atol=1e-12)
    np.testing.assert_allclose(cop[1], geo.points_in_frame[1, :2], atol=1e-12)
    assert np.isnan(cop[2]).all()  # unloaded
    sole = talos.profile.sole
    viol = cop_violation(np.array([[0.0, 0.0], [sole.x_max + 0.03, 0.0], [np.nan, np.nan]]), (sole.x_min, sole.x_max), (sole.y_min, sole.y_max))
    np.testing.assert_allclose(viol, [0.0, 0.03, 0.0], atol=1e-12)
    R = np.eye(3)
    np.testing.assert_allclose(friction_violation(np.array([[70.0, 0.0, 100.0], [80.0, 0.0, 100.0], [0.0, 0.0, -5.0]]), R, 0.7), [0.0, 10.0, 5.0], atol=1e-9)


def test_contact_geometry_enters_as_parameters(talos):
    """Two placements with the same contact pattern share the structure; only the values differ."""
    feet = _feet(talos)
    moved = tuple(Contact(frame=c.frame, placement=Pose(position=(c.placement.position[0] + 0.3, c.placement.position[1], 0.0),
                                                        rpy=(0.0, 0.0, 0.4))) for c in feet)
    com = [ca.SX.sym(f"c{k}", 3) for k in range(4)]
    a = build_centroidal(com, 0.1, [tuple(contact_geometry(c, talos) for c in feet)] * 4, talos.mass)
    b = build_centroidal(com, 0.1, [tuple(contact_geometry(c, talos) for c in moved)] * 4, talos.mass)
    assert a.structure == b.structure
    # per knot and foot: 4 corners, rotation, friction, and the levers of 4 corners about 2 ankle axes
    assert a.parameter_values.shape == b.parameter_values.shape == (2 * 2 * (12 + 10 + 24),)
    assert not np.allclose(a.parameter_values, b.parameter_values)
    g, _, _ = a.g()
    assert ca.depends_on(g, a.parameters)  # the pyramid edges use the rotation and friction parameters
    single = build_centroidal(com, 0.1, [tuple(contact_geometry(c, talos) for c in feet[:1])] * 4, talos.mass)
    assert single.structure != a.structure


def test_symbolic_dt_and_pyramid_with_parameters(talos, rng):
    """dt as a CasADi parameter and the parameterized pyramid rows give the numeric values."""
    feet = tuple(contact_geometry(c, talos) for c in _feet(talos, yaw=0.3))
    dt = ca.SX.sym("dt")
    com = [ca.SX.sym(f"c{k}", 3) for k in range(3)]
    terms = build_centroidal(com, dt, [feet] * 3, talos.mass,
                             settings=CentroidalSettings(whole_body_momentum=False, inner_pyramid=False, friction_edges=False,
                                                         ankle_torque_margin=None))
    g, _, _ = terms.g()
    fun = ca.Function("g", [terms.variables, terms.parameters, dt, *com], [g])
    u = rng.uniform(0.0, 0.2, terms.n_variables)
    cs = [rng.normal(size=3) for _ in range(3)]
    got = np.array(fun(u, terms.parameter_values, 0.05, *cs)).ravel()
    ref = []
    for f in feet:
        idx = terms.force_index[1][f.frame]
        for i in range(4):
            local = f.rotation.T @ u[idx[i]]
            mu = f.friction_coefficient
            ref += [local[2], mu * local[2] - local[0], mu * local[2] + local[0], mu * local[2] - local[1], mu * local[2] + local[1]]
    acc = (cs[2] - 2 * cs[1] + cs[0]) / 0.05**2
    total = u.reshape(-1, 3).sum(axis=0)
    ref += list(acc / 9.81 - np.array([0, 0, -1.0]) - total)
    np.testing.assert_allclose(got, ref, atol=1e-9)


def test_edge_weights_give_the_dynamics_and_the_corner_forces(talos, rng):
    """With friction edges the rows are Newton's law only, on the forces E u; corner_forces is E u [N]."""
    feet = tuple(contact_geometry(c, talos) for c in _feet(talos, yaw=0.3))
    dt = ca.SX.sym("dt")
    com = [ca.SX.sym(f"c{k}", 3) for k in range(3)]
    terms = build_centroidal(com, dt, [feet] * 3, talos.mass,
                             settings=CentroidalSettings(whole_body_momentum=False, ankle_torque_margin=None))
    g, lbg, ubg = terms.g()
    assert g.numel() == 3 and np.all(lbg == 0.0) and np.all(ubg == 0.0)
    np.testing.assert_array_equal(terms.lower, 0.0)
    fun = ca.Function("g", [terms.variables, terms.parameters, dt, *com], [g])
    u = rng.uniform(0.0, 0.2, terms.n_variables)
    cs = [rng.normal(size=3) for _ in range(3)]
    got = np.array(fun(u, terms.parameter_values, 0.05, *cs)).ravel()
    total = np.zeros(3)
    corners = terms.corner_forces(u)
    for f in feet:
        idx = terms.force_index[1][f.frame]
        assert idx.shape == (4, 4)
        E = pyramid_edges(f.rotation, f.friction_coefficient)
        expected = u[idx] @ E.T  # (4 corners, 3) in body weights
        np.testing.assert_allclose(corners[f.frame][1], expected * terms.weight, rtol=1e-12)
        total += expected.sum(axis=0)
    acc = (cs[2] - 2 * cs[1] + cs[0]) / 0.05**2
    np.testing.assert_allclose(got, acc / 9.81 - np.array([0, 0, -1.0]) - total, atol=1e-9)


def test_layout_contacts_hold_at_both_ends_of_a_phase(talos):
    """On a step spec, the lift-off and touch-down knots carry both feet; single support one."""
    from planner.trajopt.centroidal import layout_contacts
    from planner.trajopt.layout import make_layout
    from tasks.actions import Action
    from tasks.compose import compile_actions

    spec = compile_actions([Action(name="step", params={"direction": "forward", "length": 0.1, "count": 1})], talos, dt=0.1)
    lay = make_layout(spec, talos)
    sets = layout_contacts(lay, cop_margin=0.0)
    counts = [len(s) for s in sets]
    starts = np.cumsum([0.0, *[p.duration for p in spec.phases]])
    single = [i for i, p in enumerate(spec.phases) if len(p.contacts) == 1]
    for i in single:
        k0, k1 = round(starts[i] / lay.dt), round(starts[i + 1] / lay.dt)
        assert counts[k0] == 2 and counts[k1] == 2  # the swing foot is held at lift-off and touch-down
        assert all(c == 1 for c in counts[k0 + 1 : k1])
    # the moved right foot's corners at the end are 0.1 m ahead of the standing ones
    right = [c for c in sets[-1] if c.frame == talos.frame("right_foot")][0]
    np.testing.assert_allclose(right.points_in_world - talos.sole_corners_in_world(talos.q_standing, "right"), [[0.1, 0, 0]] * 4, atol=1e-9)


def test_heading_guess_follows_the_feet(talos):
    """After a 90 deg turn the guessed base yaw is 90 deg; the first two knots are not moved."""
    from planner.trajopt.centroidal import heading_guess
    from planner.trajopt.layout import make_layout
    from planner.trajopt.symbolic import chart_to_configuration
    from tasks.actions import Action
    from tasks.compose import compile_actions

    spec = compile_actions([Action(name="turn", params={"angle": math.pi / 2})], talos, dt=0.1)
    lay = make_layout(spec, talos)
    dq = heading_guess(lay)
    np.testing.assert_allclose(dq[:2], 0.0)
    q_end = chart_to_configuration(talos.model, lay.q_ref, dq[-1])
    R0 = pin.Quaternion(lay.q_ref[3:7]).matrix()
    R1 = pin.Quaternion(q_end[3:7]).matrix()
    yaw = math.atan2((R1 @ R0.T)[1, 0], (R1 @ R0.T)[0, 0])
    assert yaw == pytest.approx(math.pi / 2, abs=1e-6)
    data = talos.data()
    for side in ("left", "right"):  # with the joints at the reference, the feet land on their final placements
        pin.framesForwardKinematics(talos.model, data, q_end)
        final = [c for c in spec.phases[-1].contacts if c.frame == talos.frame(f"{side}_foot")][0]
        np.testing.assert_allclose(data.oMf[talos.frame_id(f"{side}_foot")].translation[:2], final.placement.position[:2], atol=1e-6)


def test_centroidal_function_and_dynamic_checks_on_a_standing_plan(talos):
    """Standing still: the weight split over the 8 corners passes every check; a sliding force fails friction."""
    from planner.trajopt.centroidal import centroidal_function, dynamic_checks
    from planner.trajopt.layout import make_layout
    from tasks.actions import Action
    from tasks.compose import compile_actions

    spec = compile_actions([Action(name="step", params={"direction": "forward", "length": 0.1, "count": 1})], talos, dt=0.1)
    lay = make_layout(spec, talos)
    cf = centroidal_function(lay, settings=CentroidalSettings(whole_body_momentum=False, cop_margin=0.0))
    terms = cf.terms
    assert cf.function.n_in() == 4 and terms.n_variables > 0
    # every swing knot has the 4 corners of the lifted foot
    swing = {(k, fid) for k, fid, _ in cf.corner_rows}
    assert all(fid not in lay.contacts_at[k] for k, fid in swing)
    assert len(cf.corner_rows) == 4 * len(swing)
    # a static plan: q standing everywhere, CoM constant, weight shared by the active corners
    q = np.tile(talos.q_standing, (lay.N + 1, 1))
    com = np.tile(pin.centerOfMass(talos.model, talos.data(), talos.q_standing), (lay.N + 1, 1))
    u = np.zeros(terms.n_variables)
    for k in terms.dynamics_knots:
        idx = np.concatenate([i for i in terms.force_index[k].values()])  # (corners, 4 edges)
        u[idx] = 1.0 / (4 * len(idx))  # each corner carries 1/len of the weight, along the normal
    g, cost = cf.function(np.array(com.T), u, terms.parameter_values, lay.dt)
    g = np.array(g).ravel()
    assert np.all(g >= cf.lbg - 1e-9) and np.all(g <= cf.ubg + 1e-9)
    # swing corners: at standing the "swinging" foot is on the ground (0 m), which the check accepts
    checks = {c.name: c for c in dynamic_checks(lay, q, com, terms, cf.corner_rows, u)}
    assert all(c.ok for c in checks.values()), [c for c in checks.values() if not c.ok]
    assert checks["CoM dynamics m(c'' - g) = sum f"].violation < 1e-6
    k = terms.dynamics_knots[0]
    frame, idx = next(iter(terms.force_index[k].items()))
    normal = 4 * u[idx[0, 0]]  # corner 0's normal force [body weights]
    mu_p = talos.profile.friction_coefficient / math.sqrt(2)
    u_bad = u.copy()
    u_bad[idx[0]] += normal / (4 * mu_p) * np.array([1.0, -1.0, -1.0, 1.0])  # negative weights: f_x = f_n
    bad = {c.name: c for c in dynamic_checks(lay, q, com, terms, cf.corner_rows, u_bad)}
    assert not bad[f"{frame} friction cone"].ok
    expected = (1.0 - talos.profile.friction_coefficient) * normal * terms.weight
    assert bad[f"{frame} friction cone"].violation == pytest.approx(expected, rel=1e-9)
    assert not bad["CoM dynamics m(c'' - g) = sum f"].ok  # the extra force is unbalanced


def test_dynamic_blocks_derivatives_match_automatic_differentiation(talos, rng):
    """Hand-assembled gradient, Jacobian and Lagrangian Hessian equal CasADi AD at a random point
    (with the forces' moment lifted to variables, the default: its rows and diagonal cost)."""
    from planner.trajopt.centroidal import centroidal_function, dynamic_blocks, to_dynamic_layout
    from planner.trajopt.centroidal.momentum import momentum_parameters, momentum_sizes
    from planner.trajopt.centroidal.nlp import moment_rows
    from planner.trajopt.layout import make_layout

    feet = _feet(talos)
    spec = TaskSpec(robot="talos", phases=(
        Phase(name="push", duration=0.2, contacts=feet),
        Phase(name="flight", duration=0.2),
        Phase(name="land", duration=0.2, contacts=feet),
    ), dt=0.1, dynamic=True)
    lay = to_dynamic_layout(make_layout(spec, talos))
    cf = centroidal_function(lay)
    nv, n = talos.nv, lay.N - 2
    n_l = moment_rows(lay)
    assert n_l == 3 * (lay.N - 1)
    pm = ca.MX.sym("pm", momentum_sizes(nv, lay.N))  # whole-body momentum rows (linear in x)
    x = ca.MX.sym("x", nv * n)
    u = ca.MX.sym("u", cf.terms.n_variables)
    c = ca.MX.sym("c", 3 * n)
    m = ca.MX.sym("m", n_l)
    q_ref = ca.MX.sym("q_ref", talos.nq)
    p = ca.MX.sym("p", cf.terms.parameter_values.size)
    dt = ca.MX.sym("dt")
    lam_f = ca.MX.sym("lam_f")
    n_g = len(cf.lbg) + 3 * n + len(cf.corner_rows) + n_l
    lam = ca.MX.sym("lam", n_g)
    b = dynamic_blocks(lay, cf, x, u, c, q_ref, p, dt, lam_f, lam, pm=pm, moment=m)
    assert b.g.numel() == n_g == len(b.lbg)
    assert len(cf.corner_rows) == 8 * sum(1 for k in range(2, lay.N) if not lay.contacts_at[k])
    w = ca.vertcat(x, u, c, m)
    lag = lam_f * b.f + ca.dot(lam, b.g)
    zx = ca.MX(nv * n, 1)
    n_u = cf.terms.n_variables
    ours = ca.Function("ours", [x, u, c, m, q_ref, p, dt, lam_f, lam, pm], [
        ca.vertcat(zx, b.grad_u, b.grad_c, b.grad_l), ca.horzcat(b.jac_x, b.jac_u, b.jac_c, b.jac_l),
        ca.blockcat([[b.hess_xx, ca.MX(nv * n, n_u), ca.MX(nv * n, 3 * n), ca.MX(nv * n, n_l)],
                     [ca.MX(n_u, nv * n), b.hess_uu, b.hess_uc, ca.MX(n_u, n_l)],
                     [ca.MX(3 * n, nv * n), b.hess_uc.T, b.hess_cc, ca.MX(3 * n, n_l)],
                     [ca.MX(n_l, nv * n), ca.MX(n_l, n_u), ca.MX(n_l, 3 * n), b.hess_ll]])])
    ad = ca.Function("ad", [x, u, c, m, q_ref, p, dt, lam_f, lam, pm],
                     [ca.gradient(b.f, w), ca.jacobian(b.g, w), ca.hessian(lag, w)[0]])
    args = [rng.normal(size=nv * n) * 0.05, rng.uniform(0, 0.2, cf.terms.n_variables),
            np.tile([0.0, 0.0, 0.85], n) + rng.normal(size=3 * n) * 0.02, rng.normal(size=n_l) * 0.05,
            talos.q_standing, cf.terms.parameter_values, 0.1, 0.7, rng.normal(size=n_g),
            momentum_parameters(lay, rng.normal(size=(lay.N + 1, nv)) * 0.05)]
    for a, r in zip(ours(*args), ad(*args), strict=True):
        np.testing.assert_allclose(np.array(ca.densify(a)), np.array(ca.densify(r)), atol=1e-8, rtol=1e-8)
    assert np.abs(np.array(ca.densify(ours(*args)[2]))[-n_l:, -n_l:]).max() > 0.0  # the moment cost is there


def test_pattern_matches_the_symbolic_terms(talos):
    """The cheap numeric pattern has the terms' exact bounds, guess, values, rows and indices."""
    from planner.trajopt.centroidal import centroidal_pattern

    feet = tuple(contact_geometry(c, talos) for c in _feet(talos, yaw=0.2))
    sets = [feet, feet, (feet[0],), (), (feet[1],), feet, feet]
    com = [ca.SX.sym(f"c{k}", 3) for k in range(len(sets))]
    terms = build_centroidal(com, 0.05, sets, talos.mass)
    pat = centroidal_pattern(sets, talos.mass)
    for name in ("lower", "upper", "initial", "parameter_values"):
        np.testing.assert_array_equal(getattr(pat, name), getattr(terms, name), err_msg=name)
    _, lbg, ubg = terms.g()
    np.testing.assert_array_equal(pat.lbg, lbg)
    np.testing.assert_array_equal(pat.ubg, ubg)
    assert pat.structure == terms.structure and pat.frames == terms.frames
    assert pat.dynamics_knots == terms.dynamics_knots and pat.n_variables == terms.n_variables
    for a, b in zip(pat.force_index, terms.force_index, strict=True):
        assert a.keys() == b.keys() and all(np.array_equal(a[f], b[f]) for f in a)
    for a, b in zip(pat.generators, terms.generators, strict=True):
        assert a.keys() == b.keys() and all(np.array_equal(a[f], b[f]) for f in a)


@pytest.mark.slow
def test_extended_nlp_derivatives_match_automatic_differentiation(talos, rng):
    """The dynamic NLP's hand-assembled gradient, Jacobian and Lagrangian Hessian (stage Hessians
    merged with the CoM rows, soft CoM targets split into J^T J + curvature) equal CasADi AD of
    its cost and rows at a random point, on a spec with double and single support (a swinging
    foot, soft CoM centring) and a flight knot."""
    from planner.trajopt.centroidal import initial_guess, to_dynamic_layout
    from planner.trajopt.layout import make_layout
    from planner.trajopt.transcription import build_nlp, parameter_values

    feet = _feet(talos)
    spec = TaskSpec(robot="talos", phases=(
        Phase(name="both", duration=0.2, contacts=feet),
        Phase(name="left", duration=0.2, contacts=feet[:1]),
        Phase(name="both again", duration=0.1, contacts=feet),
        Phase(name="flight", duration=0.1),
        Phase(name="land", duration=0.1, contacts=feet),
    ), dt=0.1, dynamic=True)
    lay = to_dynamic_layout(make_layout(spec, talos))
    assert any(t.kind == "com_pos" and t.structure[2] == "soft" for t in lay.terms)
    assert lay.corner_rows()  # the right foot swings
    nlp, der, nl = build_nlp(lay)
    x, p = nlp["x"], nlp["p"]
    lam_f = ca.MX.sym("lam_f")
    lam_g = ca.MX.sym("lam_g", nl.n_g)
    ad = ca.Function("ad", [x, p, lam_f, lam_g], [
        ca.gradient(nlp["f"], x), ca.jacobian(nlp["g"], x),
        ca.triu(ca.hessian(lam_f * nlp["f"] + ca.dot(lam_g, nlp["g"]), x)[0])])
    x0 = initial_guess(lay)
    xv = x0 + np.concatenate([rng.normal(size=nl.n_x_kin) * 0.03, rng.uniform(0.0, 0.05, nl.n_x - nl.n_x_kin)])
    pv = parameter_values(lay, nl)
    lv = rng.normal(size=nl.n_g)
    grad_ad, jac_ad, hess_ad = ad(xv, pv, 0.8, lv)
    np.testing.assert_allclose(np.array(der["grad_f"](xv, pv)[1]).ravel(), np.array(grad_ad).ravel(), atol=1e-8, rtol=1e-8)
    np.testing.assert_allclose(np.array(ca.densify(der["jac_g"](xv, pv)[1])), np.array(ca.densify(jac_ad)), atol=1e-8, rtol=1e-8)
    ours = np.array(ca.densify(der["hess_lag"](xv, pv, 0.8, lv)))
    np.testing.assert_allclose(ours, np.array(ca.densify(hess_ad)), atol=1e-7, rtol=1e-7)
    assert np.abs(ours).max() > 1.0  # not a vacuous comparison


def test_momentum_linearization_matches_pinocchio(talos, rng):
    """The linearized whole-body momentum rows: exact at the iterate (Pinocchio's A_g v of each
    interval), and their chart Jacobians match finite differences of A_g(q_mid) v(dq) with A_g frozen;
    the NLP's rates (parameters r + J x) are the differences of those interval momenta."""
    from planner.trajopt.centroidal import to_dynamic_layout
    from planner.trajopt.centroidal.momentum import (
        interval_linearization,
        interval_momentum,
        momentum_parameters,
    )
    from planner.trajopt.centroidal.nlp import momentum_rates
    from planner.trajopt.layout import make_layout
    from planner.trajopt.symbolic import chart_to_configuration

    feet = _feet(talos)
    spec = TaskSpec(robot="talos", phases=(Phase(name="a", duration=0.3, contacts=feet),), dt=0.1, dynamic=True)
    lay = to_dynamic_layout(make_layout(spec, talos))
    nv, N, dt = talos.nv, lay.N, lay.dt
    dq = rng.normal(size=(N + 1, nv)) * 0.1
    dq[:, 3:6] += [0.0, 0.0, 1.2]  # a yawed base: the chart's rotation derivative matters
    b, P, Q = interval_linearization(lay, dq)
    weight = talos.mass * 9.81
    q = np.array([chart_to_configuration(talos.model, lay.q_ref, d) for d in dq])
    exact = interval_momentum(talos, q, dt) / weight

    def lin(j, d0, d1):
        return b[j] + P[j] @ d0 + Q[j] @ d1

    j = 1
    np.testing.assert_allclose([lin(i, dq[i], dq[i + 1]) for i in range(N)], exact, atol=1e-10)
    data = talos.data()
    A = pin.computeCentroidalMap(talos.model, data, pin.integrate(
        talos.model, q[j], 0.5 * pin.difference(talos.model, q[j], q[j + 1])))[3:] / weight

    def frozen(d0, d1):
        qa = chart_to_configuration(talos.model, lay.q_ref, d0)
        qb = chart_to_configuration(talos.model, lay.q_ref, d1)
        return A @ pin.difference(talos.model, qa, qb) / dt

    eps = 1e-6
    for _ in range(3):
        delta = rng.normal(size=(2, nv))
        fd = (frozen(dq[j] + eps * delta[0], dq[j + 1] + eps * delta[1])
              - frozen(dq[j] - eps * delta[0], dq[j + 1] - eps * delta[1])) / (2 * eps)
        lin_d = lin(j, delta[0], delta[1]) - b[j]
        np.testing.assert_allclose(lin_d, fd, rtol=1e-5, atol=1e-8)
    # the rows of the NLP at other chart variables x (knots 2..N-1; dq_0 = dq_1 = 0, dq_N = dq_{N-1})
    x = rng.normal(size=(N - 2, nv)) * 0.1
    d = np.vstack([np.zeros((2, nv)), x, x[-1:]])
    h = np.array([lin(i, d[i], d[i + 1]) for i in range(N)])
    xs = ca.MX.sym("x", nv * (N - 2))
    rates, jac = momentum_rates(lay, xs, ca.MX(momentum_parameters(lay, dq)))
    fn = ca.Function("rates", [xs], [rates, jac])
    ours, at_zero = fn(x.ravel()), fn(np.zeros(nv * (N - 2)))
    np.testing.assert_allclose(np.array(ours[0]).ravel(), ((h[1:] - h[:-1]) / dt).ravel(), atol=1e-10)
    assert np.abs(np.array(ours[0])).max() > 1e-3  # not a vacuous comparison
    np.testing.assert_allclose(np.array(ca.densify(ours[1])) @ x.ravel(),  # affine: J is the Jacobian
                               np.array(ours[0] - at_zero[0]).ravel(), atol=1e-10)


def test_ankle_axes_are_found_from_the_kinematic_chain(talos, g1):
    """The joints above each sole up to the knee: roll then pitch, axes in the sole plane, with the
    model's effort limits; the bound is 0.9 x the limit (G1's pitch: less than its whole weight on
    the toe corners, Talos's: more)."""
    from planner.trajopt.centroidal.contacts import ankle_axes

    expected = {"g1": ("{s}_ankle_roll_joint", "{s}_ankle_pitch_joint"), "talos": ("leg_{s}_6_joint", "leg_{s}_5_joint")}
    for robot in (talos, g1):
        model = robot.model
        for side in ("left", "right"):
            axes = ankle_axes(robot, robot.frame(f"{side}_foot"))
            assert tuple(a.joint for a in axes) == tuple(n.format(s=side) for n in expected[robot.name])
            np.testing.assert_allclose(np.abs(axes[0].axis), [1.0, 0.0, 0.0], atol=1e-3)  # roll
            np.testing.assert_allclose(np.abs(axes[1].axis), [0.0, 1.0, 0.0], atol=1e-3)  # pitch
            for a in axes:
                assert a.effort == model.effortLimit[model.joints[model.getJointId(a.joint)].idx_v]
                assert 0.03 < a.origin[2] < 0.15  # the ankle above the sole
        pitch = ankle_axes(robot, robot.frame("right_foot"))[1]
        toe = robot.profile.sole.x_max - CentroidalSettings().cop_margin
        weight_on_toe = robot.mass * 9.81 * (toe - pitch.origin[0])
        assert (0.9 * pitch.effort < weight_on_toe) == (robot.name == "g1")


@pytest.mark.parametrize("edges", [True, False])
def test_ankle_rows_are_the_moment_of_the_forces_rnea(g1, rng, edges):
    """For a random set of corner forces on the right sole at the standing posture, the ankle rows
    times the body weight are the joint torques that RNEA gives for these forces as external
    forces (no gravity, no motion, so the foot's inertia plays no part), with opposite sign; and
    the rows' bounds are 0.9 x the effort limits."""
    model = g1.model.copy()
    model.gravity.linear = np.zeros(3)
    data = model.createData()
    settings = CentroidalSettings(friction_edges=edges)
    geo = contact_geometry(_feet(g1)[1], g1, cop_margin=settings.cop_margin)
    com = [ca.SX.sym(f"c{k}", 3) for k in range(3)]
    terms = build_centroidal(com, 0.1, [(), (geo,), ()], g1.mass, settings=settings)
    block = next(b for b in terms.constraints if b.name == f"ankle torque {geo.frame}")
    weight = g1.mass * 9.81
    np.testing.assert_allclose(block.upper, [0.9 * a.effort / weight for a in geo.ankle])
    np.testing.assert_allclose(block.lower, -block.upper)
    rows = ca.Function("rows", [terms.variables, terms.parameters], [block.expr])
    u = rng.uniform(0.0, 0.5, terms.n_variables)
    if not edges:
        u = rng.uniform(-0.3, 0.5, terms.n_variables)  # any force (components)
    forces = terms.corner_forces(u)[geo.frame][1]  # (4, 3) world [N]
    q = g1.q_standing
    pin.forwardKinematics(model, data, q)
    joint = model.frames[g1.frame_id(geo.frame)].parentJoint
    fext = pin.StdVec_Force()
    for _ in range(model.njoints):
        fext.append(pin.Force.Zero())
    for p, f in zip(geo.points_in_world, forces, strict=True):
        fext[joint] += data.oMi[joint].actInv(pin.Force(f, np.cross(p, f)))
    tau = pin.rnea(model, data, q, np.zeros(model.nv), np.zeros(model.nv), fext)
    expected = [-tau[model.joints[model.getJointId(a.joint)].idx_v] for a in geo.ankle]
    assert max(abs(x) for x in expected) > 1.0  # a real load [N m]
    np.testing.assert_allclose(np.asarray(rows(u, terms.parameter_values)).ravel() * weight, expected, atol=1e-9)
    np.testing.assert_allclose(geo.ankle_torques(forces), expected, atol=1e-9)


def test_lifted_moment_reaches_the_same_plan(talos):
    """Lifting the forces' moment to variables is an exact reformulation: a short stepping-in-place
    plan (double support, right foot lifted, double support) reaches the same optimum with and
    without it, with 3 more variables and rows per dynamics knot."""
    from planner import CacheSettings, PlannerSettings, plan
    from planner.trajopt.centroidal import to_dynamic_layout
    from planner.trajopt.centroidal.nlp import moment_rows
    from planner.trajopt.layout import make_layout

    feet = _feet(talos)
    spec = TaskSpec(robot="talos", phases=(
        Phase(name="both", duration=0.3, contacts=feet),
        Phase(name="left", duration=0.3, contacts=feet[:1]),
        Phase(name="both again", duration=0.3, contacts=feet),
    ), dt=0.1, dynamic=True)
    plans = {}
    for lifted in (True, False):
        settings = PlannerSettings(cache=CacheSettings(compile=False, use_cache=False),
                                   centroidal=CentroidalSettings(lifted_moment=lifted))
        plans[lifted] = plan(spec, talos, settings=settings)
    a, b = plans[True], plans[False]
    lay = to_dynamic_layout(make_layout(spec, talos))
    assert moment_rows(lay) == 3 * (lay.N - 1)
    assert a.stats.n_variables - b.stats.n_variables == moment_rows(lay)
    assert a.stats.n_constraints - b.stats.n_constraints == moment_rows(lay)
    assert a.ok and b.ok
    assert a.stats.objective == pytest.approx(b.stats.objective, rel=1e-5)
    np.testing.assert_allclose(a.q, b.q, atol=1e-4)
    for frame in a.extras["corner_forces"]:
        np.testing.assert_allclose(a.extras["corner_forces"][frame], b.extras["corner_forces"][frame],
                                   atol=1e-3 * talos.mass * 9.81)
