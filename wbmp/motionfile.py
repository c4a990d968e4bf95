"""The motion file (``.npz``, DESIGN.md section 6) and its JSON/CSV exports.

Keys of the ``.npz`` (``docs/formats.md`` documents them for other tools):

* plan: ``t`` (T,) [s], ``q`` (T, nq) in Pinocchio order (free-flyer quaternion x, y, z, w),
  ``v`` (T, nv), ``a`` (T, nv), ``com`` (T, 3) [m]; ``robot`` (profile name), ``joint_names``
  (actuated joints, Pinocchio order), ``frame_names`` (the contact frames of the spec);
* execution, when simulated: ``exec_t`` (T',) [s], ``exec_q`` (T', nq), ``exec_v`` (T', nv),
  ``exec_tau`` (T', nv - 6) [N m];
* ``spec_json`` (the TaskSpec, which round-trips), ``actions_json`` (the parsed actions when the
  input was a sentence, else ``null``), ``report_json`` (solver stats, constraint report,
  diagnosis, and the caller's entries such as the simulation ``certificate``), ``version``.

Every file is written atomically: to a temporary file in the same directory, then
``os.replace``.
"""

from __future__ import annotations

import csv
import io
import json
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from planner import ConstraintCheck, Plan, SolverStats, SolveStatus
from tasks.serialize import spec_from_json, spec_to_json
from wbmp.errors import CliError, ExitCode

FORMAT_VERSION = 1
EXEC_KEYS = ("exec_t", "exec_q", "exec_v", "exec_tau")


class MotionFileError(CliError):
    """A motion file is missing, unreadable or lacks required keys (exit code 2)."""

    def __init__(self, message: str) -> None:
        super().__init__(message, ExitCode.USAGE)


@dataclass(eq=False)
class MotionFile:
    """A loaded motion file.

    Attributes:
        plan: The plan rebuilt from the arrays, the spec and the report.
        execution_arrays: ``exec_t``, ``exec_q``, ``exec_v``, ``exec_tau`` when simulated (else empty).
        actions: The parsed actions (list of dicts) or None.
        report: The whole report dict (``solver``, ``checks``, ``diagnosis``, ``ok``, and the
            caller's entries such as ``certificate``).
        robot_name: Robot profile name.
        joint_names: Actuated joint names.
        frame_names: Contact frame names.
        version: File format version.
    """

    plan: Plan
    execution_arrays: dict[str, np.ndarray] = field(default_factory=dict)
    actions: list | None = None
    report: dict = field(default_factory=dict)
    robot_name: str = ""
    joint_names: list[str] = field(default_factory=list)
    frame_names: list[str] = field(default_factory=list)
    version: int = FORMAT_VERSION


def plan_report(plan: Plan) -> dict[str, Any]:
    """Solver stats, constraint report and diagnosis of a plan as a JSON-friendly dict."""
    s = plan.stats
    return {
        "solver": {
            "status": s.status.name, "message": s.status.value, "iterations": s.iterations,
            "build_time": s.build_time, "solve_time": s.solve_time, "cache": s.cache,
            "objective": s.objective if np.isfinite(s.objective) else None,
            "n_variables": s.n_variables, "n_constraints": s.n_constraints, "backend": s.backend,
            "raw_status": s.raw_status,
        },
        "checks": [
            {"name": c.name, "violation": c.violation, "tolerance": c.tolerance if np.isfinite(c.tolerance) else None,
             "unit": c.unit, "time": c.time, "ok": c.ok}
            for c in plan.checks
        ],
        "diagnosis": plan.diagnosis,
        "ok": plan.ok,
    }


def _contact_frames(plan: Plan, robot) -> list[str]:
    names = []
    for frame in plan.spec.contact_frames():
        try:
            names.append(robot.model.frames[robot.frame_id(frame)].name)
        except Exception:  # noqa: BLE001 - a frame the robot lacks: keep the spec's name
            names.append(frame)
    return names


def motion_arrays(plan: Plan, robot, *, execution=None, actions=None, report=None) -> dict[str, Any]:
    """Every key of the motion file, as numpy arrays and JSON strings."""
    # the caller's report (pipeline timings, simulation certificate...) plus the plan's own
    # solver stats, constraint report and diagnosis (which win: load_motion rebuilds from them)
    full_report = {**(report or {}), **plan_report(plan)}
    out: dict[str, Any] = {
        "t": np.asarray(plan.t, dtype=float),
        "q": np.asarray(plan.q, dtype=float),
        "v": np.asarray(plan.v, dtype=float),
        "a": np.asarray(plan.a, dtype=float),
        "com": np.asarray(plan.com, dtype=float),
        "robot": np.array(plan.robot if robot is None else robot.name),
        "joint_names": np.array(list(robot.joint_names) if robot is not None else [], dtype=str),
        "frame_names": np.array(_contact_frames(plan, robot) if robot is not None else list(plan.spec.contact_frames()),
                                dtype=str),
        "spec_json": np.array(spec_to_json(plan.spec, indent=None)),
        "actions_json": np.array(json.dumps(_plain_actions(actions))),
        "report_json": np.array(json.dumps(full_report, default=_json_default)),
        "version": np.array(FORMAT_VERSION),
    }
    for name, arr in plan.forces.items():
        out[f"force_{name}"] = np.asarray(arr, dtype=float)
    if execution is not None:
        for key, attr in zip(EXEC_KEYS, ("t", "q", "v", "tau"), strict=True):
            out[key] = np.asarray(getattr(execution, attr), dtype=float)
    return out


