"""Damaged motion files: `show` and `export` refuse them with one line naming the file and the key.

Each damaged file is made from M (a valid planned motion): truncated, emptied, renamed from
another format, a key dropped or changed (dtype, shape, NaN, bad JSON, a pickle...). Both
commands exit 2 with one error line, no traceback, and write nothing; an unknown robot name in
the file is exit 3 (as an unknown robot is for ``solve``), and so only for ``show``, which needs
the robot (``export`` converts the file without it).
"""

from __future__ import annotations

import io
import json
import os
import shutil
import struct
import tempfile
import zipfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given
from hypothesis import settings as hsettings
from hypothesis import strategies as st

from tests.badinput.conftest import Tree, assert_refused, run_cli


def _arrays(motion_file: Path) -> dict[str, np.ndarray]:
    with np.load(motion_file) as data:
        return {k: data[k] for k in data.files}


def _save(path: Path, arrays: dict) -> None:
    with open(path, "wb") as fh:
        np.savez(fh, **arrays)


def _edit(change: Callable[[dict], None]) -> Callable[[Path, Path], None]:
    """A maker that writes M's arrays after ``change(arrays)``."""
    def make(motion_file: Path, out: Path) -> None:
        arrays = _arrays(motion_file)
        change(arrays)
        _save(out, arrays)
    return make


def _drop(key: str) -> Callable[[Path, Path], None]:
    return _edit(lambda a: a.pop(key))


def _set(key: str, value_of: Callable[[dict], object]) -> Callable[[Path, Path], None]:
    def change(a: dict) -> None:
        a[key] = value_of(a)
    return _edit(change)


def _with_nan(key: str, index: tuple[int, ...], value: float = np.nan) -> Callable[[Path, Path], None]:
    def change(a: dict) -> None:
        arr = np.array(a[key], dtype=float)
        arr[index] = value
        a[key] = arr
    return _edit(change)


def _truncated(n: int | float) -> Callable[[Path, Path], None]:
    def make(motion_file: Path, out: Path) -> None:
        data = motion_file.read_bytes()
        out.write_bytes(data[: int(n * len(data)) if isinstance(n, float) else n])
    return make


def _bytes(data: bytes) -> Callable[[Path, Path], None]:
    return lambda motion_file, out: out.write_bytes(data)


def _npy(motion_file: Path, out: Path) -> None:
    with open(out, "wb") as fh:
        np.save(fh, _arrays(motion_file)["q"])


def _directory(motion_file: Path, out: Path) -> None:
    out.mkdir()


def _fifo(motion_file: Path, out: Path) -> None:
    os.mkfifo(out)  # reading it would block forever


def _pickle(motion_file: Path, out: Path) -> None:
    arrays = _arrays(motion_file)
    arrays["report_json"] = np.array([{"solver": {}}], dtype=object)
    _save(out, arrays)  # np.savez pickles object arrays


def _flipped_middle(motion_file: Path, out: Path) -> None:
    data = bytearray(motion_file.read_bytes())
    for i in range(len(data) // 2, len(data) // 2 + 64):
        data[i] ^= 0xFF
    out.write_bytes(bytes(data))


def _bad_compression_method(motion_file: Path, out: Path) -> None:
    data = bytearray(motion_file.read_bytes())
    # every central-directory record gets compression method 99 (unknown)
    pos = 0
    while (pos := data.find(b"PK\x01\x02", pos)) >= 0:
        data[pos + 10:pos + 12] = struct.pack("<H", 99)
        pos += 4
    out.write_bytes(bytes(data))


def _huge_declared_shape(motion_file: Path, out: Path) -> None:
    """A member whose .npy header declares 8 TB of data (would allocate before reading)."""
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": "<f8", "fortran_order": False,
                                              "shape": (10**12,)})
    buf.write(b"\0" * 64)
    with zipfile.ZipFile(out, "w") as zf:
        arrays = _arrays(motion_file)
        for key, arr in arrays.items():
            if key == "q":
                zf.writestr("q.npy", buf.getvalue())
            else:
                member = io.BytesIO()
                np.save(member, arr)
                zf.writestr(f"{key}.npy", member.getvalue())


