"""Stairs in scenes, the surface under a point, and ``step_up`` footsteps on the treads."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from tasks.actions import Action
from tasks.compose import compile_actions
from tasks.exceptions import BeyondCapability, TaskDefinitionError
from tasks.scene import Scene, SceneObject, Stairs, load_scene, scene_from_dict, scene_to_dict
from tasks.terrain import surface_at
from wbmp.errors import classify

ROOT = Path(__file__).resolve().parents[2]
STAIRS = ROOT / "examples" / "scenes" / "stairs.json"


def _tread_box(stairs: Stairs, i: int) -> tuple[float, float, float, float, float]:
    """Step i's top face by hand: (x0, x1, y0, y1, height) for a flight climbing along +x."""
    x0 = stairs.position[0] + (i - 1) * stairs.run
    y = stairs.position[1]
    return x0, x0 + stairs.run, y - stairs.width / 2, y + stairs.width / 2, i * stairs.rise


def test_the_example_stairs_expand_into_three_walkable_treads():
    scene = load_scene(STAIRS)
    (flight,) = scene.stairs
    assert (flight.count, flight.rise, flight.run) == (3, 0.1, 0.25)
    assert [o.name for o in scene.objects] == ["stairs.1", "stairs.2", "stairs.3"]
    assert scene.get("stairs").name == "stairs.1"  # "the stairs" names the first tread
    for i, obj in enumerate(scene.objects, start=1):
        x0, x1, y0, y1, h = _tread_box(flight, i)
        assert obj.walkable and obj.shape == "box" and not obj.movable
        lo = np.array(obj.position) - np.array(obj.size) / 2
        hi = np.array(obj.position) + np.array(obj.size) / 2
        assert np.allclose(lo, (x0, y0, 0.0)) and np.allclose(hi, (x1, y1, h))
    # written out and read back: the same scene (the treads are not doubled)
    assert scene_from_dict(scene_to_dict(scene)) == scene


@pytest.mark.parametrize("x", np.linspace(-0.2, 1.2, 29) + 0.013)  # off the tread edges
def test_surface_height_under_a_point_matches_the_tread_by_hand(x):
    scene = load_scene(STAIRS)
    (flight,) = scene.stairs
    expected = 0.0
    for i in range(1, flight.count + 1):
        x0, x1, _, _, h = _tread_box(flight, i)
        if x0 <= x <= x1:
            expected = max(expected, h)
    s = surface_at(scene, float(x), 0.1)
    assert s.height == pytest.approx(expected, abs=1e-12)
    assert s.normal == pytest.approx((0.0, 0.0, 1.0))
    assert surface_at(scene, float(x), 0.6).height == 0.0  # beside the flight (1 m wide): the floor


def test_a_turned_flight_and_a_walkable_box():
    flight = Stairs(name="steps", count=2, rise=0.15, run=0.3, width=0.8, position=(1.0, 1.0), yaw=math.pi / 2)
    box = SceneObject(name="crate", shape="box", size=(0.4, 0.4, 0.12), position=(-1.0, 0.0, 0.06), walkable=True)
    table = SceneObject(name="table", shape="box", size=(0.6, 0.6, 0.7), position=(3.0, 0.0, 0.35))
    scene = Scene(objects=(box, table), stairs=(flight,))
    assert surface_at(scene, 1.0, 1.0 + 0.45).height == pytest.approx(0.30)  # second tread along +y
    assert surface_at(scene, 1.0, 1.0 + 0.15).name == "steps.1"
    assert surface_at(scene, 1.45, 1.15).height == 0.0  # beside it (x 0.6..1.4)
    assert surface_at(scene, -1.0, 0.1).height == pytest.approx(0.12)
    assert surface_at(scene, 3.0, 0.0).height == 0.0  # a table top is no floor for the feet


@pytest.mark.parametrize(("data", "words"), [
    ({"stairs": [{"count": 0}]}, ("stairs[0].count",)),
    ({"stairs": [{"rise": -0.1}]}, ("stairs[0].rise",)),
    ({"stairs": [{"position": [0.1]}]}, ("stairs[0].position",)),
    ({"objects": [{"name": "ball", "shape": "sphere", "size": [0.1], "position": [1, 0, 0.1], "walkable": True}]},
     ("objects[0].walkable", "box or cylinder")),
    ({"objects": [{"name": "stairs", "shape": "box", "size": [1, 1, 1], "position": [5, 0, 0.5]}],
      "stairs": [{}]}, ("already names",)),
])
def test_bad_stairs_are_refused_naming_the_field(data, words):
    with pytest.raises(TaskDefinitionError) as err:
        scene_from_dict(data)
    for w in words:
        assert w in str(err.value)


def test_step_up_puts_each_sole_flat_on_its_tread(talos):
    """Every contact placement of the compiled climb: at its tread's height, every sole corner over
    that tread (recomputed from the tread boxes, not from surface_at), and rises one step each."""
    scene = load_scene(STAIRS)
    (flight,) = scene.stairs
    spec = compile_actions([Action(name="step_up", params={"object": "the stairs"})], talos, scene=scene)
    sole = talos.profile.sole
    heights = []
    for phase in spec.phases:
        for c in phase.contacts:
            x, y, z = c.placement.position
            assert c.placement.rpy == pytest.approx((0.0, 0.0, 0.0), abs=1e-9)
            if z == 0.0:
                continue
            i = round(z / flight.rise)
            assert z == pytest.approx(i * flight.rise, abs=1e-9)
            x0, x1, y0, y1, _ = _tread_box(flight, i)
            for cx in (sole.x_min, sole.x_max):
                for cy in (sole.y_min, sole.y_max):
                    assert x0 - 1e-9 <= x + cx <= x1 + 1e-9 and y0 <= y + cy <= y1
            heights.append(z)
    assert max(heights) == pytest.approx(flight.count * flight.rise)
    last = spec.phases[-1].contacts
    assert [c.placement.position[2] for c in last] == pytest.approx([0.3, 0.3])
    # count: only the first two treads
    two = compile_actions([Action(name="step_up", params={"object": "stairs", "count": 2})], talos, scene=scene)
    assert max(c.placement.position[2] for p in two.phases for c in p.contacts) == pytest.approx(0.2)


