"""Hand targets the robot's arms can hold: the torque rule, and the gaps it leaves named in body terms.

A human holds an arm out, raised behind the body or swung fast with no thought of its joints'
torques; a robot's shoulder may not carry the same pose (talos's shoulder roll, 22.3 N m, cannot
hold its stretched arm's 27.3 N m). Tracked there, the plan asks for the pose, the controller
saturates the joint and the hand drops (talos's bend: the windmill's raised arm, the right hand
0.35 m below its plan at 3.86 s, ``arm_right_2_joint`` at 21.7 of 22.3 N m).

:func:`hold_within_strength` finds, per knot, the robot's pose for the scaled targets (a damped
least-squares inverse kinematics of the whole body, Pinocchio, warm-started from the knot before:
:func:`whole_body_poses`) and the torque each arm joint needs there: the inverse dynamics
(``pinocchio.rnea``) of that pose with the velocities and accelerations of the poses' sequence,
the arm's weight and its swing. Where a joint needs more than :data:`ARM_STRENGTH_MARGIN` of its
limit, the hand target is brought in horizontally towards the vertical through its shoulder (its
height kept: the elbow bends), by the least factor that brings the joint within (the lever arm of
the arm's weight is horizontal). Only the joints that could need it are checked: those whose arm
beyond, stretched horizontally, weighs more than the margin of their limit (talos's shoulder roll,
upper-arm yaw and elbow; none on G1, whose joints carry the whole arm: the rule costs nothing there).

Every move of a target leaves a gap to the human, and :class:`Gap` names it in body terms:
``"right hand 0.21 m from the source at 3.86 s, mostly 0.19 m in towards the body: arm_right_2_joint's
torque limit"`` (:func:`gaps_of` for any per-frame move: the arms, the body raised, the hands and
feet kept out of the body).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from robots import Robot

SIDES = ("left", "right")
#: [-] of an arm joint's torque limit: the most the target pose may ask of it (the rest moves and
#: holds the arm against the controller's errors; the same margin as the sideways rule's,
#: ``retarget.ARM_TORQUE_MARGIN``: with 0.8 talos's waving hand sagged 61 mm off its plan).
ARM_STRENGTH_MARGIN = 0.65
KNOT = 0.08  # [s] the poses are solved on this grid (the planner's knots); the factors interpolated between
IK_WEIGHTS = {"base": 400.0, "torso": 100.0, "head": 100.0, "left_hand": 200.0, "right_hand": 200.0,
              "left_foot": 200.0, "right_foot": 200.0}  # the spec's tracking weights (retarget.WEIGHTS)
HEADING_WEIGHT = 20.0  # [1/rad^2] the base's orientation (retarget.HEADING_WEIGHT)
POSTURE_WEIGHT = 1.0  # [1/rad^2] a weak pull towards standing: the redundant joints stay where the robot's do
DAMPING = 1e-3  # [-] Levenberg-Marquardt damping of the least-squares steps
IK_STEPS = (30, 8)  # Gauss-Newton steps at the first knot, and at each next one (warm-started)
#: [-] the weight of the strained joints' gravity torques (over their limits, squared) in the pose
#: (against the hands' 200 [1/m^2]): the elbow where the arm loads its shoulder least
STRAIN_WEIGHT = 1.0
HOLD_ITERATIONS = 4
#: [-] of a joint's limit: a run of knots over the margin is held in only where its pose somewhere asks more
#: than this (talos's march swings its arms to 0.79 of the rolls' limits, held by the controller; brought in
#: to 0.65 its hand met its rising shin and it fell; the bend asks 1.10, its arm dropped)
ARM_STRENGTH_TRIGGER = 0.9  # re-solves of the pose per knot while bringing the hand in


@dataclass(frozen=True)
class Gap:
    """Where a target was moved furthest from the scaled source, and why, in body terms.

    Attributes:
        role: The robot keypoint (``right_hand``).
        metres: How far the target is from the source there [m].
        time: When, on the plan's time axis [s].
        direction: The move's largest component in the heading frame, in words (``"0.19 m in
            towards the body"``).
        cause: What the robot could not do (``"arm_right_2_joint's torque limit"``).
    """

    role: str
    metres: float
    time: float
    direction: str
    cause: str

    def text(self) -> str:
        """One line: ``right hand 0.21 m from the source at 3.86 s, mostly 0.19 m below it: ...``."""
        return (f"{self.role.replace('_', ' ')} {self.metres:.2f} m from the source at {self.time:.2f} s, "
                f"mostly {self.direction}: {self.cause}")

    def to_dict(self) -> dict[str, object]:
        """JSON-ready."""
        return {"role": self.role, "m": self.metres, "time_s": self.time, "direction": self.direction,
                "cause": self.cause, "text": self.text()}


def gaps_of(role: str, before: np.ndarray, after: np.ndarray, t: np.ndarray, heading: np.ndarray, cause: str,
            least: float = 0.005) -> Gap | None:
    """The :class:`Gap` of a target moved from ``before`` to ``after`` (F, 3) [m] at times ``t`` (F,),
    at its largest move; None when it moved less than ``least`` [m]. The direction is the move's
    largest component in the heading frame (``heading`` (F,) [rad]), named from the target's side:
    forward/back, left/right, up/down."""
    moved = np.linalg.norm(after - before, axis=1)
    if len(moved) == 0 or float(moved.max()) < least:
        return None
    i = int(np.argmax(moved))
    c, s = np.cos(heading[i]), np.sin(heading[i])
    d = after[i] - before[i]
    local = np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1], d[2]])
    axis = int(np.argmax(np.abs(local)))
    words = [("behind", "ahead of"), ("right of", "left of"), ("below", "above")][axis]
    # the robot's keypoint relative to the source: "0.19 m below it"
    direction = f"{abs(local[axis]):.2f} m {words[int(local[axis] > 0)]} it"
    return Gap(role=role, metres=float(moved[i]), time=float(t[i]), direction=direction, cause=cause)


def _chain(model: pin.Model, frame_id: int) -> list[int]:
    """The actuated 1-dof joints from the free flyer to a frame (root first)."""
    j = int(model.frames[frame_id].parentJoint)
    out = []
    while j > 1:
        if model.joints[j].nv == 1:
            out.append(j)
        j = int(model.parents[j])
    return out[::-1]


def _subtree(model: pin.Model, j: int) -> list[int]:
    out = []
    for k in range(1, model.njoints):
        p = k
        while p > 0 and p != j:
            p = int(model.parents[p])
        if p == j:
            out.append(k)
    return out


def arm_torque_joints(robot: Robot) -> tuple[str, ...]:
    """Names of both arms' :func:`strained_joints` (left, then right): the joints whose torques a
    retarget's plan keeps within a margin of their limits (``CentroidalSettings.torque_joints``;
    talos: ``arm_*_1_joint`` to ``arm_*_5_joint``, G1: none)."""
    return tuple(str(robot.model.names[j]) for side in SIDES for j in strained_joints(robot, side))


def strained_joints(robot: Robot, side: str, margin: float = ARM_STRENGTH_MARGIN) -> list[int]:
    """The joints of ``side``'s arm (from its shoulder frame's parent joint out) whose arm beyond,
    stretched, could load them beyond ``margin`` of their torque limit: its mass x g x the
    farthest its centre of mass can be from the joint (at standing, by Pinocchio, the chain's
    length to it as the bound)."""
    model = robot.model
    data = model.createData()
    pin.forwardKinematics(model, data, np.asarray(robot.q_standing, dtype=float))
    shoulder = int(model.frames[robot.frame_id(f"{side}_shoulder")].parentJoint)
    chain = _chain(model, robot.frame_id(f"{side}_hand"))
    first = chain.index(shoulder) - 1 if shoulder in chain else 0
    out = []
    for j in chain[max(first, 0):]:
        sub = _subtree(model, j)
        mass = sum(model.inertias[k].mass for k in sub)
        if mass <= 0.0:
            continue
        # the farthest the subtree's CoM can be: the mass-weighted chain distances of its bodies' CoMs
        lever = 0.0
        for k in sub:
            along, p = 0.0, k
            while p != j:  # the chain of joint origins from j out to k, then k's CoM
                along += float(np.linalg.norm(data.oMi[p].translation - data.oMi[int(model.parents[p])].translation))
                p = int(model.parents[p])
            along += float(np.linalg.norm(model.inertias[k].lever))
            lever += model.inertias[k].mass * along
        moment = 9.81 * lever  # mass x g x the CoM's farthest distance
        limit = float(model.effortLimit[model.joints[j].idx_v])
        if limit > 0.0 and moment > margin * limit:
            out.append(j)
    return out


class _Ik:
    """Damped least-squares inverse kinematics of the whole body on the retarget's targets."""

    def __init__(self, robot: Robot) -> None:
        self.robot = robot
        self.model = robot.model
        self.data = self.model.createData()
        self.fids = {role: robot.frame_id(role) for role in IK_WEIGHTS}
        self.base = robot.frame_id("base")
        self.q_stand = np.asarray(robot.q_standing, dtype=float)
        pin.framesForwardKinematics(self.model, self.data, self.q_stand)
        self.base_rotation = self.data.oMf[self.base].rotation.copy()
        self.lo = self.model.lowerPositionLimit.copy()
        self.hi = self.model.upperPositionLimit.copy()
        self.lo[:7], self.hi[:7] = -np.inf, np.inf

    def solve(self, q: np.ndarray, targets: dict[str, np.ndarray], yaw: float, steps: int,
              strain: list[int] | None = None) -> np.ndarray:
        """The pose nearest ``q`` for ``targets`` (role -> (3,) [m]) and base heading ``yaw`` [rad];
        with ``strain`` (joint ids), of the poses that reach them, one whose gravity torques on those
        joints (over their limits) are small: the elbow held where the arm's weight loads the
        shoulder least (a robot's best way of holding the hand there)."""
        model, data = self.model, self.data
        R_goal = pin.rpy.rpyToMatrix(0.0, 0.0, yaw) @ self.base_rotation
        nv = model.nv
        w_post = np.sqrt(POSTURE_WEIGHT) * np.ones(nv)
        w_post[:6] = 0.0
        posture, damping = np.diag(w_post), DAMPING * np.eye(nv)
        for _ in range(steps):
            pin.computeJointJacobians(model, data, q)
            pin.updateFramePlacements(model, data)
            rows, errs = [], []
            for role, fid in self.fids.items():
                if role not in targets:
                    continue  # the feet (not placed yet): the legs stay near standing
                w = np.sqrt(IK_WEIGHTS[role])
                J = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)[:3]
                rows.append(w * J)
                errs.append(w * (targets[role] - data.oMf[fid].translation))
            M = data.oMf[self.base]
            Jb = pin.getFrameJacobian(model, data, self.base, pin.LOCAL_WORLD_ALIGNED)[3:]
            rows.append(np.sqrt(HEADING_WEIGHT) * Jb)
            errs.append(np.sqrt(HEADING_WEIGHT) * pin.log3(R_goal @ M.rotation.T))
            rows.append(posture)
            errs.append(w_post * pin.difference(model, q, self.q_stand))
            if strain:
                cols = [model.joints[j].idx_v for j in strain]
                w = np.sqrt(STRAIN_WEIGHT) / self.model.effortLimit[cols]
                g = pin.computeGeneralizedGravity(model, data, q)[cols]
                dg = pin.computeGeneralizedGravityDerivatives(model, data, q)[cols]
                rows.append(w[:, None] * dg)
                errs.append(-w * g)
            J = np.vstack(rows)
            e = np.concatenate(errs)
            dq = np.linalg.solve(J.T @ J + damping, J.T @ e)
            q = pin.integrate(model, q, dq)
            q = np.clip(q, self.lo, self.hi)
        return q


