"""Bad spec files (``wbmp solve --spec FILE``): refused on load, exit 3, one line naming the problem.

Every case is refused before a robot is loaded or a solver built, so each takes milliseconds.
A case writes one file into ``tmp_path``, runs the CLI with ``--out`` into the same folder, and
checks: no traceback, exit 3 (invalid spec), exactly one ``wbmp solve: error:`` line holding the
words that say what was wrong (the file name, the field path, the limit), and nothing created.

The random part (hypothesis) puts arbitrary JSON values (huge and non-finite numbers, strings,
lists, objects, nulls) at every path of the example squat spec and runs it with ``--robot`` of a
robot that does not exist: a spec that loads is then refused for the robot (exit 3 as well), so
no case ever plans, and no value gets a traceback.
"""

from __future__ import annotations

import codecs
import copy
import io
import json
import os
import sys
from collections.abc import Callable
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tasks.exceptions import TaskDefinitionError
from tasks.limits import MAX_SPEC_BYTES
from tasks.serialize import load_spec
from tests.badinput.conftest import REPO, Tree, assert_refused, run_cli, run_cli_process

SQ = REPO / "examples" / "specs" / "squat.json"
SQ_TEXT = SQ.read_text(encoding="utf-8")
SQ_DATA = json.loads(SQ_TEXT)
IS_ROOT = os.geteuid() == 0


def _edit(change: Callable[[dict], None]) -> bytes:
    """The example spec with one change, as UTF-8 JSON bytes."""
    data = copy.deepcopy(SQ_DATA)
    change(data)
    return json.dumps(data, indent=1, ensure_ascii=False).encode("utf-8")


def _set(path: str, value) -> Callable[[dict], None]:
    """A change that sets ``path`` (``phases.0.duration``) to ``value``."""

    def change(data: dict) -> None:
        *parents, last = [int(p) if p.isdigit() else p for p in path.split(".")]
        node = data
        for p in parents:
            node = node[p]
        node[last] = value

    return change


def _drop(path: str) -> Callable[[dict], None]:
    def change(data: dict) -> None:
        *parents, last = [int(p) if p.isdigit() else p for p in path.split(".")]
        node = data
        for p in parents:
            node = node[p]
        del node[last]

    return change


def _text_sub(old: str, new: str) -> bytes:
    assert old in SQ_TEXT
    return SQ_TEXT.replace(old, new, 1).encode("utf-8")


CONTACT = SQ_DATA["phases"][0]["contacts"][0]
TARGET = {"name": "touch", "frame": "left_hand", "position": [0.3, 0.3, 1.0], "time": 1.0}
JOINT_TARGET = {"name": "neck", "joint": "head_1_joint", "value": 0.1, "time": 1.0}

