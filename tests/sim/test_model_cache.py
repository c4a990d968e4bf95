"""The compiled MuJoCo model's disk cache (sim/modelcache.py): hit, miss, invalidation, damage.

A model read from the cache must behave exactly as the one built from the URDF: the same
arrays and the same simulated trajectory, step for step.
"""

from __future__ import annotations

import json
import logging
import re
from pathlib import Path

import mujoco
import numpy as np
import pytest

import sim.model as sm
from robots import load_robot


@pytest.fixture
def counted(tmp_path, monkeypatch):
    """A fresh cache folder and a count of the real builds (sim.model._build)."""
    monkeypatch.setenv("WBMP_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.delenv("WBMP_MUJOCO_CACHE", raising=False)
    builds: list[int] = []
    real = sm._build

    def build(*args):
        builds.append(1)
        return real(*args)

    monkeypatch.setattr(sm, "_build", build)
    return builds


def _model(robot, **options):
    """A SimModel without the in-memory cache (a new process, as far as the disk is concerned)."""
    args = {"timestep": 0.001, "joint_friction": True, "scene": None, "pairs": ()} | options
    return sm._cached.__wrapped__(robot, args["timestep"], args["joint_friction"], args["scene"], args["pairs"])


def _rollout(sim_model, steps: int = 60) -> np.ndarray:
    data = mujoco.MjData(sim_model.model)
    sim_model.set_state(data, sim_model.robot.q_standing)
    data.ctrl[:] = 0.3 * np.sin(np.arange(sim_model.model.nu))
    for _ in range(steps):
        mujoco.mj_step(sim_model.model, data)
    return np.concatenate([data.qpos, data.qvel])


def _same(a, b) -> None:
    for name in ("body_mass", "geom_size", "geom_friction", "jnt_range", "actuator_ctrlrange", "dof_damping"):
        np.testing.assert_array_equal(getattr(a.model, name), getattr(b.model, name), err_msg=name)
    for name in ("qpos_index", "dof_index", "actuator_index", "geom_role", "pair_index"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    assert a.sole_geoms == b.sole_geoms and a.floor_geom == b.floor_geom and a.rest_overlap == b.rest_overlap
    np.testing.assert_array_equal(_rollout(a), _rollout(b))


def test_mujoco_cache_hit_miss_and_changed_urdf(talos, tmp_path, counted, caplog):
    """Built once, then read back (no build) into a model that simulates bit for bit the same;
    another timestep misses; an edited URDF (a joint's effort limit) misses and the new model
    has the new limit."""
    caplog.set_level(logging.WARNING, logger="sim.modelcache")
    built = _model(talos)
    assert len(counted) == 1
    again = _model(talos)
    assert len(counted) == 1
    _same(built, again)
    assert _model(talos, timestep=0.002).model.opt.timestep == 0.002 and len(counted) == 2

    text = Path(talos.urdf_path).read_text(encoding="utf-8")
    joint = "leg_left_4_joint"
    edited, n = re.subn(rf'(<joint name="{joint}".*?effort=")([^"]+)"', r'\g<1>123.5"', text, count=1, flags=re.S)
    assert n == 1
    urdf = tmp_path / "talos_edited.urdf"
    urdf.write_text(edited, encoding="utf-8")
    srdf = str(talos.urdf_path).replace("robots/talos_reduced.urdf", "srdf/talos.srdf")
    profile = {"name": "mytalos", "urdf": str(urdf), "package_dirs": list(talos.package_dirs), "srdf": srdf,
               "reference_posture": "half_sitting", "frames": dict(talos.profile.frames),
               "sole": {"x_min": -0.1, "x_max": 0.1, "y_min": -0.06, "y_max": 0.06}}
    path = tmp_path / "mytalos.json"
    path.write_text(json.dumps(profile))
    robot = load_robot(path)
    first = _model(robot)
    assert len(counted) == 3
    k = list(robot.model.names)[2:].index(joint)
    assert first.model.actuator_ctrlrange[first.actuator_index[k]][1] == pytest.approx(123.5)
    urdf.write_text(edited.replace('effort="123.5"', 'effort="99.5"', 1), encoding="utf-8")
    second = _model(load_robot(path))
    assert len(counted) == 4
    assert second.model.actuator_ctrlrange[second.actuator_index[k]][1] == pytest.approx(99.5)
    assert not caplog.records


@pytest.mark.parametrize("damage", ["binary", "meta", "fields"])
def test_mujoco_cache_damaged_entry_is_rebuilt_with_one_warning(talos, tmp_path, counted, caplog, damage):
    """A damaged entry (model bytes, unreadable meta, index maps that do not fit the model) is
    removed with one warning and rebuilt into the same model."""
    built = _model(talos)
    entry = next((tmp_path / "cache" / "mujoco").iterdir())
    if damage == "binary":
        data = bytearray((entry / "model.mjb").read_bytes())
        data[len(data) // 3] ^= 0x5A
        (entry / "model.mjb").write_bytes(bytes(data))
    elif damage == "meta":
        (entry / "meta.json").write_text("[")
    else:
        meta = json.loads((entry / "meta.json").read_text())
        meta["fields"]["qpos_index"] = meta["fields"]["qpos_index"][:-1]
        (entry / "meta.json").write_text(json.dumps(meta))
    caplog.set_level(logging.INFO, logger="sim.modelcache")
    again = _model(talos)
    assert len(counted) == 2
    warnings = [r for r in caplog.records if r.levelno >= logging.WARNING]
    assert len(warnings) == 1 and "damaged" in warnings[0].getMessage()
    _same(built, again)
    caplog.clear()
    _model(talos)
    assert len(counted) == 2 and not caplog.records


def test_an_entry_removed_while_read_is_a_miss_without_a_warning(tmp_path, monkeypatch, caplog):
    """Another process (the cache's size cap, ``wbmp cache --clear``) removes the entry after its
    manifest was read: a miss, the model built again, no "damaged" warning; a hit renews the
    entry's use time."""
    import os
    import time
    import types

    from robots.store import cache_usage, remove_entry
    from sim import modelcache

    monkeypatch.setenv("WBMP_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.delenv("WBMP_MUJOCO_CACHE", raising=False)
    xml = "<mujoco><worldbody><body><freejoint/><geom size='0.1'/></body></worldbody></mujoco>"
    builds: list[int] = []

    def build():
        builds.append(1)
        return mujoco.MjModel.from_xml_string(xml), {"n": 3}

    def check(model, fields):
        return model.nq, model.nv, fields["n"]

    key = "ab" * 32
    entry = tmp_path / "cache" / "mujoco" / key
    assert modelcache.cached_model(key, build, check) == (7, 6, 3) and entry.is_dir()
    os.utime(entry, (1000.0, 1000.0))
    assert modelcache.cached_model(key, build, check) == (7, 6, 3) and len(builds) == 1  # a hit
    assert os.lstat(entry).st_mtime > time.time() - 60

    def racing_loads(raw):
        out = json.loads(raw)
        (victim,) = [e for f in cache_usage() for e in f.entries if e.name == key]
        assert remove_entry(victim)
        return out

    monkeypatch.setattr(modelcache, "json", types.SimpleNamespace(loads=racing_loads, dumps=json.dumps))
    with caplog.at_level(logging.INFO):
        assert modelcache.cached_model(key, build, check) == (7, 6, 3)
    assert len(builds) == 2 and entry.is_dir()  # built and stored again
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING]
