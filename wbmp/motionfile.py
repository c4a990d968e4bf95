"""The motion file (``.npz``, docs/formats.md): the typed record (a :class:`MotionFile`: the plan,
the :class:`sim.Execution`, the actions, the report) to and from its arrays, read and written
(the exports: :mod:`wbmp.export.files`).

Keys of the ``.npz`` (``docs/formats.md`` documents them for other tools):

* plan: ``t`` (T,) [s], ``q`` (T, nq) in Pinocchio order (free-flyer quaternion x, y, z, w),
  ``v`` (T, nv), ``a`` (T, nv), ``com`` (T, 3) [m]; ``robot`` (profile name), ``joint_names``
  (actuated joints, Pinocchio order), ``frame_names`` (the contact frames of the spec);
* execution, when simulated: ``exec_t`` (T',) [s], ``exec_q`` (T', nq), ``exec_v`` (T', nv),
  ``exec_tau`` (T', nv - 6) [N m];
* movable scene objects, when the spec's scene has any: ``object_names`` (k,), ``object_pose``
  (T, k, 7) where the plan puts them, and, when simulated, ``exec_object_pose`` (T', k, 7) where
  the simulation moved them; a pose is the centre [m] then a quaternion (x, y, z, w);
* ``spec_json`` (the TaskSpec, which round-trips), ``actions_json`` (the parsed actions when the
  input was a sentence, else ``null``), ``report_json`` (solver stats, constraint report,
  diagnosis, and the caller's entries such as the simulation ``certificate``), ``version``.

Every file is written atomically through :mod:`viz.files` (a temporary file beside the target,
renamed at the end; a new file gets ``0o666 & ~umask``, a replaced one keeps its mode).
:func:`load_motion` validates every key it reads (zip structure, dtypes, shapes, finite
numbers, the JSON entries) and refuses a damaged file with a one-line :class:`MotionFileError`
naming the file and the key; it never unpickles anything.
"""

from __future__ import annotations

import io
import json
import os
import stat
import struct
import zipfile
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

import numpy as np

from planner import Check, CheckKind, Plan, SolverStats, SolveStatus
from robots import LIMITS, FileTooLarge, open_regular
from sim import Certificate, Event, Execution
from tasks import TaskError, spec_from_json, spec_to_json
from viz import Staging, atomic_write
from wbmp.errors import ExitCode, MotionFileError

FORMAT_VERSION = 1
EXEC_KEYS = ("exec_t", "exec_q", "exec_v", "exec_tau")
REQUIRED_KEYS = ("t", "q", "v", "com", "robot", "spec_json", "report_json")
MAX_MOTION_BYTES = 1 << 30  # [bytes] of arrays (uncompressed) a motion file may declare
# [s] a motion file's times lie in [-MAX_MOTION_SECONDS, MAX_MOTION_SECONDS] (a plan starts at 0 s):
# the exports and the HTML replay sample a motion's span, and nanosecond stamps must fit 64 bits
MAX_MOTION_SECONDS = 3600.0
_NPY_MAGIC = b"\x93NUMPY"


@dataclass(eq=False)
class MotionFile:
    """A loaded motion file.

    Attributes:
        plan: The plan rebuilt from the arrays, the spec and the report.
        execution: The simulated execution when the file has one (``exec_t``, ``exec_q``,
            ``exec_v``, ``exec_tau``, ``exec_object_pose``; its certificate and events from the
            report), else None.
        actions: The parsed actions (list of dicts) or None.
        report: The whole report dict (``solver``, ``checks``, ``diagnosis``, ``ok``, and the
            caller's entries such as ``certificate``).
        robot_name: Robot profile name.
        joint_names: Actuated joint names.
        frame_names: Contact frame names.
        version: File format version.
        objects: Movable scene object -> its planned pose at each knot (T, 7) (``object_pose``;
            empty in files written before it existed).
    """

    plan: Plan
    execution: Execution | None = None
    actions: list | None = None
    report: dict = field(default_factory=dict)
    robot_name: str = ""
    joint_names: list[str] = field(default_factory=list)
    frame_names: list[str] = field(default_factory=list)
    version: int = FORMAT_VERSION
    objects: dict[str, np.ndarray] = field(default_factory=dict)


