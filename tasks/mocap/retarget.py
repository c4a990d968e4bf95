"""A human clip as a robot task: scaled, aligned, cut into contact phases, tracked by costs.

:func:`retarget_spec` makes the whole-trajectory problem the planner solves (docs/retarget.md):

* **Scale** (one number per robot and clip): the robot's standing base height over the human's
  standing pelvis height (leg length from hip to ankle, its 95th percentile over the clip, plus the
  ankle's height and the pelvis above the hips). Arms get their own ratio (the robot's
  shoulder-to-hand chain over the human's longest shoulder-to-hand distance).
* **Align**: the clip already faces +x from the pelvis at its first frame with the ground at 0
  (:func:`tasks.mocap.source.human_motion`); the whole scaled clip is moved so that its first-frame
  feet sit where the robot's standing feet are (their mean), and each foot keeps the offset of its
  first frame (turned with the foot's yaw), so the robot's stance width is kept.
* **Contacts**: the labelled contacts (:func:`tasks.mocap.source.label_contacts`), sampled on the
  knot grid, become phases; each stance of a foot is one fixed placement on the ground (the
  median of the scaled source foot over the stance): the planner holds it in 6D (no slip) and
  keeps every other foot above the floor. A stance that holds at the first frame is the standing
  placement. A lead-in (standing) precedes the clip and a lead-out (both feet down where they last
  were) follows it, so the motion starts and ends at rest.
* **Tracking**: soft targets at every knot of the clip on the base (position and heading), torso,
  head, both hands and, while swinging, both feet: the scaled source keypoints, each with a
  per-keypoint offset for the robot's proportions (torso, head, shoulders: the median offset from
  the pelvis in the heading frame; hands: from the tracked shoulder, with the arm ratio).

The robot's joint, velocity and torque limits, friction, self-collision and (when a phase has one
foot or none) the centroidal dynamics are the planner's, as for any spec.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from itertools import pairwise

import numpy as np
import pinocchio as pin

from robots import Robot
from tasks.exceptions import ClipError
from tasks.limits import MAX_ITEMS
from tasks.mocap.keepout import feet_yaw, keep_feet_apart, keep_hands_out
from tasks.mocap.legs import (
    EARLY_STEP,
    HIGH_SWING,
    apart_from_stance,
    land_softly,
    no_higher_than_standing,
    quick_shuffles,
    steps_for_flights,
)
from tasks.mocap.source import SIDES, HumanMotion, segments
from tasks.mocap.splay import keep_splay
from tasks.mocap.strength import Gap, gaps_of, hold_within_strength
from tasks.primitives.geometry import Stance, standing_geometry
from tasks.specs import (
    CoMBounds,
    Contact,
    FrameTarget,
    JointTarget,
    Phase,
    Pose,
    Priority,
    TaskSpec,
)

LEAD_IN = 0.8  # [s] from standing into the clip's first pose (the targets blend over it)
LEAD_OUT = 1.0  # [s] both feet down after it (coming to rest)
DT = 0.08  # [s] knot spacing
#: [s] The knot spacing of a clip slowed for the robot by at least COARSE_SLOW: its knots then sample
#: the human's motion at most every 0.04 s of the human's time (half an unslowed clip's DT), with a
#: fifth fewer of them (talos's wave, slowed 4.4 x: 143 -> 115 knots, 35 -> 30 s of CPU, certified).
#: A divisor of the lead-in.
COARSE_DT = 0.1
#: [-] From 1.25 x (COARSE_DT / DT) talos's walk (1.88 x) and g1's certified too, but talos's
#: forward jumps (made as steps, 2.23 x) did not: its right hand 53 mm off its plan (> 50 mm) at
#: 10.25 s, certified on 0.08 s knots.
COARSE_SLOW = 2.5
MIN_PHASE_KNOTS = 2  # a contact phase shorter than this many knot intervals joins its neighbour
MAX_CLIP = 60.0 - LEAD_IN - LEAD_OUT  # [s] the planner's work bound (tasks.limits.MAX_HORIZON) less lead-in/out
# Cost weights per second of tracked motion [1/m^2 s]; a knot's weight is this times dt.
WEIGHTS = {"base": 400.0, "torso": 100.0, "head": 100.0, "left_hand": 200.0, "right_hand": 200.0,
           "left_foot": 200.0, "right_foot": 200.0}
SMOOTHNESS = 1e-2  # [-] the spec's cost on accelerations (TaskSpec's default 1e-3 let a walk's plan fail its RNEA check)
HEADING_WEIGHT = 20.0  # [1/rad^2 s] base orientation towards the source heading
SWING_CLEARANCE = (0.01, 0.08)  # [m] mid-swing clearance asked of a foot: 0.8 x the source's lift, within these
# The tracking targets' report tolerance [m]: the simulation's certificate checks each target within
# it (plus its margin): the robot executing the plan, not the plan matching the human (that is
# the tracking error among the figures; a robot's proportions keep it centimetres away).
TRACK_TOLERANCE = 0.25
STRIDE_STEPS = 2.0  # [-] the longest stride asked, in the robot's longest steps (stride_scale)
MIN_SWING = 1.0  # [-] of the robot's step duration: the shortest swing it is asked for (time_scale)
LAND_VERTICALLY = True  # a swinging foot is over its next placement a knot before touch-down (swing_target)
SWING_TO_PLACEMENTS = True  # a swinging foot is tracked from its placement to its next (swing_target)
LAND_SOFTLY = True  # ... and comes onto it no faster than legs.LAND_SPEED (swing_target)
SWING_APART = True  # ... and is kept apart sideways from the standing foot (legs.apart_from_stance)
SHUFFLE_LIFT = 0.05  # [m] a swing lower than this ...
GROUNDED_TRAVEL = 0.3  # [m] a clip that jumps and travels less than this is made with its feet down (ground_jumps)
#: [-] how much slower than the human a grounded clip is made: its arms and body keep the tempo of the
#: jumps (talos's jumping jacks at the human's speed: its wrist at its 6.6 N m limit, a fall; at half
#: the speed: certified, as on g1)
GROUNDED_SLOW = 2.0
SHUFFLE_STEP = 0.08  # [m] ... that lands closer than this to where it left is no step (drop_shuffles)
#: [-] of the robot's standing base height: the lowest the base is asked to go. A deeper human squat
#: is raised as a whole (base, torso, head, arms) to this: at talos's hip pitch of -1.9 rad (base
#: 0.55 m) its thigh meshes pass into its pelvis (coal), a pair its capsule model cannot keep apart
#: (they touch at rest); at 0.6 they stay 19 mm apart. The report names the lift (``raised_m``).
MIN_BASE_HEIGHT = 0.6
QUICK_SHUFFLES = True  # quick low swings on the spot are no steps (legs.quick_shuffles)
STEPS_FOR_FLIGHTS = True  # a travelling jump that must be slowed is made as steps (legs.steps_for_flights)
KEEP_OUT = True  # hand targets kept off the robot's pelvis and thighs, feet apart (tasks.mocap.keepout)
ARM_STRENGTH = True  # hand targets within what the arms' joints hold (tasks.mocap.strength)
#: [rad] how far out from standing a soft posture term holds each shoulder's joint (the joint carrying
#: the robot's shoulder frame: the roll on talos and G1), and its weight: the planner's capsules do
#: not keep the upper arm off the torso (they touch at rest), so an arm brought in to the chest
#: passed into it on the meshes (G1's chicken dance: torso / upper arm 13 mm deep; with this,
#: certified, the tracking error's mean 15.5 against 15.3 mm).
SHOULDER_OUT = 0.15
SHOULDER_WEIGHT = 10.0
#: [-] of a shoulder joint's torque limit: the most an arm's weight may ask of it (the rest moves the
#: arm; with 0.8 talos's waving hand sagged 61 mm off its plan, with 0.65 the wave is certified).
ARM_TORQUE_MARGIN = 0.65
TRACKED = ("base", "torso", "head", "left_hand", "right_hand", "left_foot", "right_foot")


@dataclass(frozen=True, eq=False)
class Reference:
    """The scaled source on the robot, on the clip's frames and the planner's time axis.

    Attributes:
        t: Frame times on the plan's time axis (F,) [s] (the lead-in shifts them).
        points: Robot role -> target positions (F, 3) [m] (base, torso, head, hands, feet).
        contact: Foot side -> labelled contact per frame (F,).
        placements: Foot side -> per frame, the sole's fixed ground position while in contact
            (F, 3) [m] (NaN in swing).
        heading: Source heading per frame (F,) [rad].
        scale: Body scale robot / human [-].
        arm_scale: Arm scale robot / human [-].
        lead_in: Seconds of standing before the clip [s].
        stride_scale: How much the body's travel over the ground was shortened to fit the robot's
            longest stride (1: not shortened).
        time_scale: How much slower than the human the robot moves (1: as fast; :func:`time_scale`).
        raised: Per frame, how far the body was raised so that the base stays at
            :data:`MIN_BASE_HEIGHT` of its standing height or above (F,) [m] (a deep squat's gap).
        arm_moved: Hand side -> per frame, how far the hand target was brought in sideways so
            that the arm's weight stays within its shoulder's torque limits (F,) [m]
            (:func:`arm_reach`: talos cannot hold its arm out sideways).
        kept_out: Role (hands, feet) -> per frame, how far its target was moved out of the
            robot's own body (F,) [m] (:mod:`tasks.mocap.keepout`).
        grounded_s: Seconds of the source's flights (both feet up) the robot makes with both feet
            down instead (:func:`ground_jumps`; 0: none).
        splay_turned: How far a stance placement was turned at most so that the feet's relative
            yaw stays within the robot's hip yaw range [rad] (:mod:`tasks.mocap.splay`).
        arm_held: Hand side -> per frame, how far the hand target was brought in towards its
            shoulder's vertical so that the robot's pose for it is within its arm joints' torque
            limits (F,) [m] (:func:`tasks.mocap.strength.hold_within_strength`).
        gaps: Each target's largest move away from the scaled source, and why, in body terms
            (:class:`tasks.mocap.strength.Gap`).
        stepped_s: Seconds of the source's flights the robot makes as steps, a foot down
            (:func:`tasks.mocap.legs.steps_for_flights`: a travelling jump; 0: none).
    """

    t: np.ndarray
    points: dict[str, np.ndarray]
    contact: dict[str, np.ndarray]
    placements: dict[str, np.ndarray]
    heading: np.ndarray
    scale: float
    arm_scale: float
    lead_in: float
    stride_scale: float = 1.0
    time_scale: float = 1.0
    raised: np.ndarray | None = None
    arm_moved: dict[str, np.ndarray] | None = None
    kept_out: dict[str, np.ndarray] | None = None
    grounded_s: float = 0.0
    splay_turned: float = 0.0
    arm_held: dict[str, np.ndarray] | None = None
    gaps: tuple[Gap, ...] = ()
    stepped_s: float = 0.0

    def raised_max(self) -> float:
        """How far the body was raised at most to keep the base at its lowest (a deep squat's gap) [m]."""
        return 0.0 if self.raised is None or len(self.raised) == 0 else float(np.max(self.raised))

    def arm_moved_max(self) -> dict[str, float]:
        """Hand side -> how far its target was brought in sideways at most (its shoulder's torque
        limits) [m]."""
        return {side: float(np.max(v)) if len(v) else 0.0 for side, v in (self.arm_moved or {}).items()}

    def kept_out_max(self) -> dict[str, float]:
        """Role (hand or foot) -> how far its target was moved out of the robot's body at most
        (:mod:`tasks.mocap.keepout`: hands off the pelvis and thighs, feet apart) [m]."""
        return {role: float(np.max(v)) if len(v) else 0.0 for role, v in (self.kept_out or {}).items()}

    def arm_held_max(self) -> dict[str, float]:
        """Hand side -> how far its target was brought in at most for its arm joints' torques [m]."""
        return {side: float(np.max(v)) if len(v) else 0.0 for side, v in (self.arm_held or {}).items()}


def _rot(yaw: np.ndarray | float) -> np.ndarray:
    yaw = np.asarray(yaw, dtype=float)
    c, s = np.cos(yaw), np.sin(yaw)
    out = np.zeros((*yaw.shape, 3, 3))
    out[..., 0, 0], out[..., 0, 1], out[..., 1, 0], out[..., 1, 1], out[..., 2, 2] = c, -s, s, c, 1.0
    return out


def body_scale(motion: HumanMotion, robot: Robot) -> tuple[float, float]:
    """(body scale, arm scale) robot / human (see the module)."""
    g = standing_geometry(robot)
    P = motion.points
    leg = np.mean([np.percentile(np.linalg.norm(P[f"{s}_hip"] - P[f"{s}_ankle"], axis=1), 95) for s in SIDES])
    ankle = np.mean([np.percentile(P[f"{s}_ankle"][:, 2], 5) for s in SIDES])
    above = np.median(P["pelvis"][:, 2] - 0.5 * (P["left_hip"][:, 2] + P["right_hip"][:, 2]))
    human = float(leg + ankle + above)
    robot_base = float(g.placements["base"].translation[2])
    arm = np.mean([np.percentile(np.linalg.norm(P[f"{s}_hand"] - P[f"{s}_shoulder"], axis=1), 99) for s in SIDES])
    robot_arm = float(np.mean([g.arm_length[s] for s in SIDES]))
    return robot_base / human, robot_arm / float(arm)


def reference(motion: HumanMotion, labels: dict[str, np.ndarray], robot: Robot, *,
              lead_in: float = LEAD_IN) -> Reference:
    """The scaled and aligned source keypoints and foot placements (see the module)."""
    g = standing_geometry(robot)
    stand = {role: M.translation for role, M in g.placements.items()}
    s, s_arm = body_scale(motion, robot)
    P = {k: s * v for k, v in motion.points.items()}
    heading = motion.heading()
    R = _rot(heading)
    stride = stride_scale(P, labels, robot)
    pelvis_xy = P["pelvis"] * [1.0, 1.0, 0.0]
    P = {k: v - (1.0 - stride) * pelvis_xy for k, v in P.items()}  # the body's travel shortened, its shape kept
    foot = {side: 0.5 * (P[f"{side}_ankle"] + P[f"{side}_toe"]) for side in SIDES}
    for side in SIDES:
        foot[side][:, 2] = np.minimum(P[f"{side}_ankle"][:, 2], P[f"{side}_toe"][:, 2])
    shift = np.mean([stand[f"{side}_foot"] - foot[side][0] for side in SIDES], axis=0)
    shift[2] = 0.0
    P = {k: v + shift for k, v in P.items()}
    foot = {side: v + shift for side, v in foot.items()}
    points: dict[str, np.ndarray] = {}
    placements: dict[str, np.ndarray] = {}
    contact = {side: np.asarray(labels[side], dtype=bool) for side in SIDES}
    # the base: the pelvis, its height corrected to the robot's standing base height
    base_z = stand["base"][2] - float(np.percentile(P["pelvis"][:, 2], 95))
    points["base"] = P["pelvis"] + [0.0, 0.0, base_z]
    # a squat deeper than the robot's lowest base is raised as a whole (MIN_BASE_HEIGHT): the torso,
    # head, shoulders and hands are placed from the base below
    raised = np.maximum(0.0, MIN_BASE_HEIGHT * stand["base"][2] - points["base"][:, 2])
    points["base"][:, 2] += raised
    t = motion.t + lead_in
    gaps: list[Gap | None] = [gaps_of("base", points["base"] - raised[:, None] * [0.0, 0.0, 1.0], points["base"], t,
                                      heading, f"the robot's lowest base ({MIN_BASE_HEIGHT:g} of its standing height)")]
    for key, role in (("torso", "torso"), ("head", "head"), ("left_shoulder", "left_shoulder"),
                      ("right_shoulder", "right_shoulder")):
        robot_rel = stand[role] - stand["base"]  # standing: heading 0
        human_rel = np.einsum("fba,fb->fa", R, P[key] - P["pelvis"])  # in the heading frame
        offset = robot_rel - np.median(human_rel, axis=0)
        points[role] = points["base"] + (P[key] - P["pelvis"]) + np.einsum("fab,b->fa", R, offset)
    arm_moved = _place_hands(points, P, R, stand, s_arm, robot, t, heading, gaps)
    arm_held: dict[str, np.ndarray] = {}
    if ARM_STRENGTH:  # the hands within what the arms' joints hold (tasks.mocap.strength)
        hands, arm_held, held = hold_within_strength(robot, points, heading, t)
        points.update({f"{side}_hand": hands[side] for side in SIDES})
        gaps += held
    kept_out: dict[str, np.ndarray] = {}
    if KEEP_OUT:  # the hands off the robot's pelvis, hips and thighs (tasks.mocap.keepout)
        hands, moved = keep_hands_out({side: points[f"{side}_hand"] for side in SIDES}, points["base"], R, robot)
        for side in SIDES:
            gaps.append(gaps_of(f"{side}_hand", points[f"{side}_hand"], hands[side], t, heading,
                                "the robot's pelvis and thighs (the hand kept out of them)"))
            points[f"{side}_hand"] = hands[side]
            kept_out[f"{side}_hand"] = moved[side]
    soles: dict[str, np.ndarray] = {}
    for side in SIDES:
        # the robot's stance width: the foot's sideways offset from the pelvis (heading frame, median
        # over the labelled stances) becomes the robot's standing one
        lateral = np.einsum("fba,fb->fa", R, foot[side] - P["pelvis"])[:, 1]
        stance = contact[side] if contact[side].any() else np.ones(len(lateral), dtype=bool)
        d_y = (stand[f"{side}_foot"][1] - stand["base"][1]) - float(np.median(lateral[stance]))
        sole = foot[side] + np.einsum("fab,b->fa", R, np.array([0.0, d_y, 0.0]))
        sole[:, 2] = np.maximum(sole[:, 2], 0.0)
        soles[side] = sole
    if KEEP_OUT:  # the feet at least FOOT_GAP of the robot's standing gap apart (tasks.mocap.keepout)
        # in the feet's own frame, then in the hips' (the legs hang from the hips: a boxer's stance,
        # feet turned from the pelvis, has them apart in their own frame but in line under the hips)
        before = {side: soles[side].copy() for side in SIDES}
        soles, _ = keep_feet_apart(soles, contact, feet_yaw(motion), robot)
        soles, _ = keep_feet_apart(soles, contact, heading, robot)
        kept_out.update({f"{side}_foot": np.linalg.norm(soles[side] - before[side], axis=1) for side in SIDES})
        gaps += [gaps_of(f"{side}_foot", before[side], soles[side], t, heading,
                         "the other foot (the feet kept apart)") for side in SIDES]
    for side in SIDES:
        sole = soles[side]
        points[f"{side}_foot"] = sole
        contact[side] = drop_shuffles(contact[side], sole)
        fixed = np.full_like(sole, np.nan)
        for a, b, down in segments(contact[side]):
            if not down:
                continue
            where = stand[f"{side}_foot"] if a == 0 else np.array([*np.median(sole[a:b, :2], axis=0), 0.0])
            fixed[a:b] = where
        placements[side] = fixed
    return Reference(t=motion.t + lead_in, points=points, contact=contact, placements=placements,
                     heading=heading, scale=s, arm_scale=s_arm, lead_in=lead_in, stride_scale=stride, raised=raised,
                     arm_moved=arm_moved, kept_out=kept_out, arm_held=arm_held,
                     gaps=tuple(g for g in gaps if g is not None))


def _shoulder_joint(robot: Robot, side: str) -> str:
    """The name of the joint that carries the robot's ``side`` shoulder frame."""
    return str(robot.model.names[int(robot.model.frames[robot.frame_id(f"{side}_shoulder")].parentJoint)])


def _place_hands(points: dict[str, np.ndarray], P: dict[str, np.ndarray], R: np.ndarray,  # noqa: N803
                 stand: dict[str, np.ndarray], s_arm: float, robot: Robot, t: np.ndarray, heading: np.ndarray,
                 gaps: list[Gap | None]) -> dict[str, np.ndarray]:
    """The hand targets (into ``points``) from the tracked shoulders with the arm ratio ``s_arm``, as
    the robot's arms hang and reach (see :func:`reference`); returns how far each was brought in
    sideways per frame (:func:`arm_reach`), its gap appended to ``gaps``."""
    g = standing_geometry(robot)
    arm_moved: dict[str, np.ndarray] = {}
    for side in SIDES:
        arm = s_arm * (P[f"{side}_hand"] - P[f"{side}_shoulder"])
        # a hanging arm hangs as the robot's does at standing (its hands clear of its thighs): the
        # offset between the two, in the heading frame, applied in full to a hanging arm and
        # fading out as the arm rises to horizontal
        hang = np.clip(-arm[:, 2] / max(1e-6, float(np.linalg.norm(arm, axis=1).max())), 0.0, 1.0)
        k = int(np.argmax(hang))
        robot_arm = stand[f"{side}_hand"] - stand[f"{side}_shoulder"]
        offset = robot_arm - R[k].T @ arm[k]
        hand = points[f"{side}_shoulder"] + arm + hang[:, None] * np.einsum("fab,b->fa", R, offset)
        # below the hips, a hand stays at least as far out sideways as the robot's standing hand
        # (the robot's thighs are wider than a human's: a swinging hand would strike them)
        local = np.einsum("fba,fb->fa", R, hand - points["base"])
        sign = 1.0 if side == "left" else -1.0
        least = sign * (stand[f"{side}_hand"][1] - stand["base"][1])
        low = local[:, 2] < 0.0
        local[low, 1] = sign * np.maximum(sign * local[low, 1], least)
        hand = points["base"] + np.einsum("fab,fb->fa", R, local)
        most = arm_reach(robot, side) * g.arm_length[side]
        points[f"{side}_hand"] = _hold_arm(hand, points[f"{side}_shoulder"], R, most)
        arm_moved[side] = np.linalg.norm(points[f"{side}_hand"] - hand, axis=1)
        gaps.append(gaps_of(f"{side}_hand", hand, points[f"{side}_hand"], t, heading,
                            f"{_shoulder_joint(robot, side)}'s torque limit (the arm held out sideways)"))
    return arm_moved


def arm_reach(robot: Robot, side: str) -> float:
    """The farthest a hand may be held out sideways from its shoulder, as a fraction of the arm's
    length [-] (1: anywhere). For the joint carrying the robot's shoulder frame and its parent:
    the arm beyond it, stretched horizontally, loads it with its weight times its CoM's distance;
    where that is more than :data:`ARM_TORQUE_MARGIN` of the joint's torque limit, the hand is kept
    within that fraction out sideways (a bent arm's CoM is nearer still). Talos's shoulder roll
    (22.3 N m) cannot hold its stretched arm's 27.3 N m: 0.53 (a forward raise loads its stronger
    first joint); G1's joints carry the whole."""
    model = robot.model
    data = model.createData()
    pin.forwardKinematics(model, data, robot.q_standing)
    shoulder = int(model.frames[robot.frame_id(f"{side}_shoulder")].parentJoint)
    reach = 1.0
    for j in (int(model.parents[shoulder]), shoulder):
        if j <= 1 or model.joints[j].nv != 1:
            continue
        sub = [k for k in range(1, model.njoints) if j in _ancestors_of(model, k)]
        mass = sum(model.inertias[k].mass for k in sub)
        com = sum(model.inertias[k].mass * data.oMi[k].act(model.inertias[k].lever) for k in sub) / mass
        moment = mass * 9.81 * float(np.linalg.norm(com - data.oMi[j].translation))
        reach = min(reach, ARM_TORQUE_MARGIN * float(model.effortLimit[model.joints[j].idx_v]) / moment)
    return reach


def _ancestors_of(model: pin.Model, k: int) -> list[int]:
    out = []
    while k > 0:
        out.append(k)
        k = int(model.parents[k])
    return out


def _hold_arm(hand: np.ndarray, shoulder: np.ndarray, R: np.ndarray, most: float) -> np.ndarray:  # noqa: N803
    """The hand targets brought in sideways to at most ``most`` [m] out from the shoulder (in the
    heading frame ``R``), their forward and vertical offsets kept (the elbow bends); unchanged
    elsewhere. Continuous in the source: a hand passing the shoulder's height does not jump."""
    d = np.einsum("fba,fb->fa", R, hand - shoulder)
    d[:, 1] = np.clip(d[:, 1], -most, most)
    return shoulder + np.einsum("fab,fb->fa", R, d)


def time_scale(motion: HumanMotion, labels: dict[str, np.ndarray], robot: Robot) -> float:
    """How much slower than the human the robot moves (1: as fast): its shortest foot swing lasts at
    least :data:`MIN_SWING` x the robot's step duration (its profile's single support), which
    the whole clip is slowed down to give (a robot's foot cannot be lifted and set down again as
    fast as a human's)."""
    shortest = math.inf
    for side in SIDES:
        for a, b, down in segments(np.asarray(labels[side], dtype=bool)):
            if not down and a > 0 and b < len(motion.t):  # a swing between two stances
                shortest = min(shortest, (b - a) * motion.frame_time)
    least = MIN_SWING * robot.profile.step_duration
    return 1.0 if shortest >= least else least / shortest


def ground_jumps(motion: HumanMotion, labels: dict[str, np.ndarray],
                 robot: Robot) -> tuple[dict[str, np.ndarray], float]:
    """(contact labels, seconds of flight grounded): the labels unchanged, or, for a clip that jumps
    (frames with both feet up) in place (the pelvis ends less than :data:`GROUNDED_TRAVEL` from
    where it began) and has to be slowed for the robot's steps (:func:`time_scale` > 1), both
    feet down throughout. A flight cannot be slowed: its duration is set by its height (a 0.2 s
    flight slowed 4.6 x is a 1 m jump); a jumping jack becomes its arms and body over feet that stay
    where they stood (the gap named in the report: ``grounded_s``), made :data:`GROUNDED_SLOW`
    times slower than the human instead of for steps it no longer takes. A jump that travels is left
    to the planner (and refused when the robot cannot make it)."""
    up = ~np.asarray(labels["left"], dtype=bool) & ~np.asarray(labels["right"], dtype=bool)
    if not up.any() or time_scale(motion, labels, robot) <= 1.0:
        return labels, 0.0
    travel = float(np.linalg.norm(motion.points["pelvis"][-1, :2] - motion.points["pelvis"][0, :2]))
    if travel > GROUNDED_TRAVEL:
        return labels, 0.0
    down = np.ones(len(up), dtype=bool)
    return {side: down.copy() for side in SIDES}, float(up.sum() * motion.frame_time)


def drop_shuffles(contact: np.ndarray, sole: np.ndarray) -> np.ndarray:
    """The contact labels with the shuffles filled in: a swing in which the sole rises less than
    :data:`SHUFFLE_LIFT` and lands less than :data:`SHUFFLE_STEP` from where it left (a weight shift,
    a foot adjusted on the spot) stays a contact; the robot keeps that foot down."""
    out = contact.copy()
    runs = segments(contact)
    for i, (a, b, down) in enumerate(runs):
        if down:
            continue
        before = sole[a - 1, :2] if i > 0 else sole[a, :2]
        after = sole[b, :2] if b < len(sole) else sole[b - 1, :2]
        if sole[a:b, 2].max() < SHUFFLE_LIFT and np.linalg.norm(after - before) < SHUFFLE_STEP:
            out[a:b] = True
    return out


def stride_scale(P: dict[str, np.ndarray], labels: dict[str, np.ndarray], robot: Robot) -> float:
    """How much the body's travel is shortened so that no stride (a foot from one stance to its next)
    exceeds the robot's: twice its profile's longest step (``step_length_max``); 1 = not shortened."""
    longest = 0.0
    for side in SIDES:
        mid = 0.5 * (P[f"{side}_ankle"] + P[f"{side}_toe"])[:, :2]
        stances = [np.median(mid[a:b], axis=0) for a, b, down in segments(np.asarray(labels[side], dtype=bool)) if down]
        for p0, p1 in pairwise(stances):
            longest = max(longest, float(np.linalg.norm(p1 - p0)))
    limit = 0.9 * STRIDE_STEPS * robot.profile.step_length_max  # 10 % margin: the stances are re-measured on the knot grid
    return 1.0 if longest <= limit else limit / longest


def _placements_apart(stance_pose: dict[str, list[tuple[int, int, Pose]]], heading: np.ndarray,
                      robot: Robot) -> dict[str, list[tuple[int, int, Pose]]]:
    """The stance placements (side -> runs (first knot, end knot, pose)) kept apart as the source's
    feet are (:func:`keepout.keep_feet_apart`, in the hips' frame: ``heading`` per knot), each
    against the other foot's stances it overlaps that began no later: a placement is the median of a
    stance over which a boxer's foot pivots (CMU 135_09: 0.14 m), so two placements can be in line
    under the hips though the source's feet never were at once. The foot placed later moves."""
    out = {side: list(runs) for side, runs in stance_pose.items()}
    for i, side in enumerate(SIDES):
        other = SIDES[1 - i]
        for j, (a, b, pose) in enumerate(out[side]):
            for oa, ob, opose in out[other]:
                if a == 0 or oa > a or ob <= a:
                    continue  # the standing one, or no overlap, or the other foot placed later
                mine = np.array([pose.position])
                soles = {side: mine, other: np.array([opose.position])}
                contact = {side: np.array([False]), other: np.array([True])}
                kept, _ = keep_feet_apart(soles, contact, np.array([float(np.median(heading[a:min(b, ob)]))]), robot)
                if np.any(kept[side] != mine):
                    x, y, z = (float(v) for v in kept[side][0])
                    pose = dataclasses.replace(pose, position=(x, y, z))
                    out[side][j] = (a, b, pose)
    return out


def _foot_yaw_at(motion: HumanMotion, side: str, a: int, b: int, stand_yaw: float) -> float:
    yaw = motion.foot_yaw(side)
    return stand_yaw + float(np.median(yaw[a:b]) - yaw[0])


def knot_spacing(slow: float) -> float:
    """The knots' spacing [s] of a clip slowed ``slow`` times for the robot: :data:`COARSE_DT` from
    :data:`COARSE_SLOW` times, else :data:`DT` (a knot spans at most DT of the human's time)."""
    return COARSE_DT if slow >= COARSE_SLOW - 1e-9 else DT


def retarget_spec(motion: HumanMotion, labels: dict[str, np.ndarray], robot: Robot, *, name: str = "",
                  description: str = "", dt: float | None = DT, dynamic: bool | None = None) -> tuple[TaskSpec, Reference]:
    """The TaskSpec that tracks ``motion`` on ``robot`` with its contact schedule (``dt`` None: :func:`knot_spacing`)."""
    where = motion.source or "clip"
    motion, labels, grounded, stepped = _steps(motion, labels, robot)
    slow = time_scale(motion, labels, robot)
    if grounded > 0.0:
        slow = max(slow, GROUNDED_SLOW)
    if slow > 1.0:
        motion = dataclasses.replace(motion, t=motion.t * slow)
    dt = knot_spacing(slow) if dt is None else dt
    duration = float(motion.t[-1])
    if duration > MAX_CLIP:
        slowed = f" ({duration / slow:.1f} s slowed {slow:.2f} x for the robot's steps)" if slow > 1.0 else ""
        raise ClipError(f"{where}: the window lasts {duration:.1f} s{slowed}; wbmp retargets at most {MAX_CLIP:g} s "
                        "at a time (the planner's 60 s work bound, less the lead-in and lead-out): cut it with "
                        "--start/--end")
    ref = dataclasses.replace(reference(motion, labels, robot), time_scale=slow, grounded_s=grounded, stepped_s=stepped)
    g = standing_geometry(robot)
    stand_pose = Stance.standing(robot)
    stand_yaw = {side: float(stand_pose.sole(side).rpy[2]) for side in SIDES}
    # the contact state per knot of the clip, cleaned of phases shorter than MIN_PHASE_KNOTS
    n = max(1, int(round(duration / dt)))
    frames = np.clip(np.round(np.arange(n + 1) * dt / motion.frame_time).astype(int), 0, len(motion.t) - 1)
    state = np.array([[ref.contact[s][f] for s in SIDES] for f in frames])  # (n+1, 2)
    code = state[:, 0].astype(int) * 2 + state[:, 1].astype(int)
    code = _merge_short(code, MIN_PHASE_KNOTS)
    # stances of each foot on the knot grid -> one placement each
    stance_pose: dict[str, list[tuple[int, int, Pose]]] = {}
    for i, side in enumerate(SIDES):
        down = (code >> (1 - i)) & 1
        runs = []
        for a, b, on in segments(down.astype(bool)):
            if not on:
                continue
            fa, fb = frames[a], max(frames[min(b, n)], frames[a] + 1)
            if a == 0:
                pose = stand_pose.sole(side)
            else:
                xy = np.median(ref.points[f"{side}_foot"][fa:fb, :2], axis=0)
                pose = Pose(position=(float(xy[0]), float(xy[1]), 0.0),
                            rpy=(0.0, 0.0, _foot_yaw_at(motion, side, fa, fb, stand_yaw[side])))
            runs.append((a, b, pose))
        stance_pose[side] = runs
    stance_pose, turned = keep_splay(_placements_apart(stance_pose, ref.heading[frames], robot), stand_yaw, robot)
    # the lead-out: each foot where it last was, or beside the other as at standing (a flight: the source's)
    last: dict[str, Pose] = {}
    for side in SIDES:
        if stance_pose[side] and stance_pose[side][-1][1] == n + 1:
            last[side] = stance_pose[side][-1][2]
    for side in SIDES:
        other = SIDES[1 - SIDES.index(side)]
        if side in last:
            continue
        if other in last:
            o = last[other]
            R0 = pin.rpy.rpyToMatrix(0.0, 0.0, o.rpy[2] - stand_yaw[other])
            rel = np.array(stand_pose.sole(side).position) - np.array(stand_pose.sole(other).position)
            xy = np.array(o.position) + R0 @ rel
            last[side] = Pose(position=(float(xy[0]), float(xy[1]), 0.0),
                              rpy=(0.0, 0.0, float(o.rpy[2] - stand_yaw[other] + stand_yaw[side])))
        else:
            xy = ref.points[f"{side}_foot"][-1, :2]
            last[side] = Pose(position=(float(xy[0]), float(xy[1]), 0.0),
                              rpy=(0.0, 0.0, _foot_yaw_at(motion, side, len(motion.t) - 5, len(motion.t), stand_yaw[side])))
    frames_of = {side: robot.frame(f"{side}_foot") for side in SIDES}

    def contacts_at(k: int) -> tuple[Contact, ...]:
        out = []
        for i, side in enumerate(SIDES):
            if (code[k] >> (1 - i)) & 1:
                pose = next(p for a, b, p in stance_pose[side] if a <= k < b)
                out.append(Contact(frame=frames_of[side], placement=pose))
        return tuple(out)

    phases = [Phase(name="lead-in (standing)", duration=LEAD_IN,
                    contacts=tuple(Contact(frame=frames_of[s], placement=stand_pose.sole(s)) for s in SIDES))]
    names = {3: "double support", 2: "left support", 1: "right support", 0: "flight"}
    for a, b, _ in segments_of(code):
        lift = _lift(ref, code, a, b, frames, n)
        phases.append(Phase(name=f"{names[int(code[a])]} {a * dt:.2f}-{min(b, n) * dt:.2f} s",
                            duration=max(min(b, n) - a, 0) * dt, contacts=contacts_at(a), swing_height=lift))
    phases = [p for p in phases if p.duration > 1e-9]
    phases.append(Phase(name="lead-out (both feet down)", duration=LEAD_OUT,
                        contacts=tuple(Contact(frame=frames_of[s], placement=last[s]) for s in SIDES)))
    clip_horizon = sum(p.duration for p in phases[1:-1])
    held = {side: np.full((n + 2, 3), np.nan) for side in SIDES}  # per knot: the sole's placement (row n+1: lead-out)
    for side in SIDES:
        for a, b, pose in stance_pose[side]:
            held[side][a:min(b, n + 1)] = pose.position
        held[side][n + 1] = last[side].position
    targets = _tracking_targets(ref, robot, code, frames, dt, n, clip_horizon, held)
    horizon = sum(p.duration for p in phases)
    _check_items(where, duration, slow, len(targets), robot)
    spec = TaskSpec(robot=robot.name, phases=tuple(phases), targets=tuple(targets),
                    joint_targets=shoulders_out(robot, horizon),
                    com_bounds=(CoMBounds(name="balance", support_polygon=True, margin=g.support_margin),),
                    dt=dt, dynamic=True if dynamic is None else dynamic, smoothness_weight=SMOOTHNESS, name=name or f"retarget {where}",
                    description=description)
    return spec, dataclasses.replace(ref, splay_turned=turned)  # splay: the hips' yaw range (a pivot turn's toe-in)


def _steps(motion: HumanMotion, labels: dict[str, np.ndarray],
           robot: Robot) -> tuple[HumanMotion, dict[str, np.ndarray], float, float]:
    """(motion, contact labels, seconds of flight grounded, seconds of flight made as steps): the
    steps the robot makes of the source's: quick low swings on the spot are none
    (:func:`tasks.mocap.legs.quick_shuffles`), a jump in place is made with both feet down
    (:func:`ground_jumps`) and a travelling one that must be slowed as steps, its body no higher than
    standing (:func:`tasks.mocap.legs.steps_for_flights`)."""
    if QUICK_SHUFFLES:
        labels = quick_shuffles(motion, labels, body_scale(motion, robot)[0], MIN_SWING * robot.profile.step_duration,
                                SHUFFLE_STEP)
    labels, grounded = ground_jumps(motion, labels, robot)
    stepped = 0.0
    if STEPS_FOR_FLIGHTS and grounded == 0.0 and time_scale(motion, labels, robot) > 1.0:
        before = labels
        labels, stepped = steps_for_flights(labels, motion.frame_time)
        motion = no_higher_than_standing(motion, before) if stepped else motion
    return motion, labels, grounded, stepped


def _check_items(where: str, duration: float, slow: float, n_targets: int, robot: Robot) -> None:
    """ClipError when a clip's tracking targets (with the shoulders' joint targets and the CoM bound)
    exceed what wbmp plans at a time (a clip slowed for its quickest swing), naming the fix."""
    if n_targets + 2 * len(SIDES) + 1 <= MAX_ITEMS:
        return
    step = MIN_SWING * robot.profile.step_duration
    slowed = (f", slowed {slow:.2f} x (its quickest foot swing, {step / slow:.2f} s, to the robot's step of "
              f"{step:.2f} s)") if slow > 1.0 else ""
    raise ClipError(f"{where}: the window lasts {duration:.1f} s{slowed}: {n_targets} tracking targets, more than "
                    f"the {MAX_ITEMS} wbmp plans at a time: cut it with --start/--end")


def shoulders_out(robot: Robot, horizon: float) -> tuple[JointTarget, ...]:
    """Soft targets holding each shoulder's joint (the one carrying the robot's shoulder frame)
    :data:`SHOULDER_OUT` outwards of its standing angle over the whole motion (outwards: the way
    that takes the hand away from the body's middle, by forward kinematics); none on a shoulder
    that cannot carry its stretched arm held out (:func:`arm_reach` < 1: talos, whose chicken
    dance then saturated the shoulder, its hand 0.12 m off its plan)."""
    model = robot.model
    data = model.createData()
    out = []
    for side in SIDES:
        joint = int(model.frames[robot.frame_id(f"{side}_shoulder")].parentJoint)
        if model.joints[joint].nq != 1 or arm_reach(robot, side) < 1.0:
            continue  # a shoulder that cannot carry its arm held out is not asked to hold it out
        i = model.joints[joint].idx_q
        lateral = []
        for delta in (-0.05, 0.05):
            q = np.array(robot.q_standing, dtype=float)
            q[i] += delta
            pin.framesForwardKinematics(model, data, q)
            lateral.append(abs(float(data.oMf[robot.frame_id(f"{side}_hand")].translation[1]
                                     - data.oMf[robot.frame_id("base")].translation[1])))
        sign = 1.0 if lateral[1] > lateral[0] else -1.0
        value = float(robot.q_standing[i]) + sign * SHOULDER_OUT
        value = min(max(value, float(model.lowerPositionLimit[i])), float(model.upperPositionLimit[i]))
        out.append(JointTarget(name=f"{side} shoulder out", joint=model.names[joint], value=value,
                               window=(0.0, horizon), weight=SHOULDER_WEIGHT))
    return tuple(out)


def segments_of(code: np.ndarray) -> list[tuple[int, int, int]]:
    """Runs of equal contact codes on the knot grid: (first knot, last knot + 1, code)."""
    edges = np.flatnonzero(np.diff(code)) + 1
    starts = np.concatenate([[0], edges]).astype(int)
    ends = np.concatenate([edges, [len(code)]]).astype(int)
    return [(int(a), int(b), int(code[a])) for a, b in zip(starts, ends, strict=True)]


def _merge_short(code: np.ndarray, min_knots: int) -> np.ndarray:
    """A run shorter than ``min_knots`` (not the first or last) takes the code of its longer neighbour."""
    code = code.copy()
    for _ in range(len(code)):
        runs = segments_of(code)
        short = [(b - a, i) for i, (a, b, _) in enumerate(runs) if b - a < min_knots and 0 < i < len(runs) - 1]
        if not short:
            break
        _, i = min(short)
        a, b, _ = runs[i]
        left, right = runs[i - 1], runs[i + 1]
        code[a:b] = left[2] if left[1] - left[0] >= right[1] - right[0] else right[2]
    return code


def _lift(ref: Reference, code: np.ndarray, a: int, b: int, frames: np.ndarray, n: int) -> float:
    """Mid-swing clearance asked in a phase: 0.8 x the source's highest swinging sole, within SWING_CLEARANCE."""
    fa, fb = frames[a], frames[min(b, n)] + 1
    up = [ref.points[f"{side}_foot"][fa:fb, 2].max() for i, side in enumerate(SIDES) if not (code[a] >> (1 - i)) & 1]
    if not up:
        return 0.05
    lo, hi = SWING_CLEARANCE
    return float(min(hi, max(lo, 0.8 * max(up))))


def _smoothstep(x: float) -> float:
    x = min(1.0, max(0.0, x))
    return x * x * (3.0 - 2.0 * x)


def swing_target(src: np.ndarray, held: np.ndarray, k: int, first: np.ndarray, dt: float = DT) -> np.ndarray:
    """Where a swinging foot is tracked at knot ``k``: from the placement it left to the one it lands on.

    ``src`` (knots, 3) is the scaled source foot per knot, ``held`` (knots + 1, 3) its placement per
    knot (NaN in a swing; the last row, the lead-out's), ``first`` the lead-in's. The source's own stances do not stand still
    (the stride scale pulls them back with the body's shortened travel; the heel rolls) and its
    contact labels begin late, so that its foot can be 0.2 m from the placement a knot before
    touch-down: tracked as it is, the plan lunges onto the placement in the last knot. Here the
    target goes from the placement left (knot a) to the next one (knot b) by a smoothstep, plus the
    source's own deviation from the same blend between its positions at a and b (its lift above all),
    capped near the placements (:func:`tasks.mocap.legs.land_softly`; ``dt``: the knots' spacing [s])
    and, on a high swing that lands near where it left, gone a knot before touch-down (``HIGH_SWING``).
    """
    a = k
    while a >= 0 and np.isnan(held[a, 0]):
        a -= 1
    b = k
    while b < len(held) - 1 and np.isnan(held[b, 0]):
        b += 1
    if np.isnan(held[b, 0]):
        return src[k]
    left = held[a] if a >= 0 else first  # a swing from the clip's first knot leaves the lead-in's placement
    s = _smoothstep((k - a) / (b - a))
    sa, sb = src[max(a, 0)], src[min(b, len(src) - 1)]
    p = left + s * (held[b] - left) + (src[k] - (sa + s * (sb - sa)))
    high = LAND_SOFTLY and b - a >= 5 and float(src[max(a, 0):b, 2].max()) > HIGH_SWING
    short = float(np.linalg.norm(held[b, :2] - left[:2])) < EARLY_STEP
    early, late = int(high and short), int(high and not short)  # down a knot early / up a knot late
    if LAND_VERTICALLY:
        # over the placement a knot before touch-down: the last knot only comes down (a foot that
        # also moved across in it touched the floor early, short of the placement, and stopped there)
        # and, on a swing of three knots or more, still over the placement it left at its first
        # knot (the first knot only goes up: the certificate holds a stance to its last knot)
        lo = a + 1 + late if b - a >= 4 else a
        s_xy = _smoothstep(max(0.0, (k - lo) / max(1, b - 1 - lo)))
        p[:2] = left[:2] + s_xy * (held[b, :2] - left[:2])
        if lo < k < b - 1:
            p[:2] += src[k, :2] - (sa[:2] + s * (sb[:2] - sa[:2]))
    if LAND_SOFTLY:  # off and onto the placements no faster than legs.LAND_SPEED (a march stamps at 2 m/s)
        plain = left + s * (held[b] - left)
        if LAND_VERTICALLY:
            plain[:2] = left[:2] + s_xy * (held[b, :2] - left[:2])
        p = plain + land_softly(p - plain, min(b - k - early, k - a - late) * dt)
    p[2] = max(float(p[2]), 0.0)
    return p


def _tracking_targets(ref: Reference, robot: Robot, code: np.ndarray, frames: np.ndarray, dt: float, n: int,
                      horizon: float, held: dict[str, np.ndarray] | None = None) -> list[FrameTarget]:
    out = []
    src = {side: ref.points[f"{side}_foot"][frames] for side in SIDES}
    base_rotation = standing_geometry(robot).placements["base"].rotation
    g = standing_geometry(robot)
    n_in = int(round(ref.lead_in / dt))
    for k in range(-n_in + 2, n + 1):
        t = ref.lead_in + k * dt
        if k * dt > horizon + 1e-9:
            break
        f = frames[max(k, 0)]
        blend = 1.0 if k >= 0 else _smoothstep((k + n_in) / n_in)  # the lead-in: from standing to the first pose
        for role in TRACKED:
            if role.endswith("_foot"):
                i = SIDES.index(role.split("_")[0])
                if k < 0 or (code[k] >> (1 - i)) & 1:
                    continue  # a stance foot is held by its contact
            p = g.placements[role].translation + blend * (ref.points[role][f] - g.placements[role].translation)
            if role.endswith("_foot") and held is not None and SWING_TO_PLACEMENTS:
                side = role.split("_")[0]
                p = swing_target(src[side], held[side], k, g.placements[role].translation * [1.0, 1.0, 0.0], dt)
                stance = held[SIDES[1 - SIDES.index(side)]][k]
                if SWING_APART and KEEP_OUT and not np.isnan(stance[0]):  # off the standing foot's line
                    p = apart_from_stance(p, side, stance, float(ref.heading[f]), robot)
            out.append(FrameTarget(name=f"track {role} {t:.3f}", frame=robot.frame(role),
                                   position=(float(p[0]), float(p[1]), float(p[2])), time=round(t, 9),
                                   priority=Priority.SOFT, weight=WEIGHTS[role] * dt, tolerance=TRACK_TOLERANCE))
        rpy = pin.rpy.matrixToRpy(pin.rpy.rpyToMatrix(0.0, 0.0, blend * float(ref.heading[f])) @ base_rotation)
        out.append(FrameTarget(name=f"track heading {t:.3f}", frame=robot.frame("base"),
                               rpy=(float(rpy[0]), float(rpy[1]), float(rpy[2])),
                               time=round(t, 9), priority=Priority.SOFT, weight=HEADING_WEIGHT * dt,
                               orientation_tolerance=math.pi / 2))
    return out
