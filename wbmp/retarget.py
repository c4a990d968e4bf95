"""The retarget job: BVH clip -> human keypoints and contacts -> TaskSpec -> Plan -> Execution -> files.

Wires ``tasks.mocap`` (the clip as a task), the planner and the simulation together, like
:mod:`wbmp.pipeline` does for a sentence, and returns a :class:`RetargetResult` that the
pipeline's writers (motion file, HTML replay) take as they take a solve's result.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from wbmp.pipeline import Progress, SolveResult, _silent

#: [s] The floor's contact time constant in a retarget's simulation (MuJoCo ``solref``; its
#: default is 0.02 s): a harder floor, on which a loaded sole sinks and creeps by a fraction of a
#: millimetre instead of 3-14 mm (docs/retarget.md, "The floor").
FLOOR_TIMECONST = 0.005
#: The planner's IPOPT iteration limit per solve for a retarget (None: the planner's default, 150).
#: A long clip's solve needs more: talos's bend (5.8 s, 73 knots) was refused at the limit (its
#: diagnosis: a hand through a thigh) and plans in 238 iterations with 500. A solve that converges
#: within 150 follows the same iterates either way (the certified clips' plans are unchanged).
MAX_ITERATIONS: int | None = 500
ARM_TORQUE_MARGIN: float | None = 0.85  # of the strained arm joints' limits in the plan (None: no rows)
#: Start the plan from each knot's pose for its tracking targets (Pinocchio inverse kinematics,
#: :mod:`planner.trajopt.centroidal.tracking`) instead of the heading guess (joints at standing):
#: the clip is a guess of the whole motion. g1's squat: 106 -> 73 iterations, the first solve's
#: collision rows screened on the motion's poses (11 link pairs) instead of found by a round (16).
TRACKING_GUESS = True
#: The controller's posture weight (``WbcSettings.posture_weight``, default 1e-3) in the simulation of
#: a clip with high swings (``Reference.high_swing``: a march, a kick, jumps made as steps). G1's
#: march, its waist twisted 1.1 rad and its arms nearly straight, tracked its hands while the
#: shoulders' yaw drifted 0.65 rad off the plan (the elbow's swivel is free of the hand's pose): its
#: upper arm went 6.9 mm into the torso's mesh (limit 5 mm; the plan 20 mm apart). With 3e-3, 5e-3,
#: 1e-2 or 2e-2 it is certified. Only on a robot whose arms are never strained (``Reference.hold_posture``):
#: talos's march, its left shoulder roll near its limit, left its hand 55.8-58.9 mm off the plan with
#: 3e-3 to 1e-2 (limit 50) and is certified with the default. The other clips keep the default.
HIGH_SWING_POSTURE_WEIGHT = 0.01
START_ON_BOTH_FEET = 0.5  # [s] a clip (no --start) that starts mid-step begins at its first double support within this


def retarget_settings(robot: Any = None) -> Any:
    """The planner's settings of a retarget: :data:`MAX_ITERATIONS` per solve; with
    :data:`TRACKING_GUESS` the solve started from each knot's pose for its tracking targets (a
    collision round's re-solve starts from the solution's multipliers in every plan); for ``robot``
    (a :class:`robots.Robot`), the arm joints that could not hold their stretched arm
    (``tasks.arm_torque_joints``) kept within :data:`ARM_TORQUE_MARGIN` of their torque limits by
    the plan (talos's march swung its shoulder roll at 0.96-1.02 of its limit, the hand 50.1 mm off
    its plan in MuJoCo; G1: no such joint)."""
    from planner import CentroidalSettings, PlannerSettings, SolverSettings
    from tasks import arm_torque_joints

    solver = SolverSettings() if MAX_ITERATIONS is None else SolverSettings(max_iterations=MAX_ITERATIONS)
    joints = arm_torque_joints(robot) if robot is not None and ARM_TORQUE_MARGIN is not None else ()
    if joints and ARM_TORQUE_MARGIN is not None:
        centroidal = CentroidalSettings(tracking_guess=TRACKING_GUESS, torque_joints=joints,
                                        torque_margin=ARM_TORQUE_MARGIN)
    else:
        centroidal = CentroidalSettings(tracking_guess=TRACKING_GUESS)
    return PlannerSettings(solver=solver, centroidal=centroidal)


@dataclass(kw_only=True)
class RetargetRequest:
    """What ``wbmp retarget`` was asked to do.

    Attributes:
        clip: The BVH file.
        robot: Robot name or profile file.
        start, end: The clip's window [s] (None: its start, its end).
        skeleton: A skeleton mapping file (TOML), or None to recognise the skeleton by its joint names.
        simulate: Run the controller in MuJoCo and certify the motion.
        dt: Knot spacing of the plan [s]; None: 0.08 s, or 0.1 s for a clip slowed at least 1.25 x
            for the robot (``tasks.mocap.retarget.COARSE_DT``).
    """

    clip: str
    robot: str = "talos"
    start: float | None = None
    end: float | None = None
    skeleton: str | None = None
    simulate: bool = True
    dt: float | None = None


@dataclass(kw_only=True)
class RetargetResult(SolveResult):
    """A solve's result, with the retarget's reference and its figures (plan and execution)."""

    reference: Any = None
    figures: Any = None
    exec_figures: Any = None
    skeleton: str = ""
    clip_info: dict[str, Any] = field(default_factory=dict)

    def report(self) -> dict[str, Any]:
        """The solve's report with a ``retarget`` section: the clip, the scale and the figures."""
        out = super().report()
        section: dict[str, Any] = {**self.clip_info, "skeleton": self.skeleton}
        if self.reference is not None:
            section["scale"] = self.reference.scale
            section["arm_scale"] = self.reference.arm_scale
            section["lead_in_s"] = self.reference.lead_in
            section["stride_scale"] = self.reference.stride_scale
            section["time_scale"] = self.reference.time_scale
            section["raised_m"] = self.reference.raised_max()
            section["arm_moved_m"] = self.reference.arm_moved_max()
            section["kept_out_m"] = self.reference.kept_out_max()
            section["arm_held_m"] = self.reference.arm_held_max()
            section["gaps"] = [g.to_dict() for g in self.reference.gaps]
            section["grounded_s"] = self.reference.grounded_s
            section["splay_turned_deg"] = math.degrees(self.reference.splay_turned)
            section["stepped_s"] = self.reference.stepped_s
        if self.figures is not None:
            section["plan"] = self.figures.to_dict()
        if self.exec_figures is not None:
            section["execution"] = self.exec_figures.to_dict()
        out["retarget"] = section
        return out


