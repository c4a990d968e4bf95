"""wbmp's side of the mink peer of ``benchmarks/bench_retarget.py`` (runs in wbmp's environment).

* :func:`export_task`: the peer's input: the robot's URDF as MuJoCo reads it (:mod:`sim.urdf`,
  the same kinematic tree as wbmp's simulation) with a site at each tracked Pinocchio frame, the
  standing configuration and the scaled source keypoints (:class:`tasks.mocap.retarget.Reference`).
* :func:`peer_plan`: the peer's configurations back in Pinocchio order, their figures
  (:func:`tasks.mocap.figures.motion_figures`: the same definitions and labelled contacts as wbmp's),
  and a :class:`planner.Plan` of them (a 0.8 s smoothstep from standing into the first frame,
  the clip at its source rate, the last frame held for the lead-out; velocities and
  accelerations by central differences; wbmp's spec of the clip) tracked by wbmp's controller
  in MuJoCo with wbmp's certificate.
* :func:`markdown`: the table of the benchmark's JSON files.
"""

from __future__ import annotations

import dataclasses
import statistics
import time
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin

TRACKED = ("base", "torso", "head", "left_hand", "right_hand", "left_foot", "right_foot")


_CACHE: dict[str, tuple] = {}


def _mjcf(robot_name: str, robot) -> tuple[str, tuple[str, ...]]:
    """(MJCF text with the tracked sites, MuJoCo joint name of each Pinocchio joint 2..)."""
    if ("xml", robot_name) in _CACHE:
        return _CACHE["xml", robot_name]
    from sim.urdf import _rewrite_urdf

    spec = mujoco.MjSpec.from_string(_rewrite_urdf(robot))
    compiled = spec.compile()
    model = robot.model
    for role in TRACKED:
        frame = model.frames[robot.frame_id(role)]
        jname = model.names[frame.parentJoint]
        if frame.parentJoint == 1:  # the free flyer: its body is the root link
            body = mujoco.mj_id2name(compiled, mujoco.mjtObj.mjOBJ_BODY, 1)
        else:
            jid = mujoco.mj_name2id(compiled, mujoco.mjtObj.mjOBJ_JOINT, jname)
            body = mujoco.mj_id2name(compiled, mujoco.mjtObj.mjOBJ_BODY, int(compiled.jnt_bodyid[jid]))
        pl = frame.placement
        q = pin.Quaternion(pl.rotation)
        site = spec.body(body).add_site()
        site.name = f"wbmp_{role}"
        site.pos = pl.translation.tolist()
        site.quat = [q.w, q.x, q.y, q.z]
    _CACHE["xml", robot_name] = spec.to_xml(), tuple(model.names[j] for j in range(2, model.njoints))
    return _CACHE["xml", robot_name]


def _maps(robot) -> tuple[np.ndarray, mujoco.MjModel]:
    """MuJoCo qpos index of each Pinocchio actuated configuration index 7.., and the model."""
    if ("maps", robot.name) in _CACHE:
        return _CACHE["maps", robot.name]
    xml, names = _mjcf(robot.name, robot)
    mj = mujoco.MjModel.from_xml_string(xml)
    index = np.empty(robot.model.nq - 7, dtype=int)
    for j, name in zip(range(2, robot.model.njoints), names, strict=True):
        jid = mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_JOINT, name)
        index[robot.model.joints[j].idx_q - 7] = mj.jnt_qposadr[jid]
    _CACHE["maps", robot.name] = index, mj
    return index, mj


def to_mujoco(robot, q: np.ndarray) -> np.ndarray:
    index, mj = _maps(robot)
    out = np.zeros(mj.nq)
    out[:3], out[3:7] = q[:3], [q[6], q[3], q[4], q[5]]
    out[index] = q[7:]
    return out