def whole_body_poses(robot: Robot, points: dict[str, np.ndarray], heading: np.ndarray,
                     frames: np.ndarray, strain: list[int] | None = None) -> np.ndarray:
    """The robot's configuration (K, nq) for the targets ``points`` (role -> (F, 3) [m]; base,
    torso, head, hands, feet) and base heading ``heading`` (F,) [rad] at the frames ``frames`` (K,),
    each warm-started from the one before (the first from standing)."""
    ik = _Ik(robot)
    q = ik.q_stand.copy()
    out = np.empty((len(frames), robot.model.nq))
    for i, f in enumerate(frames):
        q = ik.solve(q, {role: points[role][f] for role in IK_WEIGHTS if role in points}, float(heading[f]),
                     IK_STEPS[0] if i == 0 else IK_STEPS[1], strain)
        out[i] = q
    return out


def arm_torques(robot: Robot, q: np.ndarray, joints: list[int], accel: np.ndarray | None = None) -> np.ndarray:
    """The torque (K, len(joints)) [N m] each of ``joints`` needs to hold the poses ``q`` (K, nq):
    Pinocchio's generalized gravity, with the arm's own acceleration ``accel`` (K, 3) [m/s^2] (the
    hand's) taken as an added gravity (- accel: the arm in the frame of its accelerating hand; its
    rotation neglected). An arm carries no contact, so its joints' torques are its own weight's
    and motion's, free of the unknown contact forces."""
    model = robot.model if accel is None else pin.Model(robot.model)  # a copy: its gravity is changed
    data = model.createData()
    cols = [model.joints[j].idx_v for j in joints]
    g0 = model.gravity.linear.copy()
    out = np.empty((len(q), len(joints)))
    for i, qi in enumerate(q):
        if accel is not None:
            model.gravity.linear = g0 - accel[i]
        out[i] = pin.computeGeneralizedGravity(model, data, qi)[cols]
    return out


