"""A hypothesis fuzz pass over the readers of files wbmp did not necessarily write (issue 36):
the motion file, the motion cache's manifests, request records and page data, the robot and
solver caches' manifests, the solution library's escalation records and the cache cap.

Each reader, given any bytes, either accepts them or refuses them with its own error (or as a
damaged entry, a miss); nothing else escapes, and nothing outside the cache folder is removed.
"""

from __future__ import annotations

import io
import json
import tempfile
import zipfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from wbmp.errors import MotionFileError
from wbmp.motionfile import motion_from_arrays, read_npz_bytes

FUZZ = settings(max_examples=150, deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])

json_values = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=20),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=10), inner, max_size=4),
    max_leaves=20,
)


@pytest.fixture(scope="module")
def motion_bytes(motion_file) -> bytes:
    return motion_file.read_bytes()


def _read(data: bytes) -> None:
    try:
        motion_from_arrays(read_npz_bytes(data, "fuzzed.npz"), source="fuzzed.npz")
    except MotionFileError:
        pass


@FUZZ
@given(data=st.data())
def test_a_mutated_motion_file_is_read_or_refused(motion_bytes, data):
    raw = bytearray(motion_bytes)
    for _ in range(data.draw(st.integers(1, 8))):
        at = data.draw(st.integers(0, len(raw) - 1))
        raw[at] = data.draw(st.integers(0, 255))
    cut = data.draw(st.integers(0, len(raw)))
    _read(bytes(raw[:cut]) if data.draw(st.booleans()) else bytes(raw))


def _npz(arrays: dict[str, np.ndarray]) -> bytes:
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


arrays_st = st.one_of(
    st.builds(lambda n, m, s: np.linspace(s, s + m, n), st.integers(0, 5), st.floats(-1e15, 1e15),
              st.floats(-1e15, 1e15)),
    st.builds(lambda r, c: np.zeros((r, c)), st.integers(0, 4), st.integers(0, 40)),
    st.just(np.array("talos")), st.just(np.array(["", ""])), st.just(np.array([np.nan, np.inf])),
    st.just(np.array("{}")), st.just(np.array("[" * 5000)), st.just(np.zeros((2, 2), dtype=np.int8)),
)
KEYS = ("t", "q", "v", "a", "com", "robot", "spec_json", "report_json", "actions_json", "joint_names",
        "frame_names", "exec_t", "exec_q", "exec_v", "exec_tau", "object_names", "object_pose", "version")


@FUZZ
@given(st.dictionaries(st.sampled_from(KEYS), arrays_st, max_size=len(KEYS)))
def test_motion_files_of_any_keys_are_read_or_refused(arrays):
    _read(_npz(arrays))


@FUZZ
@given(st.lists(st.tuples(st.sampled_from([f"{k}.npy" for k in KEYS]) | st.text(
    st.characters(min_codepoint=48, max_codepoint=122), min_size=1, max_size=12).map(lambda n: n + ".npy"),
    st.binary(max_size=64) | st.just(b"\x93NUMPY\x01\x00v\x00{'descr': '<f8', 'fortran_order': False, "
                                     b"'shape': (99999999999, 99999999999), }" + b" " * 40 + b"\n")),
    max_size=5, unique_by=lambda m: m[0]))
def test_an_archive_of_any_members_is_refused(members):
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        for name, blob in members:
            zf.writestr(name, blob)
    _read(buf.getvalue())


KEY = "ab" * 32


@FUZZ
@given(record=json_values | st.fixed_dictionaries(
    {"motion": st.text(max_size=80) | st.just("../" * 20 + "vvvv"), "files": json_values, "robot": json_values}),
    manifest=json_values, raw=st.binary(max_size=200), which=st.sampled_from(["record", "manifest", "page", "npz"]))
