"""A height map in the viewers: its ground as a triangle mesh over the grid, its outline the grid's
rectangle (the references: the grid points and the origin and cell put in by hand)."""

from __future__ import annotations

import numpy as np

from tasks.heightmap import HeightMap
from tasks.scene import Scene
from viz.scene import _object_geometry, footprint, object_transform

GRID = ((0.0, 0.01, 0.03), (0.02, 0.05, 0.04))  # 2 rows (y) x 3 columns (x)


def test_the_mesh_is_the_grid_and_the_outline_its_rectangle():
    obj = Scene(heightmaps=(HeightMap(name="g", heights=GRID, cell=0.2, origin=(1.0, -0.3)),)).objects[0]
    geometry, shape_T = _object_geometry(obj)
    T = object_transform(obj) @ shape_T
    world = np.asarray(geometry.vertices) @ T[:3, :3].T + T[:3, 3]
    expected = [(1.0 + 0.2 * j, -0.3 + 0.2 * i, GRID[i][j]) for i in range(2) for j in range(3)]
    np.testing.assert_allclose(world, expected, atol=1e-6)
    assert np.asarray(geometry.faces).shape == (2 * 2, 3)  # two triangles a cell, two cells
    outline = footprint(obj)
    assert sorted(map(tuple, np.round(outline, 9))) == [(1.0, -0.3), (1.0, -0.1), (1.4, -0.3), (1.4, -0.1)]
