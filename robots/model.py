"""Loading a humanoid: Pinocchio model + geometry + resolved frames + standing posture."""

from __future__ import annotations

import contextlib
import difflib
import functools
import math
import os
import re
import stat
import sys
import tempfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin

from robots.contact import sole_corners_in_world
from robots.exceptions import FrameNotFound, ProfileError, RobotError, RobotNotFound
from robots.profile import SIDE_PAIRS, RobotProfile, builtin_profiles, display_path, show
from robots.safeio import open_regular

STANDING_TOLERANCE = 1e-9  # [m], residual of the sole-levelling Gauss-Newton


@dataclass(frozen=True, eq=False)
class Robot:
    """A loaded humanoid. Treat every array and model here as read-only.

    Attributes:
        profile: The profile it was loaded from.
        model: Pinocchio model with a free-flyer root joint (``nq = nv + 1``).
        collision_model: Collision geometry.
        urdf_path: URDF file the model was built from.
        package_dirs: Directories that resolve ``package://`` mesh URIs.
        q_standing: Standing configuration (nq,): soles flat on z = 0, feet centred on x = y = 0.

    The visual geometry (:attr:`visual_model`) is loaded on first use: planning and simulating
    never need it, and Talos' visual meshes are the slowest part of loading the robot.
    """

    profile: RobotProfile
    model: pin.Model
    collision_model: pin.GeometryModel
    urdf_path: str
    package_dirs: tuple[str, ...]
    q_standing: np.ndarray
    _visual: _Lazy = field(default_factory=lambda: _Lazy(pin.GeometryModel), repr=False)
    _frame_ids: dict[str, int] = field(default_factory=dict, repr=False)

    @property
    def visual_model(self) -> pin.GeometryModel:
        """Visual geometry (meshes), for viewers; loaded on first use (ProfileError when its
        meshes cannot be loaded)."""
        return self._visual.get()

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

    def meet_joint(self, name_or_role: str) -> int:
        """The joint whose subtree is the frame's part in a planned self-contact: the frame's parent
        joint, for a hand frame ``[collisions] meet_joints`` joints higher up (G1's wrist links)."""
        model = self.model
        fid = self.frame_id(name_or_role)
        joint = model.frames[fid].parentJoint
        if fid in {self.frame_id(f"{s}_hand") for s in ("left", "right") if self.has_role(f"{s}_hand")}:
            for _ in range(self.profile.collisions.meet_joints):
                if model.parents[joint] > 1:  # not past the root joint
                    joint = model.parents[joint]
        return int(joint)

    def meet_links(self, name_or_role: str, other: str) -> frozenset[str]:
        """The links (frames carrying collision geometry) that make up the frame ``name_or_role``'s
        part when it meets ``other``'s (a hand meeting the other hand or the head): those on its
        :meth:`meet_joint` or below it, but for the joints that carry ``other``'s (a head on the
        trunk leaves out the trunk, which carries the hand's own arm). When its joint carries
        ``other``'s (G1's head is fixed on the torso, whose joint carries the arms), only the
        frame's own link."""
        model = self.model
        joint, theirs = self.meet_joint(name_or_role), self.meet_joint(other)
        geoms = self.collision_model.geometryObjects
        if joint in set(model.supports[theirs]):
            own = model.frames[self.frame_id(name_or_role)].name
            return frozenset(model.frames[g.parentFrame].name for g in geoms
                             if model.frames[g.parentFrame].name == own)
        below = set(model.subtrees[joint]) - set(model.supports[theirs])
        return frozenset(model.frames[g.parentFrame].name for g in geoms if g.parentJoint in below)

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
        return sole_corners_in_world(self.profile.sole, foot, data.oMf[self.frame_id(f"{foot}_foot")])

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
    A profile is checked field by field before any model is built, then against its URDF
    (frames, joints, posture) before the meshes are loaded.

    Raises:
        RobotNotFound: the name is neither a built-in robot nor an existing file.
        ProfileError: the profile file is malformed or names missing or broken files.
        FrameNotFound: a profile frame is not in the model.
    """
    if isinstance(name_or_path, RobotProfile):
        return _build(name_or_path)
    builtins = builtin_profiles()
    if not isinstance(name_or_path, (str, os.PathLike)):
        raise RobotNotFound(show(name_or_path), list(builtins))
    text = os.fspath(name_or_path)
    if not isinstance(text, str):  # a bytes path
        raise RobotNotFound(repr(text), list(builtins))
    if text in builtins:
        return _load_builtin(text)
    if not text.strip():
        raise RobotNotFound(text, list(builtins))
    path = Path(text)
    try:
        path = path.expanduser()
    except RuntimeError:  # ~user that does not exist: reported as a missing file below
        pass
    if path.suffix.lower() in (".toml", ".json") or _exists(path):
        return _build(RobotProfile.from_file(path))
    raise RobotNotFound(text, list(builtins))


def _exists(path: Path) -> bool:
    try:
        return path.exists()
    except (OSError, ValueError):  # a name too long, a NUL byte: not a file
        return False


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
        with open_regular(path, "mesh") as f:  # a FIFO or a device is not waited on
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
    where = profile.where
    if profile.loader is not None:
        urdf, srdf, package_dirs = _loader_paths(where, profile.loader)
    else:
        urdf = _check_file(where, "urdf", profile.urdf, "a URDF file")
        srdf = _check_file(where, "srdf", profile.srdf, "an SRDF file") if profile.srdf else None
        for i, d in enumerate(profile.package_dirs):
            _check_dir(where, f"package_dirs[{i}]", d)
        package_dirs = tuple(profile.package_dirs) or _guess_package_dirs(urdf)
        _check_xml(where, "urdf", urdf, root="robot")
        if srdf:
            _check_xml(where, "srdf", srdf, root="robot")
    # The kinematic model (milliseconds) is checked against the profile before the meshes
    # (seconds) are loaded, so a wrong frame or joint name costs nothing.
    model = _kinematic_model(where, urdf)
    if srdf:
        _load_srdf(where, model, srdf)
    _check_model(where, urdf, model)
    _add_extra_frames(where, model, profile)
    names = [f.name for f in model.frames]
    for role, frame in profile.frames:
        if not model.existFrame(frame):
            raise FrameNotFound(frame, profile.name, names, where=f"{where}: frames.{role}")
    q_ref = _reference_configuration(model, profile)
    _check_sides(where, model, profile, q_ref)
    skeleton = Robot(profile=profile, model=model, collision_model=pin.GeometryModel(), urdf_path=urdf,
                     package_dirs=(), q_standing=q_ref)
    try:
        q_stand = level_soles(skeleton, q_ref)
    except RobotError as e:
        raise ProfileError(f"{where}: frames: {e}") from None
    _check_standing(where, model, q_stand)
    q_stand.setflags(write=False)
    dirs = tuple(package_dirs)
    collision = _geometry(where, urdf, dirs, "collision")
    return Robot(
        profile=profile,
        model=model,
        collision_model=collision,
        urdf_path=str(Path(urdf).resolve()),
        package_dirs=tuple(str(Path(p).resolve()) for p in package_dirs),
        q_standing=q_stand,
        _visual=_Lazy(lambda: _geometry(where, urdf, dirs, "visual")),
    )


MAX_MODEL_FILE_BYTES = 64 << 20  # a URDF or SRDF (the largest example-robot-data URDF is ~0.3 MB)
URDF_JOINT_TYPES = ("revolute", "continuous", "prismatic", "fixed", "floating", "planar")


def _check_file(where: str, key: str, path: str | None, what: str) -> str:
    """``path`` is a readable regular file of a sane size; returns it."""
    shown = display_path(path or "")
    try:
        st = os.stat(path or "")
    except (FileNotFoundError, NotADirectoryError):
        raise ProfileError(f"{where}: {key}: {shown} does not exist (expected {what}; a relative path is "
                           "relative to the profile's folder)") from None
    except (OSError, ValueError) as e:
        raise ProfileError(f"{where}: {key}: cannot read {shown}: {getattr(e, 'strerror', None) or e}") from None
    if stat.S_ISDIR(st.st_mode):
        raise ProfileError(f"{where}: {key}: {shown} is a directory, expected {what}")
    if not stat.S_ISREG(st.st_mode):
        raise ProfileError(f"{where}: {key}: {shown} is not a regular file, expected {what}")
    if st.st_size > MAX_MODEL_FILE_BYTES:
        raise ProfileError(f"{where}: {key}: {shown} is larger than {MAX_MODEL_FILE_BYTES >> 20} MB; "
                           f"expected {what}")
    if not os.access(path or "", os.R_OK):
        raise ProfileError(f"{where}: {key}: cannot read {shown}: permission denied")
    return str(path)


def _check_dir(where: str, key: str, path: str) -> None:
    shown = display_path(path)
    try:
        is_dir = Path(path).is_dir()
    except (OSError, ValueError):
        is_dir = False
    if not is_dir:
        raise ProfileError(f"{where}: {key}: {shown} is not a folder (expected a folder that holds the "
                           "URDF's package:// meshes)")


def _check_xml(where: str, key: str, path: str, *, root: str) -> None:
    """The file is well-formed XML with a named ``<robot>`` root (and, for a URDF, a joint tree).

    Catches what Pinocchio's parser would report only as "does not contain a valid URDF model"
    (after printing the reason on stderr), with the reason in the message.
    """
    import xml.etree.ElementTree as ET

    shown = display_path(path)
    kind = key.upper()
    article = "an" if kind == "SRDF" else "a"
    try:
        tree = ET.parse(path)
    except ET.ParseError as e:
        raise ProfileError(f"{where}: {key}: {shown} is not {article} {kind} file (not well-formed XML: {e})") from None
    except (OSError, ValueError, RecursionError) as e:
        raise ProfileError(f"{where}: {key}: cannot read {shown} as XML: {e}") from None
    top = tree.getroot()
    if top.tag != root:
        raise ProfileError(f"{where}: {key}: {shown} is not {article} {kind} file: its root element is "
                           f"<{str(top.tag)[:40]}>, expected <{root}>")
    if key != "urdf":
        return
    if not top.get("name"):
        raise ProfileError(f"{where}: urdf: {shown}: the <robot> element has no name attribute")
    links = [el.get("name") for el in top.findall("link")]
    if not links:
        raise ProfileError(f"{where}: urdf: {shown} has no <link>; expected a robot model")
    if None in links or "" in links:
        raise ProfileError(f"{where}: urdf: {shown}: a <link> has no name")
    if len(set(links)) != len(links):
        dup = next(n for n in links if links.count(n) > 1)
        raise ProfileError(f"{where}: urdf: {shown}: link {dup!r} is defined twice")
    joints = top.findall("joint")
    if not joints:
        raise ProfileError(f"{where}: urdf: {shown} has no <joint>; wbmp needs a humanoid with joints")
    for link_el in top.findall("link"):
        mass = link_el.find("inertial/mass")
        value = mass.get("value") if mass is not None else None
        if mass is not None and not _is_mass(value):
            raise ProfileError(f"{where}: urdf: {shown}: link {link_el.get('name')!r} has mass {show(value)}; "
                               "expected a finite number of kilograms >= 0")
    known = set(links)
    children: set[str | None] = set()
    for j in joints:
        name = j.get("name")
        if not name:
            raise ProfileError(f"{where}: urdf: {shown}: a <joint> has no name")
        if j.get("type") not in URDF_JOINT_TYPES:
            raise ProfileError(f"{where}: urdf: {shown}: joint {name!r} has type {j.get('type')!r}; "
                               f"expected one of {', '.join(URDF_JOINT_TYPES)}")
        for end in ("parent", "child"):
            el = j.find(end)
            link = el.get("link") if el is not None else None
            if link not in known:
                raise ProfileError(f"{where}: urdf: {shown}: joint {name!r} has {end} link {link!r}, "
                                   "which is not a <link> of the file")
        child = link  # the loop's last end: the child's link, checked above
        if child in children:
            raise ProfileError(f"{where}: urdf: {shown}: link {child!r} is the child of two joints")
        children.add(child)
    roots = [n for n in links if n not in children]
    if len(roots) != 1:
        raise ProfileError(f"{where}: urdf: {shown}: the links do not form one tree "
                           f"({len(roots)} links have no parent joint)")


def _is_mass(text: str | None) -> bool:
    try:
        value = float(text or "")
    except ValueError:
        return False
    return math.isfinite(value) and value >= 0.0


@contextlib.contextmanager
def _native_stderr(sink: list[str]):
    """Collect what C++ code (urdfdom, Pinocchio) prints on file descriptor 2 into ``sink``.

    Pinocchio's URDF parser prints its reasons there and raises a generic error; the reason
    belongs in the one-line message instead. Falls back to doing nothing if fd 2 cannot be
    redirected.
    """
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError, AttributeError):
        yield
        return
    with tempfile.TemporaryFile() as tmp:
        try:
            os.dup2(tmp.fileno(), 2)
            yield
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            tmp.seek(0)
            sink.append(tmp.read(1 << 16).decode("utf-8", errors="replace"))


def _native_reason(captured: list[str]) -> str:
    """The first meaningful line of what urdfdom printed ("Error:   No link elements ...")."""
    for line in "".join(captured).splitlines():
        text = line.strip()
        if text.lower().startswith("error:"):
            text = text[6:].strip()
        if text and not text.startswith("at line"):
            return text[:200]
    return ""


def _echo_native(captured: list[str]) -> None:
    """Pass on what C++ code printed during a load that succeeded (warnings stay visible)."""
    text = "".join(captured)
    if text.strip():
        sys.stderr.write(text)


def _kinematic_model(where: str, urdf: str) -> pin.Model:
    captured: list[str] = []
    try:
        with _native_stderr(captured):
            model = pin.buildModelFromUrdf(urdf, pin.JointModelFreeFlyer())
    except (ValueError, RuntimeError, TypeError, IndexError) as e:
        reason = _native_reason(captured) or str(e).splitlines()[0][:200]
        raise ProfileError(f"{where}: urdf: Pinocchio cannot load {display_path(urdf)}: {reason}") from None
    reason = _native_reason(captured)
    if reason:  # urdfdom went on after an error (e.g. an unreadable <inertial>): the model is wrong
        raise ProfileError(f"{where}: urdf: Pinocchio cannot load {display_path(urdf)}: {reason}")
    return model


def _load_srdf(where: str, model: pin.Model, srdf: str) -> None:
    captured: list[str] = []
    try:
        with _native_stderr(captured):
            pin.loadReferenceConfigurations(model, srdf, False)
    except (ValueError, RuntimeError, TypeError, IndexError) as e:
        reason = _native_reason(captured) or str(e).splitlines()[0][:200]
        raise ProfileError(f"{where}: srdf: Pinocchio cannot read {display_path(srdf)}: {reason}") from None
    reason = _native_reason(captured)
    if reason:  # e.g. "Could not read joint config (leg_left_1_joint , abc)": the value was dropped
        raise ProfileError(f"{where}: srdf: Pinocchio cannot read {display_path(srdf)}: {reason}")


def _check_model(where: str, urdf: str, model: pin.Model) -> None:
    """The model has joints, finite non-negative masses and consistent limits."""
    shown = display_path(urdf)
    if model.nv <= 6:
        raise ProfileError(f"{where}: urdf: {shown} has no movable joint; wbmp needs a humanoid with legs")
    for i in range(1, model.njoints):
        inertia = model.inertias[i]
        values = np.concatenate([[inertia.mass], inertia.lever, np.ravel(inertia.inertia)])
        if not np.all(np.isfinite(values)) or inertia.mass < 0.0:
            raise ProfileError(f"{where}: urdf: {shown}: the body of joint {model.names[i]!r} has mass "
                               f"{inertia.mass:g} kg; expected finite masses >= 0 and finite inertias")
        if not np.all(np.isfinite(model.jointPlacements[i].homogeneous)):
            raise ProfileError(f"{where}: urdf: {shown}: joint {model.names[i]!r} has a non-finite origin")
    if not pin.computeTotalMass(model) > 0.0:
        raise ProfileError(f"{where}: urdf: {shown} has no mass (every <inertial> is missing or 0 kg)")
    lo, hi = model.lowerPositionLimit, model.upperPositionLimit
    for i in range(2, model.njoints):
        j = model.joints[i]
        sl = slice(j.idx_q, j.idx_q + j.nq)
        if np.any(np.isnan(lo[sl])) or np.any(np.isnan(hi[sl])) or np.any(lo[sl] > hi[sl]):
            raise ProfileError(f"{where}: urdf: {shown}: joint {model.names[i]!r} has lower limit "
                               f"{lo[sl][0]:g} above its upper limit {hi[sl][0]:g}")
        vs = slice(j.idx_v, j.idx_v + j.nv)
        for name, limit in (("velocity", model.velocityLimit[vs]), ("effort", model.effortLimit[vs])):
            if np.any(np.isnan(limit)) or np.any(limit < 0.0):
                raise ProfileError(f"{where}: urdf: {shown}: joint {model.names[i]!r} has {name} limit "
                                   f"{limit[0]:g}; expected a number >= 0")


def _add_extra_frames(where: str, model: pin.Model, profile: RobotProfile) -> None:
    for i, extra in enumerate(profile.extra_frames):
        names = [f.name for f in model.frames]
        if model.existFrame(extra.name):
            raise ProfileError(f"{where}: extra_frames[{i}].name: the model already has a frame {extra.name!r}; "
                               "give the extra frame a new name")
        if not model.existFrame(extra.parent):
            raise FrameNotFound(extra.parent, profile.name, names, where=f"{where}: extra_frames[{i}].parent")
        parent_id = model.getFrameId(extra.parent)
        parent = model.frames[parent_id]
        placement = parent.placement * pin.SE3(np.eye(3), np.array(extra.translation))
        model.addFrame(pin.Frame(extra.name, parent.parentJoint, parent_id, placement, pin.FrameType.OP_FRAME))


def _check_sides(where: str, model: pin.Model, profile: RobotProfile, q: np.ndarray) -> None:
    """Each left frame lies to the left (+y of the left foot frame) of its right twin."""
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    ref = data.oMf[model.getFrameId(profile.frame("left_foot"))]
    for left, right in SIDE_PAIRS:
        if profile.frame(left) is None:
            continue
        y = [float(ref.actInv(data.oMf[model.getFrameId(profile.frame(r))]).translation[1]) for r in (left, right)]
        if y[0] - y[1] >= 0.01:
            continue
        pair = f"{left} {profile.frame(left)!r} and {right} {profile.frame(right)!r}"
        at = f"y = {y[0]:.3f} m and {y[1]:.3f} m across the left foot's frame at the reference posture"
        if y[0] < y[1] - 0.01:
            raise ProfileError(f"{where}: frames: {pair} are mirrored ({at}); are left and right swapped?")
        raise ProfileError(f"{where}: frames: {pair} are less than 1 cm apart sideways ({at}); "
                           "name a frame on each side of the robot")


def _check_standing(where: str, model: pin.Model, q: np.ndarray) -> None:
    if not np.all(np.isfinite(q)):
        raise ProfileError(f"{where}: the standing posture is not finite; check reference_posture and "
                           "posture_overrides")
    lo, hi = model.lowerPositionLimit, model.upperPositionLimit
    for i in range(2, model.njoints):
        j = model.joints[i]
        if j.nq != 1:
            continue
        v = q[j.idx_q]
        if not lo[j.idx_q] - 1e-6 <= v <= hi[j.idx_q] + 1e-6:
            raise ProfileError(
                f"{where}: posture_overrides: standing with both soles flat puts joint {model.names[i]!r} at "
                f"{v:.3f}, outside its limits [{lo[j.idx_q]:.3f}, {hi[j.idx_q]:.3f}]; adjust posture_overrides "
                "or reference_posture"
            )


class _Lazy:
    """A value made on first use (by ``load``), then kept."""

    def __init__(self, load: Callable[[], pin.GeometryModel]) -> None:
        self._load: Callable[[], pin.GeometryModel] | None = load
        self._value: pin.GeometryModel | None = None

    def get(self) -> pin.GeometryModel:
        if self._value is None:
            assert self._load is not None
            self._value = self._load()
            self._load = None
        return self._value

    def __reduce__(self):  # a pickled robot carries its visual model, not the loader (a closure)
        return (_loaded, (self.get(),))


def _loaded(value: pin.GeometryModel) -> _Lazy:
    lazy = _Lazy(pin.GeometryModel)
    lazy._value = value
    return lazy


def _geometry(where: str, urdf: str, package_dirs: tuple[str, ...], kind: str) -> pin.GeometryModel:
    """The ``kind`` (collision, visual) geometry of ``urdf``: a copy of a cached load (meshes
    take seconds; cached in memory, and on disk by :mod:`robots.cache`)."""
    try:
        st = os.stat(urdf)
        gmodel = _cached_geometry(urdf, os.path.realpath(urdf), st.st_mtime_ns, st.st_size, package_dirs, kind)
    except (ValueError, RuntimeError, TypeError, IndexError, OSError) as e:
        reason = str(e).splitlines()[0][:200] if str(e) else type(e).__name__
        raise ProfileError(f"{where}: urdf: cannot load the meshes of {display_path(urdf)}: {reason} "
                           "(package_dirs must hold the folder of each package:// mesh)") from None
    return gmodel.copy()


@functools.lru_cache(maxsize=12)
def _cached_geometry(urdf: str, _realpath: str, _mtime_ns: int, _size: int,
                     package_dirs: tuple[str, ...], kind: str) -> pin.GeometryModel:
    from robots.cache import cached_geometry

    return cached_geometry(urdf, package_dirs, kind, lambda: _load_geometry(urdf, package_dirs, kind))


def _load_geometry(urdf: str, package_dirs: tuple[str, ...], kind: str) -> pin.GeometryModel:
    captured: list[str] = []
    gtype = pin.GeometryType.COLLISION if kind == "collision" else pin.GeometryType.VISUAL
    with _native_stderr(captured):
        model = pin.buildModelFromUrdf(urdf, pin.JointModelFreeFlyer())
        gmodel = pin.buildGeomFromUrdf(model, urdf, gtype, package_dirs=list(package_dirs))
    _echo_native(captured)
    correct_collada_up_axis(gmodel)
    return gmodel


def _loader_paths(where: str, loader: str) -> tuple[str, str | None, tuple[str, ...]]:
    """(urdf, srdf, package_dirs) of an example-robot-data robot, without loading it."""
    from example_robot_data import robots_loader

    cls = robots_loader.ROBOTS.get(loader)
    if cls is None:
        close = difflib.get_close_matches(loader, list(robots_loader.ROBOTS), n=3, cutoff=0.5)
        hint = f"; did you mean {', '.join(repr(c) for c in close)}?" if close else ""
        raise ProfileError(f"{where}: loader: expected an example-robot-data robot such as 'talos', 'g1', 'icub' "
                           f"or 'romeo', got {show(loader)}{hint}")
    if not cls.urdf_filename or not cls.free_flyer:
        why = "has no URDF" if not cls.urdf_filename else "is fixed to the ground"
        raise ProfileError(f"{where}: loader: the example-robot-data robot {loader!r} {why}; wbmp plans for "
                           "free-floating humanoids described by a URDF")
    sub = os.path.join(cls.path, cls.urdf_subpath, cls.urdf_filename)
    try:
        model_path = Path(cls.model_path or robots_loader.getModelPath(sub)).resolve()
    except OSError:
        raise ProfileError(f"{where}: loader: the files of {loader!r} are not installed "
                           "(reinstall example-robot-data)") from None
    srdf = str(model_path / cls.path / cls.srdf_subpath / cls.srdf_filename) if cls.srdf_filename else None
    # package:// URIs resolve against .../share (example-robot-data's own loader uses model_path/../..)
    return str(model_path / sub), srdf, (str(model_path.parents[1]), str(model_path))


def _guess_package_dirs(urdf: str) -> tuple[str, ...]:
    # package://pkg/... resolves against a directory that contains pkg: try the URDF's ancestors.
    return tuple(str(p) for p in Path(urdf).resolve().parents[:4])


def _reference_configuration(model: pin.Model, profile: RobotProfile) -> np.ndarray:
    where = profile.where
    refs = {e.key(): np.array(e.data()) for e in model.referenceConfigurations}
    name = profile.reference_posture
    if name == "q0":
        q = pin.neutral(model)
    elif name in refs:
        q = refs[name].copy()
        if q.shape != (model.nq,) or not np.all(np.isfinite(q)):
            raise ProfileError(f"{where}: reference_posture: {name!r} from the SRDF is not a finite "
                               f"configuration of {model.nq} values")
    else:
        srdf = "" if profile.loader or profile.srdf else " (give 'srdf' to read named postures)"
        raise ProfileError(f"{where}: reference_posture: expected 'q0' or a posture of the SRDF "
                           f"({', '.join(repr(k) for k in ['q0', *refs])}), got {show(name)}{srdf}")
    joints = list(model.names)[2:]
    for joint, value in profile.posture_overrides:
        key = f"posture_overrides.{joint}"
        if joint in ("universe", "root_joint"):
            raise ProfileError(f"{where}: {key}: {joint!r} is the robot's root, not a joint posture_overrides "
                               "can set; name actuated joints")
        if joint not in joints:
            close = difflib.get_close_matches(joint, joints, n=3, cutoff=0.6)
            hint = (f"did you mean {', '.join(repr(c) for c in close)}?" if close
                    else f"its joints include {', '.join(repr(j) for j in joints[:5])}, ... ({len(joints)} in all)")
            raise ProfileError(f"{where}: {key}: the URDF has no actuated joint {joint!r}; {hint}")
        j = model.joints[model.getJointId(joint)]
        if j.nq == 2 and j.nv == 1:  # continuous joint: stored as (cos, sin)
            q[j.idx_q:j.idx_q + 2] = (np.cos(value), np.sin(value))
            continue
        if j.nq != 1:
            raise ProfileError(f"{where}: {key}: joint {joint!r} has {j.nq} coordinates; posture_overrides "
                               "sets revolute, continuous and prismatic joints only")
        lo, hi = model.lowerPositionLimit[j.idx_q], model.upperPositionLimit[j.idx_q]
        if not lo - 1e-9 <= value <= hi + 1e-9:
            raise ProfileError(f"{where}: {key}: expected a value within the joint's limits "
                               f"[{lo:.4g}, {hi:.4g}], got {value:g}")
        q[j.idx_q] = value
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
