"""A MuJoCo model built from the robot's own URDF, with index maps to Pinocchio.

The URDF that Pinocchio loaded is rewritten in memory (:mod:`sim.urdf`; docs/control.md, measured with
MuJoCo 4.0): ``package://`` mesh URIs become absolute file names, a ``<mujoco><compiler/>``
tag keeps every body (``fusestatic="false"``), and the root link hangs from a new ``world``
link through a ``floating`` joint, which MuJoCo turns into a free joint. Through
:class:`mujoco.MjSpec` we then add

* a floor plane (z = 0) with the scene's ``floor_friction`` (without a scene: the profile's
  friction coefficient), told as the contact model of :mod:`robots.contact` says (elliptic
  cone, ``condim`` 3),
* one thin box per sole, the profile's sole rectangle with its bottom face on the sole frame
  (the foot meshes stop colliding, so the feet touch the floor exactly where the controller's
  contact model says they do),
* a torque actuator per actuated joint, saturating at the URDF effort limit,
* self-collision: one explicit MuJoCo ``<pair>`` per pair of collision geoms of two links that
  the planner's collision model (:func:`robots.collision.collision_model`) says must not
  collide, and no other robot-robot contact (docs/simulation-collisions.md),
* the fingers, in a scene with a movable object (something to grasp): a fixed URDF joint that
  mimics a moving one becomes a MuJoCo hinge, coupled to it by a joint equality
  (:func:`_free_mimic_joints`; talos's gripper closes: :func:`hand_gripper`). Without one the
  fingers stay fixed, as in Pinocchio (12 fewer dofs: a talos step costs ~20 % less),
* the scene's objects (:class:`tasks.scene.Scene`): static ones as geoms of the world body,
  movable ones as free bodies with their mass and friction, each with an inactive weld to each
  hand (:func:`grasp_weld_name`; :mod:`sim.grasp` engages it when the closed hand holds the object).

Friction per surface: the floor's and the objects' geoms have a higher MuJoCo ``priority`` than the
robot's, so a contact of the robot with the world takes the surface's own friction coefficient (MuJoCo
would otherwise take the larger of the two geoms'): an icy slope is icy in the simulation, as in the
plan (:func:`tasks.terrain.with_surface_friction`). Two objects touching take the larger of theirs.

Joints are matched to Pinocchio by name, so either joint order works. Conventions: MuJoCo's free joint stores the
quaternion ``(w, x, y, z)`` and the base linear velocity in the world frame; Pinocchio stores
``(x, y, z, w)`` and the linear velocity in the base frame. :class:`SimModel` converts.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin

from robots import MUJOCO_CONDIM, MUJOCO_CONE, Robot, mujoco_friction, sole_corners
from sim.exceptions import SimModelError

# The URDF rewriting lives in sim.urdf; its names stay importable here.
from sim.urdf import (  # noqa: F401 (re-exported)
    FOREIGN_MESHES,
    MIN_INERTIA,
    ROOT_JOINT,
    _free_mimic_joints,
    _repair_inertia,
    _rewrite_urdf,
)
from tasks import Scene, SceneObject

FLOOR = "wbmp_floor"
SOLE_THICKNESS = 0.01  # [m] sole boxes: bottom face on the sole frame, 1 cm thick
ROBOT_CONTYPE, ROBOT_CONAFFINITY = 2, 1  # robot geoms collide with the floor (and objects) only
FLOOR_CONTYPE, FLOOR_CONAFFINITY = 1, 2
OBJECT_CONTYPE, OBJECT_CONAFFINITY = 1, 7  # objects collide with the robot, the feet, the floor, each other
WORLD_PRIORITY = 1  # the floor and the objects: a robot-world contact takes the surface's friction (module docstring)
FOOT_CONTYPE, FOOT_CONAFFINITY = 4, 0  # foot meshes (replaced by sole boxes on the floor) touch objects only
OBJECT_PREFIX = "wbmp_object_"
GRASP_PREFIX = "wbmp_grasp_"
#: Geom roles in :attr:`SimModel.geom_role`.
FLOOR_ROLE, ROBOT_ROLE, OBJECT_ROLE = 0, 1, 2


@dataclass(frozen=True, eq=False)
class SimModel:
    """A compiled MuJoCo model of a robot plus the maps between MuJoCo and Pinocchio.

    Attributes:
        robot: The robot it was built from.
        model: The compiled ``mujoco.MjModel`` (treat as read-only).
        qpos_index: For each Pinocchio actuated-joint configuration index ``7..nq-1``, the MuJoCo
            qpos index (nq - 7,).
        dof_index: For each Pinocchio actuated velocity index ``6..nv-1``, the MuJoCo dof index.
        actuator_index: For each actuated Pinocchio joint (nv - 6,), the MuJoCo actuator index.
        sole_geoms: Foot role (``left_foot``) -> MuJoCo geom id of its sole box.
        geom_body_names: MuJoCo body name of every geom (ngeom,).
        floor_geom: Geom id of the floor.
        torque_limits: Actuator limits in Pinocchio order (nv - 6,) [N m].
        collision_pairs: The link pairs (sorted names, sorted list) that must not collide, each
            with at least one MuJoCo pair: the collision model's pairs.
        pair_index: For each MuJoCo pair (npair,), its index in ``collision_pairs``.
        rest_overlap: Link pair -> how deep [m] (> 0) the convex hulls of its geoms overlap in the
            robot's standing configuration; these pairs have no MuJoCo pair (their hulls would
            push the links apart at rest).
        geom_role: ``FLOOR_ROLE``, ``ROBOT_ROLE`` or ``OBJECT_ROLE`` of every geom (ngeom,).
        geom_object: Scene object index of every geom, -1 for the floor and the robot (ngeom,).
        object_names: The scene's object names, in the scene's order.
        scene: The scene the model was built with (None: floor only).
        qpos_select, dof_select, actuator_select: The three index maps as slices where they are
            contiguous ranges (the per-tick copies use them), else the index arrays.
    """

    robot: Robot
    model: mujoco.MjModel
    qpos_index: np.ndarray
    dof_index: np.ndarray
    actuator_index: np.ndarray
    sole_geoms: dict[str, int]
    geom_body_names: tuple[str, ...]
    floor_geom: int
    torque_limits: np.ndarray
    collision_pairs: tuple[tuple[str, str], ...] = ()
    pair_index: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    rest_overlap: dict[tuple[str, str], float] = field(default_factory=dict)
    geom_role: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    geom_object: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    object_names: tuple[str, ...] = ()
    scene: Scene | None = None
    xml: str = field(repr=False, default="")
    # set by __post_init__: the index maps as slices where they are contiguous ranges
    qpos_select: slice | np.ndarray = field(init=False, repr=False)
    dof_select: slice | np.ndarray = field(init=False, repr=False)
    actuator_select: slice | np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        # the per-tick copies use slices where the index maps are contiguous ranges (fancy
        # indexing costs a few microseconds a call)
        object.__setattr__(self, "qpos_select", _as_slice(self.qpos_index))
        object.__setattr__(self, "dof_select", _as_slice(self.dof_index))
        object.__setattr__(self, "actuator_select", _as_slice(self.actuator_index))

    def data(self) -> mujoco.MjData:
        """A fresh ``mujoco.MjData``."""
        return mujoco.MjData(self.model)

    def set_state(self, data: mujoco.MjData, q: np.ndarray, v: np.ndarray | None = None) -> None:
        """Write a Pinocchio state (q (nq,), v (nv,)) into MuJoCo data, then run mj_forward.

        The scene's movable objects and the fingers (MuJoCo's only joints: :func:`_free_mimic_joints`)
        keep their state in ``data``.
        """
        qpos = np.array(data.qpos)
        qpos[:3] = q[:3]
        qpos[3] = q[6]
        qpos[4:7] = q[3:6]
        qpos[self.qpos_index] = q[7:]
        qvel = np.array(data.qvel)
        qvel[:6] = 0.0
        qvel[self.dof_index] = 0.0
        if v is not None:
            rot = pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix()
            qvel[:3] = rot @ v[:3]
            qvel[3:6] = v[3:6]
            qvel[self.dof_index] = v[6:]
        data.qpos[:] = qpos
        data.qvel[:] = qvel
        mujoco.mj_forward(self.model, data)

    def state(self, data: mujoco.MjData, q: np.ndarray, v: np.ndarray) -> None:
        """Read MuJoCo data into Pinocchio-convention ``q`` (nq,) and ``v`` (nv,) in place."""
        qpos, qvel = data.qpos, data.qvel
        q[:3] = qpos[:3]
        q[3:6] = qpos[4:7]
        q[6] = qpos[3]
        q[7:] = qpos[self.qpos_select]
        w, x, y, z = qpos[3:7].tolist()  # Python floats: scalar arithmetic on numpy items is slow
        # R^T @ world linear velocity, R from the unit quaternion (w, x, y, z)
        vx, vy, vz = qvel[:3].tolist()
        v[0] = (1 - 2 * (y * y + z * z)) * vx + 2 * (x * y + w * z) * vy + 2 * (x * z - w * y) * vz
        v[1] = 2 * (x * y - w * z) * vx + (1 - 2 * (x * x + z * z)) * vy + 2 * (y * z + w * x) * vz
        v[2] = 2 * (x * z + w * y) * vx + 2 * (y * z - w * x) * vy + (1 - 2 * (x * x + y * y)) * vz
        v[3:6] = qvel[3:6]
        v[6:] = qvel[self.dof_select]


def _as_slice(index: np.ndarray) -> slice | np.ndarray:
    """``index`` as a slice when it is a contiguous increasing range, else unchanged."""
    if len(index) and np.array_equal(index, np.arange(index[0], index[0] + len(index))):
        return slice(int(index[0]), int(index[0]) + len(index))
    return index


@functools.cache
def _cached(robot: Robot, timestep: float, joint_friction: bool, scene: Scene | None,
            pairs: tuple[tuple[str, str], ...] | None, floor_timeconst: float | None = None) -> SimModel:
    """In memory per process, and on disk across processes (:mod:`sim.modelcache`)."""
    from sim.modelcache import cached_model, model_key

    if pairs is None:
        pairs = model_pairs(robot)
    xml = _rewrite_urdf(robot, fingers=scene is not None and any(o.movable for o in scene.objects))
    try:
        key: str | None = model_key(robot, xml, timestep=timestep, joint_friction=joint_friction, scene=scene,
                                    pairs=pairs, floor_timeconst=floor_timeconst)
    except OSError:  # a mesh that cannot be read: _build reports it
        key = None
    return cached_model(key, lambda: _build(robot, timestep, joint_friction, scene, pairs, xml, floor_timeconst),
                        lambda model, fields: _sim_model(robot, model, fields, scene, pairs, xml))


def _sim_model(robot: Robot, model: mujoco.MjModel, fields: dict, scene: Scene | None,
               pairs: tuple[tuple[str, str], ...], xml: str) -> SimModel:
    """The SimModel of a compiled model and its index maps (``fields``, JSON types: what
    :func:`_build` made, or a cache entry held). Raises ValueError, KeyError, TypeError or
    IndexError when the maps do not fit the model."""
    n_act = robot.model.nv - 6
    ints = {name: np.asarray(fields[name], dtype=int) for name in
            ("qpos_index", "dof_index", "actuator_index", "pair_index", "geom_role", "geom_object")}
    for name, size, bound in (("qpos_index", n_act, model.nq), ("dof_index", n_act, model.nv),
                              ("actuator_index", n_act, model.nu), ("pair_index", model.npair, max(len(pairs), 1)),
                              ("geom_role", model.ngeom, 3), ("geom_object", model.ngeom, model.ngeom)):
        array = ints[name]
        if array.shape != (size,) or (size and not (array.min() >= -1 and array.max() < bound)):
            raise ValueError(f"{name} does not fit the model")
    sole_geoms = {str(k): int(v) for k, v in dict(fields["sole_geoms"]).items()}
    body_names = tuple(str(n) for n in fields["geom_body_names"])
    floor_geom = int(fields["floor_geom"])
    if len(body_names) != model.ngeom or not 0 <= floor_geom < model.ngeom \
            or any(not 0 <= g < model.ngeom for g in sole_geoms.values()):
        raise ValueError("geom ids do not fit the model")
    torque_limits = np.asarray(fields["torque_limits"], dtype=float)
    if torque_limits.shape != (n_act,):
        raise ValueError("torque_limits does not fit the robot")
    return SimModel(
        robot=robot,
        model=model,
        qpos_index=ints["qpos_index"],
        dof_index=ints["dof_index"],
        actuator_index=ints["actuator_index"],
        sole_geoms=sole_geoms,
        geom_body_names=body_names,
        floor_geom=floor_geom,
        torque_limits=torque_limits,
        collision_pairs=pairs,
        pair_index=ints["pair_index"],
        rest_overlap={(str(a), str(b)): float(d) for a, b, d in fields["rest_overlap"]},
        geom_role=ints["geom_role"],
        geom_object=ints["geom_object"],
        object_names=tuple(o.name for o in scene.objects) if scene is not None else (),
        scene=scene,
        xml=xml,
    )


def build_model(robot: Robot, *, timestep: float = 0.001, joint_friction: bool = True,
                scene: Scene | None = None,
                collision_pairs: tuple[tuple[str, str], ...] | None = None,
                floor_timeconst: float | None = None) -> SimModel:
    """Build (once per robot and options) the MuJoCo model of ``robot``.

    Args:
        robot: A loaded robot.
        timestep: MuJoCo integration step [s].
        joint_friction: Keep the URDF's joint ``damping`` and ``friction`` (MuJoCo frictionloss);
            False simulates frictionless joints.
        scene: Objects around the robot (None: the floor only).
        collision_pairs: The link pairs that must not collide (sorted names); None takes the
            robot's collision model's (:func:`robots.collision.collision_model`).
        floor_timeconst: The floor's and soles' contact time constant (``solref`` ``(t, 1)``) [s];
            None keeps MuJoCo's default (:class:`sim.settings.SimSettings`).

    Returns:
        The compiled model with its index maps.

    Raises:
        SimModelError: The URDF cannot be converted (missing meshes, several roots, unmatched
            joints), a collision pair names a link without collision geometry, or a scene object
            cannot be built (an unreadable mesh).
    """
    pairs = None if collision_pairs is None else tuple(tuple(sorted(p)) for p in collision_pairs)
    stiff = None if floor_timeconst is None else float(floor_timeconst)
    return _cached(robot, float(timestep), bool(joint_friction), scene, pairs, stiff)


def model_pairs(robot: Robot) -> tuple[tuple[str, str], ...]:
    """The link pairs of the robot's collision model that must not collide (sorted names)."""
    from robots import collision_model

    return tuple(tuple(sorted(p)) for p in collision_model(robot).pairs)  # type: ignore[misc]


