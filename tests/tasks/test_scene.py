"""Scenes as data: validation, exact round trips, distances (against coal), targets inside objects."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from tasks.exceptions import SceneConflict, TaskDefinitionError
from tasks.robot_check import check_spec_in_scene
from tasks.scene import (
    SCENE_MARGIN,
    Scene,
    SceneObject,
    load_scene,
    scene_from_dict,
    scene_to_dict,
    signed_distance,
)
from tasks.serialize import spec_from_dict, spec_from_json, spec_to_dict, spec_to_json
from tasks.spec_schema import scene_schema, schema_json
from tests.tasks.test_spec_schema import validate

ROOT = Path(__file__).resolve().parents[2]
SCENES = ROOT / "examples" / "scenes"
TABLE = load_scene(SCENES / "table.json")


def _objects() -> tuple[SceneObject, ...]:
    return (
        SceneObject(name="table", shape="box", size=(0.6, 1.2, 0.62), position=(0.65, 0.0, 0.31),
                    rpy=(0.0, 0.0, 0.4), aliases=("desk", "桌子")),
        SceneObject(name="bin", shape="cylinder", size=(0.15, 0.5), position=(0.3, 0.6, 0.25),
                    rpy=(0.3, -0.2, 0.1), colour=(0.1, 0.2, 0.3, 0.5)),
        SceneObject(name="ball", shape="sphere", size=(0.11,), position=(1.0, -0.5, 0.11), movable=True,
                    mass=0.45, friction=0.5),
    )


def test_spec_with_a_scene_round_trips_exactly(talos):
    from tasks.actions import Action
    from tasks.compose import compile_actions

    spec = compile_actions([Action(name="squat")], talos)
    spec = dataclasses.replace(spec, scene=Scene(name="kitchen", objects=_objects(), floor_friction=0.6))
    assert spec_from_json(spec_to_json(spec)) == spec
    assert spec_from_dict(json.loads(json.dumps(spec_to_dict(spec)))) == spec
    assert spec_to_dict(spec)["scene"]["objects"][2]["mass"] == 0.45
    assert spec_from_dict({**spec_to_dict(spec), "scene": None}).scene is None


def test_scene_file_round_trips_and_resolves_mesh_paths(tmp_path):
    scene = Scene(name="s", objects=_objects())
    path = tmp_path / "s.json"
    path.write_text(json.dumps(scene_to_dict(scene)), encoding="utf-8")
    assert load_scene(path) == scene
    (tmp_path / "meshes").mkdir()
    (tmp_path / "meshes" / "cup.stl").write_bytes(b"solid cup\nendsolid cup\n")
    data = {"objects": [{"name": "cup", "shape": "mesh", "size": [1, 1, 1], "position": [0.5, 0, 0.8],
                         "mesh": "meshes/cup.stl"}]}
    path.write_text(json.dumps(data), encoding="utf-8")
    assert load_scene(path).objects[0].mesh == str((tmp_path / "meshes" / "cup.stl").resolve())


@pytest.mark.parametrize(("change", "words"), [
    (lambda o: o.update(size=[0.5, -1, 0.8]), "objects[1].size: a box needs 3 positive lengths [m]"),
    (lambda o: o.update(shape="cone"), "objects[1].shape: must be one of box, cylinder, sphere, mesh"),
    (lambda o: o.update(size=[0.1, 0.2], shape="sphere"), "objects[1].size: a sphere needs 1 positive radius"),
    (lambda o: o.update(colour=[1, 0, 0, 2]), "objects[1].colour"),
    (lambda o: o.update(movable=True), "objects[1].mass: a movable object needs a mass > 0 kg"),
    (lambda o: o.update(name="table"), "objects[1].name: 'table' already names objects[0]"),
    (lambda o: o.update(aliases=["desk"]), "objects[1].aliases[0]: 'desk' already names objects[0]"),
    (lambda o: o.update(mesh="a.stl"), "objects[1].mesh: only a mesh object has a mesh file"),
    (lambda o: o.update(friction=0), "objects[1].friction"),
    (lambda o: o.update(position=[0, 0]), "objects[1].position: expected 3 items in metres"),
    (lambda o: o.update(colur=[1, 0, 0, 1]), "objects[1]: unknown key(s) ['colur']"),
])
def test_bad_objects_name_the_field(change, words):
    data = scene_to_dict(Scene(objects=_objects()[:1]))
    other = {"name": "shelf", "shape": "box", "size": [0.4, 0.4, 1.5], "position": [-0.8, 0.0, 0.75]}
    change(other)
    data["objects"].append(other)
    with pytest.raises(TaskDefinitionError) as e:
        scene_from_dict(data)
    assert words in str(e.value)
    # the same object inside a spec: the same words behind the spec's path
    with pytest.raises(TaskDefinitionError) as e2:
        spec_from_dict({"phases": [{"name": "p", "duration": 1.0}], "scene": {k: v for k, v in data.items()
                                                                               if k != "version"}})
    assert f"spec.scene.{words}" in str(e2.value)


def test_signed_distance_matches_coal():
    """Distances from random points outside each shape equal coal's (GJK on the same shapes)."""
    import coal
    import pinocchio as pin

    rng = np.random.default_rng(7)
    request, point = coal.DistanceRequest(), coal.Sphere(1e-9)
    for obj in _objects():
        size = obj.size
        if obj.shape == "box":
            shape = coal.Box(*size)
        elif obj.shape == "cylinder":
            shape = coal.Cylinder(size[0], size[1])
        else:
            shape = coal.Sphere(size[0])
        pose = coal.Transform3s(pin.rpy.rpyToMatrix(*obj.rpy), np.array(obj.position))
        checked = 0
        while checked < 60:
            p = np.array(obj.position) + rng.uniform(-1.0, 1.0, 3)
            ours = signed_distance(obj, p)
            assert ours is not None
            if ours < 0.02:  # coal's GJK distance is for separated shapes: inside is checked below
                continue
            result = coal.DistanceResult()
            theirs = coal.distance(shape, pose, point, coal.Transform3s(np.eye(3), p), request, result)
            assert ours == pytest.approx(theirs, abs=1e-6)
            checked += 1
        # inside: the depth is the distance to the nearest face, seen along the object's own axes
        R = pin.rpy.rpyToMatrix(*obj.rpy)
        centre = np.array(obj.position)
        if obj.shape == "box":
            depth = min(size) / 2
        elif obj.shape == "cylinder":
            depth = min(size[0], size[1] / 2)
        else:
            depth = size[0]
        assert signed_distance(obj, centre) == pytest.approx(-depth, abs=1e-12)
        local = np.array([0.0, 0.0, 0.9 * size[-1] / 2]) if obj.shape != "sphere" else np.array([0, 0, 0.9 * size[0]])
        assert signed_distance(obj, centre + R @ local) < 0


