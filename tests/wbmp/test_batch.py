"""``wbmp batch``: a small real batch on the local pool and on a real local Ray instance.

Items: two cheap sentences (squat, wave) planned without simulation on talos, one spec whose
balance margin cannot hold (a task-level diagnosis, exit 4), one sentence the parser does not
understand (exit 2).
"""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from tasks.serialize import spec_to_dict
from tests.planner.planning_cases import squat_spec
from wbmp.cli import main
from wbmp.motionfile import load_motion


@pytest.fixture(autouse=True)
def _no_compilation(monkeypatch, tmp_path_factory):
    """Solvers are built in memory (the disk cache has its own tests); workers inherit this."""
    monkeypatch.setenv("WBMP_COMPILE", "0")


def _items(folder: Path, talos) -> Path:
    wide = spec_to_dict(squat_spec(talos, 0.1, margin=0.3))
    lines = [
        {"id": "squat", "instruction": "squat"},
        {"id": "wave", "instruction": "wave your right hand"},
        {"id": "wide", "spec": wide},
        {"id": "moon", "instruction": "fly to the moon"},
    ]
    path = folder / "items.jsonl"
    path.write_text("# a small library\n\n" + "\n".join(json.dumps(x) for x in lines) + "\n")
    return path


def _index(folder: Path) -> dict[str, dict]:
    records = [json.loads(line) for line in (folder / "index.jsonl").read_text().splitlines()]
    assert len(records) == len({r["id"] for r in records})
    return {r["id"]: r for r in records}


@pytest.fixture(scope="module")
def library(tmp_path_factory, talos):
    """The batch run once with the local pool (2 workers): (items file, library folder, exit, stderr)."""
    import os

    old = os.environ.get("WBMP_COMPILE")
    os.environ["WBMP_COMPILE"] = "0"
    try:
        folder = tmp_path_factory.mktemp("batch")
        items = _items(folder, talos)
        out = folder / "lib"
        code = main(["batch", str(items), "--out-dir", str(out), "--no-sim", "--workers", "2"])
    finally:
        if old is None:
            os.environ.pop("WBMP_COMPILE", None)
        else:
            os.environ["WBMP_COMPILE"] = old
    return items, out, code


def test_index_records_each_item_with_status_code_and_message(library):
    """One record per item: ok ones name their motion file and its sha256; failures their code and
    the one-line message `wbmp solve` prints; the batch exits with the first failure's code (4)."""
    _, out, code = library
    assert code == 4  # the first failed item in file order is 'wide' (infeasible)
    index = _index(out)
    assert list(index) == ["squat", "wave", "wide", "moon"]
    for name in ("squat", "wave"):
        rec = index[name]
        assert (rec["status"], rec["exit_code"], rec["robot"], rec["message"]) == ("ok", 0, "talos", "")
        assert rec["motion"] == f"{name}__talos.npz"
        assert rec["sha256"] == hashlib.sha256((out / rec["motion"]).read_bytes()).hexdigest()
        assert rec["certificate"] is None  # --no-sim
        assert rec["timings"]["plan"] > 0 and rec["timings"]["total"] >= rec["timings"]["plan"]
        assert rec["skipped"] is False and rec["backend"] == "local"
    wide, moon = index["wide"], index["moon"]
    assert (wide["status"], wide["exit_code"], wide["motion"]) == ("failed", 4, None)
    assert "CoM bound 'balance' cannot hold in phase 'squat'" in wide["message"]
    assert (moon["status"], moon["exit_code"], moon["motion"]) == ("failed", 2, None)
    assert moon["message"].startswith('could not understand "fly", "moon"')
    assert "\n" not in wide["message"] + moon["message"]
    assert sorted(p.name for p in out.iterdir()) == ["index.jsonl", "squat__talos.npz", "summary.md",
                                                      "wave__talos.npz"]
    summary = (out / "summary.md").read_text()
    assert "| talos | 2 | 2 | 4 |" in summary and "| wide | talos | 5 | 4 |" in summary


