"""The stairs of a scene in MuJoCo: the same treads the planner's surface query sees."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest

from sim.model import OBJECT_PREFIX, build_model
from tasks.scene import load_scene
from tasks.terrain import surface_at

STAIRS = Path(__file__).resolve().parents[2] / "examples" / "scenes" / "stairs.json"


def test_stairs_treads_are_mujoco_boxes_and_rays_land_on_the_surface_heights(talos):
    scene = load_scene(STAIRS)
    sm = build_model(talos, scene=scene)
    m = sm.model
    for obj in scene.objects:
        g = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, OBJECT_PREFIX + obj.name)
        assert g >= 0 and m.geom_bodyid[g] == 0 and m.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX
        np.testing.assert_allclose(m.geom_size[g], np.array(obj.size) / 2)
        np.testing.assert_allclose(m.geom_pos[g], obj.position)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    start_z = 2.0
    geomid = np.zeros(1, dtype=np.int32)
    # beside the robot (y = 0.45, within the 1 m wide flight), off the tread edges
    for x in np.linspace(-0.3, 1.2, 16) + 0.013:
        dist = mujoco.mj_ray(m, d, np.array([x, 0.45, start_z]), np.array([0.0, 0.0, -1.0]), None, 1, -1, geomid)
        assert dist > 0
        hit = start_z - dist
        assert hit == pytest.approx(surface_at(scene, float(x), 0.45).height, abs=1e-6), x


SLOPE = Path(__file__).resolve().parents[2] / "examples" / "scenes" / "slope.json"


def test_the_slope_is_a_tilted_mujoco_box_and_rays_land_on_the_inclined_plane(talos):
    """The ramp of ``examples/scenes/slope.json`` in MuJoCo: vertical rays land on the plane
    ``z = tan(10 deg) (x - 0.15)`` by hand, on the landing at its top edge's height, on the floor
    before and after; its geom's normal is the plane's (MuJoCo's own rotation of the geom)."""
    scene = load_scene(SLOPE)
    slope = scene.slopes[0]
    m = build_model(talos, scene=scene).model
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    g = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, OBJECT_PREFIX + "slope")
    assert g >= 0 and m.geom_bodyid[g] == 0 and m.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX
    angle = slope.angle
    np.testing.assert_allclose(d.geom_xmat[g].reshape(3, 3)[:, 2], [-np.sin(angle), 0.0, np.cos(angle)], atol=1e-9)
    top = slope.length * np.tan(angle)
    geomid = np.zeros(1, dtype=np.int32)
    for x in np.linspace(-0.2, 1.4, 33) + 0.007:
        dist = mujoco.mj_ray(m, d, np.array([x, 0.45, 2.0]), np.array([0.0, 0.0, -1.0]), None, 1, -1, geomid)
        hit = 2.0 - dist
        if 0.15 <= x <= 0.65:
            expected = np.tan(angle) * (x - 0.15)
        elif 0.65 < x <= 1.25:
            expected = top
        else:
            expected = 0.0
        assert hit == pytest.approx(expected, abs=1e-6), x
        assert surface_at(scene, float(x), 0.45).height == pytest.approx(expected, abs=1e-9)


def test_a_swing_is_measured_from_the_lower_of_the_stances_around_it():
    """The intent check's floor under a sole (``sim.intent._stance_floor``): standing, the height it
    stands at; swinging, the lower of where it lifted off and where it lands, so a step down is
    back on the tread below when it lands there, not when it passes the tread it left (by hand)."""
    from sim.intent import _stance_floor

    planned = np.array([1, 1, 1, 0, 0, 0, 1, 1, 1, 0, 0, 0, 1, 1, 1], dtype=bool)
    down = np.repeat([0.3, 0.25, 0.2, 0.15, 0.1], 3)  # the plan's sole height: down two steps
    down[6:9] = 0.2
    down[12:] = 0.1
    np.testing.assert_allclose(_stance_floor(planned, down, 0.0), np.repeat([0.3, 0.2, 0.2, 0.1, 0.1], 3))
    up = down[::-1].copy()
    np.testing.assert_allclose(_stance_floor(planned, up, 0.0), np.repeat([0.1, 0.1, 0.2, 0.2, 0.3], 3))
    flat = np.full(15, 0.004)
    assert _stance_floor(planned, flat, -0.001) == -0.001  # one level: the lowest simulated stance
