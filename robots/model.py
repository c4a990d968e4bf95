"""Loading a humanoid: Pinocchio model + geometry + resolved frames + standing posture."""

from __future__ import annotations

import functools
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin

from robots.exceptions import FrameNotFound, ProfileError, RobotError, RobotNotFound
from robots.profile import RobotProfile, builtin_profiles

STANDING_TOLERANCE = 1e-9  # [m], residual of the sole-levelling Gauss-Newton


@dataclass(frozen=True, eq=False)
class Robot:
    """A loaded humanoid. Treat every array and model here as read-only.

    Attributes:
        profile: The profile it was loaded from.
        model: Pinocchio model with a free-flyer root joint (``nq = nv + 1``).
        visual_model: Visual geometry (meshes), for viewers.
        collision_model: Collision geometry.
        urdf_path: URDF file the model was built from.
        package_dirs: Directories that resolve ``package://`` mesh URIs.
        q_standing: Standing configuration (nq,): soles flat on z = 0, feet centred on x = y = 0.
    """

    profile: RobotProfile
    model: pin.Model
    visual_model: pin.GeometryModel
    collision_model: pin.GeometryModel
    urdf_path: str
    package_dirs: tuple[str, ...]
    q_standing: np.ndarray
    _frame_ids: dict[str, int] = field(default_factory=dict, repr=False)

    @property
    def name(self) -> str:
        """Profile name (``talos``)."""
        return self.profile.name

    @property
    def nq(self) -> int:
        """Configuration size."""
        return self.model.nq

    @property
    def nv(self) -> int:
        """Tangent (velocity) size."""
        return self.model.nv

    @property
    def mass(self) -> float:
        """Total mass [kg]."""
        return float(pin.computeTotalMass(self.model))

    @property
    def joint_names(self) -> list[str]:
        """Actuated joint names in Pinocchio order (the free flyer excluded)."""
        return list(self.model.names)[2:]

    @property
    def lower_limits(self) -> np.ndarray:
        """Joint position lower limits (nq,) [m, rad]; free-flyer entries are -inf."""
        lo = np.array(self.model.lowerPositionLimit, dtype=float)
        lo[:7] = -np.inf
        return lo

    @property
    def upper_limits(self) -> np.ndarray:
        """Joint position upper limits (nq,) [m, rad]; free-flyer entries are +inf."""
        hi = np.array(self.model.upperPositionLimit, dtype=float)
        hi[:7] = np.inf
        return hi

    @property
    def velocity_limits(self) -> np.ndarray:
        """Joint velocity limits (nv,) [m/s, rad/s]; free-flyer entries are +inf."""
        v = np.array(self.model.velocityLimit, dtype=float)
        v[:6] = np.inf
        return v

    @property
    def torque_limits(self) -> np.ndarray:
        """Actuated joint torque limits (nv - 6,) [N m]."""
        return np.array(self.model.effortLimit, dtype=float)[6:]

    def frame(self, role: str) -> str:
        """Frame name of a role (``left_foot``), raising FrameNotFound if the robot lacks it."""
        name = self.profile.frame(role)
        if name is None:
            raise FrameNotFound(role, self.name, [r for r, _ in self.profile.frames])
        return name

    def has_role(self, role: str) -> bool:
        """True when the profile names a frame for ``role``."""
        return self.profile.frame(role) is not None

    def frame_id(self, name_or_role: str) -> int:
        """Pinocchio frame id of a frame name or a role name."""
        name = self.profile.frame(name_or_role) or name_or_role
        fid = self._frame_ids.get(name)
        if fid is None:
            if not self.model.existFrame(name):
                raise FrameNotFound(name, self.name, [f.name for f in self.model.frames])
            fid = self.model.getFrameId(name)
            self._frame_ids[name] = fid
        return fid

    def data(self) -> pin.Data:
        """A fresh Pinocchio data for this model."""
        return self.model.createData()

    def foot_side(self, frame: str) -> str | None:
        """'left' or 'right' when ``frame`` is a foot frame, else None."""
        if frame == self.profile.frame("left_foot"):
            return "left"
        if frame == self.profile.frame("right_foot"):
            return "right"
        return None

    def sole_corners_in_world(self, q: np.ndarray, foot: str) -> np.ndarray:
        """Sole rectangle corners (4, 3) of ``foot`` ('left'/'right') in the world at ``q`` [m]."""
        data = self.data()
        pin.framesForwardKinematics(self.model, data, q)
        oMf = data.oMf[self.frame_id(f"{foot}_foot")]
        corners = np.array([[x, y, 0.0] for x, y in self.profile.sole.corners(foot)])
        return corners @ oMf.rotation.T + oMf.translation

    def height(self) -> float:
        """Standing height: the highest frame origin at ``q_standing`` [m]."""
        data = self.data()
        pin.framesForwardKinematics(self.model, data, self.q_standing)
        return float(max(f.translation[2] for f in data.oMf))