def _header_text(text: bytes) -> Callable[[Path, Path], None]:
    """M with the .npy header of ``q`` replaced by ``text`` (numpy parses it with Python's tokenizer)."""
    def make(motion_file: Path, out: Path) -> None:
        header = text.ljust(118) + b"\n"
        with zipfile.ZipFile(out, "w") as zf:
            for key, arr in _arrays(motion_file).items():
                member = io.BytesIO()
                np.save(member, arr)
                if key == "q":
                    raw = member.getvalue()
                    member = io.BytesIO(raw[:8] + struct.pack("<H", len(header)) + header + raw[10 + len(header):])
                zf.writestr(f"{key}.npy", member.getvalue())
    return make


def _no_arrays(motion_file: Path, out: Path) -> None:
    with zipfile.ZipFile(out, "w") as zf:
        zf.writestr("readme.txt", "not an array")


def _duplicate_key(motion_file: Path, out: Path) -> None:
    shutil.copy(motion_file, out)
    with zipfile.ZipFile(out, "a") as zf, pytest.warns(UserWarning):
        member = io.BytesIO()
        np.save(member, np.zeros(3))
        zf.writestr("t.npy", member.getvalue())


def _report(change: Callable[[dict], object]) -> Callable[[Path, Path], None]:
    def edit(a: dict) -> None:
        report = json.loads(str(a["report_json"]))
        result = change(report)
        a["report_json"] = np.array(json.dumps(report if result is None else result))
    return _edit(edit)


