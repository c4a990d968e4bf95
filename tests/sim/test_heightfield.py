"""A scene's height map in MuJoCo (issue 33): the height field under the grid, by rays.

Only the scene's geoms are built (no robot: milliseconds). MuJoCo's height field is two triangles
per cell, so on the grid points it must equal the map exactly, and inside a cell it may differ from
the map's bilinear ground by at most ``|h00 + h11 - h01 - h10| / 4`` (the triangles' largest gap to
the bilinear surface, at the cell's centre), which the test computes by hand from the four corners.
The grid is random and not a plane, so a transposed or mirrored grid would fail. The walk on it:
``tests/sim/test_heightmap_walk.py`` (long).
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from sim.model import OBJECT_PREFIX, _add_scene
from tasks.heightmap import HeightMap
from tasks.scene import Scene

RNG = np.random.default_rng(3)
GRID = np.round(RNG.uniform(0.01, 0.06, size=(5, 7)), 4)  # 5 rows (y) x 7 columns (x)
CELL, ORIGIN = 0.08, (0.2, -0.15)


@pytest.fixture(scope="module")
def world():
    scene = Scene(heightmaps=(HeightMap(name="rough", heights=tuple(map(tuple, GRID.tolist())), cell=CELL,
                                        origin=ORIGIN, friction=0.6),))
    spec = mujoco.MjSpec()
    _add_scene(spec, scene)
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return model, data


def _ray_height(model, data, x: float, y: float) -> float:
    hit = np.zeros(1, dtype=np.int32)
    dist = mujoco.mj_ray(model, data, np.array([x, y, 1.0]), np.array([0.0, 0.0, -1.0]), None, 1, -1, hit)
    assert hit[0] == mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, OBJECT_PREFIX + "rough")
    return 1.0 - dist


def test_the_height_field_meets_the_map_on_every_grid_point(world):
    model, data = world
    for i in range(GRID.shape[0]):
        for j in range(GRID.shape[1]):
            x = ORIGIN[0] + j * CELL + (1e-7 if j == 0 else -1e-7 if j == GRID.shape[1] - 1 else 0.0)
            y = ORIGIN[1] + i * CELL + (1e-7 if i == 0 else -1e-7 if i == GRID.shape[0] - 1 else 0.0)
            assert _ray_height(model, data, x, y) == pytest.approx(GRID[i, j], abs=1e-5)


def test_inside_a_cell_it_stays_within_the_triangles_gap_of_the_bilinear_ground(world):
    model, data = world
    worst = 0.0
    for _ in range(60):
        u, v = RNG.uniform(0, GRID.shape[1] - 1), RNG.uniform(0, GRID.shape[0] - 1)
        j, i = min(int(u), GRID.shape[1] - 2), min(int(v), GRID.shape[0] - 2)
        fu, fv = u - j, v - i
        h00, h01, h10, h11 = GRID[i, j], GRID[i, j + 1], GRID[i + 1, j], GRID[i + 1, j + 1]
        bilinear = (1 - fu) * (1 - fv) * h00 + fu * (1 - fv) * h01 + (1 - fu) * fv * h10 + fu * fv * h11
        gap = abs(h00 + h11 - h01 - h10) / 4
        z = _ray_height(model, data, ORIGIN[0] + u * CELL, ORIGIN[1] + v * CELL)
        assert abs(z - bilinear) <= gap + 1e-5
        assert min(h00, h01, h10, h11) - 1e-5 <= z <= max(h00, h01, h10, h11) + 1e-5
        worst = max(worst, abs(z - bilinear))
    assert worst > 1e-4  # the grid is no plane: the check above is not vacuous


def test_its_friction_is_the_maps(world):
    model, _ = world
    g = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, OBJECT_PREFIX + "rough")
    assert model.geom_type[g] == mujoco.mjtGeom.mjGEOM_HFIELD
    assert model.geom_friction[g][0] == pytest.approx(0.6)
