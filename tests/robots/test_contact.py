"""One home for contact facts: every face of the friction model agrees, sole corners match Pinocchio.

The friction model (robots/contact.py): the 4-edge pyramid inscribed in the Coulomb cone,
``|fx|, |fy| <= mu/sqrt(2) fz`` in the sole frame, whose edges lie on the cone. On a 45-degree
diagonal its limit is the cone's, ``|f_t| = mu fz``: the planner's rows, the controller's rows, the
report's cone check and MuJoCo (elliptic cone) must all accept a diagonal force at 0.9 of that
limit and all refuse one at 1.1.
"""

from __future__ import annotations

import casadi as ca
import mujoco
import numpy as np
import pinocchio as pin
import pytest
from scipy.optimize import nnls

from planner.trajopt.centroidal import friction_pyramid, friction_violation, pyramid_edges
from planner.wbc import WholeBodyController
from planner.wbc import kernel as wbc_kernel
from robots import contact
from sim import build_model
from sim.handmade import standing_plan
from sim.model import set_contact_friction, set_friction_cone

ROW_ATOL = 1e-9  # [N] exact arithmetic on 100 N forces
EDGE_RESIDUAL = 1e-6  # [N] non-negative least squares: inside the pyramid means a zero residual
BELOW, ABOVE = 0.9, 1.1  # multiples of the diagonal limit mu fz, clearly on each side of it
FZ = 100.0  # [N]
STILL = 0.005  # [m] a box pushed below the limit creeps less than this in 0.5 s (MuJoCo's soft contact)
SLID = 0.03  # [m] above the limit it slides at least this far (0.1 mu g over 0.5 s: ~8 cm)


def _diagonal_force(k: float, mu: float) -> np.ndarray:
    """Force (3,) in the contact frame: normal FZ, tangential k mu FZ at 45 degrees [N]."""
    ft = k * mu * FZ
    return np.array([ft / np.sqrt(2.0), ft / np.sqrt(2.0), FZ])


@pytest.fixture(scope="module")
def sole_rotation(talos):
    """A contact frame that is not the world's: the standing left sole yawed by 0.3 rad."""
    data = talos.data()
    pin.framesForwardKinematics(talos.model, data, talos.q_standing)
    return data.oMf[talos.frame_id("left_foot")].rotation @ pin.rpy.rpyToMatrix(0.0, 0.0, 0.3)


@pytest.fixture(scope="module")
def controller(talos):
    """A controller after one tick on a standing plan (its QP rows are built)."""
    ctrl = WholeBodyController(talos)
    q, v = talos.q_standing.copy(), np.zeros(talos.nv)
    ctrl.reset(q, v)
    ctrl.compute(0.0, q, v, standing_plan(talos, duration=1.0, dt=0.05))
    return ctrl


def _planner_accepts(force_world: np.ndarray, R: np.ndarray, mu: float) -> bool:
    rows = np.array(ca.Function("rows", [], [friction_pyramid(ca.DM(force_world), R, mu)])()["o0"]).ravel()
    by_rows = bool(np.all(rows >= -ROW_ATOL))
    weights, residual = nnls(pyramid_edges(R, mu), force_world)  # f = E w, w >= 0 (the planner's variables)
    by_edges = residual <= EDGE_RESIDUAL
    assert by_rows == by_edges, (rows, weights, residual)
    return by_rows


def _controller_accepts(ctrl: WholeBodyController, nv: int, force_local: np.ndarray) -> bool:
    rows = ctrl.C[0:4, nv : nv + 3]  # the first corner's pyramid rows (scaled forces: homogeneous)
    by_qp = bool(np.all(rows @ force_local <= ROW_ATOL))
    fx, fy, fz = force_local
    by_kernel = all(sx * fx + sy * fy - ctrl._mu * fz <= ROW_ATOL for sx, sy in wbc_kernel._FACETS)
    assert by_qp == by_kernel
    return by_qp


def _box_slides(k: float, mu: float) -> float:
    """Displacement [m] of a 10 kg box on the floor pushed for 0.5 s by k mu m g at 45 degrees."""
    spec = mujoco.MjSpec()
    spec.option.timestep = 0.001
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    set_friction_cone(spec)
    floor = spec.worldbody.add_geom()
    floor.type = mujoco.mjtGeom.mjGEOM_PLANE
    floor.size = [0.0, 0.0, 0.05]
    set_contact_friction(floor, mu)
    body = spec.worldbody.add_body()
    body.pos = [0.0, 0.0, 0.005]
    body.add_freejoint()
    box = body.add_geom()
    box.type = mujoco.mjtGeom.mjGEOM_BOX
    box.size = [0.1, 0.05, 0.005]  # [m] a sole-sized plate
    box.mass = 10.0
    set_contact_friction(box, mu)
    m = spec.compile()
    d = mujoco.MjData(m)
    for _ in range(200):  # settle
        mujoco.mj_step(m, d)
    start = d.qpos[:2].copy()
    d.xfrc_applied[1, :2] = k * mu * 10.0 * 9.81 * np.array([1.0, 1.0]) / np.sqrt(2.0)
    for _ in range(500):
        mujoco.mj_step(m, d)
    return float(np.linalg.norm(d.qpos[:2] - start))


