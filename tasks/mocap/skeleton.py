"""Which joints of a mocap skeleton are the body's keypoints: the two CMU skeletons built in,
others from a small TOML mapping file (``--skeleton FILE``, docs/retarget.md).

A mapping names, for each keypoint, the skeleton's joint (or end site, ``<joint>_end``) that
stands for it, gives the file's length unit in metres and its axes (which file axis is up, which
is the body's forward at rest). Keypoints: ``pelvis``, ``torso``, ``head``, ``left_shoulder``,
``right_shoulder``, ``left_hand``, ``right_hand``, ``left_hip``, ``right_hip``, ``left_ankle``,
``right_ankle``, ``left_toe``, ``right_toe`` (the toe tip, the lowest point of the foot).
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from pathlib import Path

from tasks.exceptions import ClipError

KEYPOINTS = ("pelvis", "torso", "head", "left_shoulder", "right_shoulder", "left_hand", "right_hand",
             "left_hip", "right_hip", "left_ankle", "right_ankle", "left_toe", "right_toe")
AXES = ("x", "y", "z", "-x", "-y", "-z")


@dataclass(frozen=True, slots=True, kw_only=True)
class SkeletonMap:
    """A skeleton's keypoint joints, length unit and axes.

    Attributes:
        name: What it is called in reports.
        joints: Keypoint -> joint name (every name of :data:`KEYPOINTS`).
        unit: Metres per length unit of the file.
        up: The file's up axis (``y``, ``z``, ``-y`` ...).
        forward: The body's forward axis in the file at rest (orthogonal to ``up``).
    """

    name: str
    joints: dict[str, str]
    unit: float
    up: str = "y"
    forward: str = "z"

    def __post_init__(self) -> None:
        missing = [k for k in KEYPOINTS if k not in self.joints]
        if missing:
            raise ClipError(f"skeleton {self.name!r}: no joint for {', '.join(missing)} (a mapping names all of "
                            f"{', '.join(KEYPOINTS)})")
        extra = sorted(set(self.joints) - set(KEYPOINTS))
        if extra:
            raise ClipError(f"skeleton {self.name!r}: unknown keypoints {extra}; the keypoints are {', '.join(KEYPOINTS)}")
        if not (isinstance(self.unit, (int, float)) and math.isfinite(self.unit) and 1e-5 <= self.unit <= 10.0):
            raise ClipError(f"skeleton {self.name!r}: unit must be metres per file unit in [1e-05, 10], got {self.unit!r}")
        if self.up not in AXES or self.forward not in AXES or self.up[-1] == self.forward[-1]:
            raise ClipError(f"skeleton {self.name!r}: up and forward must be two different axes of {AXES}, "
                            f"got up={self.up!r} forward={self.forward!r}")


MOTIONBUILDER = SkeletonMap(
    name="CMU MotionBuilder-friendly (31 joints)", unit=0.056444, up="y", forward="z",
    joints={"pelvis": "Hips", "torso": "Spine1", "head": "Head", "left_shoulder": "LeftArm",
            "right_shoulder": "RightArm", "left_hand": "LeftHand", "right_hand": "RightHand",
            "left_hip": "LeftUpLeg", "right_hip": "RightUpLeg", "left_ankle": "LeftFoot", "right_ankle": "RightFoot",
            "left_toe": "LeftToeBase_end", "right_toe": "RightToeBase_end"},
)
DAZ = SkeletonMap(
    name="CMU Daz-friendly (43 joints)", unit=0.01, up="y", forward="z",
    joints={"pelvis": "hip", "torso": "chest", "head": "head", "left_shoulder": "lShldr", "right_shoulder": "rShldr",
            "left_hand": "lHand", "right_hand": "rHand", "left_hip": "lThigh", "right_hip": "rThigh",
            "left_ankle": "lFoot", "right_ankle": "rFoot", "left_toe": "lFoot_end", "right_toe": "rFoot_end"},
)
BUILTIN = (MOTIONBUILDER, DAZ)


def recognize_skeleton(names: tuple[str, ...], source: str = "clip") -> SkeletonMap:
    """The built-in skeleton whose keypoint joints the clip has (ClipError when none fits)."""
    have = set(names)
    for skeleton in BUILTIN:
        if set(skeleton.joints.values()) <= have:
            return skeleton
    raise ClipError(f"{source}: unknown skeleton (root {names[0]!r}, {len(names)} joints); wbmp knows the CMU "
                    "MotionBuilder (Hips, LeftUpLeg ...) and Daz (hip, lThigh ...) skeletons: map yours with "
                    "--skeleton FILE (docs/retarget.md)")


def check_joints(skeleton: SkeletonMap, names: tuple[str, ...], source: str = "clip") -> None:
    """Every keypoint joint of the mapping is in the clip (ClipError naming the missing ones)."""
    missing = sorted({j for j in skeleton.joints.values() if j not in set(names)})
    if missing:
        raise ClipError(f"{source}: skeleton {skeleton.name!r} names joints the clip does not have: {', '.join(missing)}")


def load_skeleton(path: str | Path) -> SkeletonMap:
    """A mapping file (TOML): ``name``, ``unit``, ``up``, ``forward`` and a ``[joints]`` table."""
    where = str(path)
    try:
        if Path(path).stat().st_size > 64 * 1024:
            raise ClipError(f"{where}: a skeleton mapping is a few lines of TOML; this file is larger than 64 kB")
        data = tomllib.loads(Path(path).read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ClipError(f"{where}: no such skeleton mapping file") from None
    except (OSError, UnicodeDecodeError) as e:
        raise ClipError(f"{where}: cannot be read ({e})") from None
    except tomllib.TOMLDecodeError as e:
        raise ClipError(f"{where}: not valid TOML ({e})") from None
    joints = data.get("joints")
    if not isinstance(joints, dict) or not all(isinstance(v, str) for v in joints.values()):
        raise ClipError(f"{where}: needs a [joints] table of keypoint = \"joint name\" (docs/retarget.md)")
    unit = data.get("unit")
    if isinstance(unit, bool) or not isinstance(unit, (int, float)):
        raise ClipError(f"{where}: needs unit = metres per file unit (0.01 for centimetres)")
    return SkeletonMap(name=str(data.get("name", Path(path).stem)), joints=dict(joints), unit=float(unit),
                       up=str(data.get("up", "y")), forward=str(data.get("forward", "z")))