_CONES = {"elliptic": mujoco.mjtCone.mjCONE_ELLIPTIC, "pyramidal": mujoco.mjtCone.mjCONE_PYRAMIDAL}


def set_friction_cone(spec: mujoco.MjSpec) -> None:
    """Tell MuJoCo the contact model's cone (:data:`robots.contact.MUJOCO_CONE`: elliptic, the
    Coulomb cone itself, so that MuJoCo accepts every force the planner and the controller do)."""
    spec.option.cone = _CONES[MUJOCO_CONE]


def set_contact_friction(geom: mujoco.MjsGeom, mu: float) -> None:
    """Tell a MuJoCo geom the contact model's friction: coefficient ``mu`` [-] and ``condim`` 3
    (:func:`robots.contact.mujoco_friction`, :data:`robots.contact.MUJOCO_CONDIM`)."""
    geom.friction = list(mujoco_friction(mu))
    geom.condim = MUJOCO_CONDIM


def _add_foreign_meshes(robot: Robot, spec: mujoco.MjSpec, bodies: dict, mu: float) -> None:
    """Collision meshes MuJoCo cannot read (Collada), rebuilt from the triangles Pinocchio loaded."""
    pmodel = robot.model
    for i, obj in enumerate(robot.collision_model.geometryObjects):
        if Path(obj.meshPath).suffix.lower() not in FOREIGN_MESHES:
            continue
        vertices = getattr(obj.geometry, "vertices", None)
        if not callable(vertices):
            continue
        points = np.asarray(vertices(), dtype=float)
        if points.ndim != 2 or len(points) < 4:
            continue
        frame = pmodel.frames[obj.parentFrame]
        body = bodies.get(frame.name)
        if body is None:  # a frame MuJoCo merged or renamed: use the joint's body
            body = bodies.get(pmodel.names[obj.parentJoint])
        if body is None:
            continue
        placement = frame.placement.actInv(obj.placement)  # geometry in the frame (= MuJoCo body)
        mesh = spec.add_mesh()
        mesh.name = f"wbmp_mesh_{i}"
        mesh.uservert = points.reshape(-1).tolist()  # Pinocchio's loader already applied meshScale
        geom = body.add_geom()
        geom.name = f"wbmp_collision_{i}"
        geom.type = mujoco.mjtGeom.mjGEOM_MESH
        geom.meshname = mesh.name
        geom.pos = placement.translation
        quat = pin.Quaternion(placement.rotation)
        geom.quat = [quat.w, quat.x, quat.y, quat.z]
        set_contact_friction(geom, mu)
        geom.contype, geom.conaffinity = ROBOT_CONTYPE, ROBOT_CONAFFINITY
        geom.group = 3
        geom.mass = 0.0
        geom.density = 0.0


