"""Foot contacts labelled from the shared clips: a walk alternates, a squat keeps both feet
down, jumps and jumping jacks have flights; the ground and heading are aligned."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tasks.mocap import human_motion, label_contacts, read_bvh, recognize_skeleton
from tasks.mocap.source import segments

MOCAP = Path("/work/shared/mocap")
pytestmark = pytest.mark.skipif(not MOCAP.is_dir(), reason="the shared CMU clips are not on this machine")


def _labels(name: str):
    clip = read_bvh(MOCAP / name)
    motion = human_motion(clip, recognize_skeleton(clip.names))
    return motion, label_contacts(motion)


def _swings(flags) -> int:
    return sum(1 for _a, _b, down in segments(flags) if not down)


@pytest.mark.parametrize("name", ["12_01_walk.bvh", "16_11_walk_turn.bvh"])
def test_a_walk_alternates_single_supports(name):
    motion, labels = _labels(name)
    left, right = labels["left"], labels["right"]
    assert not np.any(~left & ~right)  # walking has no flight
    assert _swings(left) >= 3 and _swings(right) >= 3
    # every swing of one foot happens while the other is down
    for side, other in (("left", right), ("right", left)):
        for a, b, down in segments(labels[side]):
            if not down:
                assert other[a:b].all()
    # a stance foot does not slide: over the middle half of each labelled contact longer than
    # 0.2 s (after the heel strike has rolled the sole down, before the toe-off), its toe moves < 3 cm
    for side in ("left", "right"):
        toe = motion.points[f"{side}_toe"]
        for a, b, down in segments(labels[side]):
            if down and (b - a) * motion.frame_time > 0.2:
                q = (b - a) // 4
                assert np.ptp(toe[a + q:b - q, :2], axis=0).max() < 0.03


@pytest.mark.parametrize("name", ["13_29_squat.bvh", "18_15_dance.bvh", "13_29_bend.bvh"])
def test_squat_dance_and_bend_keep_both_feet_down(name):
    _, labels = _labels(name)
    assert labels["left"].all() and labels["right"].all()


@pytest.mark.parametrize(("name", "jumps"), [("01_01_jump_forward.bvh", 3), ("13_29_jumping_jacks.bvh", 3)])
def test_jumps_have_flights(name, jumps):
    motion, labels = _labels(name)
    flight = ~labels["left"] & ~labels["right"]
    runs = [(a, b) for a, b, up in segments(flight) if up and (b - a) * motion.frame_time >= 0.1]
    assert len(runs) >= jumps
    # in flight the feet are off the ground: the lowest foot point rises above 3 cm in each
    low = np.minimum(motion.foot_low("left"), motion.foot_low("right"))
    assert all(low[a:b].max() > 0.03 for a, b in runs)


def test_ground_and_heading_are_aligned():
    motion, labels = _labels("12_01_walk.bvh")
    assert abs(motion.heading()[0]) < 1e-9  # facing +x at the start
    assert np.allclose(motion.points["pelvis"][0, :2], 0.0)
    assert 0.8 < motion.points["pelvis"][0, 2] < 1.1  # hips height of an adult [m]
    # the walk goes forward along +x, 3.86 m net (clips.csv)
    assert abs(motion.points["pelvis"][-1, 0] - 3.86) < 0.1
    toe_in_contact = np.concatenate([motion.points[f"{s}_toe"][labels[s], 2] for s in ("left", "right")])
    assert abs(np.percentile(toe_in_contact, 25)) < 0.04  # the ground is under the stance toes (end sites ~2.5 cm up)