def test_motion_files_are_what_wbmp_solve_writes(library, tmp_path):
    """Each motion file loads, and the squat equals `wbmp solve squat --no-sim` sample by sample."""
    _, out, _ = library
    squat = load_motion(out / "squat__talos.npz")
    wave = load_motion(out / "wave__talos.npz")
    assert squat.robot_name == wave.robot_name == "talos" and squat.plan.ok and wave.plan.ok
    ref_path = tmp_path / "ref.npz"
    assert main(["solve", "squat", "--no-sim", "--quiet", "--out", str(ref_path)]) == 0
    ref = load_motion(ref_path)
    assert squat.plan.q.shape == ref.plan.q.shape
    np.testing.assert_allclose(squat.plan.t, ref.plan.t, rtol=0, atol=1e-12)
    np.testing.assert_allclose(squat.plan.q, ref.plan.q, rtol=0, atol=1e-6)
    np.testing.assert_allclose(squat.plan.v, ref.plan.v, rtol=0, atol=1e-5)


def test_rerun_skips_done_items_and_redoes_a_damaged_file(library, tmp_path, capsys):
    """A second run plans nothing (each skip recorded); a damaged motion file is planned again and
    a missing one too; --force plans everything."""
    items, out, _ = library
    lib = tmp_path / "lib"
    shutil.copytree(out, lib)
    capsys.readouterr()
    assert main(["batch", str(items), "--out-dir", str(lib), "--no-sim", "--workers", "2", "--quiet"]) == 4
    assert "0 planned now, 4 done before" in capsys.readouterr().out
    index = _index(lib)
    assert all(rec["skipped"] for rec in index.values())
    good = (lib / "wave__talos.npz").read_bytes()
    damaged = bytearray(good)
    damaged[len(damaged) // 2] ^= 0xFF
    (lib / "wave__talos.npz").write_bytes(bytes(damaged))
    (lib / "squat__talos.npz").unlink()
    assert main(["batch", str(items), "--out-dir", str(lib), "--no-sim", "--workers", "2", "--quiet"]) == 4
    assert "2 planned now, 2 done before" in capsys.readouterr().out
    index = _index(lib)
    assert {k: r["skipped"] for k, r in index.items()} == {"squat": False, "wave": False, "wide": True,
                                                           "moon": True}
    for name in ("squat", "wave"):
        data = (lib / f"{name}__talos.npz").read_bytes()
        assert index[name]["sha256"] == hashlib.sha256(data).hexdigest()
        load_motion(lib / f"{name}__talos.npz")
    assert not [p for p in lib.iterdir() if p.name.endswith(".tmp")]


@pytest.mark.long  # in make test-long: the 2-core suite stays under 10 minutes (~16 s; tests/wbmp/test_batch_ray.py runs a batch on a local Ray instance)
def test_same_batch_on_a_local_ray_instance(library, tmp_path):
    """--ray starts a local Ray instance (2 CPUs), gives the same records and files as the local
    pool (motion files equal to 1e-6), and shuts it down."""
    ray = pytest.importorskip("ray", reason="ray is not installed (pip install 'wbmp[ray]')")
    items, out, _ = library
    lib = tmp_path / "lib"
    code = main(["batch", str(items), "--out-dir", str(lib), "--no-sim", "--workers", "2", "--ray", "--quiet"])
    if code == 1 and not (lib / "index.jsonl").exists():  # pragma: no cover - machine-dependent
        pytest.skip("Ray could not start a local instance on this machine")
    assert code == 4
    assert not ray.is_initialized()
    local, remote = _index(out), _index(lib)
    assert list(remote) == list(local)
    for key in local:
        assert remote[key]["backend"] == "ray"
        for field in ("status", "exit_code", "message", "motion"):
            assert remote[key][field] == local[key][field], (key, field)
    for name in ("squat", "wave"):
        a, b = load_motion(out / f"{name}__talos.npz"), load_motion(lib / f"{name}__talos.npz")
        np.testing.assert_allclose(a.plan.q, b.plan.q, rtol=0, atol=1e-6)


def test_a_library_built_again_elsewhere_is_answered_from_the_motion_cache(library, tmp_path):
    """The library's items planned again into a new folder come from the motion cache (no plan
    step; the same arrays and sha256-verified files); with --no-cache the item is planned."""
    _, out, _ = library
    items = tmp_path / "again.jsonl"
    items.write_text('{"id": "squat", "instruction": "squat"}\n{"id": "wave", "instruction": "wave your right hand"}\n')
    lib = tmp_path / "lib"
    assert main(["batch", str(items), "--out-dir", str(lib), "--no-sim", "--workers", "1", "--quiet"]) == 0
    index = _index(lib)
    for name in ("squat", "wave"):
        rec = index[name]
        assert rec["cached"] is True and "plan" not in rec["timings"] and "cache" in rec["timings"]
        assert rec["sha256"] == hashlib.sha256((lib / rec["motion"]).read_bytes()).hexdigest()
        a, b = load_motion(out / rec["motion"]), load_motion(lib / rec["motion"])
        np.testing.assert_array_equal(a.plan.q, b.plan.q)
    assert _index(out)["squat"]["cached"] is False  # the first build planned
    fresh = tmp_path / "fresh"
    items.write_text('{"id": "squat", "instruction": "squat"}\n')
    assert main(["batch", str(items), "--out-dir", str(fresh), "--no-sim", "--workers", "1", "--quiet",
                 "--no-cache"]) == 0
    rec = _index(fresh)["squat"]
    assert rec["cached"] is False and rec["timings"]["plan"] > 0


def test_a_jsonl_line_names_its_scene(tmp_path, capsys):
    """``"scene"`` of a JSONL line goes to the solver as ``wbmp solve --scene`` does: a crate under
    the robot's feet makes the squat infeasible in task terms (exit 4; the same squat without the
    scene is planned elsewhere in this module). The scene is in the record, the id and the input
    hash; a missing scene file is refused before any work (exit 2)."""
    from wbmp.batch.items import expand, read_items

    crate = {"version": 1, "name": "a crate under the robot",
             "objects": [{"name": "crate", "shape": "box", "size": [0.6, 0.6, 0.3], "position": [0.0, 0.0, 0.15]}]}
    (tmp_path / "under.json").write_text(json.dumps(crate))
    items = tmp_path / "items.jsonl"
    items.write_text('{"instruction": "squat", "scene": "under.json"}\n{"instruction": "squat"}\n')
    read = read_items(str(items))
    assert [i.scene_path for i in read] == [str(tmp_path / "under.json"), None]
    assert read[0].id != read[1].id
    before = expand(read, None, simulate=False, file=str(items))[0].input_sha256
    crate["objects"][0]["position"] = [0.0, 0.0, 0.16]
    (tmp_path / "under.json").write_text(json.dumps(crate))
    assert expand(read_items(str(items)), None, simulate=False, file=str(items))[0].input_sha256 != before
    items.write_text('{"id": "crate", "instruction": "squat", "scene": "under.json"}\n')
    out = tmp_path / "lib"
    assert main(["batch", str(items), "--out-dir", str(out), "--no-sim", "--workers", "1", "--quiet"]) == 4
    rec = _index(out)["crate"]
    assert (rec["scene"], rec["exit_code"], rec["motion"]) == ("under.json", 4, None)
    assert "inside the crate" in rec["message"]
    items.write_text('{"instruction": "squat", "scene": "nowhere.json"}\n')
    capsys.readouterr()
    assert main(["batch", str(items), "--out-dir", str(tmp_path / "lib2"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert f"{items}:1: scene file 'nowhere.json' not found" in err and "Traceback" not in err