def _build(robot: Robot, timestep: float, joint_friction: bool, scene: Scene | None,
           pairs: tuple[tuple[str, str], ...], xml: str,
           floor_timeconst: float | None = None) -> tuple[mujoco.MjModel, dict]:
    """The compiled model and its index maps in JSON types (see :func:`_sim_model`)."""
    try:
        spec = mujoco.MjSpec.from_string(xml)
    except ValueError as e:
        raise SimModelError(f"robot {robot.name!r}: MuJoCo cannot load the URDF: {e}") from None
    pmodel = robot.model
    mu = float(robot.profile.friction_coefficient)
    # keep the foot meshes that stop touching the floor (contype 0): self-collision pairs use them
    spec.compiler.discardvisual = False
    spec.option.timestep = timestep
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    set_friction_cone(spec)

    for i, geom in enumerate(spec.geoms):
        if not geom.name:  # explicit collision pairs refer to geoms by name
            geom.name = f"wbmp_geom_{i}"
        geom.contype, geom.conaffinity = ROBOT_CONTYPE, ROBOT_CONAFFINITY
        set_contact_friction(geom, mu)
    floor = spec.worldbody.add_geom()
    floor.name = FLOOR
    floor.type = mujoco.mjtGeom.mjGEOM_PLANE
    floor.size = [0.0, 0.0, 0.05]
    set_contact_friction(floor, mu if scene is None else float(scene.floor_friction))
    floor.priority = WORLD_PRIORITY
    floor.contype, floor.conaffinity = FLOOR_CONTYPE, FLOOR_CONAFFINITY

    bodies = {b.name: b for b in spec.bodies}
    _add_foreign_meshes(robot, spec, bodies, mu)
    joints = {j.name: j for j in spec.joints}
    sole_names = _add_soles(robot, spec, bodies, joints, mu)
    if floor_timeconst is not None:  # both sides of a sole's contact: MuJoCo mixes the two geoms' solref
        for geom in (floor, *(g for g in spec.geoms if g.name in sole_names.values())):
            geom.solref = [floor_timeconst, 1.0]

    _add_scene(spec, scene)
    _add_grasp_welds(robot, spec, scene)
    actuated = list(pmodel.names)[2:]
    limits = np.array(pmodel.effortLimit, dtype=float)[6:]
    _add_actuators(robot, spec, joints, actuated, limits, joint_friction)
    try:
        model = spec.compile()
    except ValueError as e:
        raise SimModelError(f"robot {robot.name!r}: MuJoCo cannot compile the model: {e}") from None

    qpos_index, dof_index, actuator_index = [], [], []
    for name in actuated:
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
        if int(model.jnt_type[jid]) not in (
            int(mujoco.mjtJoint.mjJNT_HINGE),
            int(mujoco.mjtJoint.mjJNT_SLIDE),
        ):
            raise SimModelError(
                f"robot {robot.name!r}: joint {name!r} is not a 1-dof joint in MuJoCo"
            )
        qpos_index.append(model.jnt_qposadr[jid])
        dof_index.append(model.jnt_dofadr[jid])
        actuator_index.append(
            mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, f"wbmp_motor_{name}")
        )
    if int(model.jnt_type[0]) != int(mujoco.mjtJoint.mjJNT_FREE):
        raise SimModelError(
            f"robot {robot.name!r}: MuJoCo did not make the root joint a free joint"
        )
    sole_geoms = {
        role: mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, n)
        for role, n in sole_names.items()
    }
    body_names = tuple(model.body(int(model.geom_bodyid[g])).name for g in range(model.ngeom))
    object_names = tuple(o.name for o in scene.objects) if scene is not None else ()
    geom_role = np.full(model.ngeom, ROBOT_ROLE, dtype=int)
    geom_object = np.full(model.ngeom, -1, dtype=int)
    geom_role[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, FLOOR)] = FLOOR_ROLE
    for k, name in enumerate(object_names):
        g = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, OBJECT_PREFIX + name)
        geom_role[g], geom_object[g] = OBJECT_ROLE, k
    model, pair_index, rest_overlap = _add_self_collision(robot, spec, model, pairs, geom_role, sole_geoms)
    fields = {
        "qpos_index": [int(i) for i in qpos_index],
        "dof_index": [int(i) for i in dof_index],
        "actuator_index": [int(i) for i in actuator_index],
        "sole_geoms": {k: int(v) for k, v in sole_geoms.items()},
        "geom_body_names": list(body_names),
        "floor_geom": int(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, FLOOR)),
        "torque_limits": [float(x) for x in limits],
        "pair_index": [int(i) for i in pair_index],
        "rest_overlap": [[a, b, float(d)] for (a, b), d in rest_overlap.items()],
        "geom_role": [int(i) for i in geom_role],
        "geom_object": [int(i) for i in geom_object],
    }
    return model, fields


