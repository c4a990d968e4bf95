"""The scaled source kept out of the robot's own body: hands off its pelvis and thighs, feet apart.

A human's hand brushes the thigh, crosses in front of the pelvis, and a human's feet land a few
centimetres apart or cross; the robot's hips and thighs are wider, so the scaled keypoints can lie
inside its collision model. Tracked there, the plan is pulled against its own self-collision
constraints and the planner gives up (talos turn in place: the left forearm through the pelvis;
the jumping jacks: a foot through the other foot). These rules move such targets out, each by the
least distance, and say how far (the gap to the human, named in the report):

* :func:`keep_hands_out`: each hand target at least its own hand's and forearm's capsule radius
  plus :data:`HAND_CLEARANCE` away from the robot's pelvis, hip and thigh capsules (Pinocchio
  forward kinematics of its collision model at standing, carried with the base target and heading).
* :func:`keep_feet_apart`: the two soles at least :data:`FOOT_GAP` of the robot's standing distance
  between its soles apart sideways, in the feet's own frame, where they are near each other (a
  swinging foot is moved; both, half each, when both are down or both up).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from robots import Robot, body_part, collision_model

SIDES = ("left", "right")
#: Body parts a hand target is kept out of (:func:`robots.body_part` names).
HAND_KEEP_OUT = ("pelvis", "left hip", "right hip", "left thigh", "right thigh")
HAND_CLEARANCE = 0.04  # [m] beyond the body's capsule and the hand's own radius
FOOT_GAP = 0.85  # [-] of the standing lateral distance between the soles: the least kept
#: [-] The knees lie about halfway between the hips and the feet, so a lunge's knees are about half as
#: far apart as its feet: the feet are kept apart sideways while its knees are near (the feet within
#: KNEE_REACH x a sole's length), not only while the feet are (g1's punch: its stepping lunges
#: crossed the legs above the feet, a thigh through the other shin).
KNEE_REACH = 2.0


def body_capsules(robot: Robot, parts: tuple[str, ...] = HAND_KEEP_OUT) -> list[tuple[np.ndarray, np.ndarray, float]]:
    """The capsules of the robot's ``parts`` at standing: (end a, end b, radius), the ends relative to
    the base frame's position at standing, in the world's axes (the robot faces +x at standing) [m]."""
    model, data = robot.model, robot.model.createData()
    q = np.asarray(robot.q_standing, dtype=float)
    pin.forwardKinematics(model, data, q)
    pin.updateFramePlacements(model, data)
    base = data.oMf[robot.frame_id(robot.frame("base"))].translation
    out = []
    for c in collision_model(robot).capsules:
        if body_part(robot, c.link) not in parts:
            continue
        a, b = c.endpoints()
        M = data.oMi[c.joint]
        out.append((M.act(a) - base, M.act(b) - base, float(c.radius)))
    return out


def limb_radius(robot: Robot, side: str) -> float:
    """The largest capsule radius of the robot's ``side`` hand and forearm [m]."""
    radii = [c.radius for c in collision_model(robot).capsules
             if body_part(robot, c.link) in (f"{side} hand", f"{side} forearm")]
    return float(max(radii)) if radii else 0.0


def _closest_on_segments(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Per row, the point of segment a-b nearest p (F, 3)."""
    ab = b - a
    L2 = np.maximum(np.einsum("fi,fi->f", ab, ab), 1e-12)
    s = np.clip(np.einsum("fi,fi->f", p - a, ab) / L2, 0.0, 1.0)
    return a + s[:, None] * ab


def keep_hands_out(hands: dict[str, np.ndarray], base: np.ndarray, R: np.ndarray,  # noqa: N803
                   robot: Robot) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """The hand targets (side -> (F, 3)) moved out of the robot's pelvis, hips and thighs (see the
    module), the body placed at the ``base`` targets (F, 3) turned by the heading ``R`` (F, 3, 3);
    and side -> how far each frame's target was moved (F,) [m]."""
    capsules = body_capsules(robot)
    out, moved = {}, {}
    for side in SIDES:
        h0 = np.asarray(hands[side], dtype=float)
        h = h0.copy()
        clear = limb_radius(robot, side) + HAND_CLEARANCE
        outward = np.einsum("fab,b->fa", R, np.array([0.0, 1.0 if side == "left" else -1.0, 0.0]))
        for _ in range(3):  # a push out of one capsule may end in its neighbour
            for a, b, r in capsules:
                A = base + np.einsum("fab,b->fa", R, a)
                B = base + np.einsum("fab,b->fa", R, b)
                c = _closest_on_segments(h, A, B)
                d = h - c
                dist = np.linalg.norm(d, axis=1)
                inside = dist < r + clear
                if not inside.any():
                    continue
                direction = np.where(dist[:, None] > 1e-6, d / np.maximum(dist, 1e-9)[:, None], outward)
                h[inside] = c[inside] + (r + clear) * direction[inside]
        out[side] = h
        moved[side] = np.linalg.norm(h - h0, axis=1)
    return out, moved


