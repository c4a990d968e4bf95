"""Movable scene objects in the ROS 2 bag (one tf frame each, on the base's tf topic) and in the
tracker file (``object_names``, ``object_pos``, ``object_rot``): every sample read back (the bag by
rosbags, the tracker by numpy, scipy's Slerp between knots) is the motion file's ``object_pose`` /
``exec_object_pose`` as ``numpy.load`` reads them."""

from __future__ import annotations

import dataclasses
import json
import re

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

from tests.tolerances import EXPORT_ATOL
from tests.viz.conftest import SIM_DROP, synthetic_pick_up, synthetic_pick_up_execution
from wbmp.cli import main
from wbmp.export.columns import object_frame_ids
from wbmp.motionfile import save_motion

rosbags_highlevel = pytest.importorskip("rosbags.highlevel")

NS = 1_000_000_000
EPOCH = 1_700_000_000.5  # [s]
NAMES = ["Red cup", "箱子"]  # the synthetic scene's movable cup and box, renamed
FRAMES = ["object_red_cup", "object_u7bb1_u5b50"]  # docs/export.md's rule applied by hand


@pytest.fixture(scope="module")
def motion_path(tmp_path_factory, talos, synth_plan):
    """The synthetic pick-up (the right hand takes the cup at 1 s and carries it; the box stays)
    with a non-ASCII and a spaced object name, and its 200 Hz execution (the cup 3 cm lower)."""
    plan = synthetic_pick_up(talos, synth_plan)
    scene = plan.spec.scene
    rename = {"cup": NAMES[0], "box": NAMES[1]}
    objects = tuple(dataclasses.replace(o, name=rename.get(o.name, o.name)) for o in scene.objects)
    grasps = tuple(dataclasses.replace(g, object=rename[g.object]) for g in plan.spec.grasps)
    spec = dataclasses.replace(plan.spec, scene=dataclasses.replace(scene, objects=objects), grasps=grasps)
    plan = dataclasses.replace(plan, spec=spec)
    ex = synthetic_pick_up_execution(talos, plan)
    ex.objects[NAMES[0]][:, 2] -= SIM_DROP  # (the helper lowers an object called "cup" only)
    execution = ex
    path = save_motion(tmp_path_factory.mktemp("motion") / "pick.npz", plan, talos, execution=execution)
    with np.load(path) as z:
        assert list(z["object_names"]) == NAMES
    return path


@pytest.fixture(scope="module")
def arrays(motion_path):
    with np.load(motion_path) as z:
        return {k: z[k] for k in ("t", "q", "exec_t", "exec_q", "object_pose", "exec_object_pose")}


def stamp_ns(stamp) -> int:
    return stamp.sec * NS + stamp.nanosec


def test_object_frame_ids_are_ros_names_unique_and_documented():
    """Lower case, runs of other ASCII -> '_', accents dropped, other non-ASCII -> _u<hex>_, prefix
    ``object_``; clashes (with each other or the world/base frames) numbered in order."""
    names = ["Red cup", "杯子", "Café", "Cup", "cup", "CUP", "cup 2", "  box--1 ", "!!!", "ＢＯＸ"]
    frames = object_frame_ids(names, taken=("world", "base_link", "object_box_1"))
    assert frames == {"Red cup": "object_red_cup", "杯子": "object_u676f_u5b50", "Café": "object_cafe",
                      "Cup": "object_cup", "cup": "object_cup_2", "CUP": "object_cup_3", "cup 2": "object_cup_2_2",
                      "  box--1 ": "object_box_1_2", "!!!": "object", "ＢＯＸ": "object_box"}
    assert len(set(frames.values())) == len(names)
    assert all(re.fullmatch(r"[a-z][a-z0-9]*(_[a-z0-9]+)*", f) for f in frames.values())
    assert object_frame_ids(NAMES) == dict(zip(NAMES, FRAMES, strict=True))


def test_bag_carries_every_object_pose_as_a_tf_frame(motion_path, arrays, tmp_path):
    """/tf holds, per knot, the base then each object (world -> object_<name>) at the planned pose;
    /wbmp/execution/tf the same with the simulated poses; the metadata maps names to frames."""
    from mcap.reader import make_reader

    out = tmp_path / "pick.mcap"
    assert main(["export", str(motion_path), "--out", str(out), "--stamp", repr(EPOCH)]) == 0
    tfs: dict[str, list] = {}
    with rosbags_highlevel.AnyReader([out]) as reader:
        for conn, log_ns, raw in reader.messages():
            if conn.topic in ("/tf", "/wbmp/execution/tf"):
                tfs.setdefault(conn.topic, []).append((log_ns, reader.deserialize(raw, conn.msgtype)))
    runs = [("/tf", arrays["t"], arrays["q"], arrays["object_pose"]),
            ("/wbmp/execution/tf", arrays["exec_t"], arrays["exec_q"], arrays["exec_object_pose"])]
    for topic, t, q, pose in runs:
        msgs = tfs[topic]
        assert len(msgs) == len(t)
        ns = round(EPOCH * NS) + np.rint(t * NS).astype(np.int64)
        got = np.empty((len(t), len(NAMES), 7))
        for k, (log_ns, msg) in enumerate(msgs):
            assert [tr.child_frame_id for tr in msg.transforms] == ["base_link", *FRAMES]
            assert {tr.header.frame_id for tr in msg.transforms} == {"world"}
            assert log_ns == ns[k] and {stamp_ns(tr.header.stamp) for tr in msg.transforms} == {ns[k]}
            base = msg.transforms[0].transform
            np.testing.assert_allclose([base.translation.x, base.translation.y, base.translation.z,
                                        base.rotation.x, base.rotation.y, base.rotation.z, base.rotation.w],
                                       q[k, :7], rtol=0, atol=EXPORT_ATOL)
            for i, tr in enumerate(msg.transforms[1:]):
                a, r = tr.transform.translation, tr.transform.rotation
                got[k, i] = [a.x, a.y, a.z, r.x, r.y, r.z, r.w]
        np.testing.assert_allclose(got, pose, rtol=0, atol=EXPORT_ATOL)
    # not vacuous: the cup is carried (it rises and turns) and the simulated one hangs lower
    cup = arrays["object_pose"][:, 0]
    assert np.ptp(cup[:, 2]) > 0.05 and np.max(np.abs(cup[:, 3:] - cup[0, 3:])) > 0.05
    sim_cup_z = arrays["exec_object_pose"][:, 0, 2]
    assert np.allclose(sim_cup_z, np.interp(arrays["exec_t"], arrays["t"], cup[:, 2]) - SIM_DROP, atol=0.01)
    with open(out, "rb") as fh:
        (record,) = [r for r in make_reader(fh).iter_metadata() if r.name == "wbmp"]
    assert json.loads(record.metadata["object_frames"]) == dict(zip(NAMES, FRAMES, strict=True))