def test_published_scene_schema_is_up_to_date_and_accepts_the_examples():
    assert (ROOT / "docs" / "scene.schema.json").read_text() == schema_json(scene=True), (
        "regenerate it: .venv/bin/python -m tasks.spec_schema --scene > docs/scene.schema.json")
    schema = scene_schema()
    for path in sorted(SCENES.glob("*.json")):
        assert validate(json.loads(path.read_text(encoding="utf-8")), schema) == [], path.name
    bad = json.loads((SCENES / "table.json").read_text(encoding="utf-8"))
    bad["objects"][0]["colour_rgb"] = [1, 0, 0]
    assert validate(bad, schema)


def _reach_spec(talos, sentence_target):
    from tasks.actions import Action
    from tasks.compose import compile_actions

    spec = compile_actions([Action(name="reach", params=sentence_target)], talos)
    return dataclasses.replace(spec, scene=TABLE)


def test_a_reach_over_the_table_compiles_and_one_into_it_is_refused_naming_the_table(talos):
    """'reach forward 30 cm' passes 16 cm over the table top; a target inside the table is refused."""
    from tasks.robot_check import check_spec_for_robot, check_spec_in_scene_for_robot

    table = TABLE.get("table")
    top = table.position[2] + table.size[2] / 2
    over = _reach_spec(talos, {"hand": "right", "direction": "forward", "distance": 0.3})
    target = next(t for t in over.targets if t.position is not None and "reach point" in t.name)
    assert table.position[0] - table.size[0] / 2 < target.position[0]  # above the table's footprint
    assert target.position[2] - top > 0.1
    check_spec_for_robot(over, talos)
    check_spec_in_scene_for_robot(over, talos)  # no exception
    assert signed_distance(table, target.position) == pytest.approx(target.position[2] - top, abs=1e-9)

    into = _reach_spec(talos, {"hand": "right", "target": [0.55, -0.3, -0.5]})  # base frame: 0.5 m below the base
    with pytest.raises(SceneConflict) as e:
        check_spec_in_scene_for_robot(into, talos)
    assert e.value.object_name == "table"
    message = str(e.value)
    assert message.startswith("the right hand target (") and "is inside the table" in message
    assert "z 0..0.62 m" in message


def test_margin_footsteps_and_standing_on_top():
    from tasks.specs import Contact, Phase, Pose, TaskSpec

    box = SceneObject(name="step", shape="box", size=(0.4, 0.4, 0.2), position=(0.6, 0.0, 0.1))

    def spec_at(position, *, target=None):
        phase = Phase(name="stand", duration=1.0,
                      contacts=(Contact(frame="left_foot", placement=Pose(position=position)),))
        targets = () if target is None else (target,)
        return TaskSpec(phases=(phase,), targets=targets, scene=Scene(objects=(box,)))

    check_spec_in_scene(spec_at((0.0, 0.0, 0.0)))  # far away
    check_spec_in_scene(spec_at((0.6, 0.0, 0.2)))  # standing on the top face: a support
    with pytest.raises(SceneConflict, match="puts the sole inside the step"):
        check_spec_in_scene(spec_at((0.6, 0.0, 0.0)))  # under it
    edge = 0.4 - SCENE_MARGIN / 2  # the sole point half the margin from the box's face
    with pytest.raises(SceneConflict, match=r"0\.5 cm from the step"):
        check_spec_in_scene(spec_at((0.6 - 0.2 - SCENE_MARGIN / 2, 0.0, 0.0)))
    check_spec_in_scene(spec_at((edge - 2 * SCENE_MARGIN, 0.0, 0.0)))  # 2.5 cm clear
    corners = {"left_foot": [(0.1, 0.06, 0.0), (0.1, -0.06, 0.0), (-0.1, 0.06, 0.0), (-0.1, -0.06, 0.0)]}
    with pytest.raises(SceneConflict):  # its origin is 5 cm clear, its toe 5 cm into the box
        check_spec_in_scene(spec_at((0.6 - 0.2 - 0.05, 0.0, 0.0)), contact_points=corners)
    from tasks.specs import FrameTarget

    near = FrameTarget(name="touch", frame="right_hand", position=(0.6, 0.0, 0.2 + SCENE_MARGIN / 2))
    with pytest.raises(SceneConflict, match="right hand target"):
        check_spec_in_scene(spec_at((0.0, 0.0, 0.0), target=near))
    height_only = dataclasses.replace(near, axes=(False, False, True))
    check_spec_in_scene(spec_at((0.0, 0.0, 0.0), target=height_only))  # a height target has no point
    assert math.isclose(signed_distance(box, (0.6, 0.0, 0.2 + SCENE_MARGIN / 2)), SCENE_MARGIN / 2)
