"""Bad robot profiles (``--robot FILE``): every one is a one-line RobotError (exit 3), never a traceback.

Each case starts from a real profile (the built-in ``g1.toml`` renamed ``myg1``, or a URDF profile
of Talos's example-robot-data files copied next to it) and breaks exactly one thing; the valid
starting points are shown to load first. Most cases call :func:`robots.load_robot` directly (a
refusal before the meshes load costs milliseconds); a representative subset goes through the
CLI (``wbmp robots PROFILE`` and ``wbmp solve "squat" --robot PROFILE --no-sim``).
"""

from __future__ import annotations

import copy
import json
import math
import os
import re
import shutil
import tomllib
from pathlib import Path

import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from robots import FrameNotFound, ProfileError, RobotError, RobotNotFound, load_robot
from tests.badinput.conftest import REPO, Tree, assert_refused, run_cli, run_cli_process

G1_TOML = REPO / "robots" / "profiles" / "g1.toml"
TALOS_TOML = REPO / "robots" / "profiles" / "talos.toml"


# --- writing profiles ---------------------------------------------------------------------------


def g1_profile() -> dict:
    """The built-in G1 profile as data, renamed (a built-in name is refused for a user file)."""
    data = tomllib.loads(G1_TOML.read_text())
    data["name"] = "myg1"
    return data


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v)  # JSON's string escapes are TOML basic-string escapes
    if isinstance(v, float):
        return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf") if math.isinf(v) else repr(v)
    if isinstance(v, int):
        return str(v)
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{json.dumps(k)} = {_toml_value(x)}" for k, x in v.items()) + " }"
    raise TypeError(f"no TOML for {v!r}")


def to_toml(data: dict) -> str:
    """A TOML document of ``data``: scalars first, then [tables] and [[arrays of tables]]."""
    head, tail = [], []
    for key, v in data.items():
        k = json.dumps(key)
        if isinstance(v, dict):
            tail += [f"\n[{k}]"] + [f"{json.dumps(a)} = {_toml_value(b)}" for a, b in v.items()]
        elif isinstance(v, list) and v and all(isinstance(e, dict) for e in v):
            for e in v:
                tail += [f"\n[[{k}]]"] + [f"{json.dumps(a)} = {_toml_value(b)}" for a, b in e.items()]
        else:
            head.append(f"{k} = {_toml_value(v)}")
    return "\n".join(head + tail) + "\n"


def write_profile(folder: Path, data, *, fmt: str = "toml", name: str = "myg1") -> Path:
    """Write ``data`` as ``folder/name.toml`` (or ``.json``, which can also hold null and NaN)."""
    path = folder / f"{name}.{fmt}"
    path.write_text(to_toml(data) if fmt == "toml" else json.dumps(data))
    return path


def refused(path, *words: str, kind: type[RobotError] = RobotError) -> str:
    """load_robot(path) raises ``kind`` with a one-line message naming the file and ``words``."""
    with pytest.raises(RobotError) as info:
        load_robot(path)
    msg = str(info.value)
    assert isinstance(info.value, kind), f"{type(info.value).__name__}: {msg}"
    assert "\n" not in msg and "Traceback" not in msg, msg
    assert Path(str(path)).name in msg, f"the file is not named: {msg}"
    for w in words:
        assert w.lower() in msg.lower(), f"{w!r} not in {msg!r}"
    return msg


def test_the_starting_profiles_load(tmp_path, talos):
    """The unbroken starting points load: each case below breaks exactly one thing of them."""
    robot = load_robot(write_profile(tmp_path, g1_profile()))
    g1 = load_robot("g1")
    assert robot.name == "myg1" and robot.nq == g1.nq == 36
    assert robot.profile.squat_depth_max == g1.profile.squat_depth_max == 0.25
    assert dict(robot.profile.frames) == dict(g1.profile.frames)
    assert abs(robot.q_standing - g1.q_standing).max() < 1e-9
    robot = load_robot(write_profile(tmp_path, g1_profile(), fmt="json"))
    assert robot.profile.extra_frames == g1.profile.extra_frames
    urdf_profile = _talos_urdf_profile(tmp_path / "u", talos)
    assert tomllib.loads(urdf_profile.read_text())["urdf"] == "robot.urdf"
    robot = load_robot(urdf_profile)
    assert robot.name == "mytalos" and robot.nq == talos.nq
    assert abs(robot.q_standing - talos.q_standing).max() < 1e-9


# --- one field wrong in the G1 profile ------------------------------------------------------------


def _set(path: str, value):
    """A mutation that sets a dotted field (``sole.x_min``, ``extra_frames.0.name``)."""

    def mutate(d: dict) -> None:
        *parents, last = path.split(".")
        for p in parents:
            d = d[int(p)] if isinstance(d, list) else d[p]
        if isinstance(d, list):
            d[int(last)] = value
        else:
            d[last] = value

    return mutate


