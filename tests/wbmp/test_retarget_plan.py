"""``wbmp retarget`` plans a clip: the figures it reports, recomputed here from the planned
configurations with Pinocchio (no code of tasks.mocap.figures), meet the issue's targets: no slip
of a stance foot, nothing below the floor, no float during labelled contact."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from robots import load_robot
from tasks.mocap import human_motion, label_contacts, read_bvh, recognize_skeleton
from tasks.mocap.retarget import reference
from wbmp.cli import main
from wbmp.motionfile import load_motion

MOCAP = Path("/work/shared/mocap")
pytestmark = pytest.mark.skipif(not MOCAP.is_dir(), reason="the shared CMU clips are not on this machine")


@pytest.fixture(scope="module")
def planned(tmp_path_factory):
    """The squat clip's first 1.5 s on talos, planned (no simulation), read back from its motion file."""

    tmp = tmp_path_factory.mktemp("retarget")
    out = tmp / "squat.npz"
    with pytest.MonkeyPatch.context() as mp:  # module-scoped: the environment restored after the run
        mp.setenv("WBMP_COMPILE", "0")
        mp.setenv("WBMP_CACHE_DIR", str(tmp / "cache"))
        code = main(["retarget", str(MOCAP / "13_29_squat.bvh"), "--robot", "talos", "--start", "0", "--end", "1.5",
                     "--no-sim", "--quiet", "--out", str(out)])
    assert code == 0
    return load_motion(out)


def _corners(robot, data, fid) -> np.ndarray:
    """The sole rectangle's corners in the world (from the profile's numbers and the frame's placement)."""
    s = robot.profile.sole
    M = data.oMf[fid]
    local = np.array([[x, y, 0.0] for x in (s.x_min, s.x_max) for y in (s.y_min, s.y_max)])
    return local @ M.rotation.T + M.translation


def test_stance_feet_do_not_slip_sink_or_float(planned):
    talos = load_robot("talos")
    plan, spec = planned.plan, planned.plan.spec
    data = talos.model.createData()
    starts = spec.phase_start_times()
    skate = sink = float_ = 0.0
    for t, q in zip(plan.t, plan.q, strict=True):
        pin.framesForwardKinematics(talos.model, data, q)
        i = spec.phase_at(float(t))
        for side in ("left", "right"):
            fid = talos.model.getFrameId(talos.frame(f"{side}_foot"))
            corners = _corners(talos, data, fid)
            sink = max(sink, -corners[:, 2].min())
            contact = next((c for c in spec.phases[i].contacts if c.frame == talos.frame(f"{side}_foot")), None)
            if contact is not None and t >= starts[i] - 1e-9:
                skate = max(skate, float(np.linalg.norm(data.oMf[fid].translation[:2]
                                                        - np.array(contact.placement.position[:2]))))
                float_ = max(float_, float(corners[:, 2].min()))
    assert skate * 1000 <= 2.0 and sink * 1000 <= 1.0 and float_ * 1000 <= 5.0
    figures = planned.report["retarget"]["plan"]
    assert figures["foot_skate_mm"] <= 2.0 and figures["penetration_mm"] <= 1.0 and figures["float_mm"] <= 5.0
    assert abs(figures["penetration_mm"] - 1000 * max(0.0, sink)) < 0.1


def test_the_reported_tracking_error_is_the_distance_to_the_scaled_source(planned):
    """The hands' tracking error, from the planned q and a reference rebuilt from the clip."""
    talos = load_robot("talos")
    clip = read_bvh(MOCAP / "13_29_squat.bvh").window(0.0, 1.5)
    motion = human_motion(clip, recognize_skeleton(clip.names))
    ref = reference(motion, label_contacts(motion), talos, lead_in=planned.report["retarget"]["lead_in_s"])
    plan = planned.plan
    data = talos.model.createData()
    errors = []
    for t, q in zip(plan.t, plan.q, strict=True):
        if not ref.t[0] - 1e-9 <= t <= ref.t[-1] + 1e-9:
            continue
        f = int(round((t - ref.t[0]) / motion.frame_time))
        pin.framesForwardKinematics(talos.model, data, q)
        for role in ("left_hand", "right_hand", "head", "base"):
            errors.append(np.linalg.norm(data.oMf[talos.frame_id(role)].translation - ref.points[role][f]))
    reported = planned.report["retarget"]["plan"]
    assert max(errors) <= reported["tracking_max_m"] + 1e-9
    assert reported["tracking_mean_m"] < 0.06  # the squat is tracked to a few centimetres on average
    per = reported["tracking_mean_per_keypoint_m"]
    assert per["left_hand"] < 0.05 and per["right_hand"] < 0.05
    # the robot goes down with the human: its base is lowest while the scaled pelvis is at the
    # robot's lowest base (the squat raised to it: a plateau), within 0.2 s
    base_z = []
    for q in plan.q:
        pin.framesForwardKinematics(talos.model, data, q)
        base_z.append(data.oMf[talos.frame_id("base")].translation[2])
    t_low = plan.t[int(np.argmin(base_z))]
    low = ref.t[ref.raised > 0] if ref.raised.max() > 0 else ref.t[[int(np.argmin(ref.points["base"][:, 2]))]]
    assert low[0] - 0.2 < t_low < low[-1] + 0.2


