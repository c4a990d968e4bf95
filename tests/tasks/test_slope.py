"""Slopes in scenes (issue 33): the ramp's geometry, the soles placed flat on it, walking down.

The references are by hand from the slope's angle, length, position and yaw (the inclined plane
``z = tan(angle) * d``, ``d`` the distance past the bottom edge along the climbing direction, its
normal ``(-sin(angle) cos(yaw), -sin(angle) sin(yaw), cos(angle))``), not from
:mod:`tasks.terrain`; the sole corners by the robot profile's sole rectangle rotated by Pinocchio.
The planned and executed soles against the plane: ``tests/sim/test_slope_walk.py`` (long; its
fast twins are these and ``test_the_slope_guess_stands_flat_on_the_plane`` in
``tests/planner/trajopt/test_terrain_rows.py``).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from tasks.actions import Action
from tasks.compose import compile_actions
from tasks.exceptions import BeyondCapability, TaskDefinitionError
from tasks.scene import (
    Scene,
    Slope,
    load_scene,
    scene_from_dict,
    scene_from_json,
    scene_to_dict,
    signed_distance,
)
from tasks.specs import StartState
from tasks.terrain import sole_rpy, surface_at
from tests.meshes import placed_sole_corners

SLOPE = Path(__file__).resolve().parents[2] / "examples" / "scenes" / "slope.json"
STAIRS = Path(__file__).resolve().parents[2] / "examples" / "scenes" / "stairs.json"


def _plane(slope: Slope, x: float, y: float) -> tuple[float, np.ndarray, float]:
    """(height of the inclined plane over (x, y), its normal, the distance d past the bottom edge)."""
    u = np.array([math.cos(slope.yaw), math.sin(slope.yaw)])
    d = float(np.dot(np.array([x, y]) - np.array(slope.position), u))
    n = np.array([-math.sin(slope.angle) * u[0], -math.sin(slope.angle) * u[1], math.cos(slope.angle)])
    return math.tan(slope.angle) * d, n, d


def start_on(robot, x: float, height: float, yaw: float = math.pi) -> StartState:
    """Standing at rest with the feet centred on (x, 0) at ``height``, facing ``yaw``."""
    q = np.array(robot.q_standing, dtype=float)
    R = pin.rpy.rpyToMatrix(0.0, 0.0, yaw)
    q[:2] = np.array([x, 0.0]) + R[:2, :2] @ q[:2]
    q[2] += height
    quat = pin.Quaternion(R @ pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix())
    q[3:7] = [quat.x, quat.y, quat.z, quat.w]
    return StartState(q=tuple(float(v) for v in q))


@pytest.mark.parametrize("yaw", [0.0, 0.7])
def test_the_ramp_top_is_the_inclined_plane_and_the_landing_its_top_edge_height(yaw):
    slope = Slope(angle=math.radians(10), length=0.5, position=(0.15, -0.2), yaw=yaw, landing=0.6, width=1.0)
    scene = Scene(slopes=(slope,))
    ramp, landing = scene.objects
    u = np.array([math.cos(yaw), math.sin(yaw)])
    v = np.array([-u[1], u[0]])
    top = 0.5 * math.tan(math.radians(10))
    for d in np.linspace(0.01, 0.49, 7):
        for w in (-0.45, 0.0, 0.45):
            x, y = np.array(slope.position) + d * u + w * v
            z, n, _ = _plane(slope, x, y)
            s = surface_at(scene, float(x), float(y))
            assert s.name == "slope" and s.height == pytest.approx(z, abs=1e-9)
            np.testing.assert_allclose(s.normal, n, atol=1e-12)
            # the box's top face is that plane: on it, 1 cm above it (along the normal) and inside below
            p = np.array([x, y, z])
            assert signed_distance(ramp, p) == pytest.approx(0.0, abs=1e-9)
            assert signed_distance(ramp, p + 0.01 * n) == pytest.approx(0.01, abs=1e-9)
            assert signed_distance(ramp, p - [0, 0, 0.003]) < 0
    for d in (0.55, 0.8, 1.05):  # the landing, as high as the top edge
        x, y = np.array(slope.position) + d * u
        s = surface_at(scene, float(x), float(y))
        assert s.name == "slope.top" and s.height == pytest.approx(top, abs=1e-12) and s.normal[2] == 1.0
    x, y = np.array(slope.position) - 0.02 * u  # before the bottom edge: the floor, flush with the ramp
    assert surface_at(scene, float(x), float(y)).name is None
    assert signed_distance(ramp, (float(x), float(y), 0.0)) == pytest.approx(0.02, abs=1e-9)  # to the bottom edge
    # the box reaches the floor under the top edge (no gap a foot could enter), and the landing touches it
    x, y = np.array(slope.position) + 0.5 * u
    assert signed_distance(ramp, (float(x), float(y), 0.001)) < 0
    assert signed_distance(landing, (float(x), float(y), top / 2)) == pytest.approx(0.0, abs=1e-9)


def test_the_example_slope_file_round_trips_and_bad_slopes_are_refused():
    scene = load_scene(SLOPE)
    assert [o.name for o in scene.objects] == ["slope", "slope.top"]
    assert scene.slopes[0].angle == pytest.approx(math.radians(10))
    assert scene_from_dict(scene_to_dict(scene)) == scene
    assert scene.get("斜坡").name == "slope"
    for bad, words in (({"angle": 0.5}, "slopes\\[0\\].angle: must be an inclination"),
                       ({"length": -1}, "slopes\\[0\\].length"), ({"landing": -0.1}, "slopes\\[0\\].landing")):
        with pytest.raises(TaskDefinitionError, match=words):
            scene_from_json(f'{{"slopes": [{{"name": "ramp", "angle": 0.1, {", ".join(f"{k!r}: {v}".replace(chr(39), chr(34)) for k, v in bad.items())}}}]}}')


@pytest.mark.parametrize("yaw,normal", [(0.0, (-0.3, 0.0, 0.954)), (2.0, (0.1, -0.2, 0.97)), (-0.4, (0, 0, 1))])
def test_sole_rpy_puts_the_sole_z_on_the_normal_and_its_x_on_the_heading(yaw, normal):
    n = np.array(normal) / np.linalg.norm(normal)
    R = pin.rpy.rpyToMatrix(*sole_rpy(tuple(n), yaw))
    np.testing.assert_allclose(R[:, 2], n, atol=1e-12)
    h = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    side = np.array([-math.sin(yaw), math.cos(yaw), 0.0])
    assert float(R[:, 0] @ side) == pytest.approx(0.0, abs=1e-12)  # the sole's x in the heading's vertical plane
    assert float(R[:, 0] @ h) > 0.9  # forward


def _check_soles_on(robot, spec, slope: Slope) -> set[str]:
    """Every sole corner of every contact on the plane, the landing or the floor (by hand)."""
    where = set()
    top = slope.length * math.tan(slope.angle)
    for phase in spec.phases:
        for c in phase.contacts:
            corners = placed_sole_corners(robot, c)
            d = [_plane(slope, p[0], p[1])[2] for p in corners]
            if all(0 < x < slope.length for x in d):
                z = [_plane(slope, p[0], p[1])[0] for p in corners]
                np.testing.assert_allclose(corners[:, 2], z, atol=1e-9)
                np.testing.assert_allclose(pin.rpy.rpyToMatrix(*c.placement.rpy)[:, 2],
                                           _plane(slope, 0, 0)[1], atol=1e-12)
                where.add("slope")
            elif all(x > slope.length for x in d):
                np.testing.assert_allclose(corners[:, 2], top, atol=1e-9)
                where.add("landing")
            else:
                assert all(x < 0 for x in d) and np.allclose(corners[:, 2], 0.0, atol=1e-9), (phase.name, d)
                where.add("floor")
    return where


def test_walking_up_the_slope_puts_each_sole_flat_on_the_plane(talos):
    scene = load_scene(SLOPE)
    spec = compile_actions([Action(name="step_up", params={"object": "the slope"})], talos, scene=scene)
    assert _check_soles_on(talos, spec, scene.slopes[0]) == {"floor", "slope", "landing"}
    steps = [p for p in spec.phases if "foot onto" in p.name]
    assert [p.name.rsplit(" ", 1)[-1] for p in steps] == ["slope"] * 4 + ["slope.top"] * 2
    last = spec.phases[-1].contacts
    assert [c.placement.position[2] for c in last] == pytest.approx([0.5 * math.tan(math.radians(10))] * 2)


@pytest.mark.parametrize("scene_file,obj,x,height", [(SLOPE, "the slope", 0.8, 0.5 * math.tan(math.radians(10))),
                                                      (STAIRS, "the stairs", 0.7695, 0.3)])
def test_walking_down_from_the_top_ends_on_the_floor(talos, scene_file, obj, x, height):
    scene = load_scene(scene_file)
    spec = compile_actions([Action(name="step_down", params={"object": obj})], talos, scene=scene,
                           start=start_on(talos, x, height))
    heights = [round(c.placement.position[2], 4) for p in spec.phases for c in p.contacts]
    assert heights[0] == pytest.approx(height, abs=1e-4) and heights[-1] == 0.0
    assert all(a >= b for a, b in zip(heights[::2], heights[2::2], strict=False))  # never up again
    if scene.slopes:
        assert _check_soles_on(talos, spec, scene.slopes[0]) == {"floor", "slope", "landing"}
    else:
        assert sorted(set(heights)) == pytest.approx([0.0, 0.1, 0.2, 0.3])


def test_walking_down_is_refused_where_nothing_lies_below_ahead(talos):
    with pytest.raises(TaskDefinitionError, match="the slope is not below the robot straight ahead .it stands on the floor"):
        compile_actions([Action(name="step_down", params={"object": "the slope"})], talos, scene=load_scene(SLOPE))
    far = Scene(slopes=(Slope(angle=math.radians(10), length=0.9, position=(0.5, 0.0)),))
    with pytest.raises(BeyondCapability, match="would step 0.6. m onto the slope, beyond talos's 0.30 m step: walk closer"):
        compile_actions([Action(name="step_up", params={"object": "the slope"})], talos, scene=far)


@pytest.mark.parametrize("text,action,scene_file,name", [
    ("walk up the slope", "step_up", SLOPE, "slope"), ("走上斜坡", "step_up", SLOPE, "slope"),
    ("climb up the ramp", "step_up", SLOPE, "slope"), ("walk down the slope", "step_down", SLOPE, "slope"),
    ("走下斜坡", "step_down", SLOPE, "slope"), ("walk down the stairs", "step_down", STAIRS, "stairs.1"),
    ("走下楼梯", "step_down", STAIRS, "stairs.1")])
def test_the_words_for_slopes_and_descents(text, action, scene_file, name):
    from language import parse
    from tasks.grounding import ground

    actions = parse(text).actions
    assert [a.name for a in actions] == [action]
    assert ground(actions[0].params["object"], load_scene(scene_file), action=action).name == name


def test_g1_climbs_the_stairs_with_its_climb_stride_and_is_refused_without_it(g1):
    """G1's walking stride (0.20 m) is shorter than the 0.25 m treads; its profile's climb stride
    (``climb_length_max`` 0.26 m, certified up these stairs in MuJoCo) lets it climb them, each sole
    flat on its tread by hand; with the climb stride unset it is refused, naming the 0.20 m step."""
    import dataclasses

    scene = load_scene(STAIRS)
    flight = scene.stairs[0]
    assert g1.profile.climb_length_max == pytest.approx(0.26) and g1.profile.step_length_max == pytest.approx(0.20)
    spec = compile_actions([Action(name="step_up", params={"object": "the stairs"})], g1, scene=scene)
    tops = set()
    for phase in spec.phases:
        for c in phase.contacts:
            corners = placed_sole_corners(g1, c)
            steps = {int(np.floor((x - flight.position[0]) / flight.run)) + 1 for x in corners[:, 0]}
            assert len(steps) == 1  # every corner over one tread (or the floor)
            step = min(max(steps.pop(), 0), flight.count)
            np.testing.assert_allclose(corners[:, 2], flight.rise * step, atol=1e-9)
            tops.add(step)
    assert tops == {0, 1, 2, 3}
    walker = dataclasses.replace(g1, profile=dataclasses.replace(g1.profile, climb_length_max=0.0))
    with pytest.raises(BeyondCapability, match="onto the stairs.1, beyond g1's 0.20 m step: walk closer"):
        compile_actions([Action(name="step_up", params={"object": "the stairs"})], walker, scene=scene)
