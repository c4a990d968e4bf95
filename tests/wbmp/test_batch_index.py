"""The batch index reader and the JSONL item reader: each record checked, damaged lines reported,
and a hypothesis fuzz pass over both (never an exception other than the one-line refusal)."""

from __future__ import annotations

import json
import math

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from wbmp.batch.index import read_index_lines, read_index_report, record_problem
from wbmp.batch.items import read_items
from wbmp.errors import CliError

SHA = "ab" * 32


def _record(**changes) -> dict:
    """A record as a worker writes it (an ok squat on talos), with ``changes``."""
    rec = {"id": "squat", "robot": "talos", "line": 1, "instruction": "squat", "status": "ok", "exit_code": 0,
           "certificate": None, "message": "", "timings": {"plan": 1.2, "total": 1.5}, "cached": False,
           "motion": "squat__talos.npz", "sha256": SHA, "input_sha256": "cd" * 32, "worker": "host:1",
           "skipped": False, "backend": "local", "finished": "2026-11-28T10:00:00+00:00"}
    rec.update(changes)
    return {k: v for k, v in rec.items() if v is not ...}


def test_records_as_workers_write_them_are_valid():
    """An ok record and a failed one (no motion file) pass."""
    assert record_problem(_record()) is None
    assert record_problem(_record(status="failed", exit_code=4, motion=None, sha256=None, message="no")) is None


@pytest.mark.parametrize(("changes", "words"), [
    ({"status": ...}, "'status'"),
    ({"status": "done"}, "'status'"),
    ({"message": ...}, "'message'"),
    ({"message": None}, "'message'"),
    ({"exit_code": ...}, "'exit_code'"),
    ({"exit_code": True}, "'exit_code'"),
    ({"exit_code": 4}, "'exit_code'"),  # ok with a failure's code
    ({"status": "failed", "exit_code": 0, "motion": None, "sha256": None}, "'exit_code'"),
    ({"line": ...}, "'line'"),
    ({"line": 0}, "'line'"),
    ({"timings": ...}, "'timings'"),
    ({"input_sha256": "x"}, "'input_sha256'"),
    ({"id": ""}, "'id'"),
    ({"id": "../../etc"}, "'id'"),
    ({"robot": 3}, "'robot'"),
    ({"motion": "../victim__talos.npz"}, "'motion'"),
    ({"motion": "/tmp/victim.npz"}, "'motion'"),
    ({"motion": "other__talos.npz"}, "'motion'"),
    ({"motion": None}, "'motion'"),  # ok without its file
    ({"sha256": None}, "'sha256'"),
    ({"status": "failed", "exit_code": 2, "motion": None}, "'sha256' without"),
])
def test_a_record_missing_or_bending_a_field_is_named(changes, words):
    """Each required field missing or of the wrong type or value; a motion file outside the
    folder or not the item's own."""
    problem = record_problem(_record(**changes))
    assert problem is not None and words in problem


def test_damaged_lines_are_reported_and_the_last_valid_record_wins(tmp_path):
    """Good, torn, NaN, missing-field and foreign lines: the records that hold, one note per
    damaged line with its number; a later valid record of a key replaces an earlier one."""
    lines = [json.dumps(_record()), '{"id": "squat", "robot": "tal', json.dumps(_record(line=1, id="w",
             motion="w__talos.npz")).replace('"line": 1', '"line": NaN'), json.dumps(_record(id="w", motion=...)),
             "[1, 2]", "", json.dumps(_record(message="second")),
             json.dumps(_record(id="x", motion="x__talos.npz")).replace('"plan": 1.2', '"plan": 1e999')]
    records, damaged = read_index_lines("\n".join(lines) + "\n")
    assert list(records) == [("squat", "talos")] and records[("squat", "talos")]["message"] == "second"
    assert [d.split(":")[0] for d in damaged] == ["line 2", "line 3", "line 4", "line 5", "line 8"]
    assert "NaN" in damaged[1] and "'motion'" in damaged[2] and "list" in damaged[3] and "1e999" in damaged[4]
    path = tmp_path / "index.jsonl"
    path.write_text("\n".join(lines))
    assert read_index_report(path) == (records, damaged)
    assert read_index_report(tmp_path / "missing.jsonl") == ({}, [])


def test_an_index_that_is_not_a_regular_file_is_refused_without_blocking(tmp_path):
    """A FIFO as index.jsonl: refused at once (no open that waits for a writer), exit 2."""
    import os

    fifo = tmp_path / "index.jsonl"
    os.mkfifo(fifo)
    with pytest.raises(CliError) as info:
        read_index_report(fifo)
    assert info.value.code == 2 and "not a regular file" in str(info.value)