def test_a_clip_that_starts_mid_step_begins_at_its_first_double_support():
    """The walk's first frame has the right foot in the air (its first step straight out of the
    lead-in landed 22-40 mm off on both robots): without --start it begins at the first frame whose
    contact labels have both feet down (0.18 s); with --start, and for the squat, as asked."""
    from wbmp.retarget import RetargetRequest, build_retarget_spec

    clip = read_bvh(MOCAP / "12_01_walk.bvh")
    labels = label_contacts(human_motion(clip.window(None, None), recognize_skeleton(clip.names)))
    assert labels["left"][0] and not labels["right"][0]
    both = np.nonzero(labels["left"] & labels["right"])[0]
    _, spec, _, _, info = build_retarget_spec(RetargetRequest(clip=str(MOCAP / "12_01_walk.bvh"), robot="talos"))
    assert info["start_s"] == pytest.approx(both[0] * clip.frame_time) and 0.1 < info["start_s"] < 0.3
    assert len(spec.phases[1].contacts) == 2  # the clip's first phase: both feet down
    assert spec.dt == 0.08  # slowed 1.88 x for talos's steps: below the coarser knots' 2.5 x (knot_spacing)
    _, _, _, _, info = build_retarget_spec(RetargetRequest(clip=str(MOCAP / "12_01_walk.bvh"), robot="talos", start=0.0))
    assert info["start_s"] == 0.0
    _, squat, _, _, info = build_retarget_spec(RetargetRequest(clip=str(MOCAP / "13_29_squat.bvh"), robot="talos"))
    assert info["start_s"] == 0.0 and squat.dt == 0.08  # not slowed


def test_a_clip_slowed_for_the_robot_gets_the_coarser_knots_each_spanning_no_more_of_the_human():
    """tasks.mocap.retarget.knot_spacing: 0.1 s knots from a slowdown of 2.5 x, where each spans at
    most 0.04 s of the human's time, else 0.08 s (at most 0.08 s of it); both divide the lead-in.
    The walk on talos (slowed 1.88 x) keeps 0.08 s knots, as the squat (not slowed) does."""
    from tasks.mocap.retarget import COARSE_DT, DT, LEAD_IN, knot_spacing

    assert [knot_spacing(s) for s in (1.0, 1.88, 2.23, 2.5, 4.4)] == [DT, DT, DT, COARSE_DT, COARSE_DT]
    for slow in np.linspace(1.0, 6.0, 51):
        assert knot_spacing(slow) / slow <= DT + 1e-12
        assert slow < 2.5 or knot_spacing(slow) / slow <= DT / 2 + 1e-12
    for dt in (DT, COARSE_DT):  # the lead-in's targets blend over whole knots
        assert abs(LEAD_IN / dt - round(LEAD_IN / dt)) < 1e-9


def test_the_report_names_each_moved_target_in_body_terms(planned):
    """The squat's base, raised to talos's lowest base, is named in the motion file's report: how
    far (the reference's own lift, rebuilt here from the clip), when (where that lift is largest),
    which way (above the source) and why."""
    talos = load_robot("talos")
    clip = read_bvh(MOCAP / "13_29_squat.bvh").window(0.0, 1.5)
    motion = human_motion(clip, recognize_skeleton(clip.names))
    ref = reference(motion, label_contacts(motion), talos, lead_in=planned.report["retarget"]["lead_in_s"])
    gaps = {g["role"]: g for g in planned.report["retarget"]["gaps"]}
    base = gaps["base"]
    assert base["m"] == pytest.approx(float(ref.raised.max()), abs=1e-9)
    assert base["m"] > 0.05
    assert base["time_s"] == pytest.approx(float(ref.t[int(np.argmax(ref.raised))]), abs=1e-9)
    assert base["text"] == (f"base {base['m']:.2f} m from the source at {base['time_s']:.2f} s, mostly "
                            f"{base['m']:.2f} m above it: the robot's lowest base (0.6 of its standing height)")