def standing_gap(robot: Robot) -> float:
    """The lateral distance between the robot's soles at standing [m] (Pinocchio FK)."""
    model, data = robot.model, robot.model.createData()
    pin.framesForwardKinematics(model, data, np.asarray(robot.q_standing, dtype=float))
    y = [float(data.oMf[robot.frame_id(robot.frame(f"{s}_foot"))].translation[1]) for s in SIDES]
    return abs(y[0] - y[1])


def feet_yaw(motion, window: float = 0.25) -> np.ndarray:
    """The feet's common yaw per frame (F,) [rad]: the direction of the sum of both feet's
    ankle-to-toe vectors on the ground, averaged over ``window`` seconds (a foot pointing down at
    toe-off counts little, its yaw being noise then)."""
    v = sum((motion.points[f"{s}_toe"] - motion.points[f"{s}_ankle"])[:, :2] for s in SIDES)
    n = max(1, int(round(window / max(float(motion.frame_time), 1e-6))))
    kernel = np.ones(n) / n
    smooth = np.stack([np.convolve(np.pad(v[:, i], (n // 2, n - 1 - n // 2), mode="edge"), kernel, mode="valid")
                       for i in range(2)], axis=1)
    return np.arctan2(smooth[:, 1], smooth[:, 0])


def keep_feet_apart(soles: dict[str, np.ndarray], contact: dict[str, np.ndarray], yaw: np.ndarray,
                    robot: Robot) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """The sole targets (side -> (F, 3)) moved apart sideways to at least :data:`FOOT_GAP` x the
    robot's standing gap, sideways in the feet's own frame (``yaw`` (F,): :func:`feet_yaw`), where
    they are less than :data:`KNEE_REACH` x a sole's length (or the standing gap, if longer) apart
    (where the knees, about halfway down the legs, are that near), fading to no requirement at
    twice that (legs that far apart cannot meet, whichever side each foot is on: a long lunge's);
    and side -> how far
    each frame's sole was moved (F,) [m]. ``contact``: side -> labelled contact per frame (F,); the
    swinging foot is moved, both half each when both are down or both up."""
    sole = robot.profile.sole
    length = KNEE_REACH * max(float(sole.x_max - sole.x_min), standing_gap(robot))
    least = FOOT_GAP * standing_gap(robot)
    left, right = np.asarray(soles["left"], dtype=float), np.asarray(soles["right"], dtype=float)
    yaw = np.asarray(yaw, dtype=float)
    y = np.stack([-np.sin(yaw), np.cos(yaw), np.zeros_like(yaw)], axis=1)  # the feet's left axis
    d = left - right
    apart = np.linalg.norm(d[:, :2], axis=1)
    need = least * np.clip(2.0 - apart / length, 0.0, 1.0)
    short = np.maximum(0.0, need - np.einsum("fi,fi->f", d, y))
    down_l, down_r = np.asarray(contact["left"], dtype=bool), np.asarray(contact["right"], dtype=bool)
    share_l = np.where(down_l == down_r, 0.5, np.where(down_l, 0.0, 1.0))  # the swinging foot moves
    move_l = (share_l * short)[:, None] * y
    move_r = -((1.0 - share_l) * short)[:, None] * y
    out = {"left": left + move_l, "right": right + move_r}
    return out, {"left": np.linalg.norm(move_l, axis=1), "right": np.linalg.norm(move_r, axis=1)}