def _drop(path: str):
    def mutate(d: dict) -> None:
        *parents, last = path.split(".")
        for p in parents:
            d = d[int(p)] if isinstance(d, list) else d[p]
        d.pop(int(last) if isinstance(d, list) else last)

    return mutate


def _add_extra_frame(**entry):
    return lambda d: d["extra_frames"].append(entry)


# (id, mutation of the G1 profile, words the message must hold, format)
FIELD_CASES = [
    ("squat-depth-word", _set("squat_depth_max", "deep"), ("squat_depth_max", "expected a length in metres", "'deep'"), "toml"),
    ("squat-depth-nan", _set("squat_depth_max", math.nan), ("squat_depth_max", "got nan"), "toml"),
    ("squat-depth-inf", _set("squat_depth_max", math.inf), ("squat_depth_max", "(0, 1]", "got inf"), "toml"),
    ("squat-depth-negative", _set("squat_depth_max", -0.1), ("squat_depth_max", "(0, 1]"), "toml"),
    ("squat-depth-zero", _set("squat_depth_max", 0), ("squat_depth_max", "(0, 1]"), "toml"),
    ("squat-depth-millimetres", _set("squat_depth_max", 250), ("squat_depth_max", "(0, 1]", "250"), "toml"),
    ("squat-depth-boolean", _set("squat_depth_max", True), ("squat_depth_max", "a number", "boolean"), "toml"),
    ("squat-depth-list", _set("squat_depth_max", [0.2]), ("squat_depth_max", "a list"), "toml"),
    ("squat-depth-null", _set("squat_depth_max", None), ("squat_depth_max", "null"), "json"),
    ("squat-depth-huge-int", _set("squat_depth_max", 10**400), ("squat_depth_max", "more than 60 digits"), "json"),
    ("friction-zero", _set("friction_coefficient", 0.0), ("friction_coefficient", "(0, 5]"), "toml"),
    ("friction-negative", _set("friction_coefficient", -0.7), ("friction_coefficient", "(0, 5]"), "toml"),
    ("friction-string", _set("friction_coefficient", "0.7"), ("friction_coefficient", "a number", "'0.7'"), "toml"),
    ("step-length-minus-inf", _set("step_length_max", -math.inf), ("step_length_max", "-inf"), "toml"),
    ("step-width-negative", _set("step_width", -0.1), ("step_width", "[0, 1]"), "toml"),
    ("step-duration-zero", _set("step_duration", 0), ("step_duration", "seconds", "[0.1, 5]"), "toml"),
    ("step-duration-huge", _set("step_duration", 1e9), ("step_duration", "[0.1, 5]"), "toml"),
    ("double-support-negative", _set("double_support_duration", -0.2), ("double_support_duration", "seconds"), "toml"),
    ("name-missing", _drop("name"), ("name", "missing"), "toml"),
    ("name-empty", _set("name", ""), ("name", "expected a short robot name"), "toml"),
    ("name-number", _set("name", 42), ("name", "got 42"), "toml"),
    ("name-with-space", _set("name", "my robot"), ("name", "'my robot'"), "toml"),
    ("name-newline", _set("name", "my\nrobot"), ("name", "'my\\nrobot'"), "toml"),
    ("name-too-long", _set("name", "r" * 100), ("name", "at most 64"), "toml"),
    ("name-of-a-builtin", _set("name", "g1"), ("name", "built-in robot", "own name"), "toml"),
    ("description-list", _set("description", ["a", "b"]), ("description", "one line of text"), "toml"),
    ("description-two-lines", _set("description", "a\nb"), ("description", "one line"), "toml"),
    ("loader-unknown", _set("loader", "g2"), ("loader", "example-robot-data robot", "'g2'", "did you mean"), "toml"),
    ("loader-number", _set("loader", 3), ("loader", "got 3"), "toml"),
    ("loader-fixed-base-arm", _set("loader", "panda"), ("loader", "'panda'", "fixed to the ground"), "toml"),
    ("loader-and-urdf-missing", _drop("loader"), ("exactly one of 'loader'", "neither"), "toml"),
    ("loader-and-urdf-both", _set("urdf", "g1.urdf"), ("exactly one of 'loader'", "both"), "toml"),
    ("srdf-with-loader", _set("srdf", "g1.srdf"), ("srdf", "only applies with 'urdf'"), "toml"),
    ("package-dirs-with-loader", _set("package_dirs", ["."]), ("package_dirs", "only applies with 'urdf'"), "toml"),
    ("unknown-key-typo", _set("squat_depth", 0.2), ("unknown key 'squat_depth'", "did you mean 'squat_depth_max'", "the keys are"), "toml"),
    ("unknown-key-singular", _set("frame", {"head": "head_link"}), ("unknown key 'frame'", "'frames'"), "toml"),
    ("frames-list", _set("frames", ["left_sole", "right_sole"]), ("frames", "a table [frames]", "a list"), "toml"),
    ("frames-string", _set("frames", "left_sole"), ("frames", "a table", "'left_sole'"), "toml"),
    ("frames-missing", _drop("frames"), ("frames", "missing"), "toml"),
    ("frames-without-left-hand", _drop("frames.left_hand"), ("frames", "missing role", "left_hand"), "toml"),
    ("frames-unknown-role", _set("frames.left_feet", "left_sole"), ("frames", "unknown role 'left_feet'", "'left_foot'"), "toml"),
    ("frames-name-number", _set("frames.head", 7), ("frames.head", "a frame name", "got 7"), "toml"),
    ("frames-name-empty", _set("frames.head", ""), ("frames.head", "a frame name"), "toml"),
    ("frames-same-hand-twice", _set("frames.right_hand", "left_rubber_hand"), ("left_hand and right_hand", "'left_rubber_hand'"), "toml"),
    ("frames-one-shoulder", _drop("frames.right_shoulder"), ("left_shoulder is given without right_shoulder",), "toml"),
    ("frames-not-in-urdf", _set("frames.left_foot", "left_foot_sole"), ("frames.left_foot", "no frame 'left_foot_sole'"), "toml"),
    ("frames-typo-suggests", _set("frames.left_hand", "left_rubber_hnd"), ("frames.left_hand", "did you mean 'left_rubber_hand'"), "toml"),
    ("frames-nothing-close-lists-some", _set("frames.torso", "zzzz"), ("frames.torso", "its frames include", "in all"), "toml"),
    ("frames-feet-swapped", lambda d: d["frames"].update(left_foot="right_sole", right_foot="left_sole"), ("left_foot", "right_foot", "swapped"), "toml"),
    ("frames-hands-swapped", lambda d: d["frames"].update(left_hand="right_rubber_hand", right_hand="left_rubber_hand"), ("left_hand", "swapped"), "toml"),
    ("frames-both-feet-on-one-leg", _set("frames.right_foot", "left_ankle_roll_link"), ("right_foot", "less than 1 cm apart"), "toml"),
    ("extra-frames-table", _set("extra_frames", {"name": "x"}), ("extra_frames", "a list of tables"), "toml"),
    ("extra-frames-entry-string", _set("extra_frames.0", "left_sole"), ("extra_frames[0]", "a table with name"), "toml"),
    ("extra-frame-without-name", _drop("extra_frames.0.name"), ("extra_frames[0]", "missing name"), "toml"),
    ("extra-frame-name-empty", _set("extra_frames.1.name", ""), ("extra_frames[1].name", "a frame name"), "toml"),
    ("extra-frame-without-translation", _drop("extra_frames.0.translation"), ("extra_frames[0]", "missing translation"), "toml"),
    ("extra-frame-translation-2d", _set("extra_frames.0.translation", [0.0, 0.0]), ("extra_frames[0].translation", "3 numbers"), "toml"),
    ("extra-frame-translation-nan", _set("extra_frames.0.translation", [0.0, math.nan, 0.0]), ("extra_frames[0].translation", "finite"), "toml"),
    ("extra-frame-translation-millimetres", _set("extra_frames.0.translation", [0, 0, -35]), ("extra_frames[0].translation", "[-1, 1] m"), "toml"),
    ("extra-frame-translation-strings", _set("extra_frames.0.translation", ["0", "0", "0"]), ("extra_frames[0].translation", "3 numbers"), "toml"),
    ("extra-frame-unknown-key", lambda d: d["extra_frames"][0].update(parnet="pelvis"), ("extra_frames[0]", "unknown key 'parnet'", "'parent'"), "toml"),
    ("extra-frame-twice", _add_extra_frame(name="left_sole", parent="pelvis", translation=[0, 0, 0]), ("extra_frames[2].name", "defined twice"), "toml"),
    ("extra-frame-clashes-with-urdf", _set("extra_frames.0.name", "pelvis"), ("extra_frames[0].name", "already has a frame 'pelvis'"), "toml"),
    ("extra-frame-parent-not-in-urdf", _set("extra_frames.0.parent", "left_ankle"), ("extra_frames[0].parent", "no frame 'left_ankle'", "did you mean"), "toml"),
    ("extra-frame-own-parent", _set("extra_frames.0.parent", "left_sole"), ("extra_frames[0].parent", "its own parent"), "toml"),
    ("sole-missing", _drop("sole"), ("sole", "missing"), "toml"),
    ("sole-list", _set("sole", [-0.05, 0.12, -0.025, 0.025]), ("sole", "a table [sole]"), "toml"),
    ("sole-without-y-max", _drop("sole.y_max"), ("sole", "missing y_max"), "toml"),
    ("sole-unknown-key", _set("sole.x_mn", 0.0), ("sole", "unknown key 'x_mn'", "'x_min'"), "toml"),
    ("sole-inside-out", _set("sole.x_min", 0.2), ("sole", "x_min < x_max", "x_min = 0.2"), "toml"),
    ("sole-zero-width", _set("sole.y_min", 0.025), ("sole", "y_min < y_max", "1 cm"), "toml"),
    ("sole-string", _set("sole.x_max", "12 cm"), ("sole.x_max", "a number", "'12 cm'"), "toml"),
    ("sole-millimetres", _set("sole.x_max", 120), ("sole.x_max", "[-1, 1]", "120"), "toml"),
    ("sole-nan", _set("sole.y_max", math.nan), ("sole.y_max", "nan"), "toml"),
    ("posture-name-not-in-model", _set("reference_posture", "half_sitting"), ("reference_posture", "'q0'", "'half_sitting'"), "toml"),
    ("posture-name-number", _set("reference_posture", 0), ("reference_posture", "got 0"), "toml"),
    ("posture-overrides-string", _set("posture_overrides", "bent"), ("posture_overrides", "a table", "'bent'"), "toml"),
    ("posture-overrides-list", _set("posture_overrides", [0.1, -0.2, 0.4]), ("posture_overrides", "a table", "a list of 3"), "toml"),
    ("posture-override-unknown-joint", _set("posture_overrides.left_knee", 0.4), ("posture_overrides.left_knee", "no actuated joint", "'left_knee_joint'"), "toml"),
    ("posture-override-string", _set("posture_overrides.left_knee_joint", "bent"), ("posture_overrides.left_knee_joint", "a number"), "toml"),
    ("posture-override-nan", _set("posture_overrides.left_knee_joint", math.nan), ("posture_overrides.left_knee_joint", "nan"), "toml"),
    ("posture-override-beyond-limit", _set("posture_overrides.left_knee_joint", 3.0), ("posture_overrides.left_knee_joint", "joint's limits"), "toml"),
    ("posture-override-root", _set("posture_overrides.root_joint", 0.1), ("posture_overrides.root_joint", "root"), "toml"),
    ("posture-override-degrees", _set("posture_overrides.left_knee_joint", 24.0), ("posture_overrides.left_knee_joint", "[-10, 10]"), "toml"),
]


