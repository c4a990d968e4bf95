"""The human side of a retarget: a clip's keypoints in metres on a z-up ground, and its foot contacts.

:func:`human_motion` turns a :class:`~tasks.mocap.bvh.BvhClip` and its :class:`SkeletonMap` into
keypoint trajectories in the world convention of wbmp (x forward at rest, y left, z up, metres),
with the ground at z = 0 (the lowest foot points of the clip: their 2nd percentile) and the start
heading along x (the hips' left-right axis at the first frame along y).

:func:`label_contacts` labels each foot in contact at a frame when its lowest point (ankle or toe
tip) is within :data:`CONTACT_HEIGHT` of the ground and its horizontal speed is below
:data:`CONTACT_SPEED`; runs shorter than :data:`MIN_RUN` are absorbed by their neighbours.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tasks.exceptions import ClipError
from tasks.mocap.bvh import BvhClip
from tasks.mocap.skeleton import KEYPOINTS, SkeletonMap

CONTACT_HEIGHT = 0.06  # [m] lowest foot point above the ground: in contact below
CONTACT_SPEED = 0.5  # [m/s] horizontal speed of the foot: in contact below
MIN_RUN = 0.1  # [s] a contact or swing shorter than this is noise
GROUND_PERCENTILE = 2.0  # [%] of the per-frame lowest foot points: the ground
SIDES = ("left", "right")


@dataclass(frozen=True, eq=False)
class HumanMotion:
    """Keypoint trajectories of a clip in wbmp's world convention.

    Attributes:
        t: Frame times from 0 (F,) [s].
        points: Keypoint -> positions (F, 3) [m], z up, ground at 0, facing +x at the start.
        skeleton: The mapping used.
        source: The clip's file.
    """

    t: np.ndarray
    points: dict[str, np.ndarray]
    skeleton: SkeletonMap
    source: str = ""

    @property
    def frame_time(self) -> float:
        """Time between frames [s]."""
        return float(self.t[1] - self.t[0])

    def foot_low(self, side: str) -> np.ndarray:
        """Height of the foot's lowest point (ankle or toe tip) (F,) [m]."""
        return np.minimum(self.points[f"{side}_ankle"][:, 2], self.points[f"{side}_toe"][:, 2])

    def foot_speed(self, side: str) -> np.ndarray:
        """Horizontal speed of the foot (mean of ankle and toe tip) (F,) [m/s]."""
        mid = 0.5 * (self.points[f"{side}_ankle"] + self.points[f"{side}_toe"])[:, :2]
        return np.linalg.norm(np.gradient(mid, self.t, axis=0), axis=1)

    def heading(self) -> np.ndarray:
        """Facing yaw of the hips (F,) [rad], unwrapped (0 at the start)."""
        left = self.points["left_hip"] - self.points["right_hip"]
        yaw = np.unwrap(np.arctan2(-left[:, 0], left[:, 1]))  # forward = left x up
        return yaw

    def foot_yaw(self, side: str) -> np.ndarray:
        """Yaw of the foot (ankle to toe tip) (F,) [rad], unwrapped."""
        d = self.points[f"{side}_toe"] - self.points[f"{side}_ankle"]
        return np.unwrap(np.arctan2(d[:, 1], d[:, 0]))


def _axis(name: str) -> np.ndarray:
    v = np.zeros(3)
    v["xyz".index(name[-1])] = -1.0 if name.startswith("-") else 1.0
    return v