def to_pinocchio(robot, qpos: np.ndarray) -> np.ndarray:
    index, _ = _maps(robot)
    q = np.empty((len(qpos), robot.model.nq))
    q[:, :3] = qpos[:, :3]
    q[:, 3:6], q[:, 6] = qpos[:, 4:7], qpos[:, 3]
    q[:, 3:7] /= np.linalg.norm(q[:, 3:7], axis=1, keepdims=True)
    q[:, 7:] = qpos[:, index]
    return q


def export_task(robot, ref, path: Path) -> None:
    """The peer's input file (see the module)."""
    xml, _ = _mjcf(robot.name, robot)
    targets = np.stack([ref.points[r] for r in TRACKED], axis=1)
    np.savez(path, xml=np.array(xml), roles=np.array(TRACKED), targets=targets, heading=np.asarray(ref.heading),
             q0=to_mujoco(robot, np.asarray(robot.q_standing, dtype=float)), times=np.asarray(ref.t))


def _figs(f) -> dict:
    return {k: v for k, v in f.to_dict().items() if k != "tracking_mean_per_keypoint_m"}


def peer_plan(res, data: dict, clip: Path) -> dict:
    """Figures and certificate of the peer's output ``data`` for our result ``res`` of the same clip."""
    from planner import Plan, SolverStats, SolveStatus
    from sim import simulate
    from tasks.mocap.figures import motion_figures

    robot, ref, spec = res.robot, res.reference, res.spec
    q_src = to_pinocchio(robot, np.asarray(data["qpos"]))
    frames = len(q_src)
    rec = {"frames": frames, "solve_s": float(data["solve_s"]), "load_s": float(data["load_s"]),
           "qp_solves": int(data["iterations"]), "versions": [str(v) for v in data["versions"]],
           "frames_per_s": frames / float(data["solve_s"]) if float(data["solve_s"]) > 0 else None}
    if "solve_cpu_s" in data:
        rec["solve_cpu_s"] = float(data["solve_cpu_s"])
        rec["frames_per_cpu_s"] = frames / rec["solve_cpu_s"] if rec["solve_cpu_s"] > 0 else None
    rec["kinematic"] = _figs(motion_figures(robot, np.asarray(ref.t), q_src, spec, ref))
    plan = _as_plan(robot, spec, ref, q_src, Plan, SolverStats, SolveStatus)
    plan = dataclasses.replace(plan, spec=_own_placements(robot, plan))
    t0 = time.perf_counter()
    try:
        execution = simulate(plan, robot)
    except Exception as e:  # noqa: BLE001
        rec["certified"] = False
        rec["certificate_error"] = f"{type(e).__name__}: {e}"[:300]
        return rec
    rec["certificate_s"] = time.perf_counter() - t0
    rec["certified"] = bool(execution.ok)
    rec["certificate_failures"] = [f"{c.name}: {c.violation:.3g} {c.unit}" for c in execution.certificate.checks
                                   if not c.ok][:6]
    rec["executed"] = _figs(motion_figures(robot, execution.t, execution.q, spec, ref))
    return rec


def _own_placements(robot, plan):
    """The plan's spec with each contact held where the peer's foot is when that contact begins
    (the certificate compares the executed feet with the spec's placements: the peer's feet are
    where its IK put them, not at wbmp's planned placements)."""
    from tasks.mocap.figures import contact_windows
    from tasks.specs import Pose

    spec = plan.spec
    data = robot.model.createData()

    def pose_at(frame: str, time: float) -> Pose:
        k = min(int(round(time / plan.dt)), len(plan.q) - 1)
        pin.framesForwardKinematics(robot.model, data, plan.q[k])
        M = data.oMf[robot.model.getFrameId(frame)]
        return Pose(position=tuple(float(x) for x in M.translation),
                    rpy=tuple(float(x) for x in pin.rpy.matrixToRpy(M.rotation)))

    windows: dict[str, list] = {}
    phases = []
    for start, phase in zip(spec.phase_start_times(), spec.phases, strict=True):
        contacts = []
        for c in phase.contacts:
            frame = robot.frame(c.frame) if not robot.model.existFrame(c.frame) else c.frame
            spans = windows.setdefault(c.frame, contact_windows(spec, c.frame))
            t0 = next((a for a, b in spans if a - 1e-9 <= start <= b + 1e-9), start)
            contacts.append(dataclasses.replace(c, placement=pose_at(frame, t0)))
        phases.append(dataclasses.replace(phase, contacts=tuple(contacts)))
    return dataclasses.replace(spec, phases=tuple(phases))


