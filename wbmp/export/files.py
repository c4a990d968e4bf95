"""The motion file's exports (``wbmp export``, docs/export.md): JSON and CSV hold the file's keys
as they are (:func:`export_motion`); MCAP (:mod:`wbmp.export.rosbag`), the tracker file
(:mod:`wbmp.export.tracker`) and the LAFAN1 CSV (:mod:`wbmp.export.lafan`) convert."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path
from typing import Any

import numpy as np

from viz import Staging
from wbmp.errors import MotionFileError
from wbmp.motionfile import MotionFile, json_default, load_motion, record_arrays

#: the export formats (``wbmp export --format``)
EXPORT_FORMATS = ("json", "csv", "npz", "mcap", "tracker", "lafan")
#: file suffix -> the formats a file of that suffix may hold
SUFFIX_FORMATS = {"json": ("json",), "csv": ("csv", "lafan"), "npz": ("npz", "tracker"), "mcap": ("mcap",)}


def export_motion(motion: MotionFile | str | Path, path: str | Path, fmt: str | None = None, *,
                  staging: Staging | None = None, stamp: float = 0.0, base_frame: str | None = None,
                  fps: float | None = None, source: str = "plan") -> list[Path]:
    """Export a motion file to JSON, CSV, npz, a ROS 2 bag (MCAP) or a tracker file (format from
    ``fmt`` or the suffix; ``docs/export.md`` states each format's conventions).

    JSON holds every key of the npz (arrays as nested lists; ``spec``, ``actions``, ``report``
    as objects). CSV holds the plan as one row per knot (``t``, ``q_*``, ``v_*``, ``com_*``)
    after ``#``-comment lines with the robot, the spec, the actions and the report as JSON;
    the execution, when present, goes to a sibling ``<name>.exec.csv`` (``t``, ``q_*``, ``v_*``,
    ``tau_*``). Every file is made in full before any is renamed into place: the CSV and its
    ``.exec.csv`` appear together or not at all. MCAP: :func:`wbmp.export.write_bag`; tracker:
    :func:`wbmp.export.tracker_arrays` (an ``.npz``).

    Args:
        motion: A loaded motion or the path of a motion file.
        path: Output file.
        fmt: ``json``, ``csv``, ``npz``, ``mcap``, ``tracker`` or ``lafan`` (the Unitree/LAFAN1
            CSV, :mod:`wbmp.export.lafan`); None = from ``path``'s suffix
            (``.npz`` is the motion-file copy).
        staging: Stage the files there (renamed by ``staging.commit()``) instead of writing now.
        stamp: MCAP: ROS time [s] of the motion's t = 0.
        base_frame: MCAP and tracker: the base's frame name; None = the robot profile's.
        fps: Tracker and lafan: sample rate [Hz]; None = :data:`wbmp.export.DEFAULT_FPS` (tracker),
            :data:`wbmp.export.lafan.LAFAN_FPS` (lafan).
        source: Tracker and lafan: ``plan`` or ``execution``.

    Returns:
        The paths written.

    Raises:
        MotionFileError: unknown format or a suffix that contradicts ``fmt``.
        CliError: (exit 2) joints that MCAP and tracker cannot name, or a tracker export of an
            execution the file lacks.
        ValueError: a bad ``stamp``, ``fps`` or ``source``.
    """
    if not isinstance(motion, MotionFile):
        motion = load_motion(motion)
    path = Path(path)
    fmt = export_format(path, fmt)
    if staging is None:
        with Staging() as own:
            written = export_motion(motion, path, fmt, staging=own, stamp=stamp, base_frame=base_frame, fps=fps,
                                    source=source)
            own.commit()
        return written
    if fmt == "mcap":
        from wbmp.export import BagOptions, joint_names, write_bag

        joint_names(motion)  # refused before a file is opened
        options = BagOptions(stamp=stamp, base_frame=base_frame)
        staging.add(path, lambda fh: write_bag(fh, motion, options))
        return [path]
    if fmt == "tracker":
        from wbmp.export import DEFAULT_FPS, tracker_arrays

        tracker = tracker_arrays(motion, DEFAULT_FPS if fps is None else fps, source, base_frame)
        staging.add(path, lambda fh: np.savez_compressed(fh, **tracker))
        return [path]
    if fmt == "lafan":
        from wbmp.export.lafan import LAFAN_FPS, lafan_rows, write_lafan

        rows, _ = lafan_rows(motion, LAFAN_FPS if fps is None else fps, source)
        staging.add(path, lambda fh: write_lafan(fh, rows))
        return [path]
    arrays = record_arrays(motion)
    if fmt == "npz":
        staging.add(path, lambda fh: np.savez_compressed(fh, **arrays))
        return [path]
    if fmt == "json":
        data = _json_bytes(arrays)
        staging.add(path, lambda fh: fh.write(data))
        return [path]
    return _stage_csv(motion, arrays, path, staging)


def _json_bytes(arrays: dict[str, Any]) -> bytes:
    """The JSON export: every key of the npz, arrays as nested lists, the JSON members as objects."""
    doc: dict[str, Any] = {}
    for k, val in arrays.items():
        if k in ("spec_json", "actions_json", "report_json"):
            doc[k[: -len("_json")]] = json.loads(str(val))
        else:
            val = np.asarray(val)
            doc[k] = val.tolist() if val.ndim else val.item()
    return json.dumps(doc, default=json_default).encode("utf-8")


def _stage_csv(motion: MotionFile, arrays: dict[str, Any], path: Path, staging: Staging) -> list[Path]:
    """The CSV export: the plan's knots in ``path``, the execution's ticks in its ``.exec.csv``."""
    written = [path]
    plan = motion.plan
    names = csv_columns(motion)
    header = ["t", *[f"q_{n}" for n in names[0]], *[f"v_{n}" for n in names[1]], "com_x", "com_y", "com_z",
              *_object_columns(list(motion.objects))]
    rows = np.hstack([plan.t[:, None], plan.q, plan.v, plan.com, *motion.objects.values()])
    meta = {"robot": motion.robot_name, "version": motion.version,
            "spec": json.loads(str(arrays["spec_json"])), "actions": motion.actions, "report": motion.report}
    text = _csv_text(header, rows, meta).encode("utf-8")
    staging.add(path, lambda fh: fh.write(text))
    ex = motion.execution
    if ex is not None:
        exec_path = exec_csv_path(path)
        n_tau = ex.tau.shape[1] if ex.tau is not None else 0
        exec_header = ["t", *[f"q_{n}" for n in names[0]], *[f"v_{n}" for n in names[1]],
                       *[f"tau_{n}" for n in names[1][6:6 + n_tau]]]
        parts = [ex.t[:, None], ex.q, ex.v] + ([ex.tau] if ex.tau is not None and n_tau else [])
        if poses := ex.object_poses():
            exec_header += _object_columns(list(poses))
            parts += list(poses.values())
        exec_text = _csv_text(exec_header, np.hstack(parts), {}).encode("utf-8")
        staging.add(exec_path, lambda fh: fh.write(exec_text))
        written.append(exec_path)
    return written


def _object_columns(names: list[str]) -> list[str]:
    """CSV columns of the objects' poses: ``object_<name>_x .. _qw`` (the name as in ``object_names``)."""
    return [f"object_{n}_{c}" for n in names for c in ("x", "y", "z", "qx", "qy", "qz", "qw")]


def exec_csv_path(path: str | Path) -> Path:
    """Where a CSV export puts the simulated execution: ``<name>.exec.csv`` beside ``path``."""
    path = Path(path)
    return path.with_name(path.stem + ".exec.csv")


def export_format(path: str | Path, fmt: str | None) -> str:
    """The export format for ``path``: ``fmt`` if given (it must not contradict the suffix),
    else the suffix (``.json``, ``.csv``, ``.npz``, ``.mcap``).

    Raises:
        MotionFileError: unknown format, a suffix naming another format, or no usable suffix.
    """
    suffix = Path(path).suffix.lstrip(".").lower()
    if fmt is not None:
        fmt = fmt.lower()
        if fmt not in EXPORT_FORMATS:
            raise MotionFileError(f"unknown export format {fmt!r}; use one of {', '.join(EXPORT_FORMATS)}")
        if suffix in SUFFIX_FORMATS and fmt not in SUFFIX_FORMATS[suffix]:
            raise MotionFileError(f"{str(path)!r} ends in .{suffix} but the format is {fmt}")
        return fmt
    if suffix not in SUFFIX_FORMATS:
        shown = f".{suffix}" if suffix else "no suffix"
        raise MotionFileError(f"unknown export format for {str(path)!r} ({shown}); name it .json, .csv or .mcap, "
                              "or give the format")
    return SUFFIX_FORMATS[suffix][0]


def csv_columns(motion: MotionFile) -> tuple[list[str], list[str]]:
    """The names of the q and v columns of the CSV export (without the ``q_``/``v_`` prefix):
    ``base_x, base_y, base_z, base_qx, base_qy, base_qz, base_qw, <joints>`` and
    ``base_vx, base_vy, base_vz, base_wx, base_wy, base_wz, <joints>`` (``joint<i>`` when the file
    names no joints or not one per velocity column)."""
    nq, nv = motion.plan.q.shape[1], motion.plan.v.shape[1]
    joints = list(motion.joint_names)
    if len(joints) != nv - 6:
        joints = [f"joint{i}" for i in range(nv - 6)]
    q_names = ["base_x", "base_y", "base_z", "base_qx", "base_qy", "base_qz", "base_qw", *joints]
    v_names = ["base_vx", "base_vy", "base_vz", "base_wx", "base_wy", "base_wz", *joints]
    q_names += [f"q{i}" for i in range(len(q_names), nq)]  # a joint with more than one position coordinate
    return q_names[:nq], v_names[:nv]


def _csv_text(header: list[str], rows: np.ndarray, meta: dict[str, Any]) -> str:
    buf = io.StringIO()
    for key, val in meta.items():
        buf.write(f"# {key}: {json.dumps(val, default=json_default)}\n")
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(header)
    for row in rows:
        writer.writerow([repr(float(x)) for x in row])
    return buf.getvalue()