# name -> (maker(M, out), words of the error line)
CASES: dict[str, tuple[Callable[[Path, Path], None], tuple[str, ...]]] = {
    "empty_file": (_bytes(b""), ("is empty",)),
    "truncated_20000": (_truncated(20000), ("damaged",)),
    "truncated_100": (_truncated(100), ("damaged",)),
    "truncated_4": (_truncated(4), ("damaged",)),
    "truncated_half": (_truncated(0.5), ("damaged",)),
    "truncated_last_byte": (_truncated(-1), ("damaged",)),
    "flipped_bytes": (_flipped_middle, ("damaged",)),
    "unknown_compression": (_bad_compression_method, ("damaged",)),
    "renamed_npy": (_npy, (".npy", "not a motion file")),
    "text_file": (_bytes(b"t,q,v\n0,1,2\n"), ("not an .npz",)),
    "json_file": (_bytes(b'{"t": [0, 1]}'), ("not an .npz",)),
    "python_pickle": (_bytes(b"\x80\x04\x95\x05\x00\x00\x00\x00\x00\x00\x00K\x01."), ("not an .npz",)),
    "pk_garbage": (_bytes(b"PK\x03\x04" + b"\0" * 40), ("damaged",)),
    "directory": (_directory, ("is a directory",)),
    "fifo": (_fifo, ("not a regular file",)),
    "no_arrays": (_no_arrays, ("holds no arrays",)),
    "header_unterminated_string": (_header_text(b"{'descr': '<f8, 'fortran_order': False}"), ("'q'", "not a numpy array")),
    "header_unclosed_bracket": (_header_text(b"{'descr': '<f8', 'shape': ((("), ("'q'", "not a numpy array")),
    "header_not_a_dict": (_header_text(b"[1, 2, 3]"), ("'q'", "not a numpy array")),
    "duplicate_key": (_duplicate_key, ("'t'", "twice")),
    "object_array_pickle": (_pickle, ("report_json", "pickle")),
    "huge_declared_shape": (_huge_declared_shape, ("'q'", "declares shape")),
    **{f"missing_{k}": (_drop(k), ("missing key", repr(k)))
       for k in ("t", "q", "v", "com", "robot", "spec_json", "report_json")},
    "nan_in_q": (_with_nan("q", (3, 9)), ("'q'", "non-finite", "(3, 9)")),
    "inf_in_q": (_with_nan("q", (0, 0), np.inf), ("'q'", "non-finite")),
    "nan_in_t": (_with_nan("t", (2,)), ("'t'", "non-finite")),
    "nan_in_com": (_with_nan("com", (1, 2)), ("'com'", "non-finite")),
    "nan_in_v": (_with_nan("v", (1, 1)), ("'v'", "non-finite")),
    "nan_in_a": (_with_nan("a", (1, 1)), ("'a'", "non-finite")),
    "q_1d": (_set("q", lambda a: a["q"][:, 0]), ("'q'", "shape")),
    "q_short": (_set("q", lambda a: a["q"][:-1]), ("'q'", "shape")),
    "q_strings": (_set("q", lambda a: a["q"].astype(str)), ("'q'", "real numbers")),
    "q_complex": (_set("q", lambda a: a["q"].astype(complex)), ("'q'", "real numbers")),
    "q_bool": (_set("q", lambda a: a["q"] > 0), ("'q'", "real numbers")),
    "q_too_narrow": (_set("q", lambda a: a["q"][:, :5]), ("at least 7",)),
    "v_rows": (_set("v", lambda a: a["v"][:-2]), ("'v'", "shape")),
    "a_columns": (_set("a", lambda a: a["a"][:, :-1]), ("'a'", "shape")),
    "com_2d": (_set("com", lambda a: a["com"][:, :2]), ("'com'", "shape")),
    "t_decreasing": (_set("t", lambda a: a["t"][::-1].copy()), ("'t'", "must increase")),
    "t_one_sample": (_edit(lambda a: a.update(t=a["t"][:1], q=a["q"][:1], v=a["v"][:1], a=a["a"][:1],
                                              com=a["com"][:1])), ("'t'", "at least 2")),
    "t_2d": (_set("t", lambda a: a["t"][:, None]), ("'t'", "shape")),
    "force_bad_shape": (_set("force_left_sole_link", lambda a: np.zeros((len(a["t"]), 2))),
                        ("force_left_sole_link", "shape")),
    "exec_without_q": (_set("exec_t", lambda a: np.linspace(0, 1, 5)), ("exec_q",)),
    "exec_q_columns": (_edit(lambda a: a.update(exec_t=np.linspace(0, 1, 5), exec_q=np.zeros((5, 3)),
                                                exec_v=np.zeros((5, a["v"].shape[1])))), ("'exec_q'", "shape")),
    "exec_tau_columns": (_edit(lambda a: a.update(exec_t=np.linspace(0, 1, 5), exec_q=a["q"][:5],
                                                  exec_v=a["v"][:5], exec_tau=np.zeros((5, 2)))),
                         ("'exec_tau'", "shape")),
    "robot_number": (_set("robot", lambda a: np.array(7)), ("'robot'", "one string")),
    "robot_empty": (_set("robot", lambda a: np.array("")), ("'robot'", "robot name")),
    "robot_escape_codes": (_set("robot", lambda a: np.array("\x1b[31mtalos")), ("'robot'", "robot name")),
    "joint_names_numbers": (_set("joint_names", lambda a: np.arange(3.0)), ("'joint_names'", "strings")),
    "version_future": (_set("version", lambda a: np.array(99)), ("'version'", "99")),
    "version_text": (_set("version", lambda a: np.array("1")), ("'version'", "integer")),
    "spec_bad_json": (_set("spec_json", lambda a: np.array("{not json")), ("'spec_json'",)),
    "spec_empty_object": (_set("spec_json", lambda a: np.array("{}")), ("'spec_json'", "task spec")),
    "spec_array": (_set("spec_json", lambda a: np.array("[1, 2]")), ("'spec_json'", "task spec")),
    "spec_deeply_nested": (_set("spec_json", lambda a: np.array("[" * 100000 + "]" * 100000)), ("'spec_json'",)),
    "spec_as_bytes": (_set("spec_json", lambda a: np.array(b"{}")), ("'spec_json'", "one string")),
    "report_bad_json": (_set("report_json", lambda a: np.array("{")), ("'report_json'", "not valid json")),
    "report_list": (_report(lambda r: [r]), ("'report_json'", "json object")),
    "report_deeply_nested": (_set("report_json", lambda a: np.array("[" * 100000 + "]" * 100000)),
                             ("'report_json'",)),
    "report_huge_integer": (_set("report_json", lambda a: np.array('{"x": ' + "9" * 5000 + "}")),
                            ("'report_json'",)),
    "report_status_unknown": (_report(lambda r: r["solver"].update(status="GREAT")), ("solver.status", "GREAT")),
    "report_status_number": (_report(lambda r: r["solver"].update(status=3)), ("solver.status",)),
    "report_iterations_text": (_report(lambda r: r["solver"].update(iterations="many")), ("solver.iterations",)),
    "report_iterations_fraction": (_report(lambda r: r["solver"].update(iterations=2.5)),
                                   ("solver.iterations", "integer")),
    "report_solver_list": (_report(lambda r: r.update(solver=[])), ("'report_json'", "solver")),
    "report_checks_object": (_report(lambda r: r.update(checks={})), ("checks", "a list")),
    "report_check_missing_name": (_report(lambda r: r["checks"][0].pop("name") and None),
                                  ("checks[0].name", "missing")),
    "report_check_violation_text": (_report(lambda r: r["checks"][0].update(violation="big")),
                                    ("checks[0].violation",)),
    "report_diagnosis_number": (_report(lambda r: r.update(diagnosis=5)), ("diagnosis",)),
    "actions_number": (_set("actions_json", lambda a: np.array("5")), ("'actions_json'",)),
    "actions_list_of_numbers": (_set("actions_json", lambda a: np.array("[1, 2]")), ("'actions_json'",)),
}