@pytest.mark.parametrize(("mutate", "words", "fmt"), [c[1:] for c in FIELD_CASES], ids=[c[0] for c in FIELD_CASES])
def test_one_bad_field_is_a_one_line_profile_error(tmp_path, mutate, words, fmt):
    """Each field is checked on load; the message names the file, the field and what was expected."""
    data = g1_profile()
    mutate(data)
    path = write_profile(tmp_path, data, fmt=fmt)
    tree = Tree(tmp_path)
    refused(path, *words)
    tree.assert_unchanged()


def test_frame_errors_are_frame_not_found(tmp_path):
    """A frame name the URDF lacks is FrameNotFound (a RobotError), with the file and the field."""
    data = g1_profile()
    data["frames"]["base"] = "pelvs"
    refused(write_profile(tmp_path, data), "frames.base", "'pelvis'", kind=FrameNotFound)


# --- the file itself is wrong ----------------------------------------------------------------------


def _raw(content: bytes, name: str = "myg1.toml"):
    def make(folder: Path) -> Path:
        path = folder / name
        path.write_bytes(content)
        return path

    return make


def _g1_text(transform, name: str = "myg1.toml"):
    return lambda folder: _raw(transform(to_toml(g1_profile())).encode(), name)(folder)


def _directory(folder: Path) -> Path:
    (folder / "myg1.toml").mkdir()
    return folder / "myg1.toml"


