"""Scene collision avoidance: every robot sphere kept a margin away from every scene object.

The robot is the sphere sets of its collision model (:func:`planner.trajopt.collision.sphere_sets`,
which contain the URDF meshes), with its legs' sets cut into slabs (:func:`scene_sets`). An object of the spec's scene (:mod:`tasks.scene`) is a box, a
cylinder or a sphere; a mesh object is replaced by the box that bounds its vertices. For a robot
sphere of centre ``c`` and radius ``r`` and an object at ``(p_o, R_o)``, with ``u = R_o^T (c - p_o)``
its centre in the object frame and ``rho = r + margin``, a ``scene`` row is

* box, half extents ``h``: ``N = (sum_i (u_i / a_i)^P)^(1/P) >= 3^(1/P)``, ``a = h + rho``;
* cylinder, radius ``R``, half length ``L``: ``N = (((u_x^2 + u_y^2) / a_r^2)^(P/2) + (u_z / a_z)^P)^(1/P)
  >= 2^(1/P)``, ``a_r = R + rho``, ``a_z = L + rho``;
* sphere, radius ``R``: ``N = |u| / (R + rho) >= 1`` (exact).

``P`` (:data:`P_NORM`, even) makes the rows smooth everywhere but at the object's centre, with a
gradient of order ``1 / a`` inside the object too (a guess through the table is pushed out). They
are conservative: ``N >= 3^(1/P)`` implies ``max_i |u_i| / a_i >= 1``, i.e. the centre is outside
the box inflated by ``rho`` on each axis, which contains every point within ``rho`` of the box; the
level set bulges beyond that inflated box by at most ``(3^(1/P) - 1) a_i`` at the middle of a face
(P = 32: 3.5 %) and by ``rho (sqrt(3) - 1)`` at a corner. So that the bulge stays below a few mm,
boxes (and cylinders along their axis) longer than ``2 MAX_HALF`` are split into equal pieces, each
with its own rows (a 2 m wall's end face would bulge 3.7 cm, a piece's 8 mm). ``docs/collisions.md``
has the table of it.

Numeric values (object pose, inflated extents, sphere centres in their joint frames) are term
parameters; the structure ``("scene", shape, joints of the spheres)`` keys the solver cache, so two
scenes whose objects are close to the same links share a solver. Screening as for self-collision:
rows only for (sphere, object) pairs within ``settings.collision.screening`` on the initial guess
(the same function, inflated by the screening distance), on those knots widened by
:data:`~planner.trajopt.collision.KNOT_PADDING`; after a solve, pairs the solution brings within
the margin get rows and the NLP is solved again.

Planned contacts are not collisions: a contact whose placement lies on the top face of an object
(a foot standing on a box) excludes the spheres of the links on its frame's joint (a foot's: its
whole leg, :func:`supporting_joints`) from that object while it is active (and
:data:`CONTACT_PADDING` knots around), and a standing foot has no rows at all there
(:func:`contact_exclusions`); a frame target that touches an object
(``FrameTarget.touch``) excludes the spheres of its frame's joint and the joints below it from that
object over the target's knots (and as many around). A grasp (:class:`tasks.specs.Grasp`)
excludes the spheres of the hand (the links of its frame's joint and below) from the grasped object
over the whole motion, and every sphere while the object is held (it moves with the hand; its rows
would keep the robot away from where it stood) and :data:`CONTACT_PADDING` knots after the hand lets
go of it (the arm is still at it: without them a forearm within the clearance at the release had to
leave in one knot, and the plan pulled the hands apart while the simulation still welded the box to
both). The floor is not an object.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar, TypeVar

import numpy as np
import pinocchio as pin

from planner.exceptions import PlannerError
from planner.results import Check, CheckKind
from planner.trajopt.collision import CHECK_TOLERANCE, KNOT_PADDING, SphereSets, sphere_sets
from planner.trajopt.layout_data import LayoutData
from planner.trajopt.rows import PairRows
from planner.trajopt.settings import PlannerSettings
from planner.trajopt.shipped_slabs import shipped_slabs, write_shipped_slabs
from planner.trajopt.term import NumericKinematics, ReportContext, StageKinematics, Term, knots_of
from robots import Capsule, Robot, body_part, fit_capsule, link_points
from tasks import Scene, SceneObject, on_top

L = TypeVar("L", bound=LayoutData)  # a layout, kinematic or dynamic: what strip_* hands back

P_NORM = 32  # even exponent of the box and cylinder rows
MAX_HALF = 0.15  # [m] longer boxes and cylinders are split into pieces of at most this half extent
BOUND = {"box": 3.0 ** (1.0 / P_NORM), "cylinder": 2.0 ** (1.0 / P_NORM), "sphere": 1.0}
CONTACT_PADDING = 2  # knots around an active contact on an object where its link may touch it
LEG_SLAB = 0.1  # [m] a leg link's scene cover: one capsule per slab of its hull this thick (below)


@dataclass(frozen=True, eq=False)
class Obstacle:
    """A scene object as the planner sees it.

    Attributes:
        name: The object's name.
        shape: ``box``, ``cylinder`` or ``sphere`` (a mesh object becomes its bounding ``box``).
        position: Centre in the world [m] (3,).
        rotation: Orientation in the world (3, 3).
        half: Half extents [m]: box (hx, hy, hz), cylinder (R, R, L/2), sphere (R, R, R).
        from_mesh: True when the box bounds a mesh.
        key: Unique key of the piece (``table#3``) when a long object is split (:data:`MAX_HALF`).
    """

    name: str
    shape: str
    position: np.ndarray
    rotation: np.ndarray
    half: np.ndarray
    from_mesh: bool = False
    key: str = ""

    def inflated(self, rho: np.ndarray) -> np.ndarray:
        """Per-axis inflated extents ``a`` (n, 3) for sphere radii + clearance ``rho`` (n,) [m]."""
        return self.half[None, :] + np.asarray(rho, dtype=float)[:, None]


def _mesh_box(obj: SceneObject) -> tuple[np.ndarray, np.ndarray]:
    """(centre offset in the object frame, half extents) of a mesh object's scaled vertices [m]."""
    import coal  # type: ignore[import-untyped]

    try:
        mesh = coal.MeshLoader().load(str(obj.mesh), np.array(obj.size, dtype=float))
        mesh.computeLocalAABB()
    except Exception as e:  # coal raises bare exceptions for unreadable files
        raise PlannerError(f"scene object {obj.name!r}: cannot read its mesh {obj.mesh!r}: {e}") from e
    lo, hi = np.array(mesh.aabb_local.min_), np.array(mesh.aabb_local.max_)
    return 0.5 * (lo + hi), np.maximum(0.5 * (hi - lo), 1e-4)


_OBSTACLES: dict[int, tuple[Scene, list[Obstacle]]] = {}


def _pieces(ob: Obstacle) -> list[Obstacle]:
    """A box split into equal boxes, a cylinder into equal cylinders along its axis, so that no half
    extent exceeds :data:`MAX_HALF` (the rows' bulge scales with it); their union is the object."""
    if ob.shape == "sphere":
        return [dataclasses.replace(ob, key=ob.name)]
    axes = (0, 1, 2) if ob.shape == "box" else (2,)
    counts = [int(math.ceil(ob.half[i] / MAX_HALF - 1e-9)) if i in axes else 1 for i in range(3)]
    half = ob.half / np.array(counts)
    out: list[Obstacle] = []
    for idx in np.ndindex(*counts):
        offset = np.array([(2 * idx[i] + 1 - counts[i]) * half[i] for i in range(3)])
        key = ob.name if len(out) == 0 and np.prod(counts) == 1 else f"{ob.name}#{len(out)}"
        out.append(dataclasses.replace(ob, position=ob.position + ob.rotation @ offset, half=half.copy(), key=key))
    return out


def obstacles(scene: Scene | None) -> list[Obstacle]:
    """The scene's objects as :class:`Obstacle` pieces (cached per scene object)."""
    if scene is None or not scene.objects:
        return []
    hit = _OBSTACLES.get(id(scene))
    if hit is not None and hit[0] is scene:
        return hit[1]
    out = [piece for ob in whole_obstacles(scene) for piece in _pieces(ob)]
    _OBSTACLES[id(scene)] = (scene, out)
    return out


def whole_obstacles(scene: Scene | None) -> list[Obstacle]:
    """The scene's objects as :class:`Obstacle`, not split into pieces (one per object, in order)."""
    if scene is None:
        return []
    whole = []
    for obj in scene.objects:
        R = pin.rpy.rpyToMatrix(*obj.rpy)
        p = np.array(obj.position, dtype=float)
        if obj.shape in ("box", "heightfield"):  # a height map: its box, from the floor to its top
            whole.append(Obstacle(obj.name, "box", p, R, 0.5 * np.array(obj.size, dtype=float)))
        elif obj.shape == "cylinder":
            radius, length = obj.size
            whole.append(Obstacle(obj.name, "cylinder", p, R, np.array([radius, radius, 0.5 * length])))
        elif obj.shape == "sphere":
            whole.append(Obstacle(obj.name, "sphere", p, R, np.full(3, float(obj.size[0]))))
        else:
            offset, half = _mesh_box(obj)
            whole.append(Obstacle(obj.name, "box", p + R @ offset, R, half, from_mesh=True))
    return whole


# -- numerics ----------------------------------------------------------------------------------


def row_value(shape: str, u: np.ndarray, a: np.ndarray) -> np.ndarray:
    """The row function ``N`` (numpy) of points ``u`` (..., 3) in the object frame, inflated extents
    ``a`` (..., 3): compare with ``BOUND[shape]``."""
    s = u / a
    if shape == "sphere":
        return np.linalg.norm(s, axis=-1)
    if shape == "cylinder":
        radial2 = s[..., 0] ** 2 + s[..., 1] ** 2
        scale = np.maximum(np.sqrt(radial2), np.abs(s[..., 2]))
        scale = np.where(scale > 0, scale, 1.0)
        total = (radial2 / scale**2) ** (P_NORM // 2) + (s[..., 2] / scale) ** P_NORM
        return scale * total ** (1.0 / P_NORM)
    scale = np.abs(s).max(axis=-1)
    scale = np.where(scale > 0, scale, 1.0)
    return scale * (((s / scale[..., None]) ** P_NORM).sum(axis=-1)) ** (1.0 / P_NORM)


def exact_distance(ob: Obstacle, u: np.ndarray) -> np.ndarray:
    """Signed distance of points ``u`` (..., 3), in the object frame, to the object [m] (negative inside)."""
    if ob.shape == "sphere":
        return np.linalg.norm(u, axis=-1) - ob.half[0]
    if ob.shape == "cylinder":
        qr = np.hypot(u[..., 0], u[..., 1]) - ob.half[0]
        qz = np.abs(u[..., 2]) - ob.half[2]
        return np.hypot(np.maximum(qr, 0), np.maximum(qz, 0)) + np.minimum(np.maximum(qr, qz), 0)
    q = np.abs(u) - ob.half
    return np.linalg.norm(np.maximum(q, 0), axis=-1) + np.minimum(q.max(axis=-1), 0)


def sphere_centres(robot: Robot, sets: SphereSets, q: np.ndarray) -> np.ndarray:
    """World centres of every sphere at every configuration: (T, S, 3) [m]."""
    model, data = robot.model, robot.data()
    joints, where = np.unique(sets.joints, return_inverse=True)
    H = np.empty((len(q), len(joints), 4, 4))  # the joints' placements at every knot
    for k, qk in enumerate(q):
        pin.forwardKinematics(model, data, qk)
        for i, j in enumerate(joints):
            H[k, i] = data.oMi[int(j)].homogeneous
    Hs = H[:, where[sets.sphere_owner]]
    return np.einsum("tsij,sj->tsi", Hs[..., :3, :3], sets.sphere_local) + Hs[..., :3, 3]


def _reach(ob: Obstacle, rho: np.ndarray) -> np.ndarray:
    """Radius around the piece's centre beyond which a sphere's row value is at least 1 (farther than
    its clearance ``rho`` (n,)): ``N < BOUND`` needs ``|u_i| < BOUND a_i`` on every axis (``N`` is at
    least the largest ``|u_i| / a_i``), so ``|u| < BOUND |a|``."""
    return BOUND[ob.shape] * np.linalg.norm(ob.inflated(rho), axis=1)


def _objects_near(obs: list[Obstacle], world: np.ndarray, rho: np.ndarray) -> set[str]:
    """Names of the objects (all their pieces at once) that some sphere at some configuration may be
    within its clearance ``rho`` of (a broad phase: the others need no row value)."""
    near = set()
    for name in dict.fromkeys(ob.name for ob in obs):
        pieces = [ob for ob in obs if ob.name == name]
        centre = np.mean([ob.position for ob in pieces], axis=0)
        ball = max(float(np.linalg.norm(ob.position - centre)) + float(_reach(ob, rho).max()) for ob in pieces)
        if np.einsum("tsi,tsi->ts", world - centre, world - centre).min() < ball**2:
            near.add(name)
    return near


def in_object_frame(ob: Obstacle, world: np.ndarray) -> np.ndarray:
    """World points (..., 3) in the object's frame."""
    return (world - ob.position) @ ob.rotation


def supporting_joints(robot: Robot, fid: int) -> list[int]:
    """The joints whose spheres may touch the object a contact on frame ``fid`` stands on: the frame's
    joint, and for a foot every joint of its leg (the foot's joint and its parents below the root).

    **Why the whole leg:** the object under a flat sole lies below the sole's plane (its top face *is*
    that plane), and the leg's meshes lie above it (Talos's shin and ankle meshes 7 cm above the
    sole), so the leg cannot touch the object it stands on; its capsule cover can: Talos's shin
    capsule reaches 8 mm below the sole and its foot capsule 67 mm. The leg still keeps its margin
    from every other object (the next riser), and the simulation checks the meshes."""
    model = robot.model
    joint = int(model.frames[fid].parentJoint)
    if robot.foot_side(model.frames[fid].name) is None:
        return [joint]
    chain = []
    while joint > 1:  # joint 1 is the free flyer (the base moves with it)
        chain.append(joint)
        joint = int(model.parents[joint])
    return chain


def slab_capsules(points: np.ndarray, slab: float) -> list[tuple[pin.SE3, float, float]]:
    """(placement, length, radius) of capsules whose union contains the convex hull of ``points``
    (n, 3): the hull cut across its principal axis into equal slabs at most ``slab`` thick [m], one
    capsule (:func:`robots.collision.fit_capsule`) around each slab's vertices (the hull's vertices in
    it and its edges' crossings with the two cutting planes: a capsule is convex, so it then holds
    the slab)."""
    from scipy.spatial import ConvexHull

    hull = ConvexHull(points)
    tri = hull.simplices
    edges = np.unique(np.sort(np.vstack([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [0, 2]]]), axis=1), axis=0)
    vertices = points[hull.vertices]
    mean = vertices.mean(axis=0)
    axis = np.linalg.svd(vertices - mean, full_matrices=False)[2][0]
    t = (points - mean) @ axis
    tv = t[hull.vertices]
    cuts = np.linspace(tv.min(), tv.max(), max(1, math.ceil((tv.max() - tv.min()) / slab - 1e-9)) + 1)
    ta, tb = t[edges[:, 0]], t[edges[:, 1]]
    out = []
    for lo, hi in itertools.pairwise(cuts):
        parts = [vertices[(tv >= lo - 1e-12) & (tv <= hi + 1e-12)]]
        for c in (lo, hi):
            cross = (ta - c) * (tb - c) < 0
            w = ((c - ta[cross]) / (tb[cross] - ta[cross]))[:, None]
            parts.append(points[edges[cross, 0]] * (1 - w) + points[edges[cross, 1]] * w)
        out.append(fit_capsule(np.vstack(parts)))
    return out


_SCENE_SETS: dict[int, tuple[Robot, SphereSets]] = {}


def _leg_joints(robot: Robot) -> set[int]:
    """The legs' joints above the feet (the links whose scene cover is cut into slabs)."""
    model = robot.model
    feet = [robot.frame_id(f"{side}_foot") for side in ("left", "right")]
    return {j for fid in feet for j in supporting_joints(robot, fid)} - {int(model.frames[f].parentJoint) for f in feet}


def _slab_links(sets: SphereSets, legs: set[int], points: dict[str, tuple[int, np.ndarray]]) -> list[str]:
    """The leg links whose scene cover is cut into slabs (the links of ``legs`` with a hull)."""
    return [link for i, link in enumerate(sets.links[: len(sets.model.links)])
            if int(sets.joints[i]) in legs and link in points and len(points[link][1]) >= 8]


def write_slabs(robot: Robot) -> Path:
    """Store ``robot``'s leg slab capsules (:mod:`planner.trajopt.shipped_slabs`) under its current key."""
    sets = sphere_sets(robot)
    return write_shipped_slabs(robot, LEG_SLAB, _slab_links(sets, _leg_joints(robot), link_points(robot)), slab_capsules)


def scene_sets(robot: Robot) -> SphereSets:
    """The spheres kept from scene objects: the links' own sphere sets
    (:func:`planner.trajopt.collision.sphere_sets`), but for the legs above the feet, whose one or
    two capsules are cut into slabs :data:`LEG_SLAB` thick (:func:`slab_capsules`).

    **Why:** a link's capsules are fitted for self-collision, and a leg's are wide: Talos's shin is
    one capsule of 0.127 m radius around the knee's motor housing, reaching 6 cm in front of its
    meshes at the ankle and 8 mm below the sole, so on stairs the stance shin "touched" the next
    riser with 8 cm of air between the meshes, and no plan of the climb existed. The slab capsules
    contain the same meshes (their hull) and follow them: the shin's cover ends 5 cm above the sole
    and 1 to 2 cm from its meshes' front. The feet keep theirs (the sole stands on objects; a
    swinging foot clears them by the swing height). Cached per robot object."""
    hit = _SCENE_SETS.get(id(robot))
    if hit is not None and hit[0] is robot:
        return hit[1]
    sets = sphere_sets(robot)
    points = link_points(robot)
    cut = _slab_links(sets, _leg_joints(robot), points)
    shipped = shipped_slabs(robot, LEG_SLAB) if cut else None  # the fit shipped for this robot's key
    if shipped is not None and set(shipped) != set(cut):
        shipped = None
    owner, local, radius = [], [], []
    for i, link in enumerate(sets.links[: len(sets.model.links)]):
        mine = sets.sphere_owner == i
        if link in cut:
            joint = int(sets.joints[i])
            for M, length, r in shipped[link] if shipped is not None else slab_capsules(points[link][1], LEG_SLAB):
                c, rr = Capsule(link, joint, M, length, r).spheres()
                owner.append(np.full(len(c), i))
                local.append(c)
                radius.append(np.full(len(c), rr))
        else:
            owner.append(sets.sphere_owner[mine])
            local.append(sets.sphere_local[mine])
            radius.append(sets.sphere_radius[mine])
    out = dataclasses.replace(sets, sphere_owner=np.concatenate(owner), sphere_local=np.vstack(local),
                              sphere_radius=np.concatenate(radius))
    _SCENE_SETS[id(robot)] = (robot, out)
    return out


def contact_exclusions(lay: LayoutData, sets: SphereSets, obs: list[Obstacle]) -> np.ndarray:
    """(N+1, S, O) bool: sphere ``s`` may touch object ``o`` at knot ``k`` (a planned contact on it).

    A foot in a planned contact carries no rows against any object (and :data:`CONTACT_PADDING`
    knots around): it stands where its placement puts it, and the placement was checked against
    every object before planning, on the exact shapes (:func:`tasks.robot_check.check_spec_in_scene`:
    its sole corners). Its rows would only ask whether the foot's cover, 3 cm longer than Talos's
    foot, fits: a sole 5 cm from the next riser of a flight of stairs is 9 mm inside the margin of
    the rows (their bulge, module docstring), and no plan existed."""
    out = np.zeros((lay.N + 1, len(sets.sphere_radius), len(obs)), dtype=bool)
    scene = lay.spec.scene
    if scene is None:
        return out
    model = lay.robot.model
    sphere_joint = sets.joints[sets.sphere_owner]
    objects = {o.name: o for o in scene.objects}
    names = list(dict.fromkeys(ob.name for ob in obs))
    columns = {name: [oi for oi, ob in enumerate(obs) if ob.name == name] for name in names}
    supported: dict[tuple, list[str]] = {}  # (contact position) -> the objects it stands on
    for k, active in enumerate(lay.contacts_at):
        for fid, (_frame, M) in active.items():
            where = tuple(M.translation)
            lo, hi = max(0, k - CONTACT_PADDING), min(lay.N, k + CONTACT_PADDING)
            if lay.robot.foot_side(model.frames[fid].name):  # a standing foot is where its placement is
                out[lo:hi + 1, sphere_joint == model.frames[fid].parentJoint, :] = True
            if where not in supported:
                supported[where] = [name for name in names if on_top(objects[name], where)]
            if not supported[where]:
                continue
            mine = np.isin(sphere_joint, supporting_joints(lay.robot, fid))
            for name in supported[where]:
                out[lo:hi + 1, mine[:, None] & np.isin(np.arange(len(obs)), columns[name])[None, :]] = True
    for grasp in lay.spec.grasps:
        hand = np.isin(sphere_joint, list(model.subtrees[model.frames[lay.robot.frame_id(grasp.frame)].parentJoint]))
        held = np.asarray(lay.t) >= grasp.start - 1e-9
        if grasp.end is not None:
            held &= np.asarray(lay.t) <= grasp.end + 1e-9
            if held.any():  # the arm is still at the object as the hand lets go
                last = int(np.flatnonzero(held)[-1])
                held[last:last + CONTACT_PADDING + 1] = True
        for oi, ob in enumerate(obs):
            if ob.name == grasp.object:
                out[:, hand, oi] = True  # the hand goes to the object: a planned contact
                out[held, :, oi] = True  # held: the object moves with the hand, away from where it stood
    for target in lay.spec.targets:  # a hand touching an object (touch_object)
        if target.touch is None:
            continue
        joint = model.frames[lay.robot.frame_id(target.frame)].parentJoint
        subtree = np.isin(sphere_joint, list(model.subtrees[joint]))
        ks = knots_of(lay.t, target.time, target.window, lay.N)
        lo, hi = max(0, min(ks) - CONTACT_PADDING), min(lay.N, max(ks) + CONTACT_PADDING)
        for oi, ob in enumerate(obs):
            if ob.name == target.touch:
                out[lo:hi + 1, subtree, oi] = True
    return out


def values(lay: LayoutData, sets: SphereSets, obs: list[Obstacle], q: np.ndarray, clearance: float,
           world: np.ndarray | None = None) -> np.ndarray:
    """Row values ``N / BOUND`` (T, S, O) of every sphere and object, inflated by the sphere radius +
    ``clearance``: below 1, the pair is within ``clearance`` (conservatively); excluded pairs are inf,
    and so are pairs certainly farther than ``clearance`` (an object far from every sphere, or a sphere
    beyond its piece's :func:`_reach`: their values are at least 1 and are not computed). ``world``:
    the spheres' centres at ``q`` when already known (:func:`sphere_centres`)."""
    world = sphere_centres(lay.robot, sets, q) if world is None else world
    out = np.full((len(q), world.shape[1], len(obs)), np.inf)
    rho = sets.sphere_radius + clearance
    near = _objects_near(obs, world, rho)
    for oi, ob in enumerate(obs):
        if ob.name not in near:
            continue
        d = world - ob.position
        close = np.einsum("tsi,tsi->ts", d, d) < _reach(ob, rho)[None, :] ** 2
        if not close.any():
            continue
        a = np.broadcast_to(ob.inflated(rho)[None], world.shape)[close]
        out[:, :, oi][close] = row_value(ob.shape, in_object_frame(ob, world[close]), a) / BOUND[ob.shape]
    if np.isfinite(out).any():
        out[contact_exclusions(lay, sets, obs)[: len(q)]] = np.inf
    return out


# -- rows --------------------------------------------------------------------------------------


class SceneRows(PairRows):
    """Per object index: the spheres with rows and the knots that carry them (frozen:
    :meth:`PairRows.merged` returns a new one)."""


def scene_rows_of(lay: LayoutData) -> SceneRows:
    """The :class:`SceneRows` of the ``scene`` terms already in a layout (spheres found by joint and
    centre, which the terms' structure and parameters hold)."""
    obs = obstacles(lay.spec.scene)
    if not obs:
        return SceneRows()
    index = {ob.key: i for i, ob in enumerate(obs)}
    by_object: dict[int, set[int]] = {}
    knots: dict[int, set[int]] = {}
    sets = scene_sets(lay.robot)
    sphere_joint = sets.joints[sets.sphere_owner]
    for t in lay.terms:
        if not isinstance(t, SceneCollisionTerm):
            continue
        oi = index[str(t.item)]
        joints = t.joints
        local = t.params[12:].reshape(len(joints), 6)[:, :3]
        spheres = by_object.setdefault(oi, set())
        for j, c in zip(joints, local, strict=True):
            match = np.flatnonzero((sphere_joint == j) & np.all(np.abs(sets.sphere_local - c) < 1e-12, axis=1))
            spheres.update(int(m) for m in match)
        knots.setdefault(oi, set()).add(t.knot)
    return SceneRows(by_object, knots)


def select(lay: LayoutData, close: np.ndarray) -> SceneRows:
    """Rows for the (sphere, object) pairs marked in ``close`` (T, S, O) at a variable knot: per
    object, the union of its marked spheres, on their knots widened by ``KNOT_PADDING``."""
    by_object: dict[int, set[int]] = {}
    by_knot: dict[int, set[int]] = {}
    mark = close.copy()
    mark[:2] = False
    mark[lay.N:] = False
    for oi in np.flatnonzero(mark.any(axis=(0, 1))):
        spheres = {int(s) for s in np.flatnonzero(mark[:, :, oi].any(axis=0))}
        knots: set[int] = set()
        for k in np.flatnonzero(mark[:, :, oi].any(axis=1)):
            knots.update(range(max(2, int(k) - KNOT_PADDING), min(lay.N - 1, int(k) + KNOT_PADDING) + 1))
        by_object[int(oi)], by_knot[int(oi)] = spheres, knots
    return SceneRows(by_object, by_knot)


def with_scene_terms(lay: L, sets: SphereSets, obs: list[Obstacle], rows: SceneRows, objects: list[int],
                     margin: float) -> L:
    """A copy of ``lay`` whose ``scene`` terms of ``objects`` are (re)written from ``rows``: one term
    per object and knot, a row per sphere (not in a planned contact with the object there)
    ``N >= BOUND[shape]`` (``lay`` is not changed)."""
    keys = {obs[oi].key for oi in objects}
    terms = [t for t in lay.terms if not (isinstance(t, SceneCollisionTerm) and t.item in keys)]
    excluded = contact_exclusions(lay, sets, obs)
    for oi in objects:
        ob = obs[oi]
        chosen_all = sorted(rows.spheres[oi])
        for k in sorted(rows.knots[oi]):
            chosen = [s for s in chosen_all if not excluded[k, s, oi]]
            if not chosen:
                continue
            a = ob.inflated(sets.sphere_radius[chosen] + margin)
            per_sphere = np.hstack([sets.sphere_local[chosen], a]).ravel()  # (c_local, a) per sphere
            terms.append(SceneCollisionTerm(
                knot=k,
                structure=(SceneCollisionTerm.kind, ob.shape, tuple(int(sets.joints[sets.sphere_owner[s]]) for s in chosen)),
                params=np.concatenate([ob.position, ob.rotation.T.ravel(), per_sphere]),  # R column-major
                lower=np.full(len(chosen), BOUND[ob.shape]), upper=np.full(len(chosen), math.inf),
                label=f"scene collision {ob.name}", item=ob.key, phase=lay.phase_name(k),
            ))
    return lay.with_terms(terms)


@dataclass(eq=False)
class SceneCollisionTerm(Term):
    """Robot spheres kept out of one scene object: a row ``N >= BOUND[shape]`` per sphere, ``N`` the
    smooth p-norm of the sphere's centre in the object's frame over the inflated extents ``a``
    (module docstring). Structure ``("scene", shape, joints of the spheres)``; parameters the
    object's position (3) and rotation column-major (9), then per sphere its centre in its joint's
    frame (3) and ``a`` (3). ``item`` is the object's key."""

    kind: ClassVar[str] = "scene"
    check_kinds: ClassVar[tuple[CheckKind, ...]] = (CheckKind.SCENE_COLLISION,)

    @property
    def joints(self) -> tuple[int, ...]:
        """The joint of each sphere, in row order."""
        return self.structure[2]

    def expression(self, p, kin: StageKinematics) -> tuple:
        """(rows, 0) in CasADi (:meth:`Term.expression`)."""
        import casadi as ca

        _, shape, joints = self.structure
        pos_o = p[0:3]
        R_o = ca.reshape(p[3:12], 3, 3)
        out = []
        for i, j in enumerate(joints):
            off = 12 + 6 * i
            R, pos = kin.joints[j]
            c = pos + ca.mtimes(R, p[off: off + 3])
            s = ca.mtimes(R_o.T, c - pos_o) / p[off + 3: off + 6]
            if shape == "sphere":
                out.append(ca.norm_2(s))
            elif shape == "cylinder":
                out.append(((s[0] ** 2 + s[1] ** 2) ** (P_NORM // 2) + s[2] ** P_NORM) ** (1.0 / P_NORM))
            else:
                out.append((s[0] ** P_NORM + s[1] ** P_NORM + s[2] ** P_NORM) ** (1.0 / P_NORM))
        return ca.vertcat(*out), 0

    def residual(self, kin: NumericKinematics) -> np.ndarray:
        """The rows in numpy (:meth:`Term.residual`), through :func:`row_value`."""
        _, shape, joints = self.structure
        pos_o, R_o = self.params[0:3], self.params[3:12].reshape(3, 3).T
        spheres = self.params[12:].reshape(len(joints), 6)
        centres = np.array([kin.joint(j).act(c) for j, c in zip(joints, spheres[:, :3], strict=True)])
        return row_value(shape, (centres - pos_o) @ R_o, spheres[:, 3:])

    @classmethod
    def report(cls, ctx: ReportContext) -> list[Check]:
        """The robot's closest approach to the scene's objects over the plan
        (:func:`scene_collision_check`), when the spec has a scene with objects."""
        scene = ctx.lay.spec.scene
        return [scene_collision_check(ctx.lay, ctx.q)] if scene is not None and scene.objects else []


def add_screened_scene_terms(lay: L, settings: PlannerSettings, q0: np.ndarray) -> tuple[L, SceneRows]:
    """A copy of ``lay`` with the rows of the (sphere, object) pairs that the initial guess ``q0``
    (N+1, nq) brings within ``settings.collision.screening``, and those rows (``lay`` itself and
    no rows without a scene; ``lay`` is not changed)."""
    obs = obstacles(lay.spec.scene)
    if not obs:
        return lay, SceneRows()
    sets = scene_sets(lay.robot)
    rows = select(lay, values(lay, sets, obs, q0, settings.collision.screening) < 1.0)
    return with_scene_terms(lay, sets, obs, rows, sorted(rows.spheres), settings.collision.margin), rows


def missing_scene_rows(lay: L, rows: SceneRows, q: np.ndarray, settings: PlannerSettings,
                       ) -> tuple[L, SceneRows, list[int]]:
    """After a solve: pairs within the margin (less ``CHECK_TOLERANCE``) at a knot without their row
    get rows (pairs within the screening distance of those objects, there, added to ``rows``);
    returns the layout with them (a copy with those objects' terms rewritten; ``lay`` itself when
    none changed), the rows it has (a new record; ``rows`` itself when none changed) and the
    objects whose rows changed. Neither ``lay`` nor ``rows`` is changed."""
    obs = obstacles(lay.spec.scene)
    if not obs:
        return lay, rows, []
    sets = scene_sets(lay.robot)
    world = sphere_centres(lay.robot, sets, q)
    violated = values(lay, sets, obs, q, settings.collision.margin - CHECK_TOLERANCE, world) < 1.0
    for oi, spheres in rows.spheres.items():
        ks = sorted(rows.knots[oi])
        for s in spheres:
            violated[ks, s, oi] = False
    violated[:2] = False
    violated[lay.N:] = False
    if not violated.any():
        return lay, rows, []
    near = values(lay, sets, obs, q, settings.collision.screening, world) < 1.0
    bad_knots = np.asarray(violated.any(axis=1))  # (T, O)
    bad_spheres = np.asarray(violated.any(axis=0))  # (S, O)
    near &= bad_knots[:, None, :] | bad_spheres[None, :, :]
    rows, changed = rows.merged(select(lay, near | violated))
    if changed:
        return with_scene_terms(lay, sets, obs, rows, changed, settings.collision.margin), rows, changed
    return lay, rows, changed


def strip_scene_terms(lay: L) -> L:
    """A copy of ``lay`` without its scene terms (the same class: kinematic or dynamic)."""
    return lay.with_terms([t for t in lay.terms if not isinstance(t, SceneCollisionTerm)])


# -- report ------------------------------------------------------------------------------------


def closest(lay: LayoutData, q: np.ndarray) -> tuple[float, float, str, str]:
    """(exact sphere-set distance [m], time [s], link, object) of the closest robot sphere and
    object over a motion, planned contacts left out; distance inf without objects. Pieces are taken
    nearest first and a piece whose distance bound (to the ball around it) is no closer than the best
    found is skipped: a far scene costs one piece's distances."""
    obs = obstacles(lay.spec.scene)
    if not obs:
        return math.inf, 0.0, "", ""
    sets = scene_sets(lay.robot)
    world = sphere_centres(lay.robot, sets, q)
    excluded = contact_exclusions(lay, sets, obs)[: len(q)]
    bounds = []  # per piece, the distances of the spheres to its circumscribed ball (T, S), and their min
    for ob in obs:
        lower = np.linalg.norm(world - ob.position, axis=-1) - float(np.linalg.norm(ob.half)) - sets.sphere_radius
        bounds.append(float(lower.min()))
    best = (math.inf, 0, 0, 0)
    for oi in np.argsort(bounds, kind="stable"):
        if bounds[oi] >= best[0]:
            break
        ob = obs[oi]
        d = exact_distance(ob, in_object_frame(ob, world)) - sets.sphere_radius
        d[excluded[:, :, oi]] = np.inf
        k, s = (int(i) for i in np.unravel_index(int(np.argmin(d)), d.shape))
        if d[k, s] < best[0]:
            best = (float(d[k, s]), k, s, int(oi))
    d, k, s, o = best
    return d, float(lay.t[k]), sets.links[int(sets.sphere_owner[s])], obs[o].name


def scene_collision_check(lay: LayoutData, q: np.ndarray) -> Check:
    """The plan's ``scene collision`` check: the closest body part and object and their distance (the
    robot's sphere sets, which contain its meshes, against the exact shapes); it fails when they
    interpenetrate by more than ``CHECK_TOLERANCE``."""
    d, time, link, name = closest(lay, q)
    if not math.isfinite(d):
        return Check.constraint(name="scene collision (no object to check)", kind=CheckKind.SCENE_COLLISION,
                                violation=0.0, tolerance=CHECK_TOLERANCE, unit="m", time=0.0)
    part = body_part(lay.robot, link)
    return Check.constraint(
        name=f"scene collision (closest: {part} / {name}, {link}, {d * 1000:.0f} mm)", kind=CheckKind.SCENE_COLLISION,
        violation=max(0.0, -d), tolerance=CHECK_TOLERANCE, unit="m", time=time, subject=f"{link}/{name}")


# -- diagnosis ---------------------------------------------------------------------------------


def _advice(lay: LayoutData, name: str) -> str:
    """What to change: the hard target nearest to the object, or the object."""
    pieces = [o for o in obstacles(lay.spec.scene) if o.name == name]
    best = None
    for target in lay.spec.targets:
        if target.position is None:
            continue
        point = np.array(target.position, dtype=float)
        d = min(float(exact_distance(ob, in_object_frame(ob, point))) for ob in pieces)
        if best is None or d < best[0]:
            best = (d, target)
    if best is None:
        return f"move the {name} in the scene"
    target = best[1]
    return f"move target {target.name!r} farther from the {name}, or the {name} in the scene"


def scene_diagnosis(lay: L, settings: PlannerSettings, solve: Callable[[L], tuple]) -> str:
    """When the plan with scene rows failed: solve without them; if that motion brings the robot within
    the margin of an object, the object is the cause, said in task terms (empty string otherwise).
    ``solve`` solves a layout from its initial guess without a compile (as in
    :func:`planner.trajopt.collision.collision_diagnosis`)."""
    from planner.trajopt.symbolic import chart_to_configuration

    if not any(isinstance(t, SceneCollisionTerm) for t in lay.terms):
        return ""
    dq, stats, _ = solve(strip_scene_terms(lay))
    if not stats.status.ok:
        return ""
    q = np.array([chart_to_configuration(lay.robot.model, lay.q_ref, d) for d in dq])
    d, time, link, name = closest(lay, q)
    if d >= settings.collision.margin:
        return ""
    what = "pass through" if d < 0 else f"come within {max(d, 0.0) * 1000:.0f} mm of"
    return (f"the {body_part(lay.robot, link)} would {what} the {name} at t = {time:.1f} s ({link}): "
            f"{_advice(lay, name)}")