def _add_soles(robot: Robot, spec: mujoco.MjSpec, bodies: dict, joints: dict, mu: float) -> dict[str, str]:
    """One thin box per sole on its ankle body (the foot meshes stop touching the floor); the
    role -> sole geom name map."""
    pmodel = robot.model
    sole_names = {}
    for role in ("left_foot", "right_foot"):
        frame = pmodel.frames[robot.frame_id(role)]
        joint_name = pmodel.names[frame.parentJoint]
        if joint_name not in joints:
            raise SimModelError(
                f"robot {robot.name!r}: joint {joint_name!r} of the {role} is not in MuJoCo"
            )
        body = joints[joint_name].parent
        for geom in body.geoms:  # the foot mesh: the sole box replaces it on the floor
            geom.contype, geom.conaffinity = FOOT_CONTYPE, FOOT_CONAFFINITY
        for child in bodies.values():  # fixed children (sole links) of the ankle body
            if child.parent is not None and child.parent.name == body.name and not child.joints:
                for geom in child.geoms:
                    geom.contype, geom.conaffinity = FOOT_CONTYPE, FOOT_CONAFFINITY
        side = role.split("_")[0]
        corners = sole_corners(robot.profile.sole, side)
        centre = np.array([corners[:, 0].mean(), corners[:, 1].mean(), 0.5 * SOLE_THICKNESS])
        half = [0.5 * np.ptp(corners[:, 0]), 0.5 * np.ptp(corners[:, 1]), 0.5 * SOLE_THICKNESS]
        placement = frame.placement
        sole = body.add_geom()
        sole.name = f"wbmp_{role}_sole"
        sole.type = mujoco.mjtGeom.mjGEOM_BOX
        sole.size = half
        sole.pos = placement.rotation @ centre + placement.translation
        quat = pin.Quaternion(placement.rotation)
        sole.quat = [quat.w, quat.x, quat.y, quat.z]
        set_contact_friction(sole, mu)
        sole.contype, sole.conaffinity = ROBOT_CONTYPE, ROBOT_CONAFFINITY
        sole.mass = 0.0
        sole.density = 0.0
        sole_names[role] = sole.name
    return sole_names