def _fifo(folder: Path) -> Path:
    os.mkfifo(folder / "myg1.toml")
    return folder / "myg1.toml"


def _dangling_link(folder: Path) -> Path:
    (folder / "myg1.toml").symlink_to(folder / "gone.toml")
    return folder / "myg1.toml"


def _too_big(folder: Path) -> Path:
    path = folder / "myg1.toml"
    path.write_text(to_toml(g1_profile()) + ("# padding\n" * 120_000))
    return path


FILE_CASES = [
    ("empty", _raw(b""), ("empty",)),
    ("blank", _raw(b" \n\t\n"), ("empty",)),
    ("directory", _directory, ("is a directory",)),
    ("fifo", _fifo, ("not a regular file",)),
    ("dangling-symlink", _dangling_link, ("does not exist",)),
    ("missing", lambda folder: folder / "myg1.toml", ("does not exist",)),
    ("below-a-file", lambda folder: _raw(b"x")(folder) / "myg1.toml", ("does not exist",)),
    ("too-big", _too_big, ("larger than 1024 kB",)),
    ("latin-1", lambda folder: _raw((to_toml(g1_profile()) + "# caf\xe9\n").encode("latin-1"))(folder), ("not utf-8",)),
    ("latin-1-bytes", _raw(b'name = "caf\xe9"\n'), ("not utf-8", "0xe9")),
    ("utf-16", lambda folder: _raw(to_toml(g1_profile()).encode("utf-16"))(folder), ("utf-16", "save it as utf-8")),
    ("json-array", _raw(b"[1, 2, 3]", "myg1.json"), ("the top level", "a list of 3")),
    ("json-string", _raw(b'"myg1"', "myg1.json"), ("the top level", "'myg1'")),
    ("json-syntax", _raw(b'{"name": "myg1",}', "myg1.json"), ("not valid json", "line 1")),
    ("json-duplicate-key", _raw(b'{"name": "myg1", "name": "other"}', "myg1.json"), ("'name'", "twice")),
    ("json-deep-nesting", _raw(b"[" * 100_000 + b"]" * 100_000, "myg1.json"), ("nests too deeply",)),
    ("json-5000-digits", _raw(b'{"squat_depth_max": ' + b"7" * 5000 + b"}", "myg1.json"), ("too many digits",)),
    ("json-named-toml", lambda folder: _raw(json.dumps(g1_profile()).encode())(folder), ("not valid toml", "looks like json")),
    ("toml-syntax", _g1_text(lambda t: t.replace('"squat_depth_max" = 0.25', '"squat_depth_max" = = 0.25')), ("not valid toml", "line")),
    ("toml-duplicate-key", _g1_text(lambda t: t + '\n'.join(["", "[sole]", "x_min = 0.0"])), ("not valid toml", "twice")),
    ("toml-duplicate-scalar", _g1_text(lambda t: '"name" = "other"\n' + t), ("not valid toml", "twice")),
    ("toml-nul-byte", _raw(b'name = "my\x00g1"\n'), ("not valid toml",)),
    ("toml-date", _g1_text(lambda t: t.replace('"squat_depth_max" = 0.25', '"squat_depth_max" = 2024-01-01')), ("squat_depth_max", "a date")),
]


