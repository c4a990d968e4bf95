"""Robot profiles: which frames of a humanoid play which role, and how it stands.

A :class:`RobotProfile` is data. It names the Pinocchio frames that the rest of wbmp
refers to by role (``left_foot``, ``right_foot``, ``left_hand``, ``right_hand``,
``head``, ``base``, ``torso``, ``left_shoulder``, ``right_shoulder``), the sole
rectangle in the foot frame, the reference standing posture and a few gait numbers.
Built-in profiles live in ``robots/profiles/*.toml``; a user's profile is a TOML or
JSON file with the same keys plus ``urdf`` (and optionally ``srdf``, ``package_dirs``).
"""

from __future__ import annotations

import json
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from robots.exceptions import ProfileError

ROLES = (
    "left_foot",
    "right_foot",
    "left_hand",
    "right_hand",
    "head",
    "base",
    "torso",
    "left_shoulder",
    "right_shoulder",
)
REQUIRED_ROLES = ("left_foot", "right_foot", "left_hand", "right_hand", "base")

Vec3 = tuple[float, float, float]


@dataclass(frozen=True, slots=True, kw_only=True)
class SoleRectangle:
    """Sole contact rectangle of the LEFT foot, in the foot frame [m].

    The right foot uses the mirror image (``y -> -y``). The foot frame's z axis is
    the sole normal and its origin lies on the sole surface.
    """

    x_min: float
    x_max: float
    y_min: float
    y_max: float

    def __post_init__(self) -> None:
        if not (self.x_min < self.x_max and self.y_min < self.y_max):
            raise ProfileError(f"sole rectangle is empty: {self}")

    def corners(self, side: str) -> tuple[tuple[float, float], ...]:
        """Corners in the foot frame, counter-clockwise, for ``side`` 'left' or 'right' [m]."""
        ys = (self.y_min, self.y_max) if side == "left" else (-self.y_max, -self.y_min)
        return (
            (self.x_min, ys[0]),
            (self.x_max, ys[0]),
            (self.x_max, ys[1]),
            (self.x_min, ys[1]),
        )


@dataclass(frozen=True, slots=True, kw_only=True)
class ExtraFrame:
    """A frame that wbmp adds to the model: ``parent`` frame + a fixed translation [m]."""

    name: str
    parent: str
    translation: Vec3