def _add_actuators(robot: Robot, spec: mujoco.MjSpec, joints: dict, actuated: list[str],
                   limits: np.ndarray, joint_friction: bool) -> None:
    """A torque actuator per actuated joint, saturating at its URDF effort limit (none when the
    URDF gives no usable one); without ``joint_friction`` the joints' damping and friction go."""
    for name, limit in zip(actuated, limits, strict=True):
        if name not in joints:
            raise SimModelError(
                f"robot {robot.name!r}: Pinocchio joint {name!r} has no MuJoCo joint"
            )
        if not joint_friction:
            joints[name].damping = np.zeros_like(np.asarray(joints[name].damping))
            joints[name].frictionloss = 0.0
        act = spec.add_actuator()
        act.name = f"wbmp_motor_{name}"
        act.target = name
        act.trntype = mujoco.mjtTrn.mjTRN_JOINT
        if 0.0 < limit < np.inf:
            act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
            act.ctrlrange = [-limit, limit]
        else:  # no usable effort limit in the URDF: the controller's output is the only bound
            act.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
        act.gear = [1.0, 0, 0, 0, 0, 0]


def _add_scene(spec: mujoco.MjSpec, scene: Scene | None) -> None:
    """The scene's objects: static ones as world geoms, movable ones as free bodies."""
    if scene is None:
        return
    for obj in scene.objects:
        if obj.movable:
            body = spec.worldbody.add_body()
            body.name = OBJECT_PREFIX + obj.name
            body.pos = list(obj.position)
            body.quat = _quat_wxyz(obj.rpy)
            body.add_freejoint()
            geom = body.add_geom()
            geom.mass = float(obj.mass)  # MuJoCo spreads it over the shape: the shape's inertia
        else:
            geom = spec.worldbody.add_geom()
            geom.pos = list(obj.position)
            geom.quat = _quat_wxyz(obj.rpy)
        geom.name = OBJECT_PREFIX + obj.name
        _shape(spec, geom, obj)
        geom.rgba = list(obj.colour)
        set_contact_friction(geom, float(obj.friction))
        geom.priority = WORLD_PRIORITY
        geom.contype, geom.conaffinity = OBJECT_CONTYPE, OBJECT_CONAFFINITY


