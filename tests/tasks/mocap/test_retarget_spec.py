"""The TaskSpec a clip becomes (no solver): phases that follow the contact labels, stances on the
floor, strides and swings the robot can make, soft tracking targets on the scaled source."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from robots import load_robot
from tasks.mocap import human_motion, label_contacts, read_bvh, recognize_skeleton
from tasks.mocap.retarget import retarget_spec
from tasks.primitives.geometry import Stance, standing_geometry
from tasks.specs import Priority

EXAMPLES = Path(__file__).resolve().parents[3] / "examples" / "motions"


@pytest.fixture(scope="module")
def talos():
    return load_robot("talos")


def _spec(name: str, robot, start: float = 0.0, end: float | None = None):
    clip = read_bvh(EXAMPLES / name).window(start, end)
    motion = human_motion(clip, recognize_skeleton(clip.names))
    labels = label_contacts(motion)
    spec, ref = retarget_spec(motion, labels, robot)
    return motion, labels, spec, ref


def test_walk_phases_follow_the_labels_and_stand_on_the_floor(talos):
    motion, labels, spec, ref = _spec("12_01_walk.bvh", talos)
    stand = Stance.standing(talos)
    first, last = spec.phases[0], spec.phases[-1]
    assert len(first.contacts) == 2 and len(last.contacts) == 2
    assert {c.placement for c in first.contacts} == {stand.left, stand.right}
    frames = {talos.frame("left_foot"): "left", talos.frame("right_foot"): "right"}
    agree = total = 0
    for start, phase in zip(spec.phase_start_times()[1:-1], spec.phases[1:-1], strict=True):
        for c in phase.contacts:
            assert c.placement.position[2] == 0.0  # every stance on the floor
        mid = start + 0.5 * phase.duration - ref.lead_in
        f = int(round(mid / (motion.frame_time * ref.time_scale)))
        down = {frames[c.frame] for c in phase.contacts}
        agree += sum((side in down) == bool(labels[side][f]) for side in ("left", "right"))
        total += 2
    assert agree / total >= 0.9  # the knot grid merges only the shortest runs
    assert sum(1 for p in spec.phases if len(p.contacts) == 1) >= 5  # single supports, alternating
    assert not any(len(p.contacts) == 0 for p in spec.phases)  # a walk has no flight
    # its swings are low (talos's 0.073-0.105 m < HIGH_SWING): the 1.0 s lead-out kept, the task unchanged
    assert not ref.high_swing and last.duration == pytest.approx(1.0)


def test_strides_fit_the_robot(talos):
    _, _, spec, ref = _spec("12_01_walk.bvh", talos)
    assert 0.3 < ref.stride_scale < 0.8  # a human stride (~1.4 m) is over twice talos's 0.3 m step
    for side in ("left", "right"):
        frame = talos.frame(f"{side}_foot")
        spots = []
        for p in spec.phases:
            for c in p.contacts:
                if c.frame == frame and (not spots or spots[-1] != c.placement.position):
                    spots.append(c.placement.position)
        steps = [np.hypot(b[0] - a[0], b[1] - a[1]) for a, b in zip(spots, spots[1:], strict=False)]
        assert max(steps) <= 2 * talos.profile.step_length_max + 0.1  # 0.68 m measured; the human: ~1.4 m


def test_quick_steps_are_slowed_down_to_the_robots_pace(talos, monkeypatch):
    """The wave's traffic-directing steps swing a foot for 0.18 s; talos is asked for 0.4 s at least.
    (The arms' strength rule, whose per-knot poses cost ~1 s here, is not what this checks.)"""
    from tasks.mocap import retarget as rt

    monkeypatch.setattr(rt, "ARM_STRENGTH", False)
    _, _, spec, ref = _spec("13_26_wave.bvh", talos, 0.0, 2.0)
    assert ref.time_scale > 2.0
    swings = [p.duration for p in spec.phases[1:-1] if len(p.contacts) == 1]
    assert swings and min(swings) >= 0.5 * talos.profile.step_duration - spec.dt


def test_tracking_targets_are_soft_and_on_the_source(talos):
    _, _, spec, ref = _spec("13_29_squat.bvh", talos, 0.0, 1.0)
    assert spec.dynamic and all(t.priority is Priority.SOFT for t in spec.targets)
    roles = {t.name.split()[1] for t in spec.targets}
    assert {"base", "torso", "head", "left_hand", "right_hand", "heading"} <= roles
    # a hand target at a clip knot is the reference keypoint at that frame
    target = next(t for t in spec.targets if t.name.startswith("track right_hand") and t.time > ref.t[0] + 0.3)
    f = int(round((target.time - ref.t[0]) / (ref.t[1] - ref.t[0])))
    assert np.linalg.norm(np.array(target.position) - ref.points["right_hand"][f]) < 1e-9
    # the body scale of talos (base 1.08 m standing) to an adult CMU subject is about one
    assert 0.8 < ref.scale < 1.3


def test_a_deep_squat_is_raised_to_the_robots_lowest_base(talos):
    """The human's squat takes the pelvis to 40 % of its standing height; talos's base is asked to
    go no lower than 0.6 of its standing height (its thigh meshes pass into its pelvis below: coal
    in tests/wbmp/test_retarget_certified.py); the whole upper body is raised with it, the rest of
    the clip is untouched."""
    from tasks.mocap.retarget import MIN_BASE_HEIGHT
    from tasks.primitives.geometry import standing_geometry

    _, _, _, ref = _spec("13_29_squat.bvh", talos)
    stand = float(standing_geometry(talos).placements["base"].translation[2])
    base = ref.points["base"][:, 2]
    assert base.min() >= MIN_BASE_HEIGHT * stand - 1e-9
    assert 0.1 < ref.raised.max() < 0.4  # the human's 0.6 m drop, scaled, is deeper than talos's lowest base
    low = ref.raised > 0
    assert 0.1 < low.mean() < 0.8  # only around the bottom of the squat
    for role in ("torso", "head", "left_hand", "right_hand"):  # raised with the base: the body's shape is kept
        gap = ref.points[role][:, 2] - base
        assert np.ptp(gap[low]) < np.ptp(gap) + 1e-9
    np.testing.assert_allclose(base[~low], ref.points["base"][~low, 2])


def test_an_arm_held_out_sideways_is_brought_in_to_what_the_shoulder_carries(talos):
    """Talos's shoulder roll (arm_right_2_joint, 22.3 N m) cannot hold the stretched arm out sideways:
    Pinocchio's gravity torque of that pose is above the limit. The wave's raised right hand is
    brought in sideways where the human holds it out; the stretched arm rolled out as far
    sideways as the farthest target left has a gravity torque within the rule's margin of the limit
    (a bent arm's, its CoM nearer the shoulder, is less)."""
    import pinocchio as pin

    from tasks.mocap.retarget import ARM_TORQUE_MARGIN, _rot
    from tasks.primitives.geometry import standing_geometry

    model = talos.model
    data = model.createData()
    joint = model.getJointId("arm_right_2_joint")
    limit = float(model.effortLimit[model.joints[joint].idx_v])

    def gravity(angle: float) -> float:  # the stretched arm rolled out sideways by ``angle`` [rad]
        q = np.array(talos.q_standing, dtype=float)
        for i in range(1, 8):
            q[model.joints[model.getJointId(f"arm_right_{i}_joint")].idx_q] = 0.0
        q[model.joints[joint].idx_q] = -angle
        return abs(float(pin.computeGeneralizedGravity(model, data, q)[model.joints[joint].idx_v]))

    assert gravity(np.pi / 2) > limit  # out sideways: beyond the shoulder
    _, _, _, ref = _spec("13_26_wave.bvh", talos)
    assert ref.arm_moved["right"].max() > 0.1 and ref.arm_moved["left"].max() < 0.05
    d = np.einsum("fba,fb->fa", _rot(ref.heading), ref.points["right_hand"] - ref.points["right_shoulder"])
    length = standing_geometry(talos).arm_length["right"]
    out = float(np.max(np.abs(d[:, 1]))) / length  # the farthest out sideways a hand is left, of the arm
    assert gravity(float(np.arcsin(out))) <= ARM_TORQUE_MARGIN * limit * 1.02


@pytest.mark.parametrize("name", ["talos", "g1"])
def test_the_shoulders_are_held_out_away_from_the_torso(name):
    """G1's upper arm hangs 9 mm from its torso at standing (a pair the planner's capsules cannot
    keep apart): the posture term's target angles take each hand outwards (Pinocchio forward
    kinematics) and the upper arm away from the torso (the coal distance between their meshes
    grows). Talos's weak shoulder roll is not asked to hold its arm out."""
    import coal
    import pinocchio as pin

    from tasks.mocap.retarget import shoulders_out

    robot = talos_or_g1(name)
    model, gm = robot.model, robot.collision_model
    data, gd = model.createData(), pin.GeometryData(gm)
    targets = shoulders_out(robot, 3.0)
    if name == "talos":  # its shoulder roll cannot carry the stretched arm held out: not asked to
        assert targets == ()
        return
    assert len(targets) == 2 and all(t.window == (0.0, 3.0) and t.weight > 0 for t in targets)
    torso_joint = model.frames[robot.frame_id("torso")].parentJoint
    torso = [i for i, g in enumerate(gm.geometryObjects) if g.parentJoint == torso_joint]

    def gap(q: np.ndarray, side: str) -> float:
        pin.updateGeometryPlacements(model, data, gm, gd, q)
        joint = model.frames[robot.frame_id(f"{side}_shoulder")].parentJoint
        arm = [i for i, g in enumerate(gm.geometryObjects) if g.parentJoint in (joint, joint + 1)]
        best = np.inf
        for i in torso:
            for j in arm:
                r = coal.DistanceResult()
                coal.distance(gm.geometryObjects[i].geometry, coal.Transform3s(gd.oMg[i]),
                              gm.geometryObjects[j].geometry, coal.Transform3s(gd.oMg[j]), coal.DistanceRequest(), r)
                best = min(best, r.min_distance)
        return best

    q = np.array(robot.q_standing, dtype=float)
    for t in targets:
        q[model.joints[model.getJointId(t.joint)].idx_q] = t.value
    stand = np.array(robot.q_standing, dtype=float)

    def out(q: np.ndarray, side: str) -> float:
        pin.framesForwardKinematics(model, data, q)
        return abs(float(data.oMf[robot.frame_id(f"{side}_hand")].translation[1]
                         - data.oMf[robot.frame_id("base")].translation[1]))

    for t in targets:
        side = t.name.split()[0]
        assert out(q, side) > out(stand, side) + 0.03
        assert gap(q, side) > gap(stand, side) + 0.01


def talos_or_g1(name: str):
    return load_robot(name)


def test_a_swinging_foot_is_tracked_from_its_placement_onto_the_next():
    """swing_target on a synthetic swing (knots 0 and 6 in stance): it first only goes up, keeps the
    source's lift, is over the next placement a knot before touch-down (then only comes down), and
    its path across runs from one placement to the other although the source foot drifts
    backwards (as the stride scale makes a walk's source feet do)."""
    from tasks.mocap.retarget import swing_target

    n = 7
    src = np.zeros((n, 3))
    src[:, 0] = np.linspace(1.0, 0.6, n)  # the source foot drifts backwards
    src[:, 2] = [0.0, 0.03, 0.06, 0.08, 0.06, 0.03, 0.0]
    held = np.full((n + 1, 3), np.nan)
    held[0], held[6], held[7] = [0.1, 0.1, 0.0], [0.4, 0.1, 0.0], [0.4, 0.1, 0.0]
    path = np.array([swing_target(src, held, k, np.zeros(3)) for k in range(1, 6)])
    assert np.allclose(path[:, 2], src[1:6, 2])  # the lift is the source's (its ends are on the floor)
    assert np.allclose(path[-1, :2], held[6, :2])  # over the placement a knot before touch-down
    assert np.allclose(path[0, :2], held[0, :2])  # and over the one it left at the first swinging knot
    # across: onwards (the source's steady drift against the smoothstep can leave a knot up to ~1 cm
    # back of the blend), never sideways
    assert np.all(np.diff(path[:, 0]) > -0.01) and path[3, 0] > path[1, 0] and np.allclose(path[:, 1], 0.1)
    assert 0.1 < path[1, 0] < path[3, 0] < 0.4
    # a swing from the clip's first knot leaves the lead-in's placement
    held0 = held.copy()
    held0[0] = np.nan
    first = np.array([0.0, 0.1, 0.0])  # 1 m from the source foot's first position
    assert np.linalg.norm(swing_target(src, held0, 0, first)[:2] - first[:2]) < 0.07  # a knot's worth of the step


def test_a_walks_swinging_feet_are_tracked_onto_their_placements(talos):
    """Talos's walk: the source's foot a knot before touch-down was 0.17-0.22 m from the placement it
    lands on (the stride scale pulls the source's stances back; the labels begin late), so the plan
    lunged onto it in the last knot; the tracked target is now over the placement there."""
    _, _, spec, ref = _spec("12_01_walk.bvh", talos)
    starts = spec.phase_start_times()
    landings = 0
    for side in ("left", "right"):
        frame = talos.frame(f"{side}_foot")
        targets = sorted((t for t in spec.targets if t.name.startswith(f"track {side}_foot")), key=lambda t: t.time)
        assert len(targets) >= 10
        for t0, phase in zip(starts, spec.phases, strict=True):
            here = [c for c in phase.contacts if c.frame == frame]
            before = [t for t in targets if t0 - 1.5 * spec.dt < t.time < t0 - 1e-9]
            if not here or not before or t0 < ref.lead_in + 1e-9:
                continue
            gap = np.linalg.norm(np.array(before[-1].position[:2]) - np.array(here[0].placement.position[:2]))
            assert gap < 1e-6, (side, t0, gap)
            landings += 1
    assert landings >= 6


def test_a_clip_slowed_beyond_the_planners_bound_is_refused_naming_its_quickest_swing(talos, monkeypatch):
    """A clip whose quickest swing slows it so much that its tracking targets exceed what wbmp plans
    at once is refused with one line naming the slowdown, that swing and the fix (was: the spec's
    own 'split it into several specs', which a retarget user cannot do). The wave, its swings asked
    to last 4 of talos's steps: 2.4 s -> ~43 s."""
    from tasks.exceptions import ClipError
    from tasks.mocap import retarget as rt

    monkeypatch.setattr(rt, "MIN_SWING", 4.0)
    monkeypatch.setattr(rt, "ARM_STRENGTH", False)  # its per-knot poses of the 43 s clip: not what this checks
    with pytest.raises(ClipError, match=r"slowed \d+\.\d+ x \(its quickest foot swing, 0\.\d+ s.*--start/--end"):
        _spec("13_26_wave.bvh", talos)


def test_a_jump_in_place_that_must_be_slowed_is_made_with_both_feet_down(talos, monkeypatch):
    """A flight cannot be slowed (its duration is its height): the wave (it travels 4 cm and is
    slowed 4.4 x for talos's steps) given a made-up 0.1 s flight keeps both feet down throughout,
    is slowed GROUNDED_SLOW x instead, and names the grounded flight; the walk (it travels 3.9 m) given the same
    flight keeps its labels (a jump that travels is left to the planner)."""
    from tasks.mocap import retarget as rt
    from tasks.mocap.retarget import GROUNDED_SLOW, ground_jumps, time_scale

    # the made-up flight's feet do not rise: quick_shuffles would rightly call it no flight at all
    monkeypatch.setattr(rt, "QUICK_SHUFFLES", False)
    for name, grounded in (("13_26_wave.bvh", True), ("12_01_walk.bvh", False)):
        clip = read_bvh(EXAMPLES / name).window(0.0, None)
        motion = human_motion(clip, recognize_skeleton(clip.names))
        labels = label_contacts(motion)
        assert time_scale(motion, labels, talos) > 1.0
        jumped = {s: np.asarray(v, dtype=bool).copy() for s, v in labels.items()}
        mid = len(motion.t) // 2
        for s in jumped:
            jumped[s][mid:mid + 12] = False
        out, seconds = ground_jumps(motion, jumped, talos)
        if not grounded:
            assert seconds == 0.0 and all(np.array_equal(out[s], jumped[s]) for s in out)
            continue
        assert seconds == pytest.approx(12 * motion.frame_time)
        assert all(out[s].all() for s in out)
        spec, ref = retarget_spec(motion, jumped, talos)
        assert ref.grounded_s == pytest.approx(seconds) and ref.time_scale == GROUNDED_SLOW
        assert all(len(p.contacts) == 2 for p in spec.phases)
        assert spec.horizon == pytest.approx(GROUNDED_SLOW * motion.t[-1] + 0.8 + 1.0, abs=0.1)


def test_a_clip_with_high_swings_ends_on_a_whole_knot_so_the_planners_knots_fall_on_its_phases():
    """G1's forward jumps made as steps (13.28 s of clip, 166 knots): with a 1.0 s lead-out (12.5
    knots) the planner's grid (planner.trajopt.layout.knot_grid) put its knots 0.0797 s apart, off
    the phases' starts (2.56 s fell between knots at 2.552 and 2.632 s: the plan's foot was still
    up there); with the lead-out in whole knots every phase starts on a knot. A clip without high
    swings keeps LEAD_OUT (its task unchanged)."""
    from types import SimpleNamespace

    from planner.trajopt.layout import knot_grid
    from tasks.mocap.retarget import DT, LEAD_IN, LEAD_OUT, _lead_out

    starts = LEAD_IN + DT * np.array([0, 13, 22, 24, 34, 166])  # phase starts; the last: the lead-out's
    for high in (True, False):
        horizon = float(starts[-1]) + _lead_out(high, DT)
        _, _, times = knot_grid(SimpleNamespace(horizon=horizon, dt=DT))
        off = np.abs(starts[:, None] - times[None, :]).min(axis=1)
        assert (off.max() < 1e-9) == high, off
    assert _lead_out(False, DT) == LEAD_OUT and abs(_lead_out(True, DT) - LEAD_OUT) < DT


PUNCH = Path("/work/shared/mocap/135_09_punch.bvh")


# ~25 s (the whole clip and g1's collision model): long; its fast twin is
# tests/tasks/mocap/test_keepout.py::test_a_lunge_whose_knees_would_meet_is_pushed_apart
@pytest.mark.long
@pytest.mark.skipif(not PUNCH.exists(), reason="the shared CMU clips are not on this machine")
def test_a_boxers_stance_has_its_feet_apart_under_the_hips():
    """CMU 135_09 (a boxer's stepping lunges, feet turned from the pelvis): kept apart in the feet's
    own frame only, the feet came in line under g1's hips (0.5 mm apart sideways, 0.4 m fore and aft)
    and the plan crossed a thigh through the other shin; now, in the hips' frame (the base target's
    heading), wherever the feet are within KNEE_REACH soles' lengths they are at least FOOT_GAP
    standing gaps apart sideways (the long tests certify it: test_retarget_certified.py)."""
    from tasks.mocap import keepout

    g1 = load_robot("g1")
    clip = read_bvh(PUNCH)
    motion = human_motion(clip, recognize_skeleton(clip.names))
    _, ref = retarget_spec(motion, label_contacts(motion), g1)
    h = ref.heading
    d = ref.points["left_foot"] - ref.points["right_foot"]
    lateral = d[:, 0] * -np.sin(h) + d[:, 1] * np.cos(h)
    sole = g1.profile.sole
    near = np.linalg.norm(d[:, :2], axis=1) < keepout.KNEE_REACH * max(sole.x_max - sole.x_min, keepout.standing_gap(g1))
    assert near.sum() > 100  # the clip's stances and passing feet
    assert lateral[near].min() >= keepout.FOOT_GAP * keepout.standing_gap(g1) - 1e-9
    assert 0.1 < max(ref.kept_out_max().values()) < 0.6


def test_stance_placements_in_line_under_the_hips_are_moved_apart(talos):
    """Two overlapping stances whose placements (the medians of pivoting feet) are in line under
    the hips (heading 90 deg: the left foot 0.1 m ahead along y of the right, no sideways gap): the
    foot placed later (the left) is moved sideways in the hips' frame (-x here) to FOOT_GAP x the
    standing gap; the earlier one and a pair already apart are not moved."""
    from tasks.mocap import keepout
    from tasks.mocap.retarget import _placements_apart
    from tasks.specs import Pose

    least = keepout.FOOT_GAP * keepout.standing_gap(talos)
    heading = np.full(40, np.pi / 2)
    for gap, moved in ((0.0, True), (2.0 * least, False)):
        runs = {"right": [(0, 5, Pose(position=(0.0, 0.0, 0.0), rpy=(0.0, 0.0, 0.0))),
                          (6, 40, Pose(position=(0.3, 0.0, 0.0), rpy=(0.0, 0.0, np.pi / 2)))],
                "left": [(10, 30, Pose(position=(0.3 - gap, 0.1, 0.0), rpy=(0.0, 0.0, np.pi / 2)))]}
        out = _placements_apart(runs, heading, talos)
        assert out["right"] == runs["right"]
        left = np.array(out["left"][0][2].position)
        lateral = -(left[0] - 0.3)  # the hips' left axis is -x at heading 90 deg
        assert lateral == pytest.approx(least if moved else gap, abs=1e-9)
        assert left[1] == pytest.approx(0.1, abs=1e-12) and left[2] == 0.0


KICK = Path("/work/shared/mocap/10_02_kick.bvh")
JUMPS = Path("/work/shared/mocap/01_01_jump_forward.bvh")


# ~10 s (two whole clips): long; its fast twins are tests/tasks/mocap/test_legs.py's
# test_quick_low_swings_on_the_spot_are_no_steps and test_a_two_footed_jump_becomes_a_step_of_each_foot
@pytest.mark.long
@pytest.mark.skipif(not (KICK.exists() and JUMPS.exists()), reason="the shared CMU clips are not on this machine")
def test_the_kick_and_the_forward_jumps_become_steps_the_robot_can_make(talos):
    """The kick was refused (its 0.11 s swing on the spot slowed it 7.4 x to 36 s, past the 3000
    items wbmp plans at once): its quick swings on the spot are no steps and its leap is a running
    step, so it is slowed for its real steps only (talos: 0.25 s -> 0.8 s, 3.2 x) and has no flight.
    The forward jumps (0.37-0.47 s flights, 0.9 m each) become a step of each foot per jump: no
    flight either, slowed less than 2.5 x, the base never asked above its standing height."""
    for path, most in ((KICK, 3.3), (JUMPS, 2.5)):
        clip = read_bvh(path).window(0.0, None)
        motion = human_motion(clip, recognize_skeleton(clip.names))
        spec, ref = retarget_spec(motion, label_contacts(motion), talos)
        assert 1.0 < ref.time_scale <= most and ref.stepped_s > 0.2
        assert all(len(p.contacts) >= 1 for p in spec.phases)
        stand_z = float(standing_geometry(talos).placements["base"].translation[2])
        base_z = max(t.position[2] for t in spec.targets if t.name.startswith("track base "))
        assert base_z <= stand_z + 0.02
