"""A cached motion's ``--out``: the stored .npz copied member by member, the request's JSON anew."""

from __future__ import annotations

import io
import zipfile

import numpy as np

from wbmp.motionfile import npz_replacing as _npz_replacing


def _npz(arrays) -> bytes:
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    return buf.getvalue()


def test_npz_copy_keeps_members_and_replaces_the_named_ones(rng):
    """Every kept array reads back equal with its compressed bytes untouched, the replaced ones
    hold the new values, and the archive passes zipfile's CRC check."""
    arrays = {"q": rng.normal(size=(300, 39)), "t": np.linspace(0, 3, 300), "spec_json": np.array('{"a": 1}'),
              "report_json": np.array("{}"), "names": np.array(["a", "bb"])}
    source = _npz(arrays)
    new = {"spec_json": np.array('{"a": 2}'), "report_json": np.array('{"cached": true}')}
    out = _npz_replacing(source, new)
    assert out is not None
    with zipfile.ZipFile(io.BytesIO(out)) as zf:
        assert zf.testzip() is None
        assert sorted(zf.namelist()) == sorted(f"{k}.npy" for k in arrays)
    loaded = np.load(io.BytesIO(out))
    for key, value in arrays.items():
        expected = new.get(key, value)
        assert np.array_equal(loaded[key], expected) and loaded[key].dtype == expected.dtype, key
    src, dst = zipfile.ZipFile(io.BytesIO(source)), zipfile.ZipFile(io.BytesIO(out))
    for key in ("q", "t", "names"):
        a, b = src.getinfo(f"{key}.npy"), dst.getinfo(f"{key}.npy")
        assert (a.CRC, a.compress_size) == (b.CRC, b.compress_size)
        assert source.find(out[b.header_offset + 30 + len(b.filename):][:b.compress_size]) >= 0


def test_npz_copy_declines_what_it_cannot_copy():
    """Not a zip, or members written with data descriptors (a streamed archive): None, so the
    caller writes the file the ordinary way."""
    assert _npz_replacing(b"not a zip at all", {}) is None

    raw = io.BytesIO()

    class Sink(io.RawIOBase):  # not seekable: zipfile writes data descriptors
        def writable(self) -> bool:
            return True

        def write(self, b) -> int:
            raw.write(b)
            return len(b)

    with zipfile.ZipFile(Sink(), "w", compression=zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("q.npy", b"x" * 1000)
    assert _npz_replacing(raw.getvalue(), {"spec_json": np.array("{}")}) is None


def test_arrays_that_hardly_compress_are_stored_and_read_back_equal(rng):
    """``savez_fast`` stores a member whose bytes deflate by less than 10 % (random doubles: a 1 kHz
    execution's joint data) and deflates the rest (a smooth or constant array, text); numpy and the
    motion file reader read every one back equal, and a kept stored member is copied by ``--out``."""
    from wbmp.motionfile import npz_bytes, read_npz_bytes

    arrays = {"exec_q": rng.normal(size=(4000, 39)), "exec_object_pose": np.zeros((4000, 7)),
              "t": np.linspace(0.0, 4.0, 4000), "spec_json": np.array('{"a": 1}'), "few": rng.normal(size=5)}
    data = npz_bytes(arrays)
    with zipfile.ZipFile(io.BytesIO(data)) as zf:
        kinds = {i.filename: i.compress_type for i in zf.infolist()}
        assert zf.testzip() is None
    assert kinds["exec_q.npy"] == zipfile.ZIP_STORED
    assert kinds["exec_object_pose.npy"] == kinds["t.npy"] == kinds["spec_json.npy"] == zipfile.ZIP_DEFLATED
    assert kinds["few.npy"] == zipfile.ZIP_DEFLATED  # too small to be worth a sample
    for read in (dict(np.load(io.BytesIO(data))), read_npz_bytes(data, "test")):
        assert read.keys() == arrays.keys()
        assert all(np.array_equal(read[k], arrays[k]) for k in arrays)
    copied = _npz_replacing(data, {"spec_json": np.array('{"a": 2}')})
    assert copied is not None and np.array_equal(np.load(io.BytesIO(copied))["exec_q"], arrays["exec_q"])