def plan_report(plan: Plan) -> dict[str, Any]:
    """Solver stats, constraint report and diagnosis of a plan as a JSON-friendly dict."""
    s = plan.stats
    return {
        "solver": {
            "status": s.status.name, "message": s.status.value, "iterations": s.iterations,
            "build_time": s.build_time, "solve_time": s.solve_time, "cache": s.cache,
            "objective": s.objective if np.isfinite(s.objective) else None,
            "n_variables": s.n_variables, "n_constraints": s.n_constraints, "backend": s.backend,
            "raw_status": s.raw_status, "seed": s.seed,
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
    if execution is not None:  # the execution's verdict and events, as its report states them
        full_report.update(execution_report(execution))
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
        "report_json": np.array(json.dumps(full_report, default=json_default)),
        "version": np.array(FORMAT_VERSION),
    }
    for name, arr in plan.forces.items():
        out[f"force_{name}"] = np.asarray(arr, dtype=float)
    if execution is not None:
        out["exec_t"] = np.asarray(execution.t, dtype=float)
        out["exec_q"] = np.asarray(execution.q, dtype=float)
        out["exec_v"] = np.asarray(execution.v, dtype=float)
        if execution.tau is not None:
            out["exec_tau"] = np.asarray(execution.tau, dtype=float)
    out.update(object_arrays(plan, robot, execution))
    return out


def execution_report(execution: Execution) -> dict[str, Any]:
    """The report entries of an execution: its ``certificate`` (when it has one) and its
    ``events`` (when there are any); :func:`load_motion` reads them back into the execution."""
    out: dict[str, Any] = {}
    if execution.certificate is not None:
        out["certificate"] = execution.certificate.to_dict()
    if execution.events:
        out["events"] = [e.to_dict() for e in execution.events]
    return out


def events_from_report(records: Any) -> tuple[Event, ...]:
    """The events a report stores (:meth:`sim.Event.to_dict`); entries that are not one are skipped."""
    events = [Event.from_dict(e) for e in records] if isinstance(records, list) else []
    return tuple(e for e in events if e is not None)


def object_arrays(plan: Plan, robot, execution=None) -> dict[str, np.ndarray]:
    """``object_names``, ``object_pose`` (planned: :func:`viz.motion.planned_object_poses`; needs the
    robot) and ``exec_object_pose`` (the simulation's, when ``execution`` has them) of the movable
    objects of the plan's scene; empty when it has none."""
    from viz import motion as vm

    scene = plan.spec.scene
    names = [o.name for o in scene.objects if o.movable] if scene is not None else []
    if not names:
        return {}
    out: dict[str, np.ndarray] = {"object_names": np.array(names, dtype=str)}
    if robot is not None:
        planned = vm.planned_object_poses(robot, plan.spec, plan.t, plan.q)
        out["object_pose"] = np.stack([planned[n] for n in names], axis=1)
    if execution is not None:
        executed = execution.object_poses()
        if set(executed) == set(names):
            out["exec_object_pose"] = np.stack([executed[n] for n in names], axis=1)
    return out


def _plain_actions(actions) -> list | None:
    if actions is None:
        return None
    return [a.to_dict() if hasattr(a, "to_dict") else a for a in actions]


def json_default(obj):
    """``json.dumps``'s ``default`` for the reports: numpy scalars and arrays as numbers and lists,
    enums by their value, anything else by its text."""
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if hasattr(obj, "value"):
        return obj.value
    return str(obj)


def save_motion(path: str | Path, plan: Plan, robot, *, execution=None, actions=None, report=None,
                staging: Staging | None = None) -> Path:
    """Write the motion file atomically.

    Args:
        path: Output ``.npz`` path.
        plan: The plan.
        robot: The robot it was planned for (joint and frame names).
        execution: The simulated execution, or None; its certificate and events go into the report.
        actions: The parsed actions (Action objects or dicts), or None.
        report: Extra report entries (timings, the simulation ``certificate``...), merged with
            the plan's ``solver``, ``checks``, ``diagnosis`` and ``ok`` entries.
        staging: Stage the file there (renamed by ``staging.commit()`` with the command's
            other outputs) instead of writing it now.

    Returns:
        The path written.
    """
    path = Path(path)
    arrays = motion_arrays(plan, robot, execution=execution, actions=actions, report=report)
    _write(path, lambda fh: np.savez_compressed(fh, **arrays), staging)
    return path


STORE_RATIO = 0.9  # a member whose first SAMPLE_BYTES deflate to more than this fraction is stored
SAMPLE_BYTES = 1 << 18


def savez_fast(fh: Any, arrays: dict[str, Any]) -> None:
    """``np.savez_compressed`` at zlib level 1 (what ``--out`` is written with: ~25 % less CPU than
    level 6, and the file a fraction of a percent larger), but an array that hardly compresses is
    stored as it is (its first :data:`SAMPLE_BYTES` deflate to more than :data:`STORE_RATIO`): a
    1 kHz execution's joint positions, velocities and torques shrink by 4 to 7 % and their
    inflating was 0.3 s of the 0.6 s a repeated kitchen request took from the motion cache."""
    with zipfile.ZipFile(fh, "w", compression=zipfile.ZIP_DEFLATED, compresslevel=1) as zf:
        for key, value in arrays.items():
            array = np.asanyarray(value)
            sample = array.reshape(-1)[: SAMPLE_BYTES // max(1, array.itemsize)].tobytes() if array.dtype.kind in "fc" else b""
            dense = len(sample) >= 1 << 12 and len(zlib.compress(sample, 1)) > STORE_RATIO * len(sample)
            zf.compression = zipfile.ZIP_STORED if dense else zipfile.ZIP_DEFLATED
            with zf.open(f"{key}.npy", "w", force_zip64=True) as member:
                np.lib.format.write_array(member, array, allow_pickle=False)


def npz_bytes(arrays: dict[str, Any]) -> bytes:
    """The ``.npz`` of ``arrays`` as :func:`savez_fast` writes it, in memory."""
    buf = io.BytesIO()
    savez_fast(buf, arrays)
    return buf.getvalue()


_LOCAL = struct.Struct("<IHHHHHIIIHH")  # a zip local file header (30 bytes)
_CENTRAL = struct.Struct("<IHHHHHHIIIHHHHHII")  # a central directory record (46 bytes)
_END = struct.Struct("<IHHHHIIH")  # the end of central directory record (22 bytes)


def npz_replacing(source: bytes, replaced: dict[str, Any]) -> bytes | None:
    """The ``.npz`` ``source`` with the arrays ``replaced`` (key -> array) written anew and every
    other member copied byte for byte (its compressed data is not touched: a cached motion's
    ``--out`` costs a copy, not a recompression). None when ``source`` is not a plain zip this
    can copy (zip64, encrypted, streamed members): the caller writes the file the slow way."""
    try:
        infos = zipfile.ZipFile(io.BytesIO(source)).infolist()
    except (zipfile.BadZipFile, ValueError, OSError):
        return None
    names = {f"{key}.npy" for key in replaced}
    out = io.BytesIO()
    central = []

    def member(name: str, method: int, crc: int, csize: int, usize: int, dostime: int, dosdate: int,
               payload: bytes) -> None:
        raw = name.encode("ascii")
        central.append(_CENTRAL.pack(0x02014B50, 20, 20, 0, method, dostime, dosdate, crc, csize, usize,
                                     len(raw), 0, 0, 0, 0, 0, out.tell()) + raw)
        out.write(_LOCAL.pack(0x04034B50, 20, 0, method, dostime, dosdate, crc, csize, usize, len(raw), 0) + raw)
        out.write(payload)

    for info in infos:
        if info.filename in names:
            continue
        if (info.flag_bits & 0x09 or info.compress_type not in (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED)
                or not info.filename.isascii() or max(info.compress_size, info.file_size, info.header_offset) >= 1 << 31):
            return None
        head = source[info.header_offset:info.header_offset + _LOCAL.size]
        if len(head) != _LOCAL.size or head[:4] != b"PK\x03\x04":
            return None
        fields = _LOCAL.unpack(head)
        start = info.header_offset + _LOCAL.size + fields[9] + fields[10]
        payload = source[start:start + info.compress_size]
        if len(payload) != info.compress_size:
            return None
        y, mo, d, h, mi, sec = info.date_time
        member(info.filename, info.compress_type, info.CRC, info.compress_size, info.file_size,
               (h << 11) | (mi << 5) | (sec // 2), ((y - 1980) << 9) | (mo << 5) | d, payload)
    for key, value in replaced.items():
        buf = io.BytesIO()
        np.lib.format.write_array(buf, np.asanyarray(value), allow_pickle=False)
        data = buf.getvalue()
        packer = zlib.compressobj(6, zlib.DEFLATED, -15)
        payload = packer.compress(data) + packer.flush()
        member(f"{key}.npy", zipfile.ZIP_DEFLATED, zlib.crc32(data), len(payload), len(data), 0, (1 << 5) | 1,
               payload)
    start = out.tell()
    for record in central:
        out.write(record)
    out.write(_END.pack(0x06054B50, 0, 0, len(central), len(central), out.tell() - start, start, 0))
    return out.getvalue()


def _write(path: Path, write, staging: Staging | None) -> Path:
    if staging is None:
        return atomic_write(path, write)
    return staging.add(path, write)


def load_motion(path: str | Path) -> MotionFile:
    """Read and validate a motion file written by :func:`save_motion`.

    Every key is checked before it is used: the file is a regular, non-empty zip archive of
    ``.npy`` members (never a pickle or an object array), the required keys are present, the
    arrays have the documented dtypes and shapes (``q`` (T, nq), ``v`` (T, nv)... with one T),
    times increase, numbers are finite, and ``spec_json``/``report_json``/``actions_json`` hold
    what :func:`save_motion` writes. Whether the robot exists and matches the arrays is checked by
    :func:`check_robot` (it needs the robot model).

    Raises:
        MotionFileError: one line naming the file and the bad key (exit code 2).
    """
    path = Path(path)
    shown = repr(str(path))
    arrays = _read_npz(path, shown)
    return motion_from_arrays(arrays, source=str(path))


def missing_motion_file(path: str | Path) -> MotionFileError:
    """The error of a motion file that does not exist."""
    return MotionFileError(f"motion file {str(path)!r} does not exist (write one with `wbmp solve ... --out "
                           f"{path}`)")


def check_motion_exists(path: str | Path) -> None:
    """Refuse a motion file that does not exist before the outputs are checked (a missing input
    must not be reported as a missing output folder); everything else is checked when it is read."""
    if not os.path.lexists(path):
        raise missing_motion_file(path)


def _fail(shown: str, why: str) -> MotionFileError:
    return MotionFileError(f"motion file {shown}: {why}")


def _read_npz(path: Path, shown: str) -> dict[str, np.ndarray]:
    """The arrays of an ``.npz``, read member by member with every header checked first."""
    try:
        st = path.stat()
    except FileNotFoundError:
        raise missing_motion_file(path) from None
    except OSError as e:
        raise _fail(shown, f"cannot read it: {e.strerror or e}") from None
    if stat.S_ISDIR(st.st_mode):
        raise _fail(shown, "is a directory, not a motion file (.npz)")
    if not stat.S_ISREG(st.st_mode):
        raise _fail(shown, "not a regular file; give a motion file (.npz) written by `wbmp solve --out`")
    if st.st_size == 0:
        raise _fail(shown, "is empty (0 bytes), not a motion file")
    try:  # replaced by a FIFO or a device since the stat: refused, never waited on
        fh = open_regular(path, "motion")
    except FileTooLarge:
        raise _fail(shown, f"is larger than the {LIMITS['motion'] >> 20} MiB a motion file may have") from None
    except OSError as e:
        raise _fail(shown, f"cannot read it: {e.strerror or e}") from None
    with fh:
        try:
            head = fh.read(8)
            fh.seek(0)
        except OSError as e:
            raise _fail(shown, f"cannot read it: {e.strerror or e}") from None
        if head.startswith(_NPY_MAGIC):
            raise _fail(shown, "is a single numpy array (.npy), not a motion file (.npz archive of named arrays)")
        if not head.startswith(b"PK"):
            raise _fail(shown, "not a motion file: it is not an .npz (zip) archive")
        return _read_zip(fh, shown)


def read_npz_bytes(data: bytes, source: str) -> dict[str, np.ndarray]:
    """The arrays of an ``.npz`` held in memory (the motion cache reads what it verified)."""
    if not data.startswith(b"PK"):
        raise _fail(repr(source), "not a motion file: it is not an .npz (zip) archive")
    return _read_zip(io.BytesIO(data), repr(source))


def _read_zip(path: Path | io.BytesIO | IO[bytes], shown: str) -> dict[str, np.ndarray]:
    try:
        with zipfile.ZipFile(path) as zf:
            infos = zf.infolist()
            total = sum(info.file_size for info in infos)
            if total > MAX_MOTION_BYTES:
                raise _fail(shown, f"declares {total / 2**20:.0f} MiB of arrays, more than the "
                                   f"{MAX_MOTION_BYTES >> 20} MiB a motion file may hold")
            arrays: dict[str, np.ndarray] = {}
            for info in infos:
                if info.is_dir() or not info.filename.endswith(".npy"):
                    continue  # not a numpy array: not ours to read
                key = info.filename[: -len(".npy")]
                if key in arrays:
                    raise _fail(shown, f"key {key!r} appears twice in the archive")
                with zf.open(info) as member:
                    arrays[key] = _read_member(member, info.file_size, key, shown)
    except MotionFileError:
        raise
    except zipfile.BadZipFile as e:
        raise _fail(shown, f"damaged or truncated .npz archive ({e})") from None
    except (OSError, EOFError, ValueError, zlib.error, struct.error, NotImplementedError, RuntimeError,
            OverflowError) as e:
        raise _fail(shown, f"damaged .npz archive ({type(e).__name__}: {e})") from None
    if not arrays:
        raise _fail(shown, "the archive holds no arrays; not a motion file")
    return arrays


def _read_member(fh, size: int, key: str, shown: str) -> np.ndarray:
    """One ``.npy`` member: header checked (no object dtype, declared size <= stored size), then data."""
    try:
        version = np.lib.format.read_magic(fh)
        if version == (1, 0):
            shape, fortran, dtype = np.lib.format.read_array_header_1_0(fh)
        elif version == (2, 0):
            shape, fortran, dtype = np.lib.format.read_array_header_2_0(fh)
        else:
            raise ValueError(f"unsupported .npy format version {version}")
    except Exception as e:  # noqa: BLE001 - numpy parses the header text with Python's tokenizer
        # (TokenError, SyntaxError, RecursionError, ... on damaged bytes): any failure is a bad member.
        raise _fail(shown, f"key {key!r} is not a numpy array ({type(e).__name__}: {e})") from None
    if dtype.hasobject:
        raise _fail(shown, f"key {key!r} holds Python objects (a pickle); wbmp never loads pickles")
    count = 1
    for n in shape:
        count *= int(n)
    nbytes = count * dtype.itemsize
    if nbytes > size:
        raise _fail(shown, f"key {key!r} declares shape {tuple(shape)} ({nbytes} bytes) but holds {size} bytes")
    data = fh.read(nbytes)
    if len(data) != nbytes:
        raise _fail(shown, f"key {key!r} is truncated ({len(data)} of {nbytes} bytes)")
    try:
        arr = np.frombuffer(bytearray(data), dtype=dtype, count=count)
        return arr.reshape(shape, order="F" if fortran else "C")
    except (ValueError, TypeError) as e:
        raise _fail(shown, f"key {key!r} is not a readable numpy array ({e})") from None


def _numbers(arrays: dict[str, Any], key: str, shown: str, shape: tuple[int | None, ...]) -> np.ndarray:
    """``arrays[key]`` as a finite float array of ``shape`` (None: any length)."""
    arr = arrays[key]
    if arr.dtype.kind not in "fiu":
        raise _fail(shown, f"key {key!r} must hold real numbers, got dtype {arr.dtype.str!r}")
    want = "(" + ", ".join("n" if n is None else str(n) for n in shape) + ("," if len(shape) == 1 else "") + ")"
    if arr.ndim != len(shape) or any(n is not None and m != n for m, n in zip(arr.shape, shape, strict=True)):
        raise _fail(shown, f"key {key!r} must have shape {want}, got {tuple(arr.shape)}")
    out = np.asarray(arr, dtype=float)
    bad = np.argwhere(~np.isfinite(out))
    if len(bad):
        where = tuple(int(i) for i in bad[0])
        raise _fail(shown, f"key {key!r} has a non-finite value (NaN or inf) at index {where}")
    return out


def _times(arrays: dict[str, Any], key: str, shown: str, minimum: int) -> np.ndarray:
    t = _numbers(arrays, key, shown, (None,))
    if len(t) < minimum:
        raise _fail(shown, f"key {key!r} has {len(t)} samples; a motion needs at least {minimum}")
    if len(t) > 1 and not np.all(np.diff(t) > 0):
        k = int(np.argmin(np.diff(t) > 0))
        raise _fail(shown, f"key {key!r} must increase, but t[{k + 1}] = {t[k + 1]!r} <= t[{k}] = {t[k]!r}")
    if float(np.max(np.abs(t))) > MAX_MOTION_SECONDS:
        raise MotionFileError(
            f"motion file {shown}: key {key!r} runs from {float(t[0]):.6g} s to {float(t[-1]):.6g} s; wbmp reads "
            f"motions whose times lie within {MAX_MOTION_SECONDS:g} s of 0 s (a plan starts at 0 s): shift or "
            "split the motion", ExitCode.INVALID_SPEC)
    return t


def _string(arrays: dict[str, Any], key: str, shown: str) -> str:
    arr = arrays[key]
    if arr.dtype.kind != "U" or arr.ndim != 0:
        raise _fail(shown, f"key {key!r} must be one string, got dtype {arr.dtype.str!r} shape {tuple(arr.shape)}")
    return str(arr)


def _strings(arrays: dict[str, Any], key: str, shown: str) -> list[str]:
    if key not in arrays:
        return []
    arr = arrays[key]
    if arr.ndim != 1 or (arr.size and arr.dtype.kind != "U"):
        raise _fail(shown, f"key {key!r} must be a list of strings, got dtype {arr.dtype.str!r} "
                           f"shape {tuple(arr.shape)}")
    return [str(x) for x in arr]


def _json(arrays: dict[str, Any], key: str, shown: str) -> Any:
    text = _string(arrays, key, shown)
    try:
        return json.loads(text)
    except json.JSONDecodeError as e:
        raise _fail(shown, f"key {key!r} is not valid JSON (line {e.lineno} column {e.colno}: {e.msg})") from None
    except (ValueError, RecursionError) as e:
        raise _fail(shown, f"key {key!r} is not usable JSON ({type(e).__name__}: {str(e)[:120]})") from None


def _has_control(text: str) -> bool:
    return any(ord(c) < 32 or 127 <= ord(c) < 160 for c in text)


def motion_from_arrays(arrays: dict[str, Any], *, source: str = "") -> MotionFile:
    """Rebuild a :class:`MotionFile` from the key -> array mapping, validating every key.

    Raises:
        MotionFileError: a key is missing or holds the wrong dtype, shape, values or JSON.
    """
    shown = repr(source or "<arrays>")
    arrays = {k: np.asarray(v) for k, v in arrays.items()}
    missing = [k for k in REQUIRED_KEYS if k not in arrays]
    if missing:
        raise _fail(shown, f"missing key(s) {', '.join(map(repr, missing))}; a motion file written by "
                           "`wbmp solve --out` has them all")
    version = arrays.get("version", np.array(FORMAT_VERSION))
    if version.ndim != 0 or version.dtype.kind not in "iu":
        raise _fail(shown, f"key 'version' must be one integer, got dtype {version.dtype.str!r} "
                           f"shape {tuple(version.shape)}")
    if not 1 <= int(version) <= FORMAT_VERSION:
        raise _fail(shown, f"key 'version' is {int(version)}; this wbmp reads format version {FORMAT_VERSION} "
                           "(a newer wbmp wrote it?)")
    robot_name = _string(arrays, "robot", shown)
    if not robot_name.strip() or _has_control(robot_name) or len(robot_name) > 4096:
        raise _fail(shown, f"key 'robot' must be a robot name, got {robot_name[:80]!r}")
    t = _times(arrays, "t", shown, 2)
    n = len(t)
    q_cols = arrays["q"].shape[1] if arrays["q"].ndim == 2 else 7
    v_cols = arrays["v"].shape[1] if arrays["v"].ndim == 2 else 6
    q = _numbers(arrays, "q", shown, (n, q_cols))
    v = _numbers(arrays, "v", shown, (n, v_cols))
    nq, nv = q.shape[1], v.shape[1]
    if nq < 7 or nv < 6:
        raise _fail(shown, f"keys 'q' and 'v' have {nq} and {nv} columns; a floating-base robot has at least 7 and 6")
    a = _numbers(arrays, "a", shown, (n, nv)) if "a" in arrays else np.zeros_like(v)
    com = _numbers(arrays, "com", shown, (n, 3))
    forces = {}
    for key in sorted(k for k in arrays if k.startswith("force_")):
        if key == "force_" or _has_control(key):
            raise _fail(shown, f"key {key[:80]!r} does not name a contact frame")
        forces[key[len("force_"):]] = _numbers(arrays, key, shown, (n, 3))
    execution: dict[str, np.ndarray] = {}  # the exec_* arrays, checked
    if any(k in arrays for k in EXEC_KEYS):
        lacking = [k for k in EXEC_KEYS[:3] if k not in arrays]
        if lacking:
            raise _fail(shown, f"has a simulated execution but lacks key(s) {', '.join(map(repr, lacking))}")
        exec_t = _times(arrays, "exec_t", shown, 1)
        m = len(exec_t)
        execution = {"exec_t": exec_t, "exec_q": _numbers(arrays, "exec_q", shown, (m, nq)),
                     "exec_v": _numbers(arrays, "exec_v", shown, (m, nv))}
        if "exec_tau" in arrays:
            execution["exec_tau"] = _numbers(arrays, "exec_tau", shown, (m, nv - 6))
    joint_names = _strings(arrays, "joint_names", shown)
    frame_names = _strings(arrays, "frame_names", shown)
    objects = _object_keys(arrays, shown, n, execution)

    try:
        spec = spec_from_json(_string(arrays, "spec_json", shown))
    except MotionFileError:
        raise
    except (TaskError, ValueError, TypeError, KeyError, RecursionError) as e:
        raise _fail(shown, f"key 'spec_json' is not a valid task spec ({str(e)[:300]})") from None
    report = _json(arrays, "report_json", shown)
    if not isinstance(report, dict):
        raise _fail(shown, f"key 'report_json' must be a JSON object, got {type(report).__name__}")
    stats, checks, diagnosis = _report_parts(report, shown)
    actions = _json(arrays, "actions_json", shown) if "actions_json" in arrays else None
    if actions is not None and not (isinstance(actions, list) and all(isinstance(x, dict) for x in actions)):
        raise _fail(shown, "key 'actions_json' must be null or a list of objects")
    try:
        plan = Plan(robot=robot_name, spec=spec, t=t, q=q, v=v, a=a, com=com, forces=forces, stats=stats,
                    checks=checks, diagnosis=diagnosis)
    except (ValueError, TypeError) as e:  # pragma: no cover - every field was checked above
        raise _fail(shown, f"the arrays do not make a plan ({e})") from None
    return MotionFile(plan=plan, execution=_execution(execution, report), actions=actions, report=report,
                      robot_name=robot_name, joint_names=joint_names, frame_names=frame_names,
                      version=int(version), objects=objects)


def _execution(arrays: dict[str, np.ndarray], report: dict[str, Any]) -> Execution | None:
    """The execution of checked ``exec_*`` arrays with the report's certificate and events."""
    if not arrays:
        return None
    names = [str(x) for x in arrays.get("object_names", ())]
    pose = arrays.get("exec_object_pose")
    return Execution(t=arrays["exec_t"], q=arrays["exec_q"], v=arrays["exec_v"], tau=arrays.get("exec_tau"),
                     certificate=Certificate.from_dict(report.get("certificate")),
                     events=events_from_report(report.get("events")),
                     objects={} if pose is None else {n: pose[:, i, :3] for i, n in enumerate(names)},
                     object_orientations={} if pose is None else {n: pose[:, i, 3:] for i, n in enumerate(names)})


def _object_keys(arrays: dict[str, Any], shown: str, n: int, execution: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The planned object poses by name (``object_names``, ``object_pose``); ``exec_object_pose`` is
    checked and added to ``execution`` (with ``object_names``). Files without them load as before."""
    names = _strings(arrays, "object_names", shown)
    if len(set(names)) != len(names) or any(not x or _has_control(x) for x in names):
        raise _fail(shown, "key 'object_names' must hold distinct object names")
    keys = [k for k in ("object_pose", "exec_object_pose") if k in arrays]
    if keys and "object_names" not in arrays:
        raise _fail(shown, f"key {keys[0]!r} needs the key 'object_names' (the objects it is about)")
    objects: dict[str, np.ndarray] = {}
    if "object_pose" in arrays:
        pose = _numbers(arrays, "object_pose", shown, (n, len(names), 7))
        objects = {name: pose[:, i] for i, name in enumerate(names)}
    if "exec_object_pose" in arrays:
        if not execution:
            raise _fail(shown, "key 'exec_object_pose' needs a simulated execution (key 'exec_t')")
        execution["exec_object_pose"] = _numbers(arrays, "exec_object_pose", shown,
                                                 (len(execution["exec_t"]), len(names), 7))
        execution["object_names"] = np.array(names, dtype=str)
    return objects


def _report_parts(report: dict, shown: str) -> tuple[SolverStats, tuple[Check, ...], str]:
    """Solver stats, checks and diagnosis of the report, with the bad field named."""
    def bad(field_name: str, value: Any, want: str) -> MotionFileError:
        return _fail(shown, f"key 'report_json': {field_name} must be {want}, got {str(value)[:80]!r}")

    def number(where: dict, name: str, prefix: str, default: float, *, integer: bool = False,
               optional: bool = False) -> float:
        value = where.get(name, default)
        if value is None and optional:
            return default
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise bad(f"{prefix}{name}", value, "an integer" if integer else "a number")
        if integer:
            if not isinstance(value, int) and not float(value).is_integer():
                raise bad(f"{prefix}{name}", value, "an integer")
            return int(value)
        return float(value)

    def text(where: dict, name: str, prefix: str, default: str) -> str:
        value = where.get(name, default)
        if not isinstance(value, str):
            raise bad(f"{prefix}{name}", value, "a string")
        return value

    solver = report.get("solver", {})
    if not isinstance(solver, dict):
        raise bad("solver", solver, "an object")
    status = solver.get("status", "NOT_RUN")
    if not isinstance(status, str) or status not in SolveStatus.__members__:
        raise bad("solver.status", status, f"one of {', '.join(SolveStatus.__members__)}")
    stats = SolverStats(
        status=SolveStatus[status],
        iterations=int(number(solver, "iterations", "solver.", 0, integer=True)),
        build_time=number(solver, "build_time", "solver.", 0.0),
        solve_time=number(solver, "solve_time", "solver.", 0.0),
        cache=text(solver, "cache", "solver.", "built"),
        objective=number(solver, "objective", "solver.", float("nan"), optional=True),
        n_variables=int(number(solver, "n_variables", "solver.", 0, integer=True)),
        n_constraints=int(number(solver, "n_constraints", "solver.", 0, integer=True)),
        backend=text(solver, "backend", "solver.", "ipopt"),
        raw_status=text(solver, "raw_status", "solver.", ""),
        seed=text(solver, "seed", "solver.", ""),
    )
    raw_checks = report.get("checks", [])
    if not isinstance(raw_checks, list):
        raise bad("checks", raw_checks, "a list")
    checks = []
    for i, c in enumerate(raw_checks):
        prefix = f"checks[{i}]."
        if not isinstance(c, dict):
            raise bad(f"checks[{i}]", c, "an object")
        for name in ("name", "violation", "unit", "time"):
            if name not in c:
                raise _fail(shown, f"key 'report_json': {prefix}{name} is missing")
        checks.append(Check.constraint(
            name=text(c, "name", prefix, ""), kind=CheckKind.RECORDED, violation=number(c, "violation", prefix, 0.0),
            tolerance=number(c, "tolerance", prefix, float("inf"), optional=True),
            unit=text(c, "unit", prefix, ""), time=number(c, "time", prefix, 0.0)))
    diagnosis = report.get("diagnosis", "")
    if diagnosis is None:
        diagnosis = ""
    if not isinstance(diagnosis, str):
        raise bad("diagnosis", diagnosis, "a string")
    return stats, tuple(checks), diagnosis


def check_robot(motion: MotionFile, robot, source: str | Path) -> None:
    """Refuse a motion whose arrays do not fit ``robot`` (q and v widths, torques, contact frames).

    Raises:
        MotionFileError: one line naming the file, the key and both sizes.
    """
    shown = repr(str(source))
    plan = motion.plan
    sizes = {"q": (plan.q, robot.nq, "nq"), "v": (plan.v, robot.nv, "nv")}
    ex = motion.execution
    if ex is not None:
        sizes.update({"exec_q": (ex.q, robot.nq, "nq"), "exec_v": (ex.v, robot.nv, "nv")})
    for key, (arr, want, what) in sizes.items():
        if arr.shape[1] != want:
            raise _fail(shown, f"key {key!r} has {arr.shape[1]} columns but robot {robot.name!r} has "
                               f"{what} = {want} (a file of another robot?)")
    from robots import RobotError

    for frame in plan.spec.contact_frames():
        try:
            robot.frame_id(frame)
        except RobotError:
            raise _fail(shown, f"key 'spec_json' names frame {frame!r}, which robot {robot.name!r} lacks") from None


def record_arrays(motion: MotionFile) -> dict[str, Any]:
    """Every key of the motion file of ``motion`` (the inverse of :func:`motion_from_arrays`)."""
    plan = motion.plan
    out: dict[str, Any] = {
        "t": plan.t, "q": plan.q, "v": plan.v, "a": plan.a, "com": plan.com,
        "robot": np.array(motion.robot_name), "joint_names": np.array(motion.joint_names, dtype=str),
        "frame_names": np.array(motion.frame_names, dtype=str),
        "spec_json": np.array(spec_to_json(plan.spec, indent=None)),
        "actions_json": np.array(json.dumps(motion.actions)),
        "report_json": np.array(json.dumps(motion.report, default=json_default)),
        "version": np.array(motion.version),
    }
    for name, arr in plan.forces.items():
        out[f"force_{name}"] = arr
    ex = motion.execution
    if ex is not None:
        out.update({"exec_t": ex.t, "exec_q": ex.q, "exec_v": ex.v})
        if ex.tau is not None:
            out["exec_tau"] = ex.tau
        poses = ex.object_poses()
        if poses:
            out["exec_object_pose"] = np.stack(list(poses.values()), axis=1)
            out["object_names"] = np.array(list(poses), dtype=str)
    if motion.objects:
        names = list(motion.objects)
        out["object_names"] = np.array(names, dtype=str)
        out["object_pose"] = np.stack([motion.objects[k] for k in names], axis=1)
    return out