# (id, file content, words the error line must hold). The file is named spec.json.
CONTENT_CASES: list[tuple[str, bytes, tuple[str, ...]]] = [
    # Encodings and bytes.
    ("latin-1", _edit(_set("description", "squat café")).decode().encode("latin-1"),
     ("spec.json", "not UTF-8", "0xe9", "save it as UTF-8")),
    ("cp1252-quotes", SQ_TEXT.replace('"squat 10 cm', '"\u201csquat\u201d 10 cm').encode("cp1252"),
     ("not UTF-8", "save it as UTF-8")),
    ("utf-16-no-bom", SQ_TEXT.encode("utf-16-le"), ("UTF-16", "byte-order mark", "save it as UTF-8")),
    ("utf-16-bom-odd-length", codecs.BOM_UTF16_LE + SQ_TEXT.encode("utf-16-le") + b"\x00",
     ("UTF-16", "byte-order mark", "save it as UTF-8")),
    ("binary-garbage", bytes(range(256)) * 4, ("spec.json",)),
    ("png-header", b"\x89PNG\r\n\x1a\n" + b"\x00" * 64, ("not UTF-8",)),
    ("zip-renamed", b"PK\x03\x04\x14\x00\x00\x00\x08\x00" + b"\xff\xfe\xfd" * 20, ("not UTF-8",)),
    ("empty", b"", ("spec.json", "is empty")),
    ("only-blanks", b" \n\t\r\n  ", ("is empty",)),
    ("utf-8-bom-only", codecs.BOM_UTF8, ("invalid JSON",)),
    # JSON syntax.
    ("not-json", b"{not json", ("invalid JSON", "line 1")),
    ("trailing-comma", _text_sub('in 3 s"\n}', 'in 3 s",\n}'), ("invalid JSON",)),
    ("truncated", SQ_TEXT[: len(SQ_TEXT) // 2].encode(), ("invalid JSON",)),
    ("comment", b"// my squat\n" + SQ_TEXT.encode(), ("invalid JSON", "line 1")),
    ("yaml", b"robot: talos\nphases:\n  - name: stand\n    duration: 1\n", ("invalid JSON",)),
    ("nested-100000", b"[" * 100_000 + b"]" * 100_000, ("nested", "levels deep")),
    ("nested-2000-objects", b'{"a":' * 2000 + b"1" + b"}" * 2000, ("nested",)),
    ("nested-in-phases", b'{"phases": ' + b"[" * 30 + b"]" * 30 + b"}", ("nested", "at most 16")),
    ("nan", _text_sub('"duration": 3.0', '"duration": NaN'), ("NaN", "finite")),
    ("infinity", _text_sub('"dt": 0.075', '"dt": Infinity'), ("Infinity", "finite")),
    ("minus-infinity", _text_sub('"margin": 0.02', '"margin": -Infinity'), ("-Infinity",)),
    ("5000-digit-int", _text_sub('"duration": 3.0', '"duration": ' + "9" * 5000), ("5000 digits",)),
    ("5000-digit-negative", _text_sub('"swing_height": 0.05', '"swing_height": -' + "1" * 5000), ("5000 digits",)),
    ("1e400", _text_sub('"duration": 3.0', '"duration": 1e400'), ("too large",)),
    ("long-mantissa", _text_sub('"duration": 3.0', '"duration": 3.' + "1" * 200), ("out of range",)),
    ("top-level-array", b"[1, 2, 3]", ("top level", "a list")),
    ("top-level-string", b'"squat"', ("top level", "a string")),
    ("top-level-number", b"3.0", ("top level", "a number")),
    ("top-level-null", b"null", ("top level", "null")),
    ("top-level-true", b"true", ("top level", "a boolean")),
    ("lone-surrogate", _text_sub('"name": "squat"', '"name": "\\ud800"'), ("spec.phases[0].name", "invalid character")),
    # The format.
    ("version-2", _edit(_set("version", 2)), ("version 2", "expected 1")),
    ("version-string", _edit(_set("version", "1")), ("version '1'",)),
    ("version-true", _edit(_set("version", True)), ("version true",)),
    ("unknown-key", _edit(_set("phase", [])), ("unknown key", "phase")),
    ("unknown-key-huge", _edit(_set("k" * 10_000, 1)), ("unknown key",)),
    ("no-phases", _edit(_drop("phases")), ("missing key", "phases")),
    ("phases-empty", _edit(_set("phases", [])), ("at least one phase",)),
    ("phases-object", _edit(_set("phases", {"name": "a"})), ("spec.phases", "expected a list", "an object")),
    ("robot-number", _edit(_set("robot", 5)), ("spec.robot", "expected a string")),
    ("robot-long", _edit(_set("robot", "t" * 20_000)), ("robot", "at most")),
    ("name-list", _edit(_set("name", ["a"])), ("spec.name", "expected a string")),
    ("description-huge", _edit(_set("description", "squat " * 4000)), ("description", "characters")),
    ("dynamic-string", _edit(_set("dynamic", "yes")), ("spec.dynamic", "true or false")),
    ("dt-zero", _edit(_set("dt", 0)), ("dt", "[0.005, 0.5]")),
    ("dt-huge", _edit(_set("dt", 1e308)), ("dt", "[0.005, 0.5]")),
    ("dt-string", _edit(_set("dt", "fast")), ("spec.dt", "expected a number in seconds", "'fast'")),
    ("posture-weight-negative", _edit(_set("posture_weight", -1)), ("posture_weight",)),
    ("posture-weight-1e300", _edit(_set("posture_weight", 1e300)), ("posture_weight", "1e+06")),
    # Phases.
    ("duration-string", _edit(_set("phases.0.duration", "abc")),
     ("spec.phases[0].duration", "expected a number in seconds", "'abc'")),
    ("duration-bool", _edit(_set("phases.0.duration", True)), ("spec.phases[0].duration", "a boolean")),
    ("duration-null", _edit(_set("phases.0.duration", None)), ("spec.phases[0].duration",)),
    ("duration-zero", _edit(_set("phases.0.duration", 0)), ("spec.phases[0]", "duration must be > 0")),
    ("duration-negative", _edit(_set("phases.0.duration", -3.0)), ("duration must be > 0",)),
    ("duration-1e-9", _edit(_set("phases.0.duration", 1e-9)), ("spec: the motion lasts 1e-09 s", "at least 0.02 s")),
    ("duration-list", _edit(_set("phases.0.duration", [3.0])), ("spec.phases[0].duration", "a list")),
    ("phase-name-number", _edit(_set("phases.0.name", 1)), ("spec.phases[0].name", "expected a string")),
    ("phase-not-object", _edit(_set("phases.0", "squat")), ("spec.phases[0]", "expected an object")),
    ("swing-height-negative", _edit(_set("phases.0.swing_height", -0.1)), ("swing_height",)),
    ("swing-height-1e9", _edit(_set("phases.0.swing_height", 1e9)), ("swing_height", "[0, 100]")),
    ("contacts-object", _edit(_set("phases.0.contacts", CONTACT)), ("spec.phases[0].contacts", "expected a list")),
    ("same-frame-twice", _edit(_set("phases.0.contacts", [CONTACT, CONTACT])), ("two contacts",)),
    # Contacts.
    ("frame-empty", _edit(_set("phases.0.contacts.0.frame", "")), ("spec.phases[0].contacts[0]", "frame")),
    ("frame-number", _edit(_set("phases.0.contacts.0.frame", 7)),
     ("spec.phases[0].contacts[0].frame", "expected a string")),
    ("frame-long", _edit(_set("phases.0.contacts.0.frame", "f" * 500)), ("frame", "at most 200")),
    ("placement-missing", _edit(_drop("phases.0.contacts.0.placement")), ("missing key", "placement")),
    ("position-two-items", _edit(_set("phases.0.contacts.0.placement.position", [0.0, 0.085])),
     ("spec.phases[0].contacts[0].placement.position", "expected 3 items", "in metres")),
    ("position-string-item", _edit(_set("phases.0.contacts.0.placement.position", [0.0, "a", 0.0])),
     ("position[1]", "expected a number in metres")),
    ("position-1e308", _edit(_set("phases.0.contacts.0.placement.position", [1e308, 0.085, 0.0])),
     ("position", "[-100, 100]")),
    ("position-null-item", _edit(_set("phases.0.contacts.0.placement.position", [0.0, None, 0.0])),
     ("position[1]", "expected a number", "got null")),
    ("rpy-1e5", _edit(_set("phases.0.contacts.0.placement.rpy", [0.0, 0.0, 1e5])), ("rpy", "rad")),
    ("friction-negative", _edit(_set("phases.0.contacts.0.friction_coefficient", -1)), ("friction_coefficient",)),
    ("friction-1e9", _edit(_set("phases.0.contacts.0.friction_coefficient", 1e9)), ("friction_coefficient", "10")),
    ("friction-string", _edit(_set("phases.0.contacts.0.friction_coefficient", "high")),
     ("friction_coefficient", "expected a number")),
    # CoM targets and bounds.
    ("com-time-after-end", _edit(_set("com_targets.0.time", 10.0)), ("after the end",)),
    ("com-time-negative", _edit(_set("com_targets.0.time", -1.0)), ("time",)),
    ("com-priority", _edit(_set("com_targets.0.priority", "urgent")),
     ("spec.com_targets[0].priority", "'hard'", "'soft'")),
    ("com-position-all-null", _edit(_set("com_targets.0.position", [None, None, None])), ("at least one",)),
    ("com-tolerance-1e200", _edit(_set("com_targets.0.tolerance", 1e200)), ("tolerance", "[0, 100]")),
    ("com-weight-1e12", _edit(_set("com_targets.0.weight", 1e12)), ("weight", "1e+06")),
    ("com-window-reversed", _edit(_set("com_targets.0.window", [2.0, 1.0])), ("window",)),
    ("com-window-and-time", _edit(_set("com_targets.0.window", [0.0, 1.0])), ("not both",)),
    ("com-window-one-item", _edit(_set("com_targets.0.window", [1.0])), ("window", "expected 2 items")),
    ("com-window-string", _edit(_set("com_targets.0.window", "all")), ("window", "expected a list")),
    ("bounds-margin-negative", _edit(_set("com_bounds.0.margin", -0.01)), ("margin",)),
    ("bounds-lower-above-upper", _edit(lambda d: (_set("com_bounds.0.lower", [None, None, 1.0])(d),
                                                  _set("com_bounds.0.upper", [None, None, 0.5])(d))), ("exceeds",)),
    ("bounds-polygon-string", _edit(_set("com_bounds.0.support_polygon", "yes")),
     ("support_polygon", "true or false")),
    ("bounds-same-name", _edit(lambda d: d["com_bounds"].append(copy.deepcopy(d["com_bounds"][0]))),
     ("unique", "balance")),
    # Frame and joint targets.
    ("target-no-position-no-rpy", _edit(_set("targets", [{"name": "t", "frame": "left_hand"}])), ("position",)),
    ("target-axes-none", _edit(_set("targets", [{**TARGET, "axes": [False, False, False]}])), ("axes",)),
    ("target-axes-numbers", _edit(_set("targets", [{**TARGET, "axes": [1, 0, 0]}])),
     ("spec.targets[0].axes[0]", "true or false")),
    ("target-orientation-tolerance", _edit(_set("targets", [{**TARGET, "orientation_tolerance": -1}])),
     ("orientation_tolerance",)),
    ("joint-value-1e9", _edit(_set("joint_targets", [{**JOINT_TARGET, "value": 1e9}])), ("value", "rad")),
    ("joint-name-number", _edit(_set("joint_targets", [{**JOINT_TARGET, "joint": 7}])),
     ("spec.joint_targets[0].joint", "expected a string")),
    ("joint-name-empty", _edit(_set("joint_targets", [{**JOINT_TARGET, "joint": ""}])), ("joint",)),
]


def _refused(tmp_path: Path, capsys, spec: str, *words: str) -> None:
    tree = Tree(tmp_path)
    out = run_cli(["solve", "--spec", spec, "--no-sim", "--quiet", "--out", tmp_path / "m.npz"], capsys)
    assert_refused(out, 3, *words)
    tree.assert_unchanged()


@pytest.mark.parametrize(("content", "words"), [c[1:] for c in CONTENT_CASES], ids=[c[0] for c in CONTENT_CASES])
def test_bad_spec_file_is_refused(tmp_path, capsys, content, words):
    """Each damaged or invalid spec file: exit 3, one line naming the file's problem, nothing written."""
    spec = tmp_path / "spec.json"
    spec.write_bytes(content)
    _refused(tmp_path, capsys, str(spec), "spec.json", *words)


def _place_dir(tmp: Path) -> str:
    (tmp / "specs").mkdir()
    return str(tmp / "specs")


def _place_file_as_folder(tmp: Path) -> str:
    (tmp / "file").write_text("x")
    return str(tmp / "file" / "spec.json")


def _place_missing(tmp: Path) -> str:
    return str(tmp / "nope.json")


def _place_huge(tmp: Path) -> str:
    path = tmp / "huge.json"
    with open(path, "wb") as f:  # sparse: the size is refused before anything is read
        f.truncate(MAX_SPEC_BYTES + 1)
    return str(path)


def _place_dangling_link(tmp: Path) -> str:
    (tmp / "link.json").symlink_to(tmp / "gone.json")
    return str(tmp / "link.json")


def _place_socket(tmp: Path) -> str:
    import socket

    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    sock.bind(str(tmp / "sock.json"))
    sock.close()  # the socket file stays; opening it fails (ENXIO)
    return str(tmp / "sock.json")


PLACE_CASES = [
    ("directory", _place_dir, ("is a directory",)),
    ("dev-null", lambda tmp: "/dev/null", ("/dev/null", "is empty")),
    ("missing", _place_missing, ("nope.json", "does not exist")),
    ("under-a-file", _place_file_as_folder, ("does not exist",)),
    ("dangling-symlink", _place_dangling_link, ("link.json", "does not exist")),
    ("over-8-MiB", _place_huge, ("huge.json", "8 MiB")),
    ("dev-zero", lambda tmp: "/dev/zero", ("/dev/zero",)),
    ("unix-socket", _place_socket, ("sock.json", "cannot be read")),
]


@pytest.mark.parametrize(("place", "words"), [c[1:] for c in PLACE_CASES], ids=[c[0] for c in PLACE_CASES])
def test_bad_spec_path_is_refused(tmp_path, capsys, place, words):
    """A directory, a device, a missing path, an oversized file: exit 3 and what the path is."""
    spec = place(tmp_path)
    _refused(tmp_path, capsys, spec, *words)


@pytest.mark.skipif(IS_ROOT, reason="root reads a mode-000 file")
def test_unreadable_spec_file(tmp_path, capsys):
    spec = tmp_path / "spec.json"
    spec.write_text(SQ_TEXT)
    spec.chmod(0)
    try:
        _refused(tmp_path, capsys, str(spec), "permission denied")
    finally:
        spec.chmod(0o600)


# Encodings an editor may choose are read: UTF-8 with a BOM, UTF-16/32 with a BOM (Windows).
# The spec loads, then the unknown robot is refused (exit 3) without planning.
@pytest.mark.parametrize(
    "content",
    [
        codecs.BOM_UTF8 + SQ_TEXT.encode("utf-8"),
        codecs.BOM_UTF16_LE + SQ_TEXT.encode("utf-16-le"),
        codecs.BOM_UTF16_BE + SQ_TEXT.encode("utf-16-be"),
        SQ_TEXT.encode("utf-16"),  # Python writes the BOM of the machine's order
        codecs.BOM_UTF32_LE + SQ_TEXT.encode("utf-32-le"),
    ],
    ids=["utf-8-bom", "utf-16-le-bom", "utf-16-be-bom", "utf-16", "utf-32-le-bom"],
)
def test_spec_with_byte_order_mark_is_read(tmp_path, capsys, content):
    spec = tmp_path / "spec.json"
    spec.write_bytes(content)
    assert load_spec(spec) == load_spec(SQ)
    out = run_cli(["solve", "--spec", spec, "--robot", "no_such_robot", "--no-sim", "--quiet"], capsys)
    assert_refused(out, 3, "unknown robot", "no_such_robot")


def test_spec_from_standard_input_with_dash(monkeypatch, capsys):
    """``--spec -`` reads standard input (here an invalid spec, to stop before planning)."""
    bad = _edit(_set("phases.0.duration", "abc"))
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(bad), encoding="utf-8"))
    out = run_cli(["solve", "--spec", "-", "--no-sim", "--quiet"], capsys)
    assert_refused(out, 3, "standard input", "spec.phases[0].duration", "'abc'")