def grasp_weld_name(side: str, obj: str) -> str:
    """The MuJoCo equality that attaches scene object ``obj`` to the ``side`` hand (sim.grasp)."""
    return f"{GRASP_PREFIX}{side}_{obj}"


def _add_grasp_welds(robot: Robot, spec: mujoco.MjSpec, scene: Scene | None) -> None:
    """An inactive weld between each hand's body and each movable object (:mod:`sim.grasp` engages
    one when the hand holds the object: the named simplification of a closing gripper)."""
    if scene is None:
        return
    bodies = {b.name for b in spec.bodies}
    for side in ("left", "right"):
        if not robot.has_role(f"{side}_hand"):
            continue
        hand = robot.model.frames[robot.frame_id(f"{side}_hand")]
        link = hand.name if hand.name in bodies else robot.model.frames[hand.parentFrame].name
        if link not in bodies:
            continue
        for obj in scene.objects:
            if obj.movable:
                eq = spec.add_equality()
                eq.name = grasp_weld_name(side, obj.name)
                eq.type = mujoco.mjtEq.mjEQ_WELD
                eq.objtype = mujoco.mjtObj.mjOBJ_BODY
                eq.name1 = link
                eq.name2 = OBJECT_PREFIX + obj.name
                eq.active = False


@dataclass(frozen=True)
class Gripper:
    """A hand's closing gripper in the MuJoCo model: the drive joint (a Pinocchio joint) and the
    joints that mimic it (MuJoCo's only: :func:`_free_mimic_joints`, coupled to the drive by joint
    equalities).

    Attributes:
        side: ``"left"`` or ``"right"``.
        joint: The drive joint's name (talos: ``gripper_right_joint``).
        qpos, dof: Its MuJoCo qpos and dof indices.
        actuated: Its index among the robot's actuated joints (the controller's ``tau``).
        open_angle: Its standing angle [rad] (talos: 0, the fingers apart).
        closed_angle: Its limit farther from the standing angle [rad] (talos: -1.047).
        effort: Its effort limit [N m].
        mimics: ``(joint name, offset [rad], multiplier)`` of each joint that mimics it:
            ``q_mimic = offset + multiplier * q_drive``.
        finger_geoms: The robot geoms of the links the drive and its mimics move.
        pad_geoms: Those of the fingertips: the links of mimic joints that hang from another moving
            finger link (talos: ``*_fingertip_{1,2,3}_link``; not the linkage and drive links).
    """

    side: str
    joint: str
    qpos: int
    dof: int
    actuated: int
    open_angle: float
    closed_angle: float
    effort: float
    mimics: tuple[tuple[str, float, float], ...]
    finger_geoms: tuple[int, ...]
    pad_geoms: tuple[int, ...]


def subtree(model: mujoco.MjModel, body: int) -> set[int]:
    """``body`` and every body below it (MuJoCo numbers a child after its parent)."""
    out = {body}
    for b in range(body + 1, model.nbody):
        if int(model.body_parentid[b]) in out:
            out.add(b)
    return out