def human_motion(clip: BvhClip, skeleton: SkeletonMap) -> HumanMotion:
    """The clip's keypoints in metres, z up, ground at 0, facing +x at the start (see the module)."""
    where = clip.source or "clip"
    P = clip.positions() * skeleton.unit
    up, fwd = _axis(skeleton.up), _axis(skeleton.forward)
    left = np.cross(up, fwd)
    to_world = np.stack([fwd, left, up])  # rows: the file's axes of wbmp's x, y, z
    idx = {k: clip.index(skeleton.joints[k]) for k in KEYPOINTS}
    pts = {k: P[:, i] @ to_world.T for k, i in idx.items()}
    low = np.minimum.reduce([pts[f"{s}_{p}"][:, 2] for s in SIDES for p in ("ankle", "toe")])
    ground = float(np.percentile(low, GROUND_PERCENTILE))
    hip = pts["left_hip"][0] - pts["right_hip"][0]
    if math.hypot(hip[0], hip[1]) < 1e-3:
        raise ClipError(f"{where}: the hips' joints coincide at the first frame; not a body skeleton")
    yaw0 = math.atan2(-hip[0], hip[1])
    c, s = math.cos(-yaw0), math.sin(-yaw0)
    Rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    start = pts["pelvis"][0].copy()
    shift = np.array([start[0], start[1], ground])
    out = {k: (v - shift) @ Rz.T for k, v in pts.items()}
    height = float(out["head"][0, 2])
    if not 0.3 <= height <= 3.0:
        raise ClipError(f"{where}: the head is {height:.2f} m above the ground at the first frame with unit "
                        f"{skeleton.unit:g} m; give the file's unit in a --skeleton mapping")
    t = np.arange(clip.n_frames) * clip.frame_time
    return HumanMotion(t=t, points=out, skeleton=skeleton, source=where)


def _clean(flags: np.ndarray, min_frames: int) -> np.ndarray:
    """Runs shorter than ``min_frames`` take their neighbours' value (shortest first)."""
    out = flags.copy()
    for _ in range(len(out)):
        edges = np.flatnonzero(np.diff(out.astype(int))) + 1
        starts = np.concatenate([[0], edges])
        ends = np.concatenate([edges, [len(out)]])
        lengths = ends - starts
        inner = [(n, i) for i, n in enumerate(lengths) if n < min_frames and len(lengths) > 1]
        if not inner:
            break
        _, i = min(inner)
        out[starts[i]:ends[i]] = not out[starts[i]]
    return out


def label_contacts(motion: HumanMotion) -> dict[str, np.ndarray]:
    """Per foot (``left``, ``right``), a boolean (F,): in contact with the ground at that frame.

    A foot is in contact when its heel (ankle joint) or its toe tip is down: within
    :data:`CONTACT_HEIGHT` of that point's own lowest height in the clip (its 2nd percentile) and
    moving slower than :data:`CONTACT_SPEED` horizontally (a heel strike, a toe-off count)."""
    min_frames = max(1, int(round(MIN_RUN / motion.frame_time)))
    labels = {}
    for side in SIDES:
        down = np.zeros(len(motion.t), dtype=bool)
        for part in ("ankle", "toe"):
            p = motion.points[f"{side}_{part}"]
            rest = np.percentile(p[:, 2], GROUND_PERCENTILE)
            speed = np.linalg.norm(np.gradient(p[:, :2], motion.t, axis=0), axis=1)
            down |= (p[:, 2] - rest < CONTACT_HEIGHT) & (speed < CONTACT_SPEED)
        labels[side] = _clean(down, min_frames)
    return labels


def segments(flags: np.ndarray) -> list[tuple[int, int, bool]]:
    """Runs of equal flags: (first frame, last frame + 1, value)."""
    edges = np.flatnonzero(np.diff(flags.astype(int))) + 1
    starts = np.concatenate([[0], edges]).astype(int)
    ends = np.concatenate([edges, [len(flags)]]).astype(int)
    return [(int(a), int(b), bool(flags[a])) for a, b in zip(starts, ends, strict=True)]


def segments_of(code: np.ndarray) -> list[tuple[int, int, int]]:
    """Runs of equal contact codes on the knot grid: (first knot, last knot + 1, code)."""
    edges = np.flatnonzero(np.diff(code)) + 1
    starts = np.concatenate([[0], edges]).astype(int)
    ends = np.concatenate([edges, [len(code)]]).astype(int)
    return [(int(a), int(b), int(code[a])) for a, b in zip(starts, ends, strict=True)]


def merge_short(code: np.ndarray, min_knots: int) -> np.ndarray:
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