@dataclass(frozen=True, slots=True, kw_only=True)
class RobotProfile:
    """Everything wbmp needs to know about a humanoid beyond its URDF.

    Attributes:
        name: Short name (``talos``).
        description: One line for ``wbmp robots``.
        loader: ``example_robot_data`` loader name, or None for a URDF profile.
        urdf: Path to the URDF for a user profile (absolute, or relative to the profile file).
        srdf: Optional SRDF path (reference configurations are read from it).
        package_dirs: Directories searched for ``package://`` meshes.
        frames: Role -> Pinocchio frame name (see ``ROLES``).
        extra_frames: Frames added to the model before roles are resolved.
        sole: Left-foot sole rectangle in the foot frame [m].
        reference_posture: Name of a reference configuration (SRDF/loader), or ``"q0"``.
        posture_overrides: Joint name -> angle [rad] applied on top of the reference.
        friction_coefficient: Foot/ground Coulomb friction [-].
        step_length_max: Longest forward step the gait generator plans [m].
        step_width: Nominal lateral distance between the feet [m]; 0 = from the posture.
        step_duration: Single-support duration of one step [s].
        double_support_duration: Double-support duration between steps [s].
        squat_depth_max: Deepest CoM lowering the squat primitive allows [m].
    """

    name: str
    description: str = ""
    loader: str | None = None
    urdf: str | None = None
    srdf: str | None = None
    package_dirs: tuple[str, ...] = ()
    frames: tuple[tuple[str, str], ...] = ()
    extra_frames: tuple[ExtraFrame, ...] = ()
    sole: SoleRectangle
    reference_posture: str = "q0"
    posture_overrides: tuple[tuple[str, float], ...] = ()
    friction_coefficient: float = 0.7
    step_length_max: float = 0.25
    step_width: float = 0.0
    step_duration: float = 0.8
    double_support_duration: float = 0.2
    squat_depth_max: float = 0.3
    source: str = field(default="", compare=False)

    def __post_init__(self) -> None:
        if not self.name:
            raise ProfileError("a robot profile needs a 'name'")
        if (self.loader is None) == (self.urdf is None):
            raise ProfileError(f"profile {self.name!r}: give exactly one of 'loader' or 'urdf'")
        roles = dict(self.frames)
        unknown = sorted(set(roles) - set(ROLES))
        if unknown:
            raise ProfileError(
                f"profile {self.name!r}: unknown frame role(s) {unknown}; roles are {list(ROLES)}"
            )
        missing = [r for r in REQUIRED_ROLES if r not in roles]
        if missing:
            raise ProfileError(f"profile {self.name!r}: [frames] is missing {missing}")
        if self.friction_coefficient <= 0.0:
            raise ProfileError(f"profile {self.name!r}: friction_coefficient must be > 0")

    def frame(self, role: str) -> str | None:
        """Frame name playing ``role``, or None when the robot lacks it (e.g. no head)."""
        return dict(self.frames).get(role)

    @classmethod
    def from_mapping(cls, data: dict[str, Any], *, source: str = "") -> RobotProfile:
        """Build a profile from the parsed TOML/JSON mapping, resolving relative paths."""
        data = dict(data)
        base = Path(source).parent if source else Path.cwd()
        known = set(cls.__dataclass_fields__) - {"source"}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ProfileError(f"{source or 'profile'}: unknown key(s) {unknown}; known: {sorted(known)}")
        try:
            sole = data.pop("sole")
            sole = SoleRectangle(**sole)
        except KeyError:
            raise ProfileError(f"{source or 'profile'}: missing [sole] with x_min, x_max, y_min, y_max") from None
        except TypeError as e:
            raise ProfileError(f"{source or 'profile'}: bad [sole]: {e}") from None
        frames = tuple((str(k), str(v)) for k, v in dict(data.pop("frames", {})).items())
        extra = tuple(
            ExtraFrame(name=e["name"], parent=e["parent"], translation=tuple(float(x) for x in e["translation"]))
            for e in data.pop("extra_frames", [])
        )
        overrides = tuple((str(k), float(v)) for k, v in dict(data.pop("posture_overrides", {})).items())
        for key in ("urdf", "srdf"):
            if data.get(key):
                p = Path(data[key]).expanduser()
                data[key] = str(p if p.is_absolute() else (base / p).resolve())
        data["package_dirs"] = tuple(
            str(p if (p := Path(d).expanduser()).is_absolute() else (base / p).resolve())
            for d in data.get("package_dirs", ())
        )
        try:
            return cls(
                **data, sole=sole, frames=frames, extra_frames=extra,
                posture_overrides=overrides, source=source,
            )
        except TypeError as e:
            raise ProfileError(f"{source or 'profile'}: {e}") from None

    @classmethod
    def from_file(cls, path: str | Path) -> RobotProfile:
        """Read a TOML (``.toml``) or JSON (``.json``) profile file."""
        path = Path(path)
        if not path.is_file():
            raise ProfileError(f"profile file {str(path)!r} does not exist")
        try:
            if path.suffix == ".json":
                data = json.loads(path.read_text())
            else:
                data = tomllib.loads(path.read_text())
        except (json.JSONDecodeError, tomllib.TOMLDecodeError) as e:
            raise ProfileError(f"{path}: cannot parse profile: {e}") from None
        return cls.from_mapping(data, source=str(path))


PROFILE_DIR = Path(__file__).with_name("profiles")


def builtin_profiles() -> dict[str, RobotProfile]:
    """The profiles shipped with wbmp, by name (talos first: the default)."""
    out = {}
    for p in sorted(PROFILE_DIR.glob("*.toml"), key=lambda p: (p.stem != "talos", p.stem)):
        prof = RobotProfile.from_file(p)
        out[prof.name] = prof
    return out