def available_robots() -> list[str]:
    """Names of the built-in robots (the default first)."""
    return list(builtin_profiles())


DEFAULT_ROBOT = "talos"


def load_robot(name_or_path: str | Path | RobotProfile = DEFAULT_ROBOT) -> Robot:
    """Load a robot by built-in name, profile file (TOML/JSON), or profile object.

    Built-in robots are cached: loading ``talos`` twice returns the same read-only object.

    Raises:
        RobotNotFound: the name is neither a built-in robot nor an existing file.
        ProfileError: the profile file is malformed or names missing files.
        FrameNotFound: a profile frame is not in the model.
    """
    if isinstance(name_or_path, RobotProfile):
        return _build(name_or_path)
    text = str(name_or_path)
    builtins = builtin_profiles()
    if text in builtins:
        return _load_builtin(text)
    path = Path(text).expanduser()
    if path.suffix in (".toml", ".json") or path.exists():
        if not path.is_file():
            raise ProfileError(f"robot profile file {text!r} does not exist")
        return _build(RobotProfile.from_file(path))
    raise RobotNotFound(text, list(builtins))


@functools.cache
def _load_builtin(name: str) -> Robot:
    return _build(builtin_profiles()[name])


# Collada's <up_axis> -> the rotation that takes the file's coordinates to a Z-up frame
_UP_AXIS_ROTATIONS = {
    "Y_UP": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]),  # up +Y -> +Z, in +Z -> -Y
    "X_UP": np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]]),  # up +X -> +Z, right -Y -> +X
}
_UP_AXIS = re.compile(rb"<up_axis>\s*([XYZ]_UP)\s*</up_axis>")


@functools.cache
def collada_up_axis(path: str) -> str:
    """The ``<up_axis>`` of a Collada file (``Z_UP`` if absent, unreadable or not Collada)."""
    if not path.lower().endswith(".dae"):
        return "Z_UP"
    try:
        with open(path, "rb") as f:
            head = f.read(65536)
    except OSError:
        return "Z_UP"
    found = _UP_AXIS.search(head)
    return found.group(1).decode() if found else "Z_UP"


def correct_collada_up_axis(gmodel: pin.GeometryModel) -> int:
    """Rotate the placement of every Collada mesh whose file is not Z-up; returns how many.

    Pinocchio's mesh loader (coal, through assimp) keeps a Collada file's raw coordinates and
    ignores its ``<up_axis>``; a URDF's mesh frame is Z-up. iCub's meshes are ``Y_UP``: loaded
    as is, every part was turned 90 degrees about its link's x axis (the thigh pointed forward
    from the hip, the head hung below the neck). Viewers and the MuJoCo model use these
    placements, so they are corrected once, here.
    """
    n = 0
    for obj in gmodel.geometryObjects:
        rotation = _UP_AXIS_ROTATIONS.get(collada_up_axis(obj.meshPath or ""))
        if rotation is not None:
            obj.placement = obj.placement * pin.SE3(rotation, np.zeros(3))
            n += 1
    return n


def _build(profile: RobotProfile) -> Robot:
    if profile.loader is not None:
        urdf, srdf, package_dirs = _loader_paths(profile.loader)
    else:
        urdf, srdf, package_dirs = profile.urdf, profile.srdf, profile.package_dirs
        if not Path(urdf).is_file():
            raise ProfileError(f"profile {profile.name!r}: URDF {urdf!r} does not exist")
        if srdf and not Path(srdf).is_file():
            raise ProfileError(f"profile {profile.name!r}: SRDF {srdf!r} does not exist")
        package_dirs = tuple(package_dirs) or _guess_package_dirs(urdf)
    try:
        model, collision, visual = pin.buildModelsFromUrdf(
            urdf, list(package_dirs), pin.JointModelFreeFlyer()
        )
    except (ValueError, RuntimeError) as e:
        raise ProfileError(f"profile {profile.name!r}: cannot load URDF {urdf!r}: {e}") from None
    if srdf:
        try:
            pin.loadReferenceConfigurations(model, srdf, False)
        except (ValueError, RuntimeError) as e:
            raise ProfileError(f"profile {profile.name!r}: cannot read SRDF {srdf!r}: {e}") from None
    for gmodel in (visual, collision):
        correct_collada_up_axis(gmodel)
    names = [f.name for f in model.frames]
    for extra in profile.extra_frames:
        if not model.existFrame(extra.parent):
            raise FrameNotFound(extra.parent, profile.name, names)
        parent = model.frames[model.getFrameId(extra.parent)]
        placement = parent.placement * pin.SE3(np.eye(3), np.array(extra.translation))
        model.addFrame(
            pin.Frame(extra.name, parent.parentJoint, model.getFrameId(extra.parent), placement,
                      pin.FrameType.OP_FRAME)
        )
    names = [f.name for f in model.frames]
    for _role, frame in profile.frames:
        if not model.existFrame(frame):
            raise FrameNotFound(frame, profile.name, names)
    q_ref = _reference_configuration(model, profile)
    robot = Robot(
        profile=profile,
        model=model,
        visual_model=visual,
        collision_model=collision,
        urdf_path=str(Path(urdf).resolve()),
        package_dirs=tuple(str(Path(p).resolve()) for p in package_dirs),
        q_standing=q_ref,
    )
    q_stand = level_soles(robot, q_ref)
    q_stand.setflags(write=False)
    object.__setattr__(robot, "q_standing", q_stand)
    return robot