def hand_gripper(sm: SimModel, side: str) -> Gripper | None:
    """The ``side`` hand's closing gripper, or None when the hand has none: no actuated joint below
    the hand's link that other joints mimic (a robot whose URDF has no ``<mimic>`` fingers)."""
    robot, m = sm.robot, sm.model
    if not robot.has_role(f"{side}_hand"):
        return None
    pm = robot.model
    joint = pm.frames[robot.frame_id(f"{side}_hand")].parentJoint
    link = next((f.name for f in pm.frames if f.parentJoint == joint and f.type == pin.FrameType.BODY), "")
    root = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, link) if link else -1
    if root < 0:
        return None
    hand = subtree(m, root)
    actuated = list(pm.names)[2:]
    for k, name in enumerate(actuated):
        jid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)
        if jid < 0 or int(m.jnt_bodyid[jid]) not in hand:
            continue
        mimics = [e for e in range(m.neq) if int(m.eq_type[e]) == int(mujoco.mjtEq.mjEQ_JOINT)
                  and int(m.eq_obj2id[e]) == jid]
        if not mimics:
            continue
        bodies = subtree(m, int(m.jnt_bodyid[jid]))
        for e in mimics:
            bodies |= subtree(m, int(m.jnt_bodyid[m.eq_obj1id[e]]))
        moved = {int(m.jnt_bodyid[jid])} | {int(m.jnt_bodyid[m.eq_obj1id[e]]) for e in mimics}
        tips = {b for b in moved if b != int(m.jnt_bodyid[jid]) and int(m.body_parentid[b]) in moved}
        geoms = tuple(g for g in range(m.ngeom) if int(sm.geom_role[g]) == ROBOT_ROLE and int(m.geom_bodyid[g]) in bodies)
        pid = pm.getJointId(name)
        open_angle = float(robot.q_standing[pm.joints[pid].idx_q])
        lo, hi = (float(x) for x in m.jnt_range[jid])
        return Gripper(
            side=side, joint=name, qpos=int(m.jnt_qposadr[jid]), dof=int(m.jnt_dofadr[jid]), actuated=k,
            open_angle=open_angle, closed_angle=lo if abs(lo - open_angle) >= abs(hi - open_angle) else hi,
            effort=float(sm.torque_limits[k]),
            mimics=tuple((m.joint(int(m.eq_obj1id[e])).name, float(m.eq_data[e, 0]), float(m.eq_data[e, 1]))
                         for e in mimics),
            finger_geoms=geoms, pad_geoms=tuple(g for g in geoms if int(m.geom_bodyid[g]) in tips))
    return None


def _quat_wxyz(rpy: tuple[float, float, float]) -> list[float]:
    quat = pin.Quaternion(pin.rpy.rpyToMatrix(*rpy))
    return [quat.w, quat.x, quat.y, quat.z]


def _shape(spec: mujoco.MjSpec, geom: mujoco.MjsGeom, obj: SceneObject) -> None:
    """Give ``geom`` the object's shape (MuJoCo sizes are half extents)."""
    size = [float(x) for x in obj.size]
    if obj.shape == "box":
        geom.type = mujoco.mjtGeom.mjGEOM_BOX
        geom.size = [0.5 * x for x in size]
    elif obj.shape == "cylinder":
        geom.type = mujoco.mjtGeom.mjGEOM_CYLINDER
        geom.size = [size[0], 0.5 * size[1], 0.0]
    elif obj.shape == "sphere":
        geom.type = mujoco.mjtGeom.mjGEOM_SPHERE
        geom.size = [size[0], 0.0, 0.0]
    elif obj.shape == "mesh":
        if obj.mesh is None or not Path(obj.mesh).is_file():
            raise SimModelError(f"scene object {obj.name!r}: mesh file {obj.mesh!r} not found")
        if Path(obj.mesh).suffix.lower() in FOREIGN_MESHES:
            raise SimModelError(f"scene object {obj.name!r}: MuJoCo cannot read {obj.mesh!r}; "
                                "convert the mesh to STL or OBJ")
        mesh = spec.add_mesh()
        mesh.name = f"{OBJECT_PREFIX}{obj.name}_mesh"
        mesh.file = str(Path(obj.mesh).resolve())
        mesh.scale = size
        geom.type = mujoco.mjtGeom.mjGEOM_MESH
        geom.meshname = mesh.name
    elif obj.shape == "heightfield":
        _height_field(spec, geom, obj)
    else:
        raise SimModelError(f"scene object {obj.name!r}: unknown shape {obj.shape!r}")


HFIELD_BASE = 0.01  # [m] a height field's solid base below its lowest point


def _height_field(spec: mujoco.MjSpec, geom: mujoco.MjsGeom, obj: SceneObject) -> None:
    """A height map (``heightfield`` object) as a MuJoCo height field over the same grid: ``nrow`` rows
    along y (row 0 at the lowest y), ``ncol`` columns along x, its lowest point at the geom's height
    and its span the elevation (MuJoCo collides with two triangles per cell)."""
    h = np.asarray(obj.heights, dtype=float)
    lo, span = float(h.min()), float(h.max() - h.min())
    field = spec.add_hfield()
    field.name = f"{OBJECT_PREFIX}{obj.name}_hfield"
    field.nrow, field.ncol = int(h.shape[0]), int(h.shape[1])
    field.size = [0.5 * obj.size[0], 0.5 * obj.size[1], max(span, 1e-6), HFIELD_BASE]
    field.userdata = ((h - lo) / span if span > 0 else np.zeros_like(h)).ravel().tolist()
    geom.type = mujoco.mjtGeom.mjGEOM_HFIELD
    geom.hfieldname = field.name
    geom.pos = [float(obj.position[0]), float(obj.position[1]), lo]


