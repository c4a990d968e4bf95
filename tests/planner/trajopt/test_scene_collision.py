"""Scene collision avoidance in the planner (planner/trajopt/scene_collision.py): the CasADi rows
against numpy and finite differences, their conservativeness against the exact distance, screening,
and plans checked independently with coal on the URDF meshes."""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
from pathlib import Path

import coal
import numpy as np
import pinocchio as pin
import pytest

from planner import CacheSettings, PlannerSettings, plan
from planner.trajopt.api import planned_layout
from planner.trajopt.layout import make_layout
from planner.trajopt.scene_collision import (
    BOUND,
    P_NORM,
    SceneRows,
    obstacles,
    row_value,
    scene_rows_of,
    scene_sets,
    with_scene_terms,
)
from planner.trajopt.terms import stage_function
from tasks.scene import Scene, SceneObject, load_scene, signed_distance
from tests.planner.trajopt.fd import check_stage_rows

ROOT = Path(__file__).resolve().parents[3]
TABLE = ROOT / "examples" / "scenes" / "table.json"
PASSAGE = ROOT / "examples" / "scenes" / "narrow_passage.json"
MARGIN = 0.01  # [m] PlannerSettings().collision.margin
SOLVER_TOLERANCE = 1e-4  # [m] rows hold to IPOPT's constraint tolerance, far below this


def _spec(robot, sentence, scene=None, target=None):
    from language import parse
    from tasks.compose import compile_actions

    spec = compile_actions(parse(sentence).actions, robot)
    if target is not None:
        spec = dataclasses.replace(spec, targets=tuple(
            dataclasses.replace(t, position=target) if t.priority.name == "HARD" else t for t in spec.targets))
    return dataclasses.replace(spec, scene=scene)


def _shapes_scene() -> Scene:
    """A rotated box, a tilted cylinder and a sphere around Talos's right arm."""
    return Scene(objects=(
        SceneObject(name="crate", shape="box", size=(0.3, 0.2, 0.25), position=(0.35, -0.4, 0.8), rpy=(0.2, -0.3, 0.5)),
        SceneObject(name="pipe", shape="cylinder", size=(0.06, 0.5), position=(0.3, -0.3, 1.0), rpy=(1.2, 0.1, 0.0)),
        SceneObject(name="ball", shape="sphere", size=(0.1,), position=(0.25, -0.45, 0.7)),
    ))


def _coal_min_distance(robot, q: np.ndarray, obj: SceneObject) -> tuple[float, int]:
    """Smallest coal distance between the URDF collision geometries and a box object over a motion,
    and its knot (independent of the planner's sphere sets)."""
    geom = robot.collision_model.copy()
    placement = pin.SE3(pin.rpy.rpyToMatrix(*obj.rpy), np.array(obj.position))
    index = geom.addGeometryObject(pin.GeometryObject(obj.name, 0, 0, placement, coal.Box(*obj.size)))
    for i in range(index):
        geom.addCollisionPair(pin.CollisionPair(i, index))
    gdata, data = geom.createData(), robot.model.createData()
    best, knot = np.inf, -1
    for k, qk in enumerate(q):
        pin.computeDistances(robot.model, data, geom, gdata, qk)
        d = min(r.min_distance for r in gdata.distanceResults)
        if d < best:
            best, knot = d, k
    return float(best), knot


def _reference_row(shape: str, u: np.ndarray, a: np.ndarray) -> float:
    """The row function written out plainly (module docstring), for one point."""
    s = u / a
    if shape == "sphere":
        return float(np.sqrt(np.sum(s**2)))
    if shape == "cylinder":
        return float(((s[0] ** 2 + s[1] ** 2) ** (P_NORM / 2) + s[2] ** P_NORM) ** (1 / P_NORM))
    return float(np.sum(s**P_NORM) ** (1 / P_NORM))