def test_the_motion_cache_reads_any_files_as_entries_or_misses(record, manifest, raw, which):
    from wbmp.motioncache import MotionCache

    with tempfile.TemporaryDirectory() as tmp:
        outside = Path(tmp) / "victims"
        outside.mkdir()
        (outside / "victim.json").write_text("{}")
        root = Path(tmp) / "cache" / "motions"
        (root / "requests").mkdir(parents=True)
        (root / "requests" / f"{KEY}.json").write_text(json.dumps(record) if which != "record" else raw.hex())
        (root / f"{KEY}.json").write_text(json.dumps(manifest))
        (root / f"{KEY}.npz").write_bytes(raw)
        (root / f"{KEY}.page").write_bytes(raw)
        (root / f"{KEY}.page.json").write_text(json.dumps(manifest) if which != "page" else raw.hex())
        cache = MotionCache(root)
        found = cache.lookup_request(KEY)
        assert found is None or isinstance(found[0], str)
        assert cache.load(KEY) is None
        cache.load_page(KEY)
        if isinstance(record, dict) and isinstance(record.get("motion"), str):
            cache.load(record["motion"])
        assert (outside / "victim.json").read_text() == "{}"


@FUZZ
@given(manifest=json_values, raw=st.binary(max_size=100))
def test_the_robot_and_solver_cache_manifests_are_read_or_damaged(manifest, raw):
    from planner.trajopt import cache_disk
    from robots.store import EntryDamaged, EntryStale, read_manifest

    with tempfile.TemporaryDirectory() as tmp:
        entry = Path(tmp) / KEY
        entry.mkdir()
        for text in (json.dumps(manifest), raw):
            data = text.encode() if isinstance(text, str) else text
            (entry / "manifest.json").write_bytes(data)
            (entry / cache_disk.META).write_bytes(data)
            try:
                read_manifest(entry, 1)
            except (EntryDamaged, EntryStale):
                pass
            try:
                cache_disk.read_manifest(entry, KEY)
            except cache_disk.EntryDamaged:
                pass


@FUZZ
@given(st.text(max_size=200) | json_values.map(json.dumps))
def test_an_escalation_record_of_any_text_is_rows_or_none(text):
    from planner.trajopt.library import _parse_escalation

    rows = _parse_escalation(text)
    assert rows is None or isinstance(rows, dict)


@FUZZ
@given(st.text(max_size=60) | st.builds(lambda n, unit: "9" * n + unit, st.integers(300, 5000),
                                        st.sampled_from(["", "k", "G", "TiB", ".5M", "b"])))
def test_a_cache_cap_of_any_text_is_a_size_or_refused(text):
    from robots.store import MAX_SIZE_BYTES, parse_size

    try:
        size = parse_size(text)
    except ValueError:
        return
    assume(size is not None)
    assert 0 < size <= MAX_SIZE_BYTES


@pytest.fixture(scope="module")
def spec_doc() -> dict:
    return json.loads((Path(__file__).resolve().parents[2] / "examples" / "specs" / "squat.json").read_text())


def _mutate(doc, data, depth: int = 0):
    """``doc`` with one value somewhere replaced by a drawn JSON value."""
    if isinstance(doc, dict) and doc and depth < 6 and data.draw(st.booleans()):
        key = data.draw(st.sampled_from(sorted(doc)))
        return {**doc, key: _mutate(doc[key], data, depth + 1)}
    if isinstance(doc, list) and doc and depth < 6 and data.draw(st.booleans()):
        i = data.draw(st.integers(0, len(doc) - 1))
        return [*doc[:i], _mutate(doc[i], data, depth + 1), *doc[i + 1:]]
    return data.draw(json_values | st.integers(-(10**400), 10**400) | st.just(float("nan")))


@FUZZ
@given(data=st.data())
def test_a_mutated_spec_is_a_spec_or_refused(spec_doc, data):
    from tasks.exceptions import TaskDefinitionError
    from tasks.serialize import spec_from_json

    doc = spec_doc
    for _ in range(data.draw(st.integers(1, 3))):
        doc = _mutate(doc, data)
    try:
        spec_from_json(json.dumps(doc))
    except TaskDefinitionError:
        pass