def build_retarget_spec(request: RetargetRequest, progress: Progress = _silent):
    """(robot, spec, reference, skeleton name, clip info) of a request; ClipError (exit 3) for a bad clip."""
    import numpy as np

    from robots import load_robot
    from tasks import (
        check_joints,
        human_motion,
        label_contacts,
        load_skeleton,
        read_bvh,
        recognize_skeleton,
        retarget_spec,
    )

    progress(f"reading {request.clip}")
    clip = read_bvh(request.clip)
    skeleton = load_skeleton(request.skeleton) if request.skeleton is not None else recognize_skeleton(clip.names, clip.source)
    check_joints(skeleton, clip.names, clip.source)
    window = clip.window(request.start, request.end)
    motion = human_motion(window, skeleton)
    labels = label_contacts(motion)
    start = request.start or 0.0
    if request.start is None:
        # a clip that starts mid-step begins at its first double support (within START_ON_BOTH_FEET s):
        # the robot stands still before it, and a first step taken straight out of the lead-in landed
        # 22-40 mm off its placement (talos's and g1's walks)
        both = np.asarray(labels["left"], dtype=bool) & np.asarray(labels["right"], dtype=bool)
        first = int(np.argmax(both)) if both.any() else 0
        if 0 < first and first * window.frame_time <= START_ON_BOTH_FEET:
            start = first * window.frame_time
            window = clip.window(start, request.end)
            motion = human_motion(window, skeleton)
            labels = label_contacts(motion)
    robot = load_robot(request.robot)
    spec, ref = retarget_spec(motion, labels, robot, dt=request.dt, name=f"retarget {clip.source}",
                              description=f"retarget {clip.source} [{start:g}, "
                                          f"{'end' if request.end is None else format(request.end, 'g')}] s")
    info = {"clip": clip.source, "frames": window.n_frames, "frame_time_s": window.frame_time,
            "start_s": start, "duration_s": window.duration,
            "contact_fraction": {s: float(labels[s].mean()) for s in labels}}
    return robot, spec, ref, skeleton.name, info