def hold_within_strength(robot: Robot, points: dict[str, np.ndarray], heading: np.ndarray, t: np.ndarray,
                         margin: float = ARM_STRENGTH_MARGIN
                         ) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray], list[Gap]]:
    """(hand targets, how far each was moved per frame, the gaps named): each hand target
    (``points["left_hand"]`` ... (F, 3) [m] at times ``t`` (F,) [s]) brought in horizontally towards
    its shoulder's vertical where the robot's pose for the targets needs more than ``margin`` of a
    strained arm joint's torque limit (see the module). Unchanged (the same arrays) where none does."""
    hands = {side: points[f"{side}_hand"] for side in SIDES}
    moved = {side: np.zeros(len(t)) for side in SIDES}
    joints = {side: strained_joints(robot, side, margin) for side in SIDES}
    if len(t) < 3 or not any(joints.values()):
        return hands, moved, []
    frame_time = float(t[1] - t[0])
    step = max(1, int(round(KNOT / frame_time)))
    frames = np.arange(0, len(t), step)
    strain = joints["left"] + joints["right"]
    q = whole_body_poses(robot, points, heading, frames, strain)
    model = robot.model
    ik = _Ik(robot)
    shoulder = {side: points[f"{side}_shoulder"] for side in SIDES}
    gaps = []
    for side in SIDES:
        if not joints[side]:
            continue
        limits = np.array([float(model.effortLimit[model.joints[j].idx_v]) for j in joints[side]])
        ratio = np.abs(arm_torques(robot, q, joints[side])) / limits
        # the runs of knots over the margin whose pose somewhere asks more than TRIGGER of a limit (a
        # swing that only brushes past the margin is held by the controller: talos's march, 0.79)
        above = ratio.max(axis=1) > margin
        over = np.array([i for a, b in _runs(above) if ratio[a:b].max() > ARM_STRENGTH_TRIGGER
                         for i in range(a, b)], dtype=int)
        if len(over) == 0:
            continue
        factor = np.ones(len(frames))
        peak = np.unravel_index(int(np.argmax(ratio)), ratio.shape)
        for i in over:
            f = int(frames[i])
            c, qi, need = 1.0, q[i], ratio[i]
            for _ in range(HOLD_ITERATIONS):
                # the lever arm is horizontal: the torque scales with the hand's horizontal offset
                worst = float(np.max(need)) / margin
                if worst <= 1.0:
                    break
                c = c / worst
                targets = {role: points[role][f] for role in IK_WEIGHTS if role in points}
                targets[f"{side}_hand"] = _brought_in(hands[side][f], shoulder[side][f], c)
                qi = ik.solve(qi, targets, float(heading[f]), IK_STEPS[1], strain)
                need = np.abs(arm_torques(robot, qi[None], joints[side])[0]) / limits
            factor[i] = c
        # each frame's factor: the lowest of its knot's and the neighbours', interpolated (continuous,
        # and at each knot at most what that knot needs)
        eroded = np.minimum(factor, np.minimum(np.r_[factor[1:], factor[-1]], np.r_[factor[0], factor[:-1]]))
        lo = np.interp(np.arange(len(t)), frames, eroded)
        held = shoulder[side] + (hands[side] - shoulder[side]) * np.c_[lo, lo, np.ones(len(t))]
        moved[side] = np.linalg.norm(held - hands[side], axis=1)
        name = model.names[joints[side][int(peak[1])]]
        gap = gaps_of(f"{side}_hand", hands[side], held, t, heading,
                      f"{name}'s torque limit (the human's pose asks {ratio[peak]:.2f} of it, "
                      f"the robot's target at most {margin:.2f})")
        hands[side] = held
        if gap is not None:
            gaps.append(gap)
    return hands, moved, gaps


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(first, end) of each run of True in ``mask``."""
    edges = np.flatnonzero(np.diff(np.r_[0, mask.astype(int), 0]))
    return [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2], strict=True)]


def _brought_in(hand: np.ndarray, shoulder: np.ndarray, c: float) -> np.ndarray:
    """The hand's horizontal offset from its shoulder scaled by ``c``, its height kept."""
    d = hand - shoulder
    return shoulder + np.array([c * d[0], c * d[1], d[2]])