@pytest.mark.parametrize("k", [BELOW, ABOVE])
def test_every_face_of_the_friction_model_agrees_on_a_diagonal_force(talos, sole_rotation, controller, k):
    """Planner rows and edges, controller rows (QP and kernel), report check and MuJoCo: one verdict."""
    mu = talos.profile.friction_coefficient
    R = sole_rotation
    local = _diagonal_force(k, mu)
    world = R @ local
    inside = k < 1.0
    assert _planner_accepts(world, R, mu) is inside
    assert _controller_accepts(controller, talos.nv, local) is inside
    assert (float(friction_violation(world, R, mu)) == 0.0) is inside  # the planner's report
    assert (float(contact.friction_ratio(world, R, mu)) <= 1.0) is inside
    moved = _box_slides(k, mu)
    assert (moved < STILL) if inside else (moved > SLID), moved


def test_the_faces_are_built_from_the_one_model(talos, controller):
    """Each face reads its numbers from robots.contact; the robot's MuJoCo model is told the cone."""
    mu = talos.profile.friction_coefficient
    assert wbc_kernel._FACETS == contact.PYRAMID_FACETS
    np.testing.assert_allclose(controller.C[0:4, talos.nv : talos.nv + 3], contact.pyramid_facets(mu), atol=ROW_ATOL)
    np.testing.assert_allclose(pyramid_edges(np.eye(3), mu), contact.pyramid_edges_in_contact(mu), atol=ROW_ATOL)
    # every edge lies on the Coulomb cone
    np.testing.assert_allclose(contact.friction_ratio(contact.pyramid_edges_in_contact(mu).T, np.eye(3), mu), 1.0)
    sm = build_model(talos)
    assert sm.model.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC
    for g in (*sm.sole_geoms.values(), sm.floor_geom):
        assert sm.model.geom_condim[g] == contact.MUJOCO_CONDIM
        np.testing.assert_allclose(sm.model.geom_friction[g], contact.mujoco_friction(mu))


def test_controller_rows_refuse_what_the_old_per_axis_rows_allowed(talos, controller):
    """The old controller (|fx|, |fy| <= 0.9 mu fz) allowed 1.27 mu fz on a diagonal; now refused."""
    mu = talos.profile.friction_coefficient
    old_limit = 0.9 * np.sqrt(2.0)
    assert not _controller_accepts(controller, talos.nv, _diagonal_force(0.95 * old_limit, mu))


@pytest.mark.parametrize("robot_name", ["talos", "g1"])
def test_sole_corners_match_pinocchio_frames(robot_name, talos, g1, rng):
    """Frames added at the sole corners in Pinocchio land where robots.contact puts the corners."""
    robot = {"talos": talos, "g1": g1}[robot_name]
    model = pin.Model(robot.model)
    for side in ("left", "right"):
        fid = robot.frame_id(f"{side}_foot")
        foot = model.frames[fid]
        for i, corner in enumerate(contact.sole_corners(robot.profile.sole, side)):
            model.addFrame(pin.Frame(f"corner_{side}_{i}", foot.parentJoint, fid,
                                     foot.placement * pin.SE3(np.eye(3), corner), pin.FrameType.OP_FRAME))
    data = model.createData()
    for _ in range(3):
        dq = np.concatenate([np.zeros(6), 0.1 * rng.standard_normal(robot.nv - 6)])
        q = pin.integrate(robot.model, robot.q_standing, dq)
        pin.framesForwardKinematics(model, data, q)
        for side in ("left", "right"):
            expected = np.array([data.oMf[model.getFrameId(f"corner_{side}_{i}")].translation for i in range(4)])
            oMf = data.oMf[robot.frame_id(f"{side}_foot")]
            np.testing.assert_allclose(contact.sole_corners_in_world(robot.profile.sole, side, oMf), expected, atol=1e-12)
            np.testing.assert_allclose(robot.sole_corners_in_world(q, side), expected, atol=1e-12)


def test_sole_geometry_margin_polygon_and_centre_of_pressure(talos):
    """A margin moves every side inward; the polygon of both soles is the hull; equal corner loads
    put the CoP at the sole's centre, a single loaded corner puts it on that corner."""
    sole = talos.profile.sole
    left, right = contact.sole_corners(sole, "left"), contact.sole_corners(sole, "right")
    np.testing.assert_allclose(sorted(right[:, 1]), sorted(-left[:, 1]))
    shrunk = contact.sole_corners(sole, "left", margin=0.01)
    np.testing.assert_allclose(np.ptp(shrunk[:, :2], axis=0), np.ptp(left[:, :2], axis=0) - 0.02, atol=1e-12)
    square = contact.support_polygon([np.array([[0, 0], [1, 0], [1, 1], [0, 1]]), np.array([[0.5, 0.5]])])
    np.testing.assert_allclose(square, [[0, 0], [1, 0], [1, 1], [0, 1]])
    assert contact.polygon_margin(square, np.array([0.5, 0.25])) == pytest.approx(0.25)
    assert contact.polygon_margin(square, np.array([1.5, 0.5])) == pytest.approx(-0.5)
    forces = np.zeros((2, 4, 3))
    forces[0, :, 2] = 50.0
    forces[1, 2, 2] = 80.0
    cop = contact.center_of_pressure(left, forces, np.eye(3))
    np.testing.assert_allclose(cop[0], left[:, :2].mean(axis=0), atol=1e-12)
    np.testing.assert_allclose(cop[1], left[2, :2], atol=1e-12)