def test_spec_from_empty_standard_input(monkeypatch, capsys):
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(b""), encoding="utf-8"))
    out = run_cli(["solve", "--spec", "-", "--no-sim", "--quiet"], capsys)
    assert_refused(out, 3, "standard input", "is empty")


def test_spec_from_dev_stdin_is_read(tmp_path):
    """``--spec /dev/stdin`` is a pipe here, not "does not exist": its content is checked."""
    bad = _edit(_set("phases.0.duration", -1.0)).decode()
    out = run_cli_process(["solve", "--spec", "/dev/stdin", "--no-sim", "--quiet"], cwd=tmp_path,
                          input_text=bad, timeout=120)
    assert_refused(out, 3, "/dev/stdin", "duration must be > 0")
    assert list(tmp_path.iterdir()) == []


# ---------------------------------------------------------------------------------------------
# Random JSON values in every field of a valid spec.

def _paths(node, prefix=()):
    """Every path into the example spec (objects and lists included)."""
    yield prefix
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _paths(v, (*prefix, k))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from _paths(v, (*prefix, i))


PATHS = [p for p in _paths(SQ_DATA) if p]
json_values = st.recursive(
    st.none() | st.booleans() | st.integers(-10**60, 10**60) | st.floats(allow_nan=True, allow_infinity=True)
    | st.text(max_size=30),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=3),
    max_leaves=8,
)


@settings(suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(path=st.sampled_from(PATHS), value=json_values)
def test_random_value_in_any_field_never_gets_a_traceback(tmp_path, capsys, path, value):
    """Any JSON value anywhere: exit 3, one line; when the spec is invalid the line names its path."""
    data = copy.deepcopy(SQ_DATA)
    node = data
    for p in path[:-1]:
        node = node[p]
    node[path[-1]] = value
    spec = tmp_path / "random.json"
    spec.write_text(json.dumps(data), encoding="utf-8")  # NaN/Infinity written as JSON's non-standard literals
    try:
        load_spec(spec)
        loads = True
    except TaskDefinitionError as e:
        loads = False
        assert "\n" not in str(e)
        assert len(str(e)) < 600, str(e)
    out = run_cli(["solve", "--spec", spec, "--robot", "no_such_robot", "--no-sim", "--quiet"], capsys)
    assert_refused(out, 3, "random.json" if not loads else "no_such_robot")
    line = next(ln for ln in out.err.splitlines() if ": error:" in ln)
    assert len(line) < 700, line