def _smooth(x: float) -> float:
    x = min(max(x, 0.0), 1.0)
    return x * x * (3.0 - 2.0 * x)


def _as_plan(robot, spec, ref, q_src: np.ndarray, Plan, SolverStats, SolveStatus):
    """The peer's configurations as a plan on the spec's horizon (see the module)."""
    from sim.handmade import central_differences

    model = robot.model
    dt = float(ref.t[1] - ref.t[0])
    lead = float(ref.t[0])
    times = np.arange(0.0, float(spec.horizon) + 1e-9, dt)
    q_stand = np.asarray(robot.q_standing, dtype=float)
    qs = np.empty((len(times), model.nq))
    for k, tk in enumerate(times):
        if tk < lead:
            qs[k] = pin.interpolate(model, q_stand, q_src[0], _smooth(tk / lead))
        else:
            qs[k] = q_src[min(int(round((tk - lead) / dt)), len(q_src) - 1)]
    vs, acc = central_differences(model, qs, dt)
    data = model.createData()
    coms = np.array([pin.centerOfMass(model, data, qk) for qk in qs])
    return Plan(robot=robot.name, spec=spec, t=times, q=qs, v=vs, a=acc, com=coms,
                stats=SolverStats(status=SolveStatus.SOLVED, backend="mink-peer"))


# ---------------------------------------------------------------- the table


def _f(v, fmt: str = ".1f") -> str:
    return "-" if v is None else format(v, fmt)


def _row(r: dict) -> list[str]:
    w, m = r.get("wbmp", {}), r.get("mink", {})
    plan, exe = w.get("plan") or {}, w.get("executed") or {}
    kin, mexe = m.get("kinematic") or {}, m.get("executed") or {}
    status = "yes" if w.get("planned") else ("no" if "PlanningFailed" in w.get("error", "PlanningFailed") else "error")
    work = (w.get("plan_s") or 0) + (w.get("certificate_s") or 0)
    if not w:  # the peer ran on this clip, wbmp did not (a subset run)
        status = "not run"
    return [r["clip"].removesuffix(".bvh"), r["robot"], status, ("yes" if w.get("certified") else "no") if w else "-",
            f"{_f(plan.get('foot_skate_mm'))} / {_f(exe.get('foot_skate_mm'))}",
            _f(exe.get("penetration_mm")), _f(exe.get("float_mm")),
            f"{_f(plan.get('tracking_mean_m'), '.3f')} / {_f(plan.get('tracking_max_m'), '.2f')}",
            f"{_f(w.get('plan_s'), '.0f')} + {_f(w.get('certificate_s'), '.0f')}" if "plan_s" in w else "-",
            f"{_f(w.get('frames') / work if work > 0 and w.get('frames') else None, '.0f')} / "
            f"{_f(w.get('frames') / w['cpu_s'] if w.get('cpu_s') and w.get('frames') else None, '.0f')}",
            # the peer
            f"{_f(m.get('frames_per_s'), '.0f')} / {_f(m.get('frames_per_cpu_s'), '.0f')}",
            f"{_f(kin.get('foot_skate_mm'))} / {_f(mexe.get('foot_skate_mm'))}",
            f"{_f(kin.get('penetration_mm'))} / {_f(kin.get('float_mm'))}",
            f"{_f(kin.get('tracking_mean_m'), '.3f')} / {_f(kin.get('tracking_max_m'), '.2f')}",
            ("yes" if m.get("certified") else "no") if "certified" in m else "-"]


