"""A motion file as a ROS 2 bag in MCAP (``mcap`` + ``mcap-ros2-support``; no ROS installation).

What the bag holds (``docs/export.md`` is the reference):

* ``/wbmp/plan/joint_trajectory`` (``trajectory_msgs/msg/JointTrajectory``, one message): the
  planned joint positions, velocities and accelerations at every knot;
* ``/joint_states`` (``sensor_msgs/msg/JointState``): one message per knot of the plan;
* ``/tf`` (``tf2_msgs/msg/TFMessage``): the planned base pose per knot, ``world`` -> base frame,
  then, in the same message, each movable scene object's planned pose, ``world`` -> its frame
  (:func:`wbmp.export.columns.object_frame_ids`: ``object_<name as a ROS name>``);
* when the file holds a simulated execution: ``/wbmp/execution/joint_trajectory`` (positions,
  velocities, torques as ``effort``), ``/wbmp/execution/joint_states`` and ``/wbmp/execution/tf``
  (the simulated base and, when simulated, objects);
* ``/wbmp/execution/estop`` (``std_msgs/msg/String``): one message at each E-stop of the
  simulation, its record as JSON (when, why, what the robot did, whether it stayed up:
  docs/safety.md);
* ``/wbmp/report`` (``std_msgs/msg/String``, one message): the robot, spec, actions and report
  (with the simulation certificate) as JSON, also stored as MCAP metadata ``wbmp``.

Stamps: the ROS time of a sample at motion time ``t`` [s] is ``stamp + t`` (``stamp`` is the
epoch, 0 by default), rounded to the nanosecond; every message is logged at its stamp.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import IO, Any

import numpy as np

from wbmp.export.columns import (
    MotionColumns,
    execution_columns,
    joint_names,
    object_frame_ids,
    object_names,
    plan_columns,
)
from wbmp.export.msgdefs import schema_text

PLAN_TRAJECTORY_TOPIC = "/wbmp/plan/joint_trajectory"
EXEC_TRAJECTORY_TOPIC = "/wbmp/execution/joint_trajectory"
PLAN_JOINT_STATES_TOPIC = "/joint_states"
EXEC_JOINT_STATES_TOPIC = "/wbmp/execution/joint_states"
PLAN_TF_TOPIC = "/tf"
EXEC_TF_TOPIC = "/wbmp/execution/tf"
REPORT_TOPIC = "/wbmp/report"
ESTOP_TOPIC = "/wbmp/execution/estop"
METADATA_NAME = "wbmp"
WORLD_FRAME = "world"
FALLBACK_BASE_FRAME = "base_link"  # REP 105's name, for a robot this wbmp has no profile of
MAX_STAMP = 2**31 - 1  # [s] builtin_interfaces/Time.sec is an int32
NS_PER_S = 1_000_000_000


@dataclass(frozen=True, kw_only=True)
class BagOptions:
    """How a bag is stamped and framed.

    Attributes:
        stamp: ROS time of the motion's t = 0 [s] (the epoch), >= 0.
        base_frame: tf child frame of the base; None = the robot profile's ``base`` frame
            (its URDF root link: talos ``base_link``, g1 ``pelvis``), ``base_link`` if the robot
            has no built-in profile here.
        world_frame: tf parent frame.
    """

    stamp: float = 0.0
    base_frame: str | None = None
    world_frame: str = WORLD_FRAME


def base_frame_of(robot_name: str) -> str:
    """The base frame of a robot by its built-in profile's ``base`` role, else ``base_link``."""
    from robots import builtin_profiles

    profile = builtin_profiles().get(robot_name)
    frame = profile.frame("base") if profile is not None else None
    return frame or FALLBACK_BASE_FRAME


def stamps_ns(t: np.ndarray, stamp: float) -> np.ndarray:
    """ROS times [ns] of motion times ``t`` [s]: ``round(stamp * 1e9) + round(t * 1e9)``."""
    return int(round(stamp * NS_PER_S)) + np.rint(np.asarray(t, dtype=float) * NS_PER_S).astype(np.int64)


def _time(ns: int) -> dict[str, int]:
    sec, nanosec = divmod(int(ns), NS_PER_S)
    return {"sec": sec, "nanosec": nanosec}


def _header(ns: int, frame_id: str = "") -> dict[str, Any]:
    return {"stamp": _time(ns), "frame_id": frame_id}


def _trajectory(cols: MotionColumns, names: list[str], ns: np.ndarray) -> dict[str, Any]:
    points = []
    for k in range(len(cols.t)):
        points.append({
            "positions": cols.joint_positions[k].tolist(),
            "velocities": cols.joint_velocities[k].tolist(),
            "accelerations": [] if cols.joint_accelerations is None else cols.joint_accelerations[k].tolist(),
            "effort": [] if cols.joint_torques is None else cols.joint_torques[k].tolist(),
            "time_from_start": _time(int(ns[k] - ns[0])),
        })
    return {"header": _header(int(ns[0])), "joint_names": names, "points": points}


def _joint_state(cols: MotionColumns, names: list[str], k: int, ns: int) -> dict[str, Any]:
    return {"header": _header(ns), "name": names, "position": cols.joint_positions[k].tolist(),
            "velocity": cols.joint_velocities[k].tolist(),
            "effort": [] if cols.joint_torques is None else cols.joint_torques[k].tolist()}