def test_scene_rows_match_numpy_and_finite_differences(talos):
    """The stage function's scene rows (box, cylinder, sphere) equal the row function evaluated with
    Pinocchio's joint placements, and their Jacobian matches central finite differences."""
    scene = _shapes_scene()
    spec = _spec(talos, "reach forward 30 cm with your right hand", scene)
    lay = make_layout(spec, talos).with_terms([])
    sets = scene_sets(talos)
    obs = obstacles(scene)
    arm = [s for s in range(len(sets.sphere_radius))
           if sets.links[sets.sphere_owner[s]].startswith(("arm_right_5", "arm_right_7", "gripper_right_base"))]
    assert len(arm) >= 4
    n = len(obs)
    rows = SceneRows(spheres={i: set(arm) for i in range(n)}, knots={i: {5} for i in range(n)})
    lay = with_scene_terms(lay, sets, obs, rows, list(range(n)), MARGIN)
    assert [t.structure[1] for t in lay.terms] == ["box", "cylinder", "cylinder", "sphere"]  # the pipe: 2 pieces
    fn = stage_function(lay, list(range(len(lay.terms))), "scene_stage")
    p = np.concatenate([t.params for t in lay.terms])
    data = talos.model.createData()

    def reference(q):
        pin.forwardKinematics(talos.model, data, q)
        expected = []
        for ob in obs:
            for s in arm:
                M = data.oMi[int(sets.joints[sets.sphere_owner[s]])]
                centre = M.rotation @ sets.sphere_local[s] + M.translation
                u = ob.rotation.T @ (centre - ob.position)
                expected.append(_reference_row(ob.shape, u, ob.half + sets.sphere_radius[s] + MARGIN))
        return expected

    for J in check_stage_rows(fn, talos, p, reference, seed=3, rtol=1e-10, atol=1e-12):
        assert np.abs(J).max() > 1.0  # the rows do depend on the arm (so the relative FD tolerance is J's own scale)


def test_rows_are_conservative_against_the_exact_distance():
    """A point whose row holds (N >= bound, inflated by rho) is at least rho from the object (exact
    signed distance, tasks.scene), and a point that far outside a face's middle region is within a
    few percent of the inflated extent: the rows never allow less than the margin."""
    rng = np.random.default_rng(11)
    scene = _shapes_scene()
    rho = 0.05
    for obj in scene.objects:
        pieces = [ob for ob in obstacles(scene) if ob.name == obj.name]
        pts = np.array(obj.position) + rng.uniform(-0.4, 0.4, size=(4000, 3))
        allowed = np.ones(len(pts), dtype=bool)
        for ob in pieces:
            u = (pts - ob.position) @ ob.rotation
            allowed &= row_value(ob.shape, u, ob.half + rho) >= BOUND[ob.shape]
        exact = np.array([signed_distance(obj, p) for p in pts])
        assert allowed.sum() > 500 and (~allowed).sum() > 100
        assert exact[allowed].min() >= rho - 1e-12, obj.name
        # the bulge: everything beyond (3^(1/P) - 1) of the inflated extent along every axis is allowed
        slack = (BOUND["box"] - 1) * max((ob.half + rho).max() for ob in pieces)
        assert np.all(allowed[exact >= np.sqrt(3) * (rho + slack)]), obj.name


def test_far_object_adds_no_rows_and_object_numbers_are_parameters(talos):
    """Screening: a box 5 m away adds no row (the layout's structure is the scene-free one). The same
    rows against a table moved and resized give the same structure (one solver) with other
    parameters: poses and sizes are values, not structure."""
    spec = _spec(talos, "reach forward 30 cm with your right hand")
    settings = PlannerSettings(cache=CacheSettings(compile=False))
    bare = planned_layout(spec, talos, settings)
    far = Scene(objects=(SceneObject(name="far box", shape="box", size=(1.0, 1.0, 1.0), position=(5.0, 0.0, 0.5)),))
    far_lay = planned_layout(dataclasses.replace(spec, scene=far), talos, settings)
    assert not any(t.kind == "scene" for t in far_lay.terms)
    assert far_lay.structure() == bare.structure()
    table = load_scene(TABLE)
    a = planned_layout(dataclasses.replace(spec, scene=table), talos, settings)
    assert any(t.kind == "scene" for t in a.terms) and a.structure() != bare.structure()
    moved = dataclasses.replace(table, objects=(dataclasses.replace(
        table.objects[0], position=(0.7, 0.05, 0.3), size=(0.7, 1.1, 0.6), rpy=(0.0, 0.0, 0.1)),))
    b = planned_layout(dataclasses.replace(spec, scene=moved), talos,
                       dataclasses.replace(settings,
                                           collision=dataclasses.replace(settings.collision,
                                                                         scene_collision=False)))
    rows = scene_rows_of(a)
    b = with_scene_terms(b, scene_sets(talos), obstacles(moved), rows, sorted(rows.spheres), MARGIN)
    assert a.structure() == b.structure()
    pa = np.concatenate([t.params for t in a.terms if t.kind == "scene"])
    pb = np.concatenate([t.params for t in b.terms if t.kind == "scene"])
    assert pa.shape == pb.shape and not np.allclose(pa, pb)