@pytest.fixture(scope="module")
def damaged(tmp_path_factory, motion_file) -> dict[str, Path]:
    """Every damaged file of CASES, made once in a folder of its own."""
    folder = tmp_path_factory.mktemp("damaged")
    out = {}
    for name, (make, _) in CASES.items():
        path = folder / f"{name}.npz"
        make(motion_file, path)
        out[name] = path
    return out


@pytest.mark.parametrize("name", sorted(CASES))
@pytest.mark.parametrize("command", ["show", "export"])
def test_damaged_motion_file_is_refused(command, name, damaged, tmp_path, capsys):
    """Each damaged file: exit 2, one line naming the file and the problem, nothing written."""
    path = damaged[name]
    _, words = CASES[name]
    before = Tree(tmp_path)
    argv = (["show", path, "--html", tmp_path / "m.html", "--plots", tmp_path / "plots", "--quiet"]
            if command == "show" else ["export", path, "--out", tmp_path / "m.csv"])
    outcome = run_cli(argv, capsys)
    assert_refused(outcome, 2, path.name, *words)
    before.assert_unchanged()


def test_missing_motion_file(tmp_path, capsys):
    """A motion file that does not exist: exit 2 with the command that writes one."""
    before = Tree(tmp_path)
    for argv in (["show", tmp_path / "nope.npz", "--html", tmp_path / "m.html"],
                 ["export", tmp_path / "nope.npz", "--out", tmp_path / "m.json"]):
        assert_refused(run_cli(argv, capsys), 2, "nope.npz", "does not exist", "wbmp solve")
    before.assert_unchanged()


