"""``wbmp export --format mcap``: the bag is read back by an independent reader (rosbags, which
parses the bag's own message definitions and also holds ROS 2 Humble's) and every sample of
every topic is compared with the motion file."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from tests.tolerances import EXPORT_ATOL
from wbmp.cli import main
from wbmp.export.msgdefs import DEFINITIONS, schema_text
from wbmp.export.rosbag import base_frame_of
from wbmp.motionfile import load_motion, save_motion

rosbags_highlevel = pytest.importorskip("rosbags.highlevel")
from rosbags.rosbag2 import Reader  # noqa: E402
from rosbags.typesys import Stores, get_types_from_msg, get_typestore  # noqa: E402

EPOCH = 1_700_000_000.25  # [s] --stamp of the test bag: seconds and a fraction
NS = 1_000_000_000
TOPICS = {
    "/wbmp/plan/joint_trajectory": "trajectory_msgs/msg/JointTrajectory",
    "/joint_states": "sensor_msgs/msg/JointState",
    "/tf": "tf2_msgs/msg/TFMessage",
    "/wbmp/execution/joint_trajectory": "trajectory_msgs/msg/JointTrajectory",
    "/wbmp/execution/joint_states": "sensor_msgs/msg/JointState",
    "/wbmp/execution/tf": "tf2_msgs/msg/TFMessage",
    "/wbmp/report": "std_msgs/msg/String",
}


@pytest.fixture(scope="module")
def motion_path(tmp_path_factory, talos, synth_plan, synth_execution):
    ex = synth_execution
    execution = ex
    path = tmp_path_factory.mktemp("motion") / "squat.npz"
    return save_motion(path, synth_plan, talos, execution=execution,
                       report={"certificate": {"ok": True, "max_tracking_error": 0.0123}})


@pytest.fixture(scope="module")
def bag(motion_path, tmp_path_factory):
    out = tmp_path_factory.mktemp("bag") / "squat.mcap"
    assert main(["export", str(motion_path), "--out", str(out), "--stamp", repr(EPOCH)]) == 0
    return out


def read_bag(path: Path) -> dict[str, list[tuple[int, object]]]:
    """topic -> [(log time [ns], message)], deserialized from the bag's own definitions."""
    out: dict[str, list[tuple[int, object]]] = {}
    with rosbags_highlevel.AnyReader([path]) as reader:
        types_ = {c.topic: c.msgtype for c in reader.connections}
        assert types_ == TOPICS
        for conn, log_ns, raw in reader.messages():
            out.setdefault(conn.topic, []).append((log_ns, reader.deserialize(raw, conn.msgtype)))
    return out


def expected_ns(t: np.ndarray) -> np.ndarray:
    return round(EPOCH * NS) + np.rint(t * NS).astype(np.int64)


def stamp_ns(stamp) -> int:
    return stamp.sec * NS + stamp.nanosec


def test_every_sample_of_the_bag_is_the_motion_files(bag, motion_path):
    """Joint states, tf and both trajectories hold the motion file's numbers at its times."""
    m = load_motion(motion_path)
    msgs = read_bag(bag)
    names = list(m.joint_names)
    ex = m.execution
    runs = [("/joint_states", "/tf", "/wbmp/plan/joint_trajectory", m.plan.t, m.plan.q, m.plan.v, None),
            ("/wbmp/execution/joint_states", "/wbmp/execution/tf", "/wbmp/execution/joint_trajectory",
             ex.t, ex.q, ex.v, ex.tau)]
    for js_topic, tf_topic, traj_topic, t, q, v, tau in runs:
        ns = expected_ns(t)
        states, tfs = msgs[js_topic], msgs[tf_topic]
        assert len(states) == len(tfs) == len(t)
        for k, ((log_js, js), (log_tf, tf)) in enumerate(zip(states, tfs, strict=True)):
            assert log_js == log_tf == stamp_ns(js.header.stamp) == ns[k]
            assert list(js.name) == names
            np.testing.assert_allclose(js.position, q[k, 7:], rtol=0, atol=EXPORT_ATOL)
            np.testing.assert_allclose(js.velocity, v[k, 6:], rtol=0, atol=EXPORT_ATOL)
            np.testing.assert_allclose(js.effort, [] if tau is None else tau[k], rtol=0, atol=EXPORT_ATOL)
            (transform,) = tf.transforms
            assert (transform.header.frame_id, transform.child_frame_id) == ("world", "base_link")
            assert stamp_ns(transform.header.stamp) == ns[k]
            tr, rot = transform.transform.translation, transform.transform.rotation
            np.testing.assert_allclose([tr.x, tr.y, tr.z], q[k, :3], rtol=0, atol=EXPORT_ATOL)
            np.testing.assert_allclose([rot.x, rot.y, rot.z, rot.w], q[k, 3:7], rtol=0, atol=EXPORT_ATOL)
        # the stamp is the epoch plus t to the nanosecond
        got = np.array([stamp_ns(js.header.stamp) for _, js in states])
        assert np.max(np.abs((got - round(EPOCH * NS)) / NS - t)) <= 0.5e-9 + 1e-15 * t[-1]

        ((log_traj, traj),) = msgs[traj_topic]
        assert log_traj == stamp_ns(traj.header.stamp) == ns[0]
        assert list(traj.joint_names) == names and len(traj.points) == len(t)
        for k, point in enumerate(traj.points):
            assert stamp_ns(point.time_from_start) == ns[k] - ns[0]
            np.testing.assert_allclose(point.positions, q[k, 7:], rtol=0, atol=EXPORT_ATOL)
            np.testing.assert_allclose(point.velocities, v[k, 6:], rtol=0, atol=EXPORT_ATOL)
            want_acc = m.plan.a[k, 6:] if tau is None else []
            np.testing.assert_allclose(point.accelerations, want_acc, rtol=0, atol=EXPORT_ATOL)
            np.testing.assert_allclose(point.effort, [] if tau is None else tau[k], rtol=0, atol=EXPORT_ATOL)

    ((log_report, report),) = msgs["/wbmp/report"]
    assert log_report == round(EPOCH * NS)
    doc = json.loads(report.data)
    assert doc["robot"] == "talos" and doc["spec"]["name"] == "synthetic squat"
    assert doc["report"]["certificate"] == {"ok": True, "max_tracking_error": 0.0123}


