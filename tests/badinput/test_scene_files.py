"""Bad scene files (``wbmp solve ... --scene FILE``): refused on load, exit 3, one line naming the field.

A scene is loaded before the sentence is parsed or the spec read, so every case takes
milliseconds: no robot is loaded and nothing is planned. Each case writes ``scene.json`` into
``tmp_path``, runs the CLI with ``--out`` into the same folder and checks: no traceback, the
exit code, exactly one ``wbmp solve: error:`` line holding the words that say what was wrong
(the file, the field path), and nothing created. A valid scene whose object swallows a hand
target or a footstep is refused before planning with exit 4 (infeasible), naming the object.
"""

from __future__ import annotations

import codecs
import copy
import json
from collections.abc import Callable
from pathlib import Path

import pytest

from tasks.limits import MAX_OBJECTS, MAX_SPEC_BYTES
from tasks.scene import load_scene
from tests.badinput.conftest import REPO, Tree, assert_refused, run_cli

TABLE = REPO / "examples" / "scenes" / "table.json"
TABLE_TEXT = TABLE.read_text(encoding="utf-8")
TABLE_DATA = json.loads(TABLE_TEXT)
BOX = {"name": "crate", "shape": "box", "size": [0.3, 0.3, 0.3], "position": [-0.8, 0.5, 0.15]}


def _edit(change: Callable[[dict], None]) -> bytes:
    data = copy.deepcopy(TABLE_DATA)
    change(data)
    return json.dumps(data, ensure_ascii=False).encode("utf-8")


def _obj(**fields) -> bytes:
    """The table scene with a second object: BOX with ``fields`` changed (None deletes a key)."""
    obj = {**BOX, **fields}
    obj = {k: v for k, v in obj.items() if v is not None}
    return _edit(lambda d: d["objects"].append(obj))


CASES = [
    # the file
    ("empty", b"", ("scene.json", "is empty", "docs/scenes.md")),
    ("blank", b"  \n\t ", ("is empty",)),
    ("not-json", b"{objects: []}", ("invalid JSON", "line 1")),
    ("top-level-list", b"[]", ("expected a JSON object", "a list")),
    ("latin-1", TABLE_TEXT.replace("桌子", "tablé").encode("latin-1", errors="replace"), ("not UTF-8", "0xe9")),
    ("utf-16-no-bom", TABLE_TEXT.encode("utf-16-le"), ("UTF-16", "save it as UTF-8")),
    ("nan", TABLE_TEXT.replace("0.65", "NaN", 1).encode(), ("NaN",)),
    ("infinity", TABLE_TEXT.replace("0.65", "-Infinity", 1).encode(), ("Infinity",)),
    ("huge-literal", TABLE_TEXT.replace("0.65", "1" * 60, 1).encode(), ("60 digits",)),
    ("1e400", TABLE_TEXT.replace("0.65", "1e400", 1).encode(), ("too large",)),
    ("deep-nesting", ('{"objects": ' + "[" * 40 + "]" * 40 + "}").encode(), ("nested more than 16",)),
    ("version-2", _edit(lambda d: d.update(version=2)), ("version", "not supported")),
    ("unknown-top-key", _edit(lambda d: d.update(floor={"friction": 1})), ("unknown key", "'floor'", "floor_friction")),
    ("floor-friction-0", _edit(lambda d: d.update(floor_friction=0)), ("floor_friction", "(0, 10]")),
    ("floor-friction-string", _edit(lambda d: d.update(floor_friction="high")), ("floor_friction", "expected a number")),
    ("objects-not-list", _edit(lambda d: d.update(objects={"table": {}})), ("objects", "expected a list")),
    ("too-many-objects", _edit(lambda d: d.update(objects=[{**BOX, "name": f"b{i}"} for i in range(MAX_OBJECTS + 1)])),
     ("objects", f"at most {MAX_OBJECTS}")),
    # one object
    ("box-negative-size", _obj(size=[0.5, -1, 0.8]), ("objects[1].size: a box needs 3 positive lengths [m]", "-1")),
    ("box-two-sizes", _obj(size=[0.5, 0.8]), ("objects[1].size", "a box needs 3")),
    ("cylinder-three-sizes", _obj(shape="cylinder", size=[0.1, 0.2, 0.3]), ("objects[1].size", "(radius, length)")),
    ("sphere-zero", _obj(shape="sphere", size=[0]), ("objects[1].size", "sphere", "radius")),
    ("size-1e9", _obj(size=[1e9, 1, 1]), ("objects[1].size", "at most 100")),
    ("size-string", _obj(size="big"), ("objects[1].size", "expected a list")),
    ("shape-unknown", _obj(shape="cone"), ("objects[1].shape", "box, cylinder, sphere, mesh", "'cone'")),
    ("missing-position", _obj(position=None), ("objects[1]", "missing key", "position")),
    ("position-two", _obj(position=[0, 0]), ("objects[1].position", "expected 3 items in metres")),
    ("position-1e5", _obj(position=[1e5, 0, 0]), ("objects[1].position", "[-100, 100]")),
    ("rpy-string-item", _obj(rpy=[0, "a", 0]), ("objects[1].rpy[1]", "expected a number in radians")),
    ("colour-over-1", _obj(colour=[1, 0, 0, 2]), ("objects[1].colour", "[0, 1]")),
    ("colour-name", _obj(colour="red"), ("objects[1].colour", "expected a list")),
    ("movable-no-mass", _obj(movable=True), ("objects[1].mass", "movable object needs a mass")),
    ("mass-1e6", _obj(movable=True, mass=1e6), ("objects[1].mass", "1000")),
    ("movable-string", _obj(movable="yes"), ("objects[1].movable", "true or false")),
    ("friction-negative", _obj(friction=-1), ("objects[1].friction",)),
    ("duplicate-name", _obj(name="table"), ("objects[1].name", "'table' already names objects[0]")),
    ("alias-of-other", _obj(aliases=["desk"]), ("objects[1].aliases[0]", "'desk' already names objects[0]")),
    ("name-empty", _obj(name=""), ("objects[1].name", "non-empty")),
    ("name-number", _obj(name=3), ("objects[1].name", "expected a string")),
    ("name-padded", _obj(name=" crate "), ("objects[1].name", "starts or ends with a space")),
    ("unknown-object-key", _obj(color=[1, 0, 0, 1]), ("objects[1]", "unknown key", "'color'", "colour")),
    ("mesh-on-a-box", _obj(mesh="crate.stl"), ("objects[1].mesh", "only a mesh object")),
    ("mesh-without-file", _obj(shape="mesh", size=[1, 1, 1]), ("objects[1].mesh", "needs the mesh file")),
    ("mesh-missing-file", _obj(shape="mesh", size=[1, 1, 1], mesh="meshes/none.stl"),
     ("objects[1].mesh", "does not exist", "relative to the scene file")),
]