@pytest.mark.parametrize(("make", "words"), [c[1:] for c in FILE_CASES], ids=[c[0] for c in FILE_CASES])
def test_a_broken_profile_file_is_a_one_line_profile_error(tmp_path, make, words):
    """Empty, binary, UTF-16, not a file, too big, bad syntax, duplicate keys: named, never a traceback."""
    path = make(tmp_path)
    tree = Tree(tmp_path)
    refused(path, *words, kind=ProfileError)
    tree.assert_unchanged()


@pytest.mark.skipif(hasattr(os, "geteuid") and os.geteuid() == 0, reason="root reads any file")
def test_an_unreadable_profile_is_a_profile_error(tmp_path):
    path = write_profile(tmp_path, g1_profile())
    path.chmod(0)
    try:
        refused(path, "cannot read", "permission denied", kind=ProfileError)
    finally:
        path.chmod(0o600)


@pytest.mark.parametrize("name", ["asimo", "", "   ", "tal\x00os", "a" * 5000, "robot\nname", "~nosuchuser_wbmp/r.toml",
                                  "bad\x00name.toml", "b" * 5000 + ".toml"])
def test_a_bad_robot_name_is_a_robot_error(name):
    """Names that are neither a built-in robot nor a readable file: RobotNotFound or ProfileError, one line."""
    with pytest.raises(RobotError) as info:
        load_robot(name)
    msg = str(info.value)
    assert "\n" not in msg and len(msg) < 400, msg
    assert isinstance(info.value, (RobotNotFound, ProfileError))


# --- a URDF profile whose files are wrong ----------------------------------------------------------


def _talos_urdf_profile(folder: Path, talos, *, urdf_text: str | None = None, srdf_text: str | None = None,
                        fields: dict | None = None) -> Path:
    """Talos as a user would bring it: its URDF and SRDF copied beside a profile that names them.

    ``urdf_text``/``srdf_text`` replace the copied files' content; ``fields`` change the profile.
    """
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "robot.urdf").write_text(Path(talos.urdf_path).read_text() if urdf_text is None else urdf_text)
    (folder / "robot.srdf").write_text(_talos_srdf(talos).read_text() if srdf_text is None else srdf_text)
    data = tomllib.loads(TALOS_TOML.read_text())
    del data["loader"]
    data.update(name="mytalos", urdf="robot.urdf", srdf="robot.srdf", package_dirs=list(talos.package_dirs))
    data.update(fields or {})
    return write_profile(folder, data, name="mytalos")


def _talos_srdf(talos) -> Path:
    return Path(talos.urdf_path).parents[1] / "srdf" / "talos.srdf"


def _urdf_case(talos, case: dict) -> dict:
    """Keyword arguments of _talos_urdf_profile for a URDF_CASES entry."""
    fields = dict(case)
    kwargs = {"urdf_text": fields.pop("urdf_text", None), "srdf_text": fields.pop("srdf_text", None)}
    for kind, source in (("urdf", Path(talos.urdf_path)), ("srdf", _talos_srdf(talos))):
        edit = fields.pop(f"{kind}_edit", None)
        if edit is not None:
            original = source.read_text()
            kwargs[f"{kind}_text"] = edit(original)
            assert kwargs[f"{kind}_text"] != original, "the edit changed nothing"
    return {**kwargs, "fields": fields}


def _urdf_sub(pattern: str, repl: str):
    return lambda text: re.sub(pattern, repl, text, count=1)


ONE_LINK = '<robot name="r"><link name="a"/></robot>'
FIXED_ONLY = ('<robot name="r"><link name="a"><inertial><mass value="1"/><inertia ixx="1" iyy="1" izz="1" '
              'ixy="0" ixz="0" iyz="0"/></inertial></link><link name="b"/><joint name="j" type="fixed">'
              '<parent link="a"/><child link="b"/></joint></robot>')