def test_tf_rotation_is_the_base_orientation(bag, motion_path):
    """The /tf quaternion, read in ROS's x, y, z, w order, is the rotation Pinocchio gives the base."""
    m = load_motion(motion_path)
    tfs = read_bag(bag)["/tf"]
    for k, (_, tf) in enumerate(tfs):
        r = tf.transforms[0].transform.rotation
        x, y, z, w = r.x, r.y, r.z, r.w
        rotation = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                             [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                             [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
        np.testing.assert_allclose(rotation, pin.XYZQUATToSE3(m.plan.q[k, :7]).rotation, rtol=0, atol=1e-12)


def test_definitions_are_ros2_humbles_and_the_bytes_decode_with_them(bag):
    """Each message definition the bag embeds has ROS 2 Humble's fields, and every raw message
    decodes with Humble's typestore (not the bag's definitions) to the same values."""
    humble = get_typestore(Stores.ROS2_HUMBLE)
    for name in DEFINITIONS:
        parsed = get_types_from_msg(schema_text(name), name)
        for typ, fields in parsed.items():
            assert fields == humble.fielddefs[typ], typ
    with rosbags_highlevel.AnyReader([bag]) as ours, Reader(bag) as raw:
        mine = [(c.topic, ts, ours.deserialize(d, c.msgtype)) for c, ts, d in ours.messages()]
        theirs = [(c.topic, ts, humble.deserialize_cdr(d, c.msgtype)) for c, ts, d in raw.messages()]
    assert len(mine) == len(theirs) == 3 + 2 * (61 + 601)  # report, 2 trajectories, states and tf

    def plain(msg):
        if hasattr(msg, "__dataclass_fields__"):
            return {k: plain(getattr(msg, k)) for k in msg.__dataclass_fields__ if k != "__msgtype__"}
        if isinstance(msg, (list, tuple)):
            return [plain(x) for x in msg]
        if isinstance(msg, np.ndarray):
            return msg.tolist()
        return msg

    for (topic_a, ts_a, a), (topic_b, ts_b, b) in zip(mine, theirs, strict=True):
        assert (topic_a, ts_a) == (topic_b, ts_b)
        assert plain(a) == plain(b), topic_a


def test_metadata_holds_the_certificate(bag):
    """The MCAP metadata record ``wbmp`` holds the certificate, the frames and the epoch."""
    from mcap.reader import make_reader

    with open(bag, "rb") as fh:
        (record,) = [r for r in make_reader(fh).iter_metadata() if r.name == "wbmp"]
    meta = record.metadata
    assert json.loads(meta["certificate"]) == {"ok": True, "max_tracking_error": 0.0123}
    assert (meta["world_frame"], meta["base_frame"], float(meta["stamp"])) == ("world", "base_link", EPOCH)
    assert json.loads(meta["document"])["robot"] == "talos"
    assert "object_frames" not in meta  # a motion without scene objects: the record as before objects


def test_a_plan_without_simulation_has_no_execution_topics(tmp_path, talos, synth_plan, capsys):
    """Without an execution the bag holds the plan's topics only; --base-frame names the tf child."""
    path = save_motion(tmp_path / "plan.npz", synth_plan, talos)
    assert main(["export", str(path), "--format", "mcap", "--base-frame", "torso_base"]) == 0
    out = tmp_path / "plan.mcap"
    assert f"mcap: {out}" in capsys.readouterr().out
    with rosbags_highlevel.AnyReader([out]) as reader:
        assert {c.topic for c in reader.connections} == {"/wbmp/plan/joint_trajectory", "/joint_states", "/tf",
                                                          "/wbmp/report"}
        tfs = [reader.deserialize(d, c.msgtype) for c, _, d in reader.messages() if c.topic == "/tf"]
        stamps = [stamp_ns(tf.transforms[0].header.stamp) for tf in tfs]
    assert {tf.transforms[0].child_frame_id for tf in tfs} == {"torso_base"}
    assert stamps == list(np.rint(synth_plan.t * NS).astype(np.int64))  # default epoch 0


def test_base_frame_is_the_profiles_root_link():
    """The tf child frame defaults to the robot profile's base frame (its URDF root link)."""
    assert (base_frame_of("talos"), base_frame_of("g1"), base_frame_of("no-such-robot")) == (
        "base_link", "pelvis", "base_link")