# -- fuzz -------------------------------------------------------------------------------------

_json_values = st.recursive(
    st.none() | st.booleans() | st.integers(-10**6, 10**6) | st.floats(allow_nan=True, allow_infinity=True)
    | st.text(max_size=12),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=4),
    max_leaves=12)


@st.composite
def _bent_records(draw) -> dict:
    """A valid record with some fields dropped or replaced by arbitrary JSON values."""
    rec = _record()
    for key in draw(st.lists(st.sampled_from(sorted(rec)), max_size=4, unique=True)):
        if draw(st.booleans()):
            del rec[key]
        else:
            rec[key] = draw(_json_values)
    return rec


_index_lines = st.one_of(
    _bent_records().map(lambda r: json.dumps(r, allow_nan=True)),
    _json_values.map(lambda v: json.dumps(v, allow_nan=True)),
    st.text(max_size=60),
    _bent_records().map(lambda r: json.dumps(r)[: len(json.dumps(r)) // 2]),  # torn
)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(_index_lines, max_size=8))
def test_fuzz_the_index_reader_never_raises_and_keeps_only_valid_records(lines):
    """Any text: no exception; every record kept is valid (finite numbers only, its motion file
    the item's own name) and is the last valid one of its key; every other non-blank line is
    reported once."""
    text = "\n".join(lines)
    records, damaged = read_index_lines(text)
    for key, rec in records.items():
        assert record_problem(rec) is None and key == (rec["id"], rec["robot"])
        assert "/" not in (rec["motion"] or "")
        json.dumps(rec, allow_nan=False)  # nothing non-finite was kept
    numbers = [int(note.split(":")[0].removeprefix("line ")) for note in damaged]
    assert len(numbers) == len(set(numbers))
    expected = {}
    for n, line in enumerate(text.splitlines(), 1):
        if line.strip() and n not in numbers:  # not reported: it must be a valid record
            rec = json.loads(line)
            expected[(rec["id"], rec["robot"])] = rec
        elif not line.strip():
            assert n not in numbers
    assert records == expected


_jsonl_objects = st.dictionaries(
    st.sampled_from(["instruction", "spec", "robot", "scene", "id", "other"]),
    _json_values | st.sampled_from(["squat", "talos", "g1", "sq-1", "../x", "spec.json", "a__b"]),
    max_size=4) | st.fixed_dictionaries(  # well-formed lines, with anything inside the spec object
    {"spec": st.dictionaries(st.text(max_size=8), _json_values, max_size=4)},
    optional={"id": st.sampled_from(["a", "b-1", "../x", "a__b"]), "robot": st.sampled_from(["talos", "g1", ""])})


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                  HealthCheck.function_scoped_fixture])
@given(st.lists(_jsonl_objects.map(lambda d: json.dumps(d, allow_nan=True)) | st.text(max_size=40), min_size=1,
                max_size=5))
def test_fuzz_the_jsonl_reader_gives_items_or_one_refusal_line(tmp_path, lines):
    """Any JSONL text: the items, or one CliError line naming the file (exit 2 or 3); an item
    read never holds a non-finite number."""
    path = tmp_path / "items.jsonl"
    path.write_text("\n".join([json.dumps({"instruction": "squat"}), *lines]) + "\n", encoding="utf-8")
    try:
        items = read_items(str(path))
    except CliError as e:
        assert e.code in (2, 3) and "\n" not in str(e) and str(path) in str(e)
        return
    for item in items:
        if item.spec_object is not None:
            json.dumps(item.spec_object, allow_nan=False)
        assert item.instruction is None or isinstance(item.instruction, str)


@pytest.mark.parametrize("number", ["NaN", "-Infinity", "Infinity", "1e999", "-1e400"])
def test_non_finite_numbers_in_a_spec_object_are_refused_naming_the_line(tmp_path, number):
    """NaN and friends in a JSONL line (the spec object): refused with the file and line (was:
    accepted, and written back into the index as NaN)."""
    path = tmp_path / "items.jsonl"
    path.write_text('{"instruction": "squat"}\n{"spec": {"duration": ' + number + "}}\n")
    with pytest.raises(CliError) as info:
        read_items(str(path))
    assert f"{path}:2" in str(info.value) and "not finite" in str(info.value) and info.value.code == 2
    assert not math.isfinite(float(number))