def tracker(motion_path, tmp_path, *args: str) -> dict:
    out = tmp_path / "m.tracker.npz"
    assert main(["export", str(motion_path), "--format", "tracker", "--out", str(out), *args]) == 0
    with np.load(out) as f:
        return {k: f[k] for k in f.files}


def same_rotation(a: np.ndarray, b: np.ndarray) -> float:
    """Largest distance between quaternions (..., 4), up to each one's sign."""
    return float(np.max(np.minimum(np.linalg.norm(a - b, axis=-1), np.linalg.norm(a + b, axis=-1))))


def test_tracker_objects_round_trip(motion_path, arrays, tmp_path):
    """At 60 fps (3 samples per 20 Hz knot) every knot's sample holds the file's object poses;
    between knots positions are numpy's interp and orientations scipy's Slerp, xyzw like root_rot."""
    d = tracker(motion_path, tmp_path, "--fps", "60")
    assert list(d["object_names"]) == NAMES and str(d["root_rot_order"]) == "xyzw"
    t, s, pose = arrays["t"], d["t"], arrays["object_pose"]
    assert d["object_pos"].shape == (len(s), 2, 3) and d["object_rot"].shape == (len(s), 2, 4)
    np.testing.assert_allclose(d["object_pos"][::3], pose[:, :, :3], rtol=0, atol=EXPORT_ATOL)
    assert same_rotation(d["object_rot"][::3], pose[:, :, 3:]) <= EXPORT_ATOL
    for i in range(len(NAMES)):
        for c in range(3):
            np.testing.assert_allclose(d["object_pos"][:, i, c], np.interp(s, t, pose[:, i, c]), rtol=0,
                                       atol=EXPORT_ATOL)
        reference = Slerp(t, Rotation.from_quat(pose[:, i, 3:]))(np.clip(s, t[0], t[-1])).as_quat()
        assert same_rotation(d["object_rot"][:, i], reference) <= 1e-12
        assert np.all(np.sum(d["object_rot"][1:, i] * d["object_rot"][:-1, i], axis=1) > 0.0)
    np.testing.assert_allclose(np.linalg.norm(d["object_rot"], axis=2), 1.0, rtol=0, atol=EXPORT_ATOL)
    assert "object_rot" in str(d["interpolation"])

    ex = tracker(motion_path, tmp_path, "--source", "execution")  # 50 fps: every 4th 200 Hz sample
    np.testing.assert_allclose(ex["t"], arrays["exec_t"][::4], rtol=0, atol=EXPORT_ATOL)
    np.testing.assert_allclose(ex["object_pos"], arrays["exec_object_pose"][::4, :, :3], rtol=0, atol=EXPORT_ATOL)
    assert same_rotation(ex["object_rot"], arrays["exec_object_pose"][::4, :, 3:]) <= EXPORT_ATOL


def test_without_the_object_keys_the_exports_are_the_same_minus_the_objects(motion_path, tmp_path):
    """The same motion file with its object_* keys removed (a file without objects) exports the
    same tracker arrays and the same tf base transforms, and no object key, frame or metadata."""
    with np.load(motion_path) as z:
        stripped = {k: z[k] for k in z.files if not k.startswith(("object_", "exec_object_"))}
    assert len(stripped) < len(np.load(motion_path).files)
    bare = tmp_path / "bare.npz"
    np.savez(bare, **stripped)
    full_dir, bare_dir = tmp_path / "full", tmp_path / "bare"
    full_dir.mkdir(), bare_dir.mkdir()
    full, plain = tracker(motion_path, full_dir), tracker(bare, bare_dir)
    assert sorted(full) == sorted([*plain, "object_names", "object_pos", "object_rot"])
    for key, value in plain.items():
        if key != "interpolation":
            assert np.array_equal(value, full[key]), key
    bags = {}
    for name, path in (("full", motion_path), ("bare", bare)):
        out = tmp_path / f"{name}.mcap"
        assert main(["export", str(path), "--out", str(out)]) == 0
        with rosbags_highlevel.AnyReader([out]) as reader:
            bags[name] = [(c.topic, ns, reader.deserialize(raw, c.msgtype)) for c, ns, raw in reader.messages()]
    assert [(topic, ns) for topic, ns, _ in bags["full"]] == [(topic, ns) for topic, ns, _ in bags["bare"]]
    for (topic, _, a), (_, _, b) in zip(bags["full"], bags["bare"], strict=True):
        if topic.endswith("tf"):
            assert len(b.transforms) == 1 and len(a.transforms) == 1 + len(NAMES)
            assert repr(a.transforms[0]) == repr(b.transforms[0])  # (two readers: two classes)