def test_broad_phase_gives_the_values_and_closest_pair_of_every_pair(talos):
    """The screening values (below 1: within the clearance) and the report's closest sphere and object
    are those of every (sphere, object piece) pair written out (Pinocchio placements, the row function
    and the exact distance on every pair): the bounding-ball broad phase only skips pairs farther than
    asked, near objects (the shapes around the arm) and far ones (a box 5 m away) alike."""
    from planner.trajopt.scene_collision import closest, contact_exclusions, exact_distance, values

    far = SceneObject(name="far box", shape="box", size=(1.0, 1.0, 1.0), position=(5.0, 0.0, 0.5))
    scene = dataclasses.replace(_shapes_scene(), objects=(*_shapes_scene().objects, far))
    spec = _spec(talos, "reach forward 30 cm with your right hand", scene)
    lay = make_layout(spec, talos)
    sets = scene_sets(talos)
    obs = obstacles(scene)
    rng = np.random.default_rng(5)
    q = np.repeat(talos.q_standing[None], 6, axis=0)
    q[:, 7:] += rng.normal(scale=0.3, size=q[:, 7:].shape)
    data = talos.model.createData()
    world = np.empty((len(q), len(sets.sphere_radius), 3))
    for k, qk in enumerate(q):
        pin.forwardKinematics(talos.model, data, qk)
        for s, (owner, c) in enumerate(zip(sets.sphere_owner, sets.sphere_local, strict=True)):
            M = data.oMi[int(sets.joints[owner])]
            world[k, s] = M.rotation @ c + M.translation
    exact = np.stack([exact_distance(ob, (world - ob.position) @ ob.rotation) - sets.sphere_radius for ob in obs], -1)
    for clearance in (MARGIN, 0.03, 0.3):
        reference = np.stack([row_value(ob.shape, (world - ob.position) @ ob.rotation,
                                        ob.half + (sets.sphere_radius + clearance)[:, None]) / BOUND[ob.shape]
                              for ob in obs], -1)
        reference[contact_exclusions(lay, sets, obs)[: len(q)]] = np.inf  # the standing feet: no rows
        np.testing.assert_array_equal(values(lay, sets, obs, q, clearance) < 1.0, reference < 1.0)
    assert (reference < 1.0).any() and not (reference[..., -1] < 1.0).any()
    d, time, link, name = closest(lay, q)
    k, s, o = np.unravel_index(int(np.argmin(exact)), exact.shape)
    assert d == pytest.approx(exact[k, s, o], abs=1e-12)
    assert (time, link, name) == (lay.t[k], sets.links[sets.sphere_owner[s]], obs[o].name)
    far_only = dataclasses.replace(spec, scene=Scene(objects=(far,)))
    d_far = closest(make_layout(far_only, talos), q)[0]
    assert d_far == pytest.approx(exact[..., obs.index(next(ob for ob in obs if ob.name == "far box")):].min(), abs=1e-12)


def test_nominal_keyframe_keeps_the_arm_out_of_the_table(talos):
    """The initial guess's keyframe of a reach 10 cm over the table holds the hand at its target with
    every URDF collision geometry clear of the table (coal): without the scene the same keyframe puts
    the fingers into it (docs/collisions.md: that guess cost IPOPT ~100 iterations)."""
    from planner.trajopt.nominal import _keyframe_tasks, solve_ik

    table = load_scene(TABLE)
    target = (0.45, -0.3, 0.72)
    spec = _spec(talos, "reach forward 30 cm with your right hand", table, target=target)
    for scene, clear in ((table, True), (None, False)):
        lay = make_layout(dataclasses.replace(spec, scene=scene), talos)
        tasks = _keyframe_tasks(lay)
        k = next(k for k, ts in sorted(tasks.items()) if np.allclose(ts[0][2], target))
        q = solve_ik(lay, k, tasks[k])
        assert q is not None
        data = talos.data()
        pin.framesForwardKinematics(talos.model, data, q)
        assert np.linalg.norm(data.oMf[tasks[k][0][1]].translation - target) < 0.01
        d, _ = _coal_min_distance(talos, q[None], table.objects[0])
        assert (d >= MARGIN) == clear, f"scene {scene is not None}: {d:.4f} m"


@pytest.mark.long  # in make test-long (~21 s): the 2-core suite stays under 10 minutes; twins: the scene rows against
# numpy and finite differences, and test_nominal_keyframe_keeps_the_arm_out_of_the_table above
def test_reach_over_the_table_keeps_every_link_the_margin_above_it(talos):
    """A reach forward over the table (the hand 10 cm above its top): every URDF collision geometry
    stays at least the margin from the table at every knot (coal, independent of the sphere sets), and
    the plan's scene collision check names the closest body part."""
    table = load_scene(TABLE)
    spec = _spec(talos, "reach forward 30 cm with your right hand", table, target=(0.45, -0.3, 0.72))
    result = plan(spec, talos, settings=PlannerSettings(cache=CacheSettings(compile=False)))
    assert result.ok, result.diagnosis
    assert all(c.ok for c in result.checks)
    check = next(c for c in result.checks if c.kind.value == "scene_collision")
    assert "table" in check.name and "closest" in check.name
    d, k = _coal_min_distance(talos, result.q, table.objects[0])
    assert d >= MARGIN - SOLVER_TOLERANCE, f"{d:.4f} m at t = {result.t[k]:.2f} s"