def _plain_actions(actions) -> list | None:
    if actions is None:
        return None
    return [a.to_dict() if hasattr(a, "to_dict") else a for a in actions]


def _json_default(obj):
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if hasattr(obj, "value"):
        return obj.value
    return str(obj)


def _atomic_write(path: Path, write) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            write(fh)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def save_motion(path: str | Path, plan: Plan, robot, *, execution=None, actions=None, report=None) -> Path:
    """Write the motion file atomically.

    Args:
        path: Output ``.npz`` path.
        plan: The plan.
        robot: The robot it was planned for (joint and frame names).
        execution: Anything with ``t``, ``q``, ``v``, ``tau`` arrays (a simulation), or None.
        actions: The parsed actions (Action objects or dicts), or None.
        report: Extra report entries (timings, the simulation ``certificate``...), merged with
            the plan's ``solver``, ``checks``, ``diagnosis`` and ``ok`` entries.

    Returns:
        The path written.
    """
    path = Path(path)
    arrays = motion_arrays(plan, robot, execution=execution, actions=actions, report=report)
    _atomic_write(path, lambda fh: np.savez_compressed(fh, **arrays))
    return path


def load_motion(path: str | Path) -> MotionFile:
    """Read a motion file written by :func:`save_motion`.

    Raises:
        MotionFileError: the file is missing, not an npz, or lacks required keys.
    """
    path = Path(path)
    if not path.is_file():
        raise MotionFileError(f"motion file {str(path)!r} does not exist")
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files}
    except (OSError, ValueError) as e:
        raise MotionFileError(f"{path}: not a motion file ({e})") from None
    missing = [k for k in ("t", "q", "v", "com", "robot", "spec_json", "report_json") if k not in arrays]
    if missing:
        raise MotionFileError(f"{path}: missing key(s) {missing}")
    return motion_from_arrays(arrays, source=str(path))


def motion_from_arrays(arrays: dict[str, Any], *, source: str = "") -> MotionFile:
    """Rebuild a :class:`MotionFile` from the key -> array mapping."""
    spec = spec_from_json(str(arrays["spec_json"]))
    report = json.loads(str(arrays["report_json"]))
    solver = report.get("solver", {})
    stats = SolverStats(
        status=SolveStatus[solver.get("status", "NOT_RUN")],
        iterations=int(solver.get("iterations", 0)),
        build_time=float(solver.get("build_time", 0.0)),
        solve_time=float(solver.get("solve_time", 0.0)),
        cache=str(solver.get("cache", "built")),
        objective=float("nan") if solver.get("objective") is None else float(solver["objective"]),
        n_variables=int(solver.get("n_variables", 0)),
        n_constraints=int(solver.get("n_constraints", 0)),
        backend=str(solver.get("backend", "ipopt")),
        raw_status=str(solver.get("raw_status", "")),
    )
    checks = tuple(
        ConstraintCheck(name=c["name"], violation=float(c["violation"]),
                        tolerance=float("inf") if c.get("tolerance") is None else float(c["tolerance"]),
                        unit=c["unit"], time=float(c["time"]))
        for c in report.get("checks", [])
    )
    v = np.asarray(arrays["v"], dtype=float)
    a = np.asarray(arrays["a"], dtype=float) if "a" in arrays else np.zeros_like(v)
    forces = {k[len("force_"):]: np.asarray(arr, dtype=float) for k, arr in arrays.items() if k.startswith("force_")}
    robot_name = str(arrays["robot"])
    plan = Plan(robot=robot_name, spec=spec, t=np.asarray(arrays["t"], dtype=float),
                q=np.asarray(arrays["q"], dtype=float), v=v, a=a, com=np.asarray(arrays["com"], dtype=float),
                forces=forces, stats=stats, checks=checks, diagnosis=str(report.get("diagnosis", "")))
    actions_text = str(arrays.get("actions_json", "null"))
    return MotionFile(
        plan=plan,
        execution_arrays={k: np.asarray(arrays[k], dtype=float) for k in EXEC_KEYS if k in arrays},
        actions=json.loads(actions_text),
        report=report,
        robot_name=robot_name,
        joint_names=[str(x) for x in np.asarray(arrays.get("joint_names", []))],
        frame_names=[str(x) for x in np.asarray(arrays.get("frame_names", []))],
        version=int(arrays.get("version", FORMAT_VERSION)),
    )