# (id, keyword arguments of _talos_urdf_profile or a function of the URDF/SRDF text, words)
URDF_CASES = [
    ("urdf-missing", {"urdf": "nothere.urdf"}, ("urdf", "nothere.urdf", "does not exist")),
    ("urdf-directory", {"urdf": "."}, ("urdf", "is a directory")),
    ("urdf-number", {"urdf": 42}, ("urdf", "the path of the urdf file", "got 42")),
    ("urdf-empty-string", {"urdf": ""}, ("urdf", "the path of the urdf file")),
    ("urdf-is-the-profile", {"urdf": "mytalos.toml"}, ("urdf", "not well-formed xml")),
    ("urdf-is-the-srdf", {"urdf": "robot.srdf"}, ("urdf", "no <link>")),
    ("urdf-empty", {"urdf_text": ""}, ("urdf", "not a urdf file")),
    ("urdf-not-xml", {"urdf_text": "this is not a robot"}, ("urdf", "not well-formed xml")),
    ("urdf-html", {"urdf_text": "<html><body>404</body></html>"}, ("urdf", "<html>", "expected <robot>")),
    ("urdf-truncated", {"urdf_edit": lambda t: t[: len(t) // 2]}, ("urdf", "not well-formed xml")),
    ("urdf-robot-without-name", {"urdf_edit": _urdf_sub(r'<robot\s+name="[^"]*"', "<robot")}, ("urdf", "no name")),
    ("urdf-without-joints", {"urdf_text": ONE_LINK}, ("urdf", "no <joint>")),
    ("urdf-only-fixed-joints", {"urdf_text": FIXED_ONLY}, ("urdf", "no movable joint")),
    ("urdf-negative-mass", {"urdf_edit": _urdf_sub(r'<mass\s+value="[^"]*"', '<mass value="-3"')}, ("urdf", "link", "has mass '-3'", ">= 0")),
    ("urdf-nan-mass", {"urdf_edit": _urdf_sub(r'<mass\s+value="[^"]*"', '<mass value="nan"')}, ("urdf", "link", "has mass 'nan'")),
    ("urdf-word-mass", {"urdf_edit": _urdf_sub(r'<mass\s+value="[^"]*"', '<mass value="heavy"')}, ("urdf", "link", "has mass 'heavy'")),
    ("urdf-lower-above-upper", {"urdf_edit": _urdf_sub(r'lower="[^"]*"', 'lower="5"')}, ("urdf", "lower limit 5 above")),
    ("urdf-negative-effort", {"urdf_edit": _urdf_sub(r'effort="[^"]*"', 'effort="-1"')}, ("urdf", "pinocchio cannot load", "effort")),
    ("urdf-nan-origin", {"urdf_edit": _urdf_sub(r'<origin xyz="[^"]*"', '<origin xyz="nan 0 0"')}, ("urdf", "pinocchio cannot load")),
    ("urdf-child-link-missing", {"urdf_edit": _urdf_sub(r'<child link="[^"]*"', '<child link="nowhere"')}, ("urdf", "'nowhere'", "not a <link>")),
    ("urdf-joint-type-unknown", {"urdf_edit": _urdf_sub(r'type="revolute"', 'type="hinge"')}, ("urdf", "'hinge'")),
    ("urdf-link-twice", {"urdf_edit": lambda t: t.replace("</robot>", '<link name="base_link"/></robot>')}, ("urdf", "'base_link'", "defined twice")),
    ("urdf-two-trees", {"urdf_edit": lambda t: t.replace("</robot>", '<link name="lost_link"/></robot>')}, ("urdf", "one tree")),
    ("urdf-meshes-not-found", {"package_dirs": ["."]}, ("urdf", "meshes", "could not be found", "package_dirs")),
    ("package-dirs-missing-folder", {"package_dirs": ["no_such_folder"]}, ("package_dirs[0]", "not a folder")),
    ("package-dirs-string", {"package_dirs": "meshes"}, ("package_dirs", "a list of folders")),
    ("srdf-missing", {"srdf": "nothere.srdf"}, ("srdf", "nothere.srdf", "does not exist")),
    ("srdf-directory", {"srdf": "."}, ("srdf", "is a directory")),
    ("srdf-not-xml", {"srdf_text": "half_sitting: 0 0 0"}, ("srdf", "not an srdf file")),
    ("srdf-bad-joint-value", {"srdf_edit": _urdf_sub(r'(<joint name="leg_left_1_joint" value=)"[^"]*"', r'\1"abc"')}, ("srdf", "could not read joint config")),
    ("srdf-posture-not-there", {"reference_posture": "standing"}, ("reference_posture", "'half_sitting'", "'standing'")),
]


@pytest.mark.parametrize(("case", "words"), [c[1:] for c in URDF_CASES], ids=[c[0] for c in URDF_CASES])
def test_a_broken_urdf_or_srdf_is_a_one_line_profile_error(tmp_path, talos, case, words):
    """A URDF that is missing, a folder, not XML, not a URDF, joint-less, massless, inconsistent ...:
    a ProfileError naming the profile, the field and the reason (Pinocchio's reason included)."""
    path = _talos_urdf_profile(tmp_path, talos, **_urdf_case(talos, case))
    tree = Tree(tmp_path)
    refused(path, *words)
    tree.assert_unchanged()


def test_pinocchio_reasons_do_not_leak_onto_stderr(tmp_path, talos):
    """urdfdom prints its reasons on file descriptor 2; the user sees one error line with the reason."""
    urdf = re.sub(r'rpy="[^"]*"', 'rpy="a b c"', Path(talos.urdf_path).read_text(), count=1)
    path = _talos_urdf_profile(tmp_path, talos, urdf_text=urdf)
    out = run_cli_process(["robots", path])
    assert_refused(out, 3, "mytalos.toml", "urdf", "pinocchio cannot load", "component [a]")
    assert out.err.strip().count("\n") == 0, f"more than one line on stderr: {out.err!r}"


# --- through the CLI ---------------------------------------------------------------------------------


CLI_CASES = ["squat-depth-word", "squat-depth-nan", "frames-list", "extra-frame-without-name", "posture-overrides-string",
             "unknown-key-typo", "frames-feet-swapped", "frames-not-in-urdf", "sole-inside-out", "loader-unknown"]


@pytest.mark.parametrize("case", CLI_CASES)
def test_wbmp_robots_refuses_a_bad_profile_with_exit_3(tmp_path, capsys, case):
    """`wbmp robots PROFILE`: exit 3, one error line naming the file and the field."""
    _id, mutate, words, fmt = next(c for c in FIELD_CASES if c[0] == case)
    data = g1_profile()
    mutate(data)
    path = write_profile(tmp_path, data, fmt=fmt)
    tree = Tree(tmp_path)
    assert_refused(run_cli(["robots", path], capsys), 3, path.name, *words)
    tree.assert_unchanged()


@pytest.mark.parametrize("case", ["squat-depth-word", "frames-hands-swapped", "posture-override-unknown-joint"])
def test_wbmp_solve_refuses_a_bad_profile_before_planning(tmp_path, capsys, case):
    """`wbmp solve "squat" --robot PROFILE --no-sim --out M`: exit 3 before planning, no motion file."""
    _id, mutate, words, fmt = next(c for c in FIELD_CASES if c[0] == case)
    data = g1_profile()
    mutate(data)
    path = write_profile(tmp_path, data, fmt=fmt)
    tree = Tree(tmp_path)
    out = run_cli(["solve", "squat", "--robot", path, "--no-sim", "--quiet", "--out", tmp_path / "m.npz"], capsys)
    assert_refused(out, 3, path.name, *words)
    tree.assert_unchanged()


@pytest.mark.parametrize("case", ["empty", "json-array", "latin-1-bytes", "directory", "toml-duplicate-key"])
def test_wbmp_robots_refuses_a_broken_profile_file(tmp_path, capsys, case):
    _id, make, words = next(c for c in FILE_CASES if c[0] == case)
    path = make(tmp_path)
    tree = Tree(tmp_path)
    assert_refused(run_cli(["robots", path], capsys), 3, path.name, *words)
    tree.assert_unchanged()


@pytest.mark.parametrize("case", ["urdf-without-joints", "urdf-html", "urdf-negative-mass"])
def test_wbmp_robots_refuses_a_broken_urdf(tmp_path, capsys, talos, case):
    _id, kwargs, words = next(c for c in URDF_CASES if c[0] == case)
    path = _talos_urdf_profile(tmp_path, talos, **_urdf_case(talos, kwargs))
    assert_refused(run_cli(["robots", path], capsys), 3, path.name, *words)


# --- random values in every field ------------------------------------------------------------------

FIELDS = [
    "name", "description", "loader", "urdf", "srdf", "package_dirs", "frames", "extra_frames", "sole",
    "reference_posture", "posture_overrides", "friction_coefficient", "step_length_max", "step_width",
    "step_duration", "double_support_duration", "squat_depth_max", "frames.left_foot", "frames.head",
    "frames.base", "sole.x_min", "sole.y_max", "extra_frames.0", "extra_frames.0.name",
    "extra_frames.0.parent", "extra_frames.1.translation", "posture_overrides.left_knee_joint",
    "posture_overrides.waist_yaw_joint", "typo_key",
]
SCALARS = st.one_of(
    st.none(), st.booleans(), st.integers(), st.integers(min_value=-(10**80), max_value=10**80),
    st.floats(allow_nan=True, allow_infinity=True), st.floats(min_value=-1.5, max_value=1.5),
    st.text(max_size=12),
    st.sampled_from(["", "q0", "pelvis", "left_sole", "right_sole", "g1", "talos", "\n", "left_knee_joint",
                     "../g1.toml", "/dev/null", ".", "half_sitting", "x" * 300]),
)
VALUES = st.recursive(SCALARS, lambda inner: st.one_of(st.lists(inner, max_size=4),
                                                       st.dictionaries(st.text(max_size=10), inner, max_size=4)),
                      max_leaves=10)


# Values each field could well hold: with these, a fair share of the random profiles load.
_G1_FRAMES = st.sampled_from(["pelvis", "left_sole", "right_sole", "left_rubber_hand", "right_rubber_hand",
                              "head_link", "torso_link", "left_ankle_roll_link", "waist_yaw_link"])
_LENGTH = st.floats(min_value=-0.3, max_value=1.2)
PLAUSIBLE = {
    "name": st.from_regex(r"[a-z][a-z0-9_.-]{0,12}", fullmatch=True),
    "description": st.text(max_size=40),
    "loader": st.sampled_from(["g1", "talos", "icub", "go2", "solo12"]),
    "reference_posture": st.sampled_from(["q0", "standing", "half_sitting"]),
    "frames": st.fixed_dictionaries({"left_foot": st.just("left_sole"), "right_foot": st.just("right_sole"),
                                     "left_hand": _G1_FRAMES, "right_hand": _G1_FRAMES, "base": _G1_FRAMES}),
    "sole": st.fixed_dictionaries({k: st.floats(min_value=-0.15, max_value=0.15) for k in
                                   ("x_min", "x_max", "y_min", "y_max")}),
    "extra_frames.1.translation": st.lists(st.floats(min_value=-0.1, max_value=0.1), min_size=3, max_size=3),
    "extra_frames.0.parent": _G1_FRAMES,
    "extra_frames.0.name": st.from_regex(r"[a-z_]{1,12}", fullmatch=True),
    "posture_overrides": st.dictionaries(st.sampled_from(["left_knee_joint", "right_elbow_joint", "waist_yaw_joint",
                                                          "left_knee"]), st.floats(-1.0, 1.0), max_size=3),
    "posture_overrides.left_knee_joint": st.floats(min_value=-0.5, max_value=3.0),
    "posture_overrides.waist_yaw_joint": st.floats(min_value=-3.0, max_value=3.0),
    "frames.left_foot": _G1_FRAMES, "frames.head": _G1_FRAMES, "frames.base": _G1_FRAMES,
    "sole.x_min": st.floats(min_value=-0.2, max_value=0.2), "sole.y_max": st.floats(min_value=-0.2, max_value=0.2),
}


@pytest.fixture(scope="module")
def scratch(tmp_path_factory):
    return tmp_path_factory.mktemp("random-profiles")


@settings(suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(field=st.sampled_from(FIELDS), data=st.data())
def test_a_random_value_in_any_field_loads_or_is_a_robot_error(scratch, field, data):
    """Any value in any field: the robot loads, or a one-line RobotError names the file; nothing else."""
    value = data.draw(st.one_of(VALUES, PLAUSIBLE.get(field, _LENGTH)), label=field)
    profile = copy.deepcopy(g1_profile())
    _set(field, value)(profile)
    path = scratch / "myg1.json"
    path.write_text(json.dumps(profile))  # JSON holds every value: null, NaN, nested lists
    try:
        robot = load_robot(path)
    except RobotError as e:
        event(f"refused: {type(e).__name__}")
        msg = str(e)
        assert "\n" not in msg and "myg1.json" in msg, msg
        assert len(msg) < 1200, msg
    else:
        event("loaded")
        assert robot.q_standing.shape == (robot.nq,)
        assert math.isfinite(float(robot.q_standing.sum()))


@settings(suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(content=st.one_of(st.binary(max_size=200), st.text(max_size=200).map(str.encode)),
       suffix=st.sampled_from([".toml", ".json", ".txt"]))
def test_random_bytes_are_a_profile_error(scratch, content, suffix):
    """Arbitrary file content never escapes as anything but a one-line ProfileError."""
    path = scratch / f"junk{suffix}"
    path.write_bytes(content)
    with pytest.raises(ProfileError) as info:
        load_robot(path)
    assert "\n" not in str(info.value) and f"junk{suffix}" in str(info.value)


def test_copying_a_builtin_profile_keeps_working_when_renamed(tmp_path):
    """The documented way to tweak a built-in robot: copy its file, rename it, change a number."""
    data = g1_profile()
    data["squat_depth_max"] = 0.2
    robot = load_robot(write_profile(tmp_path, data))
    assert robot.profile.squat_depth_max == 0.2
    shutil.copy(G1_TOML, tmp_path / "g1copy.toml")
    refused(tmp_path / "g1copy.toml", "name", "'g1' is a built-in robot")


def test_a_utf8_byte_order_mark_is_accepted(tmp_path):
    """Windows editors may start UTF-8 files with a byte-order mark: harmless, so it loads."""
    path = tmp_path / "myg1.toml"
    path.write_bytes(b"\xef\xbb\xbf" + to_toml(g1_profile()).encode())
    assert load_robot(path).name == "myg1"
