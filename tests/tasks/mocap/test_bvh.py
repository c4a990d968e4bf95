"""The BVH reader: forward kinematics against an independent composition (Pinocchio SE3 with
scipy's Euler angles), the two shared skeletons recognised, and bad files refused in one line."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from scipy.spatial.transform import Rotation

from tasks.mocap import ClipError, read_bvh, recognize_skeleton
from tasks.mocap.bvh import parse_bvh
from tasks.mocap.skeleton import DAZ, MOTIONBUILDER, load_skeleton

MOCAP = Path("/work/shared/mocap")
pytestmark = pytest.mark.skipif(not MOCAP.is_dir(), reason="the shared CMU clips are not on this machine")


def _reference(clip, joint: int, frame: int) -> np.ndarray:
    """World position of a joint by composing SE3 placements from the root (scipy's intrinsic
    Euler angles in the channels' order)."""
    chain = []
    i = joint
    while i >= 0:
        chain.append(i)
        i = clip.joints[i].parent
    M = pin.SE3.Identity()
    for i in reversed(chain):
        j = clip.joints[i]
        values = clip.motion[frame, j.first_channel:j.first_channel + len(j.channels)] if j.channels else []
        pos = np.array(j.offset, dtype=float)
        rot_axes, rot_angles = "", []
        for name, v in zip(j.channels, values, strict=True):
            if name.endswith("position"):
                pos["XYZ".index(name[0])] += v
            else:
                rot_axes += name[0]
                rot_angles.append(v)
        R = Rotation.from_euler(rot_axes, rot_angles, degrees=True).as_matrix() if rot_axes else np.eye(3)
        M = M * pin.SE3(R, pos)
    return M.translation


@pytest.mark.parametrize("name", ["12_01_walk.bvh", "10_02_kick.bvh"])  # ZYX (MotionBuilder) and ZXY (Daz) channels
def test_forward_kinematics_matches_se3_composition(name):
    clip = read_bvh(MOCAP / name)
    P = clip.positions()
    rng = np.random.default_rng(0)
    for frame in rng.choice(clip.n_frames, 4, replace=False):
        for joint in [clip.index(n) for n in recognize_skeleton(clip.names).joints.values()]:
            ref = _reference(clip, joint, int(frame))
            assert np.linalg.norm(P[frame, joint] - ref) < 1e-9 * max(1.0, np.linalg.norm(ref))


def test_every_shared_clip_reads_with_its_skeleton():
    rows = {r.split(",")[0]: r for r in (MOCAP / "clips.csv").read_text().splitlines()[1:]}
    for path in sorted(MOCAP.glob("*.bvh")):
        clip = read_bvh(path)
        skeleton = recognize_skeleton(clip.names, str(path))
        assert skeleton is (DAZ if "Daz" in rows[path.name] else MOTIONBUILDER)
        assert abs(clip.frame_time - 1 / 120) < 1e-5
        assert f",{clip.n_frames}," in rows[path.name]


def test_window_and_its_refusals():
    clip = read_bvh(MOCAP / "13_26_wave.bvh")
    part = clip.window(0.5, 1.5)
    assert part.n_frames == 121 and np.array_equal(part.motion[0], clip.motion[60])
    with pytest.raises(ClipError, match="--start 5 s is at or after the end"):
        clip.window(5.0, None)
    with pytest.raises(ClipError, match="must be after --start"):
        clip.window(1.0, 0.5)


HEAD = "HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation\n" \
       " End Site\n {\n  OFFSET 0 1 0\n }\n}\nMOTION\n"


@pytest.mark.parametrize(("raw", "message"), [
    (b"", "empty"),
    (b"\x00\x01\x02binary" * 10, "binary"),
    (b"hello world", "must start with HIERARCHY"),
    (HEAD.encode()[:60], "truncated"),
    ((HEAD + "Frames: 3\nFrame Time: 0.01\n" + "0 0 0 0 0 0\n" * 2).encode(), "says 3 frames but the file holds 2"),
    ((HEAD + "Frames: 3\nFrame Time: 0.01\n" + "0 0 0 0 0\n" * 3).encode(), "5 values; the hierarchy has 6 channels"),
    ((HEAD + "Frames: 3\nFrame Time: 0.01\n" + "0 0 nan 0 0 0\n" * 3).encode(), "finite numbers"),
    ((HEAD + "Frames: 10000000\nFrame Time: 0.01\n0 0 0 0 0 0\n").encode(), "10,000,000 frames"),
    (HEAD.replace("CHANNELS 6", "CHANNELS 4").encode(), "has '4' channels"),
    ((HEAD + "Frames: 3\nFrame Time: 0\n").encode(), "frame time"),
])
def test_bad_files_are_refused_in_one_line(raw, message):
    with pytest.raises(ClipError, match=message) as info:
        parse_bvh(raw, "bad.bvh")
    assert "\n" not in str(info.value) and str(info.value).startswith("bad.bvh")


def test_unknown_skeleton_and_a_mapping_file(tmp_path):
    clip = parse_bvh((HEAD + "Frames: 3\nFrame Time: 0.01\n" + "0 0 0 0 0 0\n" * 3).encode(), "tiny.bvh")
    with pytest.raises(ClipError, match="unknown skeleton.*--skeleton FILE"):
        recognize_skeleton(clip.names, "tiny.bvh")
    mapping = tmp_path / "mine.toml"
    mapping.write_text("name = 'mine'\nunit = 0.01\n[joints]\n"
                       + "".join(f"{k} = '{v}'\n" for k, v in DAZ.joints.items()))
    assert load_skeleton(mapping).joints == DAZ.joints
    mapping.write_text("unit = 0.01\n[joints]\npelvis = 'hip'\n")
    with pytest.raises(ClipError, match="no joint for torso"):
        load_skeleton(mapping)