def test_a_rise_above_the_robots_step_is_refused_in_task_terms(talos):
    scene = Scene(stairs=(Stairs(rise=0.3, position=(0.15, 0.0)),))
    with pytest.raises(BeyondCapability) as err:
        compile_actions([Action(name="step_up", params={"object": "the stairs"})], talos, scene=scene)
    assert "the 0.30 m rise onto the stairs.1 is above talos's 0.20 m step" in str(err.value)
    assert classify(err.value) == 4
    # the same flight with 0.2 m rises is within talos's step
    ok = Scene(stairs=(Stairs(rise=0.2, position=(0.15, 0.0)),))
    compile_actions([Action(name="step_up", params={"object": "the stairs", "count": 1})], talos, scene=ok)


def test_step_up_refusals(talos):
    far = Scene(stairs=(Stairs(position=(0.6, 0.0)),))
    with pytest.raises(BeyondCapability, match="walk closer to it first"):
        compile_actions([Action(name="step_up", params={"object": "stairs"})], talos, scene=far)
    short = Scene(stairs=(Stairs(run=0.15, position=(0.15, 0.0)),))
    with pytest.raises(BeyondCapability, match="does not fit on the stairs.1"):
        compile_actions([Action(name="step_up", params={"object": "stairs"})], talos, scene=short)
    table = Scene(objects=(SceneObject(name="table", shape="box", size=(0.3, 0.6, 0.1), position=(0.3, 0, 0.05)),))
    with pytest.raises(TaskDefinitionError, match="walkable"):
        compile_actions([Action(name="step_up", params={"object": "table"})], talos, scene=table)
    scene = load_scene(STAIRS)
    with pytest.raises(TaskDefinitionError, match="only 3 walkable"):
        compile_actions([Action(name="step_up", params={"object": "stairs", "count": 4})], talos, scene=scene)
    box = dataclasses.replace(table.objects[0], walkable=True)
    spec = compile_actions([Action(name="step_up", params={"object": "table"})], talos, scene=Scene(objects=(box,)))
    assert [c.placement.position[2] for c in spec.phases[-1].contacts] == pytest.approx([0.1, 0.1])


@pytest.mark.parametrize("text", ["walk up the stairs", "climb the staircase", "走上楼梯", "爬上台阶"])
def test_the_words_climb_the_example_stairs(talos, text):
    from language import parse

    scene = load_scene(STAIRS)
    actions = parse(text).actions
    assert [a.name for a in actions] == ["step_up"]
    spec = compile_actions(list(actions), talos, scene=scene)
    assert [c.placement.position[2] for c in spec.phases[-1].contacts] == pytest.approx([0.3, 0.3])


@pytest.mark.parametrize(("text", "top"), [("walk up the three steps", 0.3), ("go up two steps", 0.2),
                                         ("climb one step", 0.1), ("走上三级台阶", 0.3), ("爬上两级楼梯", 0.2)])
def test_a_count_of_steps_climbs_that_many_treads_of_the_scenes_stairs(talos, text, top):
    """The issue's own sentences: "steps" after a climbing verb are the treads climbed (step_up absorbs
    step), and an unnamed flight is the scene's one flight (each tread 0.1 m: the top by hand)."""
    from language import parse

    actions = parse(text).actions
    assert [a.name for a in actions] == ["step_up"]
    spec = compile_actions(list(actions), talos, scene=load_scene(STAIRS))
    assert [c.placement.position[2] for c in spec.phases[-1].contacts] == pytest.approx([top, top])


def test_going_down_steps_names_the_flight_the_robot_stands_on(talos):
    from language import parse

    actions = parse("go down two steps").actions
    assert [a.name for a in actions] == ["step_down"] and actions[0].params["count"] == 2


@pytest.mark.parametrize(("scene", "error", "words"), [
    (None, "GroundingError", "nothing to climb without a scene"),
    (Scene(), "BeyondCapability", "no stairs or slope"),
    ("two", "GroundingError", "several to climb"),
])
def test_steps_with_nothing_or_several_to_climb_are_refused_in_words(talos, scene, error, words):
    from language import parse

    if scene == "two":
        flight = load_scene(STAIRS).stairs[0]
        scene = Scene(stairs=(flight, dataclasses.replace(flight, name="back stairs", aliases=(), position=(-2.0, 0.0),
                                                          yaw=math.pi)))
    with pytest.raises(TaskDefinitionError) as e:
        compile_actions(list(parse("walk up the three steps").actions), talos, scene=scene)
    assert type(e.value).__name__ == error and words in str(e.value), e.value


def test_step_onto_the_box_in_words(talos):
    from language import parse

    box = SceneObject(name="box", shape="box", size=(0.3, 0.5, 0.12), position=(0.27, 0.0, 0.06), walkable=True)
    spec = compile_actions(list(parse("step onto the box").actions), talos, scene=Scene(objects=(box,)))
    assert [c.placement.position[2] for c in spec.phases[-1].contacts] == pytest.approx([0.12, 0.12])