HEAD = ["clip", "robot", "planned", "certified", "skate plan / exec [mm]", "penetration exec [mm]",
        "float exec [mm]", "tracking mean / max (plan) [m]", "plan + certificate [s]", "source frames/s (wall / CPU)",
        "mink frames/s (wall / CPU)", "mink skate IK / exec [mm]", "mink penetration / float (IK) [mm]",
        "mink tracking mean / max [m]", "mink certified"]


def markdown(docs: list[dict]) -> str:
    """The results table with medians and the machine (see bench_retarget.py)."""
    merged: dict[tuple[str, str], dict] = {}  # a wbmp-only and a peer-only run of the same clip and robot: one row
    for r in (r for d in docs for r in d["runs"]):
        row = merged.setdefault((r["robot"], r["clip"]), {"clip": r["clip"], "robot": r["robot"], "wbmp": {}})
        for key, value in r.items():
            if value or key not in row:
                row[key] = value
    runs = list(merged.values())
    lines = ["| " + " | ".join(HEAD) + " |", "|" + " --- |" * len(HEAD)]
    lines += ["| " + " | ".join(_row(r)) + " |" for r in runs]
    out = ["\n".join(lines), "", "Why a motion was not certified (wbmp; the first failed checks, or the planner's diagnosis):", ""]
    for r in runs:
        w = r["wbmp"]
        if w and not w.get("certified"):
            why = w.get("error") or "; ".join(w.get("certificate_failures") or []) or w.get("diagnosis") or "?"
            out.append(f"- {r['clip'].removesuffix('.bvh')} on {r['robot']}: {why[:260]}")
    out.append("")
    for robot in sorted({r["robot"] for r in runs}):
        everything = [r for r in runs if r["robot"] == robot]
        rs = [r for r in everything if r["wbmp"]]
        ok = [r for r in rs if r["wbmp"].get("certified")]
        peers = [r for r in everything if r.get("mink")]
        peer = [r for r in peers if r["mink"].get("certified")]

        def med(vals):
            vals = [v for v in vals if v is not None]
            return statistics.median(vals) if vals else None

        fps = med([r["wbmp"]["frames"] / (r["wbmp"]["plan_s"] + r["wbmp"]["certificate_s"])
                   for r in rs if r["wbmp"].get("certificate_s")])
        cpu = med([r["wbmp"].get("cpu_s") for r in rs])
        out.append(f"- **{robot}**: wbmp planned {sum(bool(r['wbmp'].get('planned')) for r in rs)} / {len(rs)}, "
                   f"certified {len(ok)} / {len(rs)}; median plan + certificate "
                   f"{_f(med([r['wbmp'].get('plan_s', 0) + r['wbmp'].get('certificate_s', 0) for r in rs if 'plan_s' in r['wbmp']]), '.0f')} s, "
                   f"median {_f(fps, '.0f')} source frames/s (wall, of the clips simulated), median CPU {_f(cpu, '.0f')} s per clip. "
                   f"mink peer: median "
                   f"{_f(med([r['mink'].get('frames_per_s') for r in peers]), '.0f')} frames/s (wall), certified "
                   f"{len(peer)} / {sum('certified' in r['mink'] for r in peers)}; median skate (IK) "
                   f"{_f(med([(r['mink'].get('kinematic') or {}).get('foot_skate_mm') for r in peers]))} mm, "
                   f"penetration {_f(med([(r['mink'].get('kinematic') or {}).get('penetration_mm') for r in peers]))} mm, "
                   f"float {_f(med([(r['mink'].get('kinematic') or {}).get('float_mm') for r in peers]))} mm.")
    m0 = docs[0]["machine"]
    loads = [r.get("load1_before") for r in runs] + [r.get("load1_after") for r in runs]
    loads = [x for x in loads if x is not None]
    out.append(f"- Machine: {m0['cpu_model']}, {m0['cores']} cores, shared; 1-min load "
               f"{min(loads):.1f} to {max(loads):.1f} during the run; OMP_NUM_THREADS="
               f"{docs[0].get('threads', {}).get('OMP_NUM_THREADS')}; dates {', '.join(d['machine']['date_utc'] for d in docs)}.")
    return "\n".join(out)
