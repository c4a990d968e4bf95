"""The planner on stairs: the legs' scene cover, the contacts' exclusions, the stepping guess.

Fast twins of the long climb test (``tests/sim/test_stairs_climb.py``): each claim is checked
against an independent reference (the URDF's collision vertices, the tread boxes by hand,
Pinocchio forward kinematics), no solve.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from planner.trajopt.api import _formulation
from planner.trajopt.centroidal.stepping import stepping_guess
from planner.trajopt.scene_collision import contact_exclusions, obstacles, scene_sets, values
from planner.trajopt.settings import PlannerSettings
from planner.trajopt.symbolic import chart_to_configuration
from tasks.actions import Action
from tasks.compose import compile_actions
from tasks.scene import load_scene

STAIRS = Path(__file__).resolve().parents[3] / "examples" / "scenes" / "stairs.json"


def _step_up_guess(robot, scene: Path, words: str):
    """The layout of "walk up <words>" in ``scene`` and its stepping guess (N+1, nq)."""
    spec = compile_actions([Action(name="step_up", params={"object": words})], robot, scene=load_scene(scene))
    lay, _ = _formulation(spec, robot, PlannerSettings())
    dq = stepping_guess(lay)
    assert dq is not None
    q = np.array([chart_to_configuration(robot.model, lay.q_ref, d) for d in dq])
    return lay, q


@pytest.fixture(scope="module")
def climb(talos):
    """The layout of "walk up the stairs" on Talos and its stepping guess (N+1, nq)."""
    return _step_up_guess(talos, STAIRS, "the stairs")


def _vertices(robot, link: str) -> tuple[int, np.ndarray]:
    """(joint, the link's collision vertices in its joint frame), from the geometry model itself."""
    pts, joint = [], None
    for obj in robot.collision_model.geometryObjects:
        if robot.model.frames[obj.parentFrame].name != link:
            continue
        v = np.asarray(obj.geometry.vertices(), dtype=float).reshape(-1, 3)
        pts.append(v @ obj.placement.rotation.T + obj.placement.translation)
        joint = int(obj.parentJoint)
    assert joint is not None
    return joint, np.vstack(pts)


@pytest.mark.parametrize("link", ["leg_right_4_link", "leg_left_3_link", "leg_right_5_link"])
def test_the_leg_scene_cover_holds_the_link_meshes_and_hugs_the_shin(talos, link):
    sets = scene_sets(talos)
    i = sets.links.index(link)
    mine = sets.sphere_owner == i
    joint, v = _vertices(talos, link)
    assert int(sets.joints[i]) == joint
    c, r = sets.sphere_local[mine], sets.sphere_radius[mine]
    inside = (np.linalg.norm(v[:, None, :] - c[None], axis=-1) <= r[None] + 1e-9).any(axis=1)
    assert inside.all(), f"{(~inside).sum()} of {len(v)} vertices of {link} outside its scene cover"
    if link == "leg_right_4_link":  # the shin at the standing posture: its cover ends above the sole
        data = talos.data()
        pin.framesForwardKinematics(talos.model, data, talos.q_standing)
        world = c @ data.oMi[joint].rotation.T + data.oMi[joint].translation
        sole_z = data.oMf[talos.frame_id("right_foot")].translation[2]
        mesh_bottom = (v @ data.oMi[joint].rotation.T + data.oMi[joint].translation)[:, 2].min()
        assert (world[:, 2] - r).min() - sole_z > 0.03  # the self-collision capsule: 8 mm below it
        assert (world[:, 2] - r).min() < mesh_bottom


def test_a_standing_leg_may_touch_only_its_own_tread(climb):
    """While the right foot stands on stairs.1 its leg has no rows against stairs.1, but its shin
    keeps them against stairs.2; a foot on the floor has no rows against any tread."""
    lay, _ = climb
    sets = scene_sets(lay.robot)
    obs = obstacles(lay.spec.scene)
    ex = contact_exclusions(lay, sets, obs)
    right = lay.robot.frame_id("right_foot")
    k = next(k for k, a in enumerate(lay.contacts_at)
             if right in a and abs(a[right][1].translation[2] - 0.1) < 1e-9 and len(a) == 1)  # right on stairs.1, alone
    shin = np.flatnonzero(np.array([sets.links[o] == "leg_right_4_link" for o in sets.sphere_owner]))
    foot = np.flatnonzero(np.array([sets.links[o] == "leg_right_6_link" for o in sets.sphere_owner]))
    on1 = [i for i, ob in enumerate(obs) if ob.name == "stairs.1"]
    on2 = [i for i, ob in enumerate(obs) if ob.name == "stairs.2"]
    assert ex[k][np.ix_(shin, on1)].all() and not ex[k][np.ix_(shin, on2)].any()
    assert ex[k][np.ix_(foot, on2)].all()  # the standing foot: where its placement is
    left_shin = np.flatnonzero(np.array([sets.links[o] == "leg_left_4_link" for o in sets.sphere_owner]))
    assert not ex[k][np.ix_(left_shin, on1 + on2)].any()  # the swinging leg keeps every row


def test_the_stepping_guess_stands_on_the_treads_and_swings_over_them(climb):
    """Pinocchio FK of the guess: each stance sole at its placement (1 mm), each swinging sole's
    corners above the tread boxes under them (by hand from the flight), and the leg covers out of
    the treads but where they stand (the scene rows' values, at most a few mm into the margin)."""
    lay, q = climb
    robot = lay.robot
    flight = lay.spec.scene.stairs[0]
    data = robot.data()
    worst_stance, lowest = 0.0, np.inf
    for k in range(2, lay.N):
        pin.framesForwardKinematics(robot.model, data, q[k])
        for side in ("left", "right"):
            fid = robot.frame_id(f"{side}_foot")
            M = data.oMf[fid]
            if fid in lay.contacts_at[k]:
                worst_stance = max(worst_stance, float(np.linalg.norm(M.translation - lay.contacts_at[k][fid][1].translation)))
                continue
            for corner in robot.sole_corners_in_world(q[k], side):
                step = int(np.floor((corner[0] - flight.position[0]) / flight.run)) + 1
                height = flight.rise * min(max(step, 0), flight.count)
                lowest = min(lowest, float(corner[2] - height))
    assert worst_stance < 1e-3
    assert lowest > -1e-3  # no swinging sole corner below the surface under it
    v = values(lay, scene_sets(robot), obstacles(lay.spec.scene), q, 0.0)
    assert v.min() > 0.95  # no leg sphere in a tread it does not stand on (the rows' own bulge aside)


SLOPE = Path(__file__).resolve().parents[3] / "examples" / "scenes" / "slope.json"


@pytest.fixture(scope="module")
def slope_walk(talos):
    """The layout of "walk up the slope" on Talos and its stepping guess (N+1, nq)."""
    return _step_up_guess(talos, SLOPE, "the slope")


def _on_slope(slope, p: np.ndarray) -> float:
    """Height of the example's walkable surface under a point, by hand: floor, 10 deg plane, landing."""
    d = p[0] - slope.position[0]
    return float(np.tan(slope.angle) * min(max(d, 0.0), slope.length)) if d < slope.length + slope.landing else 0.0


def test_the_slope_guess_stands_flat_on_the_plane(slope_walk):
    """The fast twin of ``tests/sim/test_slope_walk.py``: Pinocchio FK of the stepping guess puts
    each standing sole's corners on the surface under them (the inclined plane by hand: 1 mm), and
    no swinging sole corner below it."""
    lay, q = slope_walk
    robot = lay.robot
    slope = lay.spec.scene.slopes[0]
    worst, lowest, tilted = 0.0, np.inf, 0
    for k in range(lay.N + 1):
        for side in ("left", "right"):
            fid = robot.frame_id(f"{side}_foot")
            corners = robot.sole_corners_in_world(q[k], side)
            gaps = [float(c[2] - _on_slope(slope, c)) for c in corners]
            if fid in lay.contacts_at[k]:
                worst = max(worst, max(abs(g) for g in gaps))
                tilted += int(0 < corners[0][0] - slope.position[0] < slope.length)
            else:
                lowest = min(lowest, min(gaps))
    assert worst < 1e-3
    assert lowest > -1e-3
    assert tilted > 20  # knots with a sole on the ramp itself


def test_the_friction_cones_on_the_slope_open_about_its_normal(slope_walk, talos):
    """A contact on the ramp: its force generators (the friction pyramid's edges) make the same
    angle with the plane's normal by hand, and their sum lies along it."""
    from planner.trajopt.centroidal.contacts import contact_geometry
    from planner.trajopt.centroidal.physics import pyramid_coefficient, pyramid_edges

    lay, _ = slope_walk
    slope = lay.spec.scene.slopes[0]
    n = np.array([-np.sin(slope.angle), 0.0, np.cos(slope.angle)])
    on_ramp = [c for p in lay.spec.phases for c in p.contacts if abs(c.placement.rpy[1]) > 0.1]
    assert on_ramp
    c = contact_geometry(on_ramp[0], talos)
    np.testing.assert_allclose(c.normal, n, atol=1e-12)
    mu = c.friction_coefficient
    E = pyramid_edges(c.rotation, mu)
    cos = (E.T @ n) / np.linalg.norm(E, axis=0)
    np.testing.assert_allclose(cos, 1.0 / np.sqrt(1.0 + 2.0 * pyramid_coefficient(mu) ** 2), atol=1e-12)
    total = E.sum(axis=1)
    np.testing.assert_allclose(total / np.linalg.norm(total), n, atol=1e-12)