def _add_self_collision(
    robot: Robot, spec: mujoco.MjSpec, model: mujoco.MjModel, pairs: tuple[tuple[str, str], ...],
    geom_role: np.ndarray, sole_geoms: dict[str, int],
) -> tuple[mujoco.MjModel, np.ndarray, dict[tuple[str, str], float]]:
    """One explicit pair per two collision geoms of each link pair, then recompile.

    MuJoCo collides meshes as their convex hulls, which are larger than the meshes: a pair whose
    hulls already overlap in the standing configuration would push the links apart at rest, so
    it gets no MuJoCo pair (MuJoCo's negative pair margins do not work for meshes: the reported
    distance shifts with the margin); ``rest_overlap`` lists such pairs, and the certificate
    still measures them (coal on the URDF meshes).
    """
    if not pairs:
        return model, np.zeros(0, dtype=int), {}
    skip = set(sole_geoms.values())
    link_geoms: dict[str, list[int]] = {}
    for g in range(model.ngeom):
        if geom_role[g] == ROBOT_ROLE and g not in skip:
            link_geoms.setdefault(model.body(int(model.geom_bodyid[g])).name, []).append(g)
    missing = sorted({link for pair in pairs for link in pair if link not in link_geoms})
    if missing:
        raise SimModelError(
            f"robot {robot.name!r}: the collision model names links without collision geometry in "
            f"MuJoCo: {missing}"
        )
    added: list[tuple[mujoco.MjsPair, int]] = []
    for k, (a, b) in enumerate(pairs):
        for ga in link_geoms[a]:
            for gb in link_geoms[b]:
                pair = spec.add_pair()
                pair.geomname1 = model.geom(ga).name
                pair.geomname2 = model.geom(gb).name
                pair.margin = 0.0
                pair.condim = MUJOCO_CONDIM
                pair.friction = [float(x) for x in model.geom_friction[ga]] + [0.0, 0.0]
                added.append((pair, k))
    compiled = _compile(robot, spec)
    rest = _rest_contacts(robot, compiled, _pair_index(model, compiled, pairs))
    rest_overlap = {pairs[k]: -dist for k, dist in rest.items()}
    if rest_overlap:  # hulls overlapping at rest: no MuJoCo pair (see the docstring)
        for pair, k in added:
            if pairs[k] in rest_overlap:
                spec.delete(pair)
        compiled = _compile(robot, spec)
    return compiled, _pair_index(model, compiled, pairs), rest_overlap


def _pair_index(model: mujoco.MjModel, compiled: mujoco.MjModel, pairs: tuple[tuple[str, str], ...]) -> np.ndarray:
    """For each compiled MuJoCo pair, the index of its link pair in ``pairs`` (MuJoCo orders the
    compiled pairs its own way: map them back through their geoms' bodies)."""
    index = {pair: k for k, pair in enumerate(pairs)}
    return np.array([
        index[tuple(sorted((model.body(int(model.geom_bodyid[compiled.pair_geom1[p]])).name,
                            model.body(int(model.geom_bodyid[compiled.pair_geom2[p]])).name)))]
        for p in range(compiled.npair)
    ], dtype=int)


def _compile(robot: Robot, spec: mujoco.MjSpec) -> mujoco.MjModel:
    try:
        return spec.compile()
    except ValueError as e:
        raise SimModelError(f"robot {robot.name!r}: MuJoCo cannot compile the collision pairs: {e}") from None


def _rest_contacts(robot: Robot, model: mujoco.MjModel, pair_index: np.ndarray) -> dict[int, float]:
    """Deepest MuJoCo contact distance [m] (< 0) of each link pair (by index) touching in the
    robot's standing configuration."""
    data = mujoco.MjData(model)
    q = robot.q_standing
    qpos = np.array(model.qpos0)
    qpos[:3], qpos[3], qpos[4:7] = q[:3], q[6], q[3:6]
    for name, value in zip(list(robot.model.names)[2:], q[7:], strict=True):
        qpos[model.jnt_qposadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)]] = value
    data.qpos[:] = qpos
    mujoco.mj_forward(model, data)
    pair_of = {(int(model.pair_geom1[p]), int(model.pair_geom2[p])): int(pair_index[p]) for p in range(model.npair)}
    deepest: dict[int, float] = {}
    for c in range(data.ncon):
        g1, g2 = (int(x) for x in data.contact.geom[c])
        k = pair_of.get((g1, g2), pair_of.get((g2, g1)))
        if k is not None and data.contact.dist[c] < 0:
            deepest[k] = min(deepest.get(k, 0.0), float(data.contact.dist[c]))
    return deepest
