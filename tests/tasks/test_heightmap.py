"""Height maps in scenes (issue 33): the grid file, its validation, the ground's height and normal,
and the soles of a walk up the example's ramp placed flat on it.

The references are independent of :mod:`tasks.heightmap`: the height by SciPy's linear
``RegularGridInterpolator`` (bilinear on a rectangular grid) or by hand on a plane, the normal by
central finite differences of that height, the sole corners by the robot profile's sole rectangle
rotated by Pinocchio. MuJoCo's height field against the map: ``tests/sim/test_heightfield.py``; the
planned and executed walk in MuJoCo: ``tests/sim/test_heightmap_walk.py`` (long; these are its fast
twins).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.interpolate import RegularGridInterpolator

from tasks.actions import Action
from tasks.compose import compile_actions
from tasks.exceptions import TaskDefinitionError
from tasks.heightmap import HeightMap
from tasks.scene import Scene, load_scene, scene_from_dict, scene_to_dict, signed_distance
from tasks.terrain import surface_at
from tests.meshes import placed_sole_corners

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "scenes" / "heightmap.json"
GRID = np.array([[0.00, 0.02, 0.05, 0.03],
                 [0.01, 0.04, 0.06, 0.02],
                 [0.03, 0.00, 0.08, 0.05]])  # 3 rows (y) x 4 columns (x), no plane
CELL, ORIGIN = 0.1, (0.3, -0.2)


def _reference():
    xs = ORIGIN[0] + CELL * np.arange(GRID.shape[1])
    ys = ORIGIN[1] + CELL * np.arange(GRID.shape[0])
    f = RegularGridInterpolator((ys, xs), GRID, method="linear")
    return lambda x, y: float(f([[y, x]])[0])


def _scene() -> Scene:
    return Scene(heightmaps=(HeightMap(name="bump", heights=tuple(map(tuple, GRID.tolist())), cell=CELL,
                                       origin=ORIGIN, friction=1.1),))


def test_the_ground_is_the_bilinear_grid_and_its_normal_the_gradient():
    ref = _reference()
    scene = _scene()
    rng = np.random.default_rng(7)
    points = np.column_stack([rng.uniform(0.3, 0.6, 40), rng.uniform(-0.2, 0.0, 40)])
    points = np.vstack([points, [[0.3 + 0.1 * j, -0.2 + 0.1 * i] for i in range(3) for j in range(4)]])
    e = 1e-6
    for x, y in points:
        s = surface_at(scene, float(x), float(y))
        assert s.name == "bump" and s.friction == pytest.approx(1.1)
        assert s.height == pytest.approx(ref(x, y), abs=1e-9)
        u = (x - ORIGIN[0]) / CELL
        v = (y - ORIGIN[1]) / CELL
        if min(abs(u - round(u)), abs(v - round(v))) < 10 * e:
            continue  # on a cell edge the gradient jumps: no central difference
        hx = (ref(x + e, y) - ref(x - e, y)) / (2 * e)
        hy = (ref(x, y + e) - ref(x, y - e)) / (2 * e)
        n = np.array([-hx, -hy, 1.0]) / math.sqrt(1 + hx * hx + hy * hy)
        assert np.allclose(s.normal, n, atol=1e-6)
    floor = surface_at(scene, 0.25, 0.0)
    assert floor.name is None and floor.height == 0.0


def test_the_example_file_reads_as_its_ramp_and_a_scene_round_trips():
    scene = load_scene(EXAMPLE)
    (hm,) = scene.heightmaps
    assert len(hm.heights) == 21 and len(hm.heights[0]) == 14 and hm.size == pytest.approx((0.65, 1.0))
    obj = scene.get("ramp")
    assert obj.shape == "heightfield" and obj.walkable and scene.get("土坡") is obj
    for x in (0.15, 0.3, 0.5, 0.55, 0.8):  # 4 cm over 0.4 m from x = 0.15, then flat: a plane by hand
        s = surface_at(scene, x, 0.1)
        assert s.height == pytest.approx(min(0.1 * (x - 0.15), 0.04), abs=1e-9) and s.friction == 0.9
    assert signed_distance(obj, (0.35, 0.0, 0.05)) == pytest.approx(0.05 - 0.02, abs=1e-9)
    back = scene_from_dict(json.loads(json.dumps(scene_to_dict(scene))))
    assert back == scene


def test_walking_up_the_ramp_puts_each_sole_flat_on_the_map(talos):
    scene = load_scene(EXAMPLE)
    spec = compile_actions([Action(name="step_up", params={"object": "the ramp"})], talos, scene=scene)
    plane = lambda x: min(max(0.1 * (x - 0.15), 0.0), 0.04)  # noqa: E731  the example's ground by hand
    on_map = 0
    for phase in spec.phases:
        for c in phase.contacts:
            corners = placed_sole_corners(talos, c)
            for p in corners:
                assert p[2] == pytest.approx(plane(p[0]), abs=1e-3)
            on_map += bool(corners[:, 0].min() >= 0.15)
    final = spec.phases[-1].contacts
    assert all(c.placement.position[2] == pytest.approx(0.04) and c.placement.rpy == pytest.approx((0, 0, 0))
               for c in final)
    tilted = [c for p in spec.phases for c in p.contacts if abs(c.placement.rpy[1]) > 1e-6]
    assert tilted and all(c.placement.rpy[1] == pytest.approx(-math.atan(0.1), abs=1e-9) for c in tilted)
    steps = [p for p in spec.phases if "foot onto" in p.name]
    assert len(steps) == 6 and on_map > 0
    # each swing passes the ground under it by the swing clearance (9 cm) or more
    assert all(p.swing_height >= 0.09 + 0.01 for p in steps)


@pytest.mark.parametrize("change,message", [
    ({"heights": [[0.0, 0.1], [0.0]]}, "row 1 has 1 heights, row 0 has 2"),
    ({"heights": [[0.0, float("nan")], [0.0, 0.0]]}, "heights[0][1]: expected a finite number"),
    ({"heights": [[0.0, 7.0], [0.0, 0.0]]}, "row 0, column 1 is 7 m; heights are in [0, 2] m"),
    ({"heights": [[0.0, -0.1], [0.0, 0.0]]}, "no pits"),
    ({"heights": [[0.0, 0.1]]}, "has 1 row(s); a height map needs 2 to 256 rows"),
    ({"heights": [[0.0, 0.1], [0.0, 0.0]], "extent": [0.5, 0.5]}, "extent: is"),
    ({"heights": [[0.0, 0.1], [0.0, 0.0]], "cell": 0.0}, "cell: must be a spacing"),
    ({}, 'a height map needs its grid: "file"'),
])
def test_a_bad_grid_is_refused_naming_the_field(change, message):
    with pytest.raises(TaskDefinitionError, match=None) as err:
        scene_from_dict({"version": 1, "heightmaps": [{"name": "g", "cell": 0.1, **change}]})
    text = str(err.value)
    assert text.startswith("heightmaps[0].") and message in text and "\n" not in text


def test_a_grid_file_is_read_from_npy_and_csv_and_refused_when_missing_or_ragged(tmp_path):
    grid = np.array([[0.0, 0.01, 0.02], [0.0, 0.015, 0.03]])
    np.save(tmp_path / "g.npy", grid)
    (tmp_path / "g.csv").write_text("# two rows\n0,0.01,0.02\n0,0.015,0.03\n")
    (tmp_path / "bad.csv").write_text("0,0.01,0.02\n0,0.015\n")
    (tmp_path / "nan.csv").write_text("0,0.01,0.02\n0,nan,0.03\n")
    for name in ("g.npy", "g.csv"):
        path = tmp_path / "s.json"
        path.write_text(json.dumps({"version": 1, "heightmaps": [{"file": name, "cell": 0.1}]}))
        assert load_scene(path).heightmaps[0].heights == tuple(map(tuple, grid.tolist()))
    for name, message in (("none.npy", "heightmaps[0].file: the grid file"), ("bad.csv", "row 1 has 2 heights"),
                          ("nan.csv", "row 1, column 1 is nan, not a number"),
                          ("g.txt", "is not a .npy or .csv file")):
        path = tmp_path / "s.json"
        path.write_text(json.dumps({"version": 1, "heightmaps": [{"file": name, "cell": 0.1}]}))
        with pytest.raises(TaskDefinitionError, match=None) as err:
            load_scene(path)
        assert message in str(err.value) and "\n" not in str(err.value)


def test_ground_too_rough_for_a_flat_sole_is_refused_in_task_terms(talos):
    from tasks.exceptions import BeyondCapability

    rough = np.random.default_rng(5).uniform(0.0, 0.03, size=(11, 15))  # 2 cm cells: no flat place a sole long
    scene = Scene(heightmaps=(HeightMap(name="rubble", heights=tuple(map(tuple, rough.tolist())), cell=0.02,
                                        origin=(0.15, -0.1)),))
    with pytest.raises(BeyondCapability, match="the ground of the rubble has no place flat enough for talos's soles"):
        compile_actions([Action(name="step_up", params={"object": "the rubble"})], talos, scene=scene)