def retarget(request: RetargetRequest, progress: Progress = _silent, *, cache: bool = False,
             cache_dir: str | Path | None = None) -> RetargetResult:
    """Run the whole job; raises the layers' exceptions (mapped to exit codes by the CLI).

    With ``cache`` (``wbmp retarget`` unless ``--no-cache``) the motion cache
    (:mod:`wbmp.motioncache`, ``$WBMP_CACHE_DIR/motions`` or ``cache_dir``) answers a repeat: the
    clip is read and its task built again (a fraction of a second), and the motion of that task
    on that robot (same clip bytes, window, skeleton, robot files, simulation switch and wbmp)
    is read back instead of planned and simulated; the figures are computed again from it. A
    fresh result that planned (and passed its certificate) is stored.
    """
    from planner import plan as plan_motion
    from wbmp.errors import check_signals

    timings: dict[str, float] = {}
    t0 = time.perf_counter()
    robot, spec, ref, skeleton, info = build_retarget_spec(request, progress)
    timings["spec"] = time.perf_counter() - t0
    check_signals()
    motions = key = None
    if cache:
        from wbmp.motioncache import MotionCache, motion_key, robot_files, robot_hash

        try:
            key = motion_key(spec, robot_hash(robot, robot_files(robot)), simulate=request.simulate, push=None)
            motions = MotionCache(cache_dir)
        except OSError:  # a robot file that cannot be hashed: retargeted, not cached
            motions = key = None
        hit = motions.load(key) if motions is not None and key is not None else None
        if hit is not None:
            progress("answering from the motion cache")
            return _cached_result(request, hit, robot, spec, ref, skeleton, info, timings, t0)
    progress(f"planning {spec.horizon:.1f} s of motion for {robot.name} ({len(spec.phases)} contact phases)")
    t0 = time.perf_counter()
    plan = plan_motion(spec, robot, progress=progress, settings=retarget_settings(robot))
    check_signals()
    timings["plan"] = time.perf_counter() - t0
    execution = None
    if request.simulate:
        from sim import simulate

        progress("simulating in MuJoCo with the whole-body controller")
        t0 = time.perf_counter()
        execution = simulate(plan, robot, progress=progress, settings=sim_settings(ref))
        check_signals()
        timings["simulate"] = time.perf_counter() - t0
    plan_figures, exec_figures = _figures(robot, spec, ref, plan, execution)
    result = RetargetResult(robot=robot, spec=spec, plan=plan, execution=execution, timings=timings,
                            reference=ref, figures=plan_figures, exec_figures=exec_figures, skeleton=skeleton,
                            clip_info=info)
    if motions is not None and key is not None and plan.ok and (execution is None or execution.ok):
        from wbmp.pipeline import result_arrays

        motions.store(key, result_arrays(result), spec)  # only a success: a failure is worth re-checking
        result.cache_key = key
    return result


def _figures(robot, spec, ref, plan, execution) -> tuple[Any, Any]:
    """The figures of the plan and of the execution (None without one)."""
    from tasks import motion_figures

    plan_figures = motion_figures(robot, plan.t, plan.q, spec, ref)
    exec_figures = None
    if execution is not None:
        import dataclasses

        from tasks import torque_cause

        exec_figures = motion_figures(robot, execution.t, execution.q, spec, ref)
        tau = getattr(execution, "tau", None)
        why = torque_cause(robot, exec_figures.worst_role, exec_figures.worst_time, execution.t, tau) \
            if tau is not None else ""
        if why:
            exec_figures = dataclasses.replace(exec_figures, worst=f"{exec_figures.worst}: {why}")
    return plan_figures, exec_figures