def _refused(tmp_path: Path, capsys, scene: str, code: int, *words: str, argv: tuple[str, ...] = ("squat",)) -> None:
    tree = Tree(tmp_path)
    out = run_cli(["solve", *argv, "--scene", scene, "--no-sim", "--no-cache", "--quiet",
                   "--out", tmp_path / "m.npz"], capsys)
    assert_refused(out, code, *words)
    tree.assert_unchanged()


@pytest.mark.parametrize(("content", "words"), [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_bad_scene_file_is_refused(tmp_path, capsys, content, words):
    scene = tmp_path / "scene.json"
    scene.write_bytes(content)
    _refused(tmp_path, capsys, str(scene), 3, "scene.json", *words)


@pytest.mark.parametrize(("place", "words"), [
    (lambda tmp: str(tmp / "none.json"), ("scene file", "does not exist")),
    (lambda tmp: str(tmp), ("is a directory",)),
    (lambda tmp: "/dev/zero", (f"larger than {MAX_SPEC_BYTES // 2**20} MiB",)),
], ids=["missing", "directory", "device"])
def test_bad_scene_path_is_refused(tmp_path, capsys, place, words):
    _refused(tmp_path, capsys, place(tmp_path), 3, *words)


def test_empty_scene_argument_is_a_usage_error(tmp_path, capsys):
    _refused(tmp_path, capsys, "", 2, "--scene is empty", "scene JSON file")


@pytest.mark.parametrize("content", [codecs.BOM_UTF8 + TABLE_TEXT.encode(), codecs.BOM_UTF16_LE + TABLE_TEXT.encode("utf-16-le")],
                         ids=["utf-8-bom", "utf-16-bom"])
def test_scene_with_byte_order_mark_is_read(tmp_path, content):
    scene = tmp_path / "scene.json"
    scene.write_bytes(content)
    assert load_scene(scene) == load_scene(TABLE)


def test_a_hand_target_inside_the_table_is_refused_before_planning(tmp_path, capsys):
    """A reach 0.5 m below the base, 0.55 m in front: into the table (exit 4, the table named)."""
    spec = json.loads((REPO / "examples" / "specs" / "reach.json").read_text(encoding="utf-8"))
    spec["targets"][0]["position"] = [0.55, -0.3, 0.5]
    path = tmp_path / "reach.json"
    path.write_text(json.dumps(spec), encoding="utf-8")
    _refused(tmp_path, capsys, str(TABLE), 4, "the right hand target (0.55, -0.3, 0.5)", "inside the table",
             "z 0..0.62 m", argv=("--spec", str(path)))


def test_a_footstep_inside_an_object_is_refused_naming_it(tmp_path, capsys):
    """A box where the robot stands: the left foot's sole is inside it (exit 4, the box named)."""
    scene = tmp_path / "scene.json"
    scene.write_text(json.dumps({"objects": [{**BOX, "name": "crate", "position": [0.0, 0.2, 0.15]}]}), encoding="utf-8")
    _refused(tmp_path, capsys, str(scene), 4, "the left foot placement", "puts the sole inside the crate")



def test_a_walk_into_a_crate_is_refused_at_the_first_footstep_inside_it(tmp_path, capsys):
    """'walk forward 1 m' with a crate 0.35 m ahead: the first footstep whose sole reaches the crate
    is refused before planning (exit 4), naming the crate."""
    scene = tmp_path / "scene.json"
    crate = {**BOX, "size": [0.3, 0.6, 0.3], "position": [0.5, 0.0, 0.15]}
    scene.write_text(json.dumps({"objects": [crate]}), encoding="utf-8")
    _refused(tmp_path, capsys, str(scene), 4, "foot placement", "the crate", "x 0.35..0.65",
             argv=("walk forward 1 m",))