def _loader_paths(loader: str) -> tuple[str, str | None, tuple[str, ...]]:
    from example_robot_data import robots_loader

    cls = robots_loader.ROBOTS.get(loader)
    if cls is None:
        raise RobotNotFound(loader, sorted(robots_loader.ROBOTS))
    inst = cls()
    srdf = inst.srdf_path if inst.srdf_filename else None
    model_path = Path(inst.model_path).resolve()  # .../share/example-robot-data/robots
    return str(Path(inst.df_path).resolve()), srdf, (str(model_path.parents[1]), str(model_path))


def _guess_package_dirs(urdf: str) -> tuple[str, ...]:
    # package://pkg/... resolves against a directory that contains pkg: try the URDF's ancestors.
    return tuple(str(p) for p in Path(urdf).resolve().parents[:4])


def _reference_configuration(model: pin.Model, profile: RobotProfile) -> np.ndarray:
    refs = {e.key(): np.array(e.data()) for e in model.referenceConfigurations}
    name = profile.reference_posture
    if name == "q0":
        q = pin.neutral(model)
    elif name in refs:
        q = refs[name].copy()
    else:
        raise ProfileError(
            f"profile {profile.name!r}: reference posture {name!r} not found; "
            f"available: {['q0', *refs]}"
        )
    for joint, angle in profile.posture_overrides:
        if not model.existJointName(joint):
            raise ProfileError(f"profile {profile.name!r}: posture override names unknown joint {joint!r}")
        jid = model.getJointId(joint)
        q[model.joints[jid].idx_q] = angle
    return q


def level_soles(robot: Robot, q: np.ndarray, *, max_iterations: int = 50) -> np.ndarray:
    """Smallest change of ``q`` that puts both soles flat on z = 0, centred on x = y = 0.

    The feet keep their relative x/y offset and the base its yaw. Solved by Gauss-Newton on the
    12 sole residuals (position z, roll, pitch of each sole; the mid-foot x, y; the yaws) with a
    minimum-norm step, so joints that do not move the feet are untouched.

    Raises:
        RobotError: the soles cannot be levelled (e.g. wrong foot frames).
    """
    model, data = robot.model, robot.data()
    ids = [robot.frame_id("left_foot"), robot.frame_id("right_foot")]
    q = q.copy()
    pin.framesForwardKinematics(model, data, q)
    yaw0 = [float(np.arctan2(data.oMf[i].rotation[1, 0], data.oMf[i].rotation[0, 0])) for i in ids]
    yaw = 0.5 * (yaw0[0] + yaw0[1]) if abs(yaw0[0] - yaw0[1]) < 0.5 else 0.0
    rel = data.oMf[ids[0]].translation[:2] - data.oMf[ids[1]].translation[:2]
    targets_xy = [0.5 * rel, -0.5 * rel]
    rot = pin.rpy.rpyToMatrix(0.0, 0.0, yaw)
    for _ in range(max_iterations):
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        errs, jacs = [], []
        for fid, xy in zip(ids, targets_xy, strict=True):
            target = pin.SE3(rot, np.array([xy[0], xy[1], 0.0]))
            err = pin.log6(target.actInv(data.oMf[fid])).vector  # in the local frame
            J = pin.Jlog6(target.actInv(data.oMf[fid])) @ pin.getFrameJacobian(
                model, data, fid, pin.ReferenceFrame.LOCAL
            )
            errs.append(err)
            jacs.append(J)
        e = np.concatenate(errs)
        if np.linalg.norm(e) < STANDING_TOLERANCE:
            return q
        J = np.vstack(jacs)
        dq = -np.linalg.lstsq(J, e, rcond=None)[0]
        q = pin.integrate(model, q, dq)
    raise RobotError(
        f"robot {robot.name!r}: could not place both soles flat on the ground "
        f"(residual {np.linalg.norm(e):.2e}); check the foot frames in the profile"
    )
