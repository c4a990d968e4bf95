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