EXPORT_FORMATS = ("json", "csv", "npz")


def export_motion(motion: MotionFile | str | Path, path: str | Path, fmt: str | None = None) -> list[Path]:
    """Export a motion file to JSON, CSV or npz (format from ``fmt`` or the suffix).

    JSON holds every key of the npz (arrays as nested lists; ``spec``, ``actions``, ``report``
    as objects). CSV holds the plan as one row per knot (``t``, ``q_*``, ``v_*``, ``com_*``)
    after ``#``-comment lines with the robot, the spec, the actions and the report as JSON;
    the execution, when present, goes to a sibling ``<name>.exec.csv`` (``t``, ``q_*``, ``v_*``,
    ``tau_*``).

    Returns:
        The paths written.

    Raises:
        MotionFileError: unknown format.
    """
    if not isinstance(motion, MotionFile):
        motion = load_motion(motion)
    path = Path(path)
    fmt = (fmt or path.suffix.lstrip(".")).lower()
    if fmt not in EXPORT_FORMATS:
        raise MotionFileError(f"unknown export format {fmt!r}; use one of {', '.join(EXPORT_FORMATS)}")
    arrays = _arrays_of(motion)
    if fmt == "npz":
        _atomic_write(path, lambda fh: np.savez_compressed(fh, **arrays))
        return [path]
    if fmt == "json":
        doc: dict[str, Any] = {}
        for k, val in arrays.items():
            if k in ("spec_json", "actions_json", "report_json"):
                doc[k[: -len("_json")]] = json.loads(str(val))
            else:
                val = np.asarray(val)
                doc[k] = val.tolist() if val.ndim else val.item()
        text = json.dumps(doc, default=_json_default)
        _atomic_write(path, lambda fh: fh.write(text.encode("utf-8")))
        return [path]
    written = [path]
    plan = motion.plan
    names = _coordinate_names(motion, plan.q.shape[1], plan.v.shape[1])
    header = ["t", *[f"q_{n}" for n in names[0]], *[f"v_{n}" for n in names[1]], "com_x", "com_y", "com_z"]
    rows = np.hstack([plan.t[:, None], plan.q, plan.v, plan.com])
    meta = {"robot": motion.robot_name, "version": motion.version,
            "spec": json.loads(str(arrays["spec_json"])), "actions": motion.actions, "report": motion.report}
    _atomic_write(path, lambda fh: fh.write(_csv_text(header, rows, meta).encode("utf-8")))
    ex = motion.execution_arrays
    if ex:
        exec_path = path.with_name(path.stem + ".exec.csv")
        n_tau = ex["exec_tau"].shape[1] if "exec_tau" in ex else 0
        exec_header = ["t", *[f"q_{n}" for n in names[0]], *[f"v_{n}" for n in names[1]],
                       *[f"tau_{n}" for n in names[1][6:6 + n_tau]]]
        parts = [ex["exec_t"][:, None], ex["exec_q"], ex["exec_v"]] + ([ex["exec_tau"]] if n_tau else [])
        exec_rows = np.hstack(parts)
        _atomic_write(exec_path, lambda fh: fh.write(_csv_text(exec_header, exec_rows, {}).encode("utf-8")))
        written.append(exec_path)
    return written


def _arrays_of(motion: MotionFile) -> dict[str, Any]:
    plan = motion.plan
    out: dict[str, Any] = {
        "t": plan.t, "q": plan.q, "v": plan.v, "a": plan.a, "com": plan.com,
        "robot": np.array(motion.robot_name), "joint_names": np.array(motion.joint_names, dtype=str),
        "frame_names": np.array(motion.frame_names, dtype=str),
        "spec_json": np.array(spec_to_json(plan.spec, indent=None)),
        "actions_json": np.array(json.dumps(motion.actions)),
        "report_json": np.array(json.dumps(motion.report, default=_json_default)),
        "version": np.array(motion.version),
    }
    for name, arr in plan.forces.items():
        out[f"force_{name}"] = arr
    out.update(motion.execution_arrays)
    return out


def _coordinate_names(motion: MotionFile, nq: int, nv: int) -> tuple[list[str], list[str]]:
    joints = list(motion.joint_names)
    if len(joints) != nv - 6:
        joints = [f"joint{i}" for i in range(nv - 6)]
    q_names = ["base_x", "base_y", "base_z", "base_qx", "base_qy", "base_qz", "base_qw", *joints]
    v_names = ["base_vx", "base_vy", "base_vz", "base_wx", "base_wy", "base_wz", *joints]
    return q_names[:nq], v_names[:nv]


def _csv_text(header: list[str], rows: np.ndarray, meta: dict[str, Any]) -> str:
    buf = io.StringIO()
    for key, val in meta.items():
        buf.write(f"# {key}: {json.dumps(val, default=_json_default)}\n")
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(header)
    for row in rows:
        writer.writerow([repr(float(x)) for x in row])
    return buf.getvalue()