@pytest.mark.long  # in make test-long: the 2-core suite stays under 10 minutes (~30 s)
@pytest.mark.slow
def test_reach_into_the_table_is_refused_naming_the_table(talos, tmp_path):
    """A hand target 4 cm above the table top (outside it, so the spec check lets it through) puts the
    gripper's fingers through the table: exit 4 through the CLI, naming the right hand and the table."""
    from tasks.serialize import spec_to_json

    spec = _spec(talos, "reach forward 30 cm with your right hand", load_scene(TABLE), target=(0.45, -0.3, 0.66))
    path = tmp_path / "into.json"
    path.write_text(spec_to_json(spec))
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    out = subprocess.run([sys.executable, "-c", "import sys; from wbmp.cli import run; sys.exit(run())",
                          "solve", "--spec", str(path), "--no-sim", "--no-cache"],
                         capture_output=True, text=True, env=env, cwd=tmp_path, timeout=1200)
    assert out.returncode == 4, out.stderr
    assert "right hand would pass through the table" in out.stderr, out.stderr


@pytest.mark.long  # 4-6 minutes: rows on every knot of the walk (docs/collisions.md)
def test_walk_through_the_narrow_passage_keeps_clear_of_the_walls(talos):
    """A walk forward between the two walls plans (dynamic), every URDF collision geometry at least the
    margin from both walls once the robot moves (coal), and the plan's check names a wall."""
    passage = load_scene(PASSAGE)
    spec = _spec(talos, "walk forward 0.5 m", passage)
    assert spec.dynamic
    result = plan(spec, talos, settings=PlannerSettings(cache=CacheSettings(compile=False)))
    assert result.ok, result.diagnosis
    check = next(c for c in result.checks if c.kind.value == "scene_collision")
    assert check.ok and "wall" in check.name
    for wall in passage.objects:
        d, k = _coal_min_distance(talos, result.q[2:], wall)  # knots 0 and 1: the fixed standing start
        assert d >= MARGIN - SOLVER_TOLERANCE, f"{wall.name}: {d:.4f} m at t = {result.t[k + 2]:.2f} s"


def test_a_collision_round_returns_a_new_layout_and_leaves_its_input_unchanged(talos):
    """A collision round on the nominal guess of a reach whose fingers go through the table (the
    target 4 cm above its top, as in the refused reach above) gives a new layout with the table's
    rows, of the same class; the layout it was given keeps its term list, its structure and every
    parameter. A second round on the same motion finds nothing more and hands its layout back."""
    from planner.trajopt.api import _formulation, collision_round
    from planner.trajopt.collision import Rows, sphere_sets

    spec = _spec(talos, "reach forward 30 cm with your right hand", load_scene(TABLE), target=(0.45, -0.3, 0.66))
    lay, settings = _formulation(spec, talos, PlannerSettings(cache=CacheSettings(compile=False)))
    terms, structure = lay.terms, lay.structure()
    params = [t.params.copy() for t in lay.terms]
    x0 = lay.initial_guess(settings)
    dq = np.zeros((lay.N + 1, talos.nv))
    dq[2:lay.N] = x0.reshape(lay.N - 2, talos.nv)
    dq[lay.N] = dq[lay.N - 1]
    rows, scene_rows = Rows(), SceneRows()
    first = collision_round(lay, settings, dq, sphere_sets(talos), rows, scene_rows, None)
    new, objects = first.layout, first.objects
    assert objects and {obstacles(spec.scene)[o].name for o in objects} == {"table"}  # pieces of it
    assert type(new) is type(lay)
    assert any(t.kind == "scene" for t in new.terms) and new.structure() != structure
    assert lay.terms is terms and lay.structure() == structure  # the input: untouched
    assert not any(t.kind in ("scene", "collision") for t in lay.terms)
    assert all(np.array_equal(t.params, p) for t, p in zip(lay.terms, params, strict=True))
    assert rows.empty and scene_rows.empty  # the records given: untouched too (the round's are new)
    assert first.scene_rows is not None and set(first.scene_rows.spheres) == set(objects)
    second = collision_round(new, settings, dq, sphere_sets(talos), first.rows, first.scene_rows, None)
    assert second.layout is new and second.changed == () and second.objects == ()
    assert second.rows is first.rows and second.scene_rows is first.scene_rows
