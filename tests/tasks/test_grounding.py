"""Grounding: references to scene objects resolved by name, alias, colour, size and relation
(tasks/grounding.py), over the example scenes; errors are one line naming what is wrong."""

from __future__ import annotations

from pathlib import Path

import pytest

from tasks.exceptions import GroundingError
from tasks.grounding import colour_name, gap, ground, in_relation, strip_reference
from tasks.scene import Scene, SceneObject, load_scene

SCENES = Path(__file__).resolve().parents[2] / "examples" / "scenes"


@pytest.fixture(scope="module")
def kitchen() -> Scene:
    return load_scene(SCENES / "kitchen.json")


@pytest.mark.parametrize(("reference", "name"), [
    ("the cup", "cup"),                          # name
    ("the mug", "cup"),                          # alias
    ("that table", "table"),                     # determiner
    ("the desk", "table"),
    ("to the table", "table"),                   # a preposition left by the parser
    ("the red box", "red box"),                  # a name with a colour in it
    ("the blue box", "blue box"),
    ("the crate", "blue box"),
    ("the big box", "blue box"),                 # size word: the largest of the boxes
    ("the small box", "red box"),
    ("the box on the table", "red box"),         # relations
    ("the box near the door", "blue box"),
    ("the box right of the table", "blue box"),
    ("the box to the right of the table", "blue box"),
    ("the box behind the table", "blue box"),
    ("the cup on the table", "cup"),
    ("the shelf left of the table", "shelf"),
    ("那个杯子", "cup"),                          # Chinese
    ("杯子", "cup"),
    ("桌子上的红色盒子", "red box"),
    ("桌子上的盒子", "red box"),
    ("门旁边的盒子", "blue box"),
    ("桌子后面的盒子", "blue box"),
    ("大盒子", "blue box"),
    ("小的盒子", "red box"),
    ("桌子旁边", "table"),
])
def test_kitchen_references(kitchen, reference, name):
    assert ground(reference, kitchen).name == name


def test_colour_words_pick_by_rgb_distance():
    """Two boxes differing only by colour: English and Chinese colour words pick the nearer named
    colour; a colour no candidate has lists the candidates' colours."""
    def box(name, rgb, y):
        return SceneObject(name=name, shape="box", size=(0.2, 0.2, 0.2), position=(1.0, y, 0.1), colour=(*rgb, 1.0))

    scene = Scene(objects=(box("box a", (0.9, 0.15, 0.1), 0.5), box("box b", (0.2, 0.7, 0.25), -0.5)))
    assert colour_name(scene.objects[0]) == "red" and colour_name(scene.objects[1]) == "green"
    assert ground("the red box", scene).name == "box a"
    assert ground("the green box", scene).name == "box b"
    with pytest.raises(GroundingError, match="its objects are box a, box b"):
        ground("红色的盒子", scene)  # 盒子 names none of them: they have English names only
    named = Scene(objects=tuple(SceneObject(name=o.name, shape=o.shape, size=o.size, position=o.position,
                                            colour=o.colour, aliases=(f"{c}盒子",))
                                for o, c in zip(scene.objects, ("甲", "乙"), strict=True)))
    assert ground("红色的盒子", named).name == "box a"
    assert ground("绿盒子", named).name == "box b"
    with pytest.raises(GroundingError, match=r'no blue box in the scene for "the blue box": box a \(red\), box b \(green\)'):
        ground("the blue box", scene)
    # the left/right relation is in the robot's initial frame: +y is its left
    landmark = SceneObject(name="post", shape="cylinder", size=(0.05, 1.0), position=(1.0, 0.0, 0.5))
    scene2 = Scene(objects=(*scene.objects, landmark))
    assert ground("the box left of the post", scene2).name == "box a"
    assert ground("the box right of the post", scene2).name == "box b"