@pytest.mark.parametrize(("robot", "code", "words"), [
    ("robby", 3, ("'robot'", "robby")),
    ("/nonexistent/profile.toml", 3, ("'robot'", "profile.toml")),
])
def test_unknown_robot_in_the_file_is_exit_3_for_show(robot, code, words, tmp_path, motion_file, capsys):
    """show needs the robot: an unknown one is exit 3 (an invalid robot, as for solve), naming the file;
    export does not need it and converts the file."""
    path = tmp_path / "in" / "m.npz"
    path.parent.mkdir()
    _set("robot", lambda a: np.array(robot))(motion_file, path)
    out = tmp_path / "out"
    out.mkdir()
    before = Tree(out)
    outcome = run_cli(["show", path, "--html", out / "m.html"], capsys)
    assert_refused(outcome, code, "m.npz", *words)
    before.assert_unchanged()
    assert run_cli(["export", path, "--out", out / "m.json"], capsys).code == 0
    assert json.loads((out / "m.json").read_text())["robot"] == robot


@pytest.mark.parametrize(("change", "words"), [
    (lambda a: a.update(q=np.hstack([a["q"], a["q"][:, :1]]), v=a["v"], a=a["a"]), ("'q'", "40 columns", "nq = 39")),
    (lambda a: a.update(v=np.hstack([a["v"], a["v"][:, :1]]), a=np.hstack([a["a"], a["a"][:, :1]])),
     ("'v'", "nv = 38")),
    (lambda a: a.update(spec_json=np.array(str(a["spec_json"]).replace("left_sole_link", "left_hoof"))),
     ("spec_json",)),
])
def test_motion_of_another_shape_than_its_robot(change, words, tmp_path, motion_file, capsys):
    """q/v widths that do not match the file's robot, or a contact frame the robot lacks: show
    refuses with exit 2 or 3 before drawing anything."""
    path = tmp_path / "in.npz"
    _edit(change)(motion_file, path)
    out = tmp_path / "out"
    out.mkdir()
    before = Tree(out)
    outcome = run_cli(["show", path, "--html", out / "m.html", "--plots", out / "p"], capsys)
    assert outcome.code in (2, 3)
    assert_refused(outcome, outcome.code, *words)
    before.assert_unchanged()


def _run_on_bytes(data: bytes, capsys) -> None:
    """export and show of ``data`` as a motion file: refused (exit 2, one line, nothing written)
    or, when the damage missed everything that matters, a complete output."""
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        path = folder / "in" / "m.npz"
        path.parent.mkdir()
        path.write_bytes(data)
        out = folder / "out"
        out.mkdir()
        before = Tree(out)
        outcome = run_cli(["export", path, "--out", out / "m.json"], capsys)
        if outcome.code == 0:
            assert json.loads((out / "m.json").read_text())["robot"] == "talos"
        else:
            assert_refused(outcome, 2, "m.npz")
            before.assert_unchanged()


@hsettings(suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(cut=st.integers(min_value=0, max_value=10**9))
def test_any_truncation_is_refused(cut, motion_file, capsys):
    """M cut at any length (property): exit 2, one line, nothing written."""
    data = motion_file.read_bytes()
    cut %= len(data)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "m.npz"
        path.write_bytes(data[:cut])
        before = Tree(Path(tmp))
        outcome = run_cli(["export", path, "--out", Path(tmp) / "m.json"], capsys)
        assert_refused(outcome, 2, "m.npz")
        before.assert_unchanged()


@hsettings(suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(edits=st.lists(st.tuples(st.integers(min_value=0, max_value=10**9), st.integers(min_value=1, max_value=255)),
                      min_size=1, max_size=8))
def test_any_byte_corruption_is_refused_or_harmless(edits, motion_file, capsys):
    """M with a few bytes changed anywhere (property): either refused with exit 2 and one line, or
    (damage in a byte nothing reads) a complete export; never a traceback or a partial file."""
    data = bytearray(motion_file.read_bytes())
    for pos, xor in edits:
        data[pos % len(data)] ^= xor
    _run_on_bytes(bytes(data), capsys)