def _transform(ns: int, parent: str, child: str, pose: list[float]) -> dict[str, Any]:
    """A ``TransformStamped`` of ``pose`` = x, y, z [m], qx, qy, qz, qw (the child in the parent)."""
    x, y, z, qx, qy, qz, qw = pose
    return {"header": _header(ns, parent), "child_frame_id": child,
            "transform": {"translation": {"x": x, "y": y, "z": z},
                          "rotation": {"x": qx, "y": qy, "z": qz, "w": qw}}}


def _tf(cols: MotionColumns, k: int, ns: int, world: str, base: str,
        object_frames: dict[str, str]) -> dict[str, Any]:
    """The base's transform, then each object's (``cols.object_names`` order) at sample ``k``."""
    transforms = [_transform(ns, world, base, cols.position_base_in_world[k].tolist()
                             + cols.quaternion_base_in_world[k].tolist())]
    if cols.object_pose is not None:
        for i, name in enumerate(cols.object_names):
            transforms.append(_transform(ns, world, object_frames[name], cols.object_pose[k, i].tolist()))
    return {"transforms": transforms}


def bag_document(motion) -> dict[str, Any]:
    """The JSON of ``/wbmp/report``: robot, format version, spec, actions, report."""
    from tasks import spec_to_json

    return {"robot": motion.robot_name, "version": motion.version,
            "spec": json.loads(spec_to_json(motion.plan.spec, indent=None)),
            "actions": motion.actions, "report": motion.report}


def write_bag(fh: IO[bytes], motion, options: BagOptions | None = None) -> None:
    """Write ``motion`` as a ROS 2 MCAP bag to the binary stream ``fh``.

    Raises:
        MotionFileError: the joints cannot be named (see :func:`wbmp.export.columns.joint_names`).
        ValueError: ``options.stamp`` is negative, not finite or past 2**31 - 1 s.
    """
    from mcap_ros2.writer import Writer

    options = options or BagOptions()
    if not (np.isfinite(options.stamp) and 0.0 <= options.stamp):
        raise ValueError(f"stamp must be a time >= 0 [s], got {options.stamp!r}")
    names = joint_names(motion)
    base = options.base_frame or base_frame_of(motion.robot_name)
    world = options.world_frame
    runs: list[tuple[str, MotionColumns]] = [("plan", plan_columns(motion))]
    execution = execution_columns(motion)
    if execution is not None:
        runs.append(("execution", execution))
    ends = [stamps_ns(c.t, options.stamp) for _, c in runs]
    if max(int(e.max()) for e in ends) // NS_PER_S > MAX_STAMP:
        raise ValueError(f"stamp + motion duration passes {MAX_STAMP} s (ROS time is an int32 of seconds)")

    document = json.dumps(bag_document(motion))
    report = motion.report if isinstance(motion.report, dict) else {}
    metadata = {
        "robot": motion.robot_name, "format_version": str(motion.version), "document": document,
        "certificate": json.dumps(report.get("certificate")),
        "stamp": repr(float(options.stamp)), "world_frame": world, "base_frame": base,
        "joint_names": json.dumps(names),
    }
    objects = object_names(motion)
    object_frames = object_frame_ids(objects, taken=(world, base))
    if objects:
        metadata["object_frames"] = json.dumps(object_frames)

    # (log time, order of writing, topic, type, message): written sorted by log time
    messages: list[tuple[int, int, str, str, dict[str, Any]]] = []

    def add(ns: int, topic: str, typ: str, msg: dict[str, Any]) -> None:
        messages.append((int(ns), len(messages), topic, typ, msg))

    epoch = int(stamps_ns(np.zeros(1), options.stamp)[0])
    add(epoch, REPORT_TOPIC, "std_msgs/msg/String", {"data": document})
    certificate = report.get("certificate")
    stops = certificate.get("stops") if isinstance(certificate, dict) else None
    for stop in stops if isinstance(stops, list) else []:
        if isinstance(stop, dict) and isinstance(stop.get("time"), (int, float)):
            stop_ns = int(stamps_ns(np.array([float(stop["time"])]), options.stamp)[0])
            add(stop_ns, ESTOP_TOPIC, "std_msgs/msg/String", {"data": json.dumps(stop)})
    for which, cols in runs:
        ns = stamps_ns(cols.t, options.stamp)
        plan = which == "plan"
        add(int(ns[0]), PLAN_TRAJECTORY_TOPIC if plan else EXEC_TRAJECTORY_TOPIC,
            "trajectory_msgs/msg/JointTrajectory", _trajectory(cols, names, ns))
        for k in range(len(cols.t)):
            add(int(ns[k]), PLAN_JOINT_STATES_TOPIC if plan else EXEC_JOINT_STATES_TOPIC,
                "sensor_msgs/msg/JointState", _joint_state(cols, names, k, int(ns[k])))
            add(int(ns[k]), PLAN_TF_TOPIC if plan else EXEC_TF_TOPIC, "tf2_msgs/msg/TFMessage",
                _tf(cols, k, int(ns[k]), world, base, object_frames))

    writer = Writer(fh)
    schemas = {}
    for _, _, _, typ, _ in messages:
        if typ not in schemas:
            schemas[typ] = writer.register_msgdef(typ, schema_text(typ))
    sequence: dict[str, int] = {}
    for log_ns, _, topic, typ, msg in sorted(messages, key=lambda m: (m[0], m[1])):
        seq = sequence.get(topic, 0)
        sequence[topic] = seq + 1
        writer.write_message(topic, schemas[typ], msg, log_time=log_ns, publish_time=log_ns, sequence=seq)
    writer.add_metadata(METADATA_NAME, metadata)
    writer.finish()