def _cached_result(request: RetargetRequest, hit, robot, spec, ref, skeleton: str, info: dict[str, Any],
                   timings: dict[str, float], t0: float) -> RetargetResult:
    """A RetargetResult from a verified motion cache entry (figures computed again from it)."""
    import types

    from wbmp.pipeline import _from_cache

    asked = types.SimpleNamespace(instruction=None, actions=None, profile=None, robot=request.robot)
    solved = _from_cache(asked, hit, robot, time.perf_counter() - t0, spec=spec)  # type: ignore[arg-type]
    plan_figures, exec_figures = _figures(robot, spec, ref, solved.plan, solved.execution)
    timings = {"spec": timings["spec"], "cache": time.perf_counter() - t0}
    return RetargetResult(robot=robot, spec=spec, plan=solved.plan, execution=solved.execution, timings=timings,
                          reference=ref, figures=plan_figures, exec_figures=exec_figures, skeleton=skeleton,
                          clip_info=info, cached=hit, cache_key=hit.key)


def is_tracking(name: str) -> bool:
    """True for a report line of a tracking target (they are summed up by the figures instead)."""
    return "'track " in name


def keypoint_plot(result: RetargetResult) -> Any:
    """What ``--plot`` draws (:class:`viz.KeypointPlot`): the executed motion's keypoints when
    simulated, else the plan's, against the scaled source; the same samples the figures are
    computed from (:func:`tasks.mocap.figures.tracks`), so its largest error is the report's."""
    import numpy as np

    from tasks import contact_windows, tracks
    from viz import KeypointPlot

    robot, ref = result.model(), result.reference
    motion = result.execution if result.execution is not None else result.plan
    t, q = np.asarray(motion.t, dtype=float), np.asarray(motion.q)
    tr = tracks(robot, t, q, ref)
    sel = tr.inside
    contact = {}
    for side in ("left", "right"):
        on = np.zeros(len(t), dtype=bool)
        for a, b in contact_windows(result.spec, robot.frame(f"{side}_foot")):
            on |= (t >= a - 1e-9) & (t <= b + 1e-9)
        contact[side] = on[sel]
    which = "executed (MuJoCo)" if result.execution is not None else "plan"
    title = (f"{Path(str(result.clip_info.get('clip', ''))).name} on {robot.name}: source (scaled, dashed) vs robot {which} "
             f"(solid)")
    return KeypointPlot(tracks=tr.select(sel), contact=contact, title=title)


def plot_path(option: str, clip: str, others: dict[str, str | None]) -> Path:
    """The PNG file of ``--plot PNG|DIR`` (in a folder: ``<clip stem>_keypoints.png``), checked
    before any work; CliError (exit 2) for a path that cannot be written, one that is another
    output's or input's (``others``: option -> path) or a file name not ending in ``.png``."""
    import os

    from wbmp.errors import CliError, ExitCode
    from wbmp.outputs import check_distinct, check_output_dir, check_output_file, output_errors

    name = f"{Path(clip).stem}_keypoints.png"
    with output_errors():
        if os.path.isdir(option) or option.endswith(("/", os.sep)):  # noqa: PTH112
            path = check_output_dir(option.rstrip("/" + os.sep) or "/", "--plot", (name,)) / name
        else:
            path = check_output_file(option, "--plot")
            if path.suffix.lower() != ".png":
                raise CliError(f"--plot {option!r}: the plot is a PNG: give a file ending in .png or a folder",
                               ExitCode.USAGE)
        check_distinct({"--plot": path}, {k: Path(v) for k, v in others.items() if v})
    return path


def write_plot(result: RetargetResult, path: str | Path) -> Path:
    """Draw :func:`keypoint_plot` of ``result`` into ``path`` (atomically)."""
    from viz import plot_keypoints
    from wbmp.outputs import output_errors

    data = keypoint_plot(result)
    with output_errors():
        return plot_keypoints(path, data)


def sim_settings(ref: Any) -> Any:
    """The simulation settings of a retarget of ``ref`` (a ``tasks.mocap.Reference``): the harder
    floor (``FLOOR_TIMECONST``), and on a clip with high swings on a robot whose arms are never
    strained (``ref.hold_posture``: G1) the plan's posture held more firmly (``HIGH_SWING_POSTURE_WEIGHT``)."""
    from planner import WbcSettings
    from sim import SimSettings

    wbc = WbcSettings(posture_weight=HIGH_SWING_POSTURE_WEIGHT) if ref.hold_posture else WbcSettings()
    return SimSettings(floor_timeconst=FLOOR_TIMECONST, wbc=wbc)