def test_relations_against_the_geometry(kitchen):
    """Each relation checked against numbers computed here from the scene file's poses."""
    cup, table, red, blue, door = (kitchen.get(n) for n in ("cup", "table", "red box", "blue box", "door"))
    # on: the cup's bottom (0.77 - 0.05) is the table's top (0.72), its centre over the table
    assert cup.position[2] - cup.size[1] / 2 == pytest.approx(table.position[2] + table.size[2] / 2)
    assert in_relation(cup, "on", table) and in_relation(red, "on", table) and not in_relation(blue, "on", table)
    # near: blue box x 2.0..2.4, door x 2.775..2.825 (y overlaps) -> gap 0.375 m; red box x ..1.775,
    # y -0.425..-0.275 against the door's y -1.45..-0.55 -> gap hypot(1.0, 0.125)
    assert gap(blue, door) == pytest.approx(0.375)
    assert gap(red, door) == pytest.approx((1.0**2 + 0.125**2) ** 0.5)
    assert in_relation(blue, "near", door) and not in_relation(red, "near", door)
    assert in_relation(blue, "behind", table) and not in_relation(red, "behind", table)
    assert in_relation(kitchen.get("shelf"), "left of", table) and in_relation(blue, "right of", table)
    assert in_relation(red, "in front of", door) and in_relation(blue, "in front of", door)


@pytest.mark.parametrize(("reference", "message"), [
    ("the mug of tea", r'no object in the scene is called "the mug of tea"; its objects are table \(desk, 桌子\), '
                       r"cup \(mug, 杯子\), red box \(红色盒子\), blue box \(蓝色盒子, crate\), shelf \(架子, 书架\), door \(门\)"),
    ("the wooden box", r'no object in the scene is called "the wooden box"; its objects are table'),
    ("the box", r'"the box" could be red box \(red, at x 1.70, y -0.35, z 0.80 m\) or blue box \(blue, at x 2.20, '
                r"y -1.00, z 0.20 m\): say which one"),
    ("盒子", r'"盒子" could be red box .* or blue box'),
    ("the box in front of the door", r"could be red box .* or blue box"),
    ("the box left of the table", r'no box is left of the table for "the box left of the table"; the box candidates '
                                  r"are red box .*, blue box"),
    ("the green box", r'no green box in the scene for "the green box": red box \(red\), blue box \(blue\)'),
    ("the cup near the sofa", r'no object in the scene is called "the sofa"'),
])
def test_grounding_errors_are_one_line(kitchen, reference, message):
    with pytest.raises(GroundingError, match=message) as info:
        ground(reference, kitchen)
    assert "\n" not in str(info.value)


def test_ambiguous_reference_names_its_candidates(kitchen):
    with pytest.raises(GroundingError) as info:
        ground("the box", kitchen)
    assert info.value.candidates == ("red box", "blue box")


def test_no_scene_and_bad_references():
    with pytest.raises(GroundingError, match=r'walk_to "the table" refers to an object, but there is no scene: '
                                             r"give one with --scene FILE"):
        ground("to the table", None, action="walk_to")
    for bad in ("", "   ", "x" * 201, 3):
        with pytest.raises(GroundingError, match="non-empty text of at most 200 characters"):
            ground(bad, Scene())
    with pytest.raises(GroundingError, match="the scene has no objects"):
        ground("the cup", Scene())


@pytest.mark.parametrize(("scene", "reference", "name"), [
    ("table.json", "the table", "table"),
    ("table.json", "桌子", "table"),
    ("table.json", "that desk", "table"),
    ("box_on_floor.json", "the box", "box"),
    ("box_on_floor.json", "the carton", "box"),
    ("box_on_floor.json", "那个箱子", "box"),
    ("narrow_passage.json", "the left wall", "left wall"),
    ("narrow_passage.json", "the right side", "right wall"),
])
def test_other_example_scenes(scene, reference, name):
    assert ground(reference, load_scene(SCENES / scene)).name == name


def test_a_wall_needs_its_side_in_the_narrow_passage():
    with pytest.raises(GroundingError, match='"the wall" could be left wall .* or right wall'):
        ground("the wall", load_scene(SCENES / "narrow_passage.json"))


def test_strip_reference():
    assert strip_reference("over to the table") == "the table"
    assert strip_reference("到桌子") == "桌子"
    assert strip_reference("to") == "to"  # nothing left to strip to
