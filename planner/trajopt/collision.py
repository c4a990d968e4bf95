"""Self-collision avoidance: smooth sphere-set distance rows, screened on the initial guess.

Each capsule of the robot's collision model (:mod:`robots.collision`) is covered by a set of
equal spheres on its axis (:meth:`robots.collision.Capsule.spheres`; the union contains the
capsule, which contains the link's meshes). A checked link pair at a knot becomes the rows

    ``|c_i - c_j|^2 >= (R_a + R_b + margin)^2``   for every sphere i of a and j of b,

smooth in ``dq`` (no min over segments): a :class:`SelfCollisionTerm` whose structure is
``("collision", joint_a, joint_b, n_a, n_b, sphere pairs)`` (so it keys the solver cache) and whose
parameters are the sphere centres in the joints' frames.

Screening keeps the NLP small: the sphere-set distance of every pair is evaluated (numpy) at
every knot of the initial guess, and rows are added only for pairs closer than
``settings.collision.screening`` somewhere, over the knots where they are (widened by
:data:`KNOT_PADDING` on each side). After a solve every pair is checked on the solution; a pair
closer than the margin without rows gets them and the NLP is solved again from that solution
(at most ``settings.collision.rounds`` times). See ``docs/collisions.md``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import ClassVar, TypeVar

import numpy as np
import pinocchio as pin

from planner.results import Check, CheckKind
from planner.trajopt.layout_data import LayoutData
from planner.trajopt.rows import PairRows
from planner.trajopt.settings import PlannerSettings
from planner.trajopt.term import NumericKinematics, ReportContext, StageKinematics, Term, knots_of
from robots import CollisionModel, Robot, body_part, collision_model

L = TypeVar("L", bound=LayoutData)  # a layout, kinematic or dynamic: what strip_* hands back

KNOT_PADDING = 3  # knots added on each side of a screened pair's close knots
CLOSEST_WITHIN = 0.1  # [m] the report's closest pair is looked for among pairs this close first
CHECK_TOLERANCE = 1e-4  # [m] a pair this much inside the margin without rows triggers another round
MEET_PADDING = 0.15  # [s] a self-contact's (FrameTarget.meets) pairs are left out this long around its time or window


@dataclass(frozen=True, eq=False)
class SphereSets:
    """The sphere sets of a robot's links and checked pairs, flattened for vectorised distances.

    A sphere set is a link's own capsules' spheres (the first ``len(model.links)`` sets, one per
    link, in the collision model's order) or an alternative cover's that some pair is checked with
    (:attr:`robots.collision.CollisionModel.covers`; then the link's name appears twice in ``links``).

    Attributes:
        model: The collision model.
        links: Link name of each sphere set.
        joints: Joint id per sphere set.
        centres: Sphere centres per set, in its joint frame (n_i, 3) [m].
        radii: Sphere radii per set (n_i,) [m].
        pairs: Checked pairs as sphere-set indices (P, 2).
        sa, sb: Indices into ``pair_local``/``pair_radius`` of every sphere pair of every checked pair.
        starts: Start of each pair's block in ``sa``/``sb`` (for ``np.minimum.reduceat``).
        sphere_owner: Set index of every sphere of the links' own sets (what scene objects are kept
            from: any cover would do, the own one is the tightest overall).
        sphere_local: Those spheres' centres in their joint frames (S, 3) [m].
        sphere_radius: Those spheres' radii (S,) [m].
        pair_owner, pair_local, pair_radius: The same over every set, alternative covers included
            (the own sets' spheres first: ``sphere_*`` is their prefix).
    """

    model: CollisionModel
    links: tuple[str, ...]
    joints: np.ndarray
    centres: tuple[np.ndarray, ...]
    radii: tuple[np.ndarray, ...]
    pairs: np.ndarray
    sa: np.ndarray
    sb: np.ndarray
    starts: np.ndarray
    sphere_owner: np.ndarray
    sphere_local: np.ndarray
    sphere_radius: np.ndarray
    pair_owner: np.ndarray
    pair_local: np.ndarray
    pair_radius: np.ndarray

    @property
    def pair_names(self) -> list[tuple[str, str]]:
        """Link names of each checked pair."""
        return [(self.links[a], self.links[b]) for a, b in self.pairs]


_SETS: dict[int, tuple[Robot, SphereSets]] = {}


def sphere_sets(robot: Robot) -> SphereSets:
    """The sphere sets of ``robot`` (cached per robot object)."""
    hit = _SETS.get(id(robot))
    if hit is not None and hit[0] is robot:
        return hit[1]
    cm = collision_model(robot)
    bodies = [(link, 0) for link in cm.links] + sorted({(c.link, c.cover) for c in cm.alternatives})
    index = {body: i for i, body in enumerate(bodies)}
    centres, radii, joints = [], [], []
    for link, cover in bodies:
        cs, rs = [], []
        for c in cm.capsules_of(link, cover):
            pts, r = c.spheres()
            cs.append(pts)
            rs.append(np.full(len(pts), r))
        centres.append(np.vstack(cs))
        radii.append(np.concatenate(rs))
        joints.append(cm.capsules_of(link, cover)[0].joint)
    offsets = np.cumsum([0] + [len(c) for c in centres])
    pairs = np.array([(index[(a, ka)], index[(b, kb)]) for (a, b), (ka, kb)
                      in ((p, cm.covers.get(p, (0, 0))) for p in cm.pairs)], dtype=int).reshape(-1, 2)
    # every sphere i of set a against every sphere j of set b, i-major, pair after pair (vectorised)
    size = np.diff(offsets)
    na, nb = size[pairs[:, 0]], size[pairs[:, 1]]
    block = na * nb
    starts = np.cumsum(block) - block
    m = np.arange(int(block.sum())) - np.repeat(starts, block)  # index within its pair's block
    nb_of = np.repeat(nb, block)
    sa = np.repeat(offsets[pairs[:, 0]], block) + m // nb_of
    sb = np.repeat(offsets[pairs[:, 1]], block) + m % nb_of
    owner = np.concatenate([np.full(len(c), i) for i, c in enumerate(centres)])
    local, radius = np.vstack(centres), np.concatenate(radii)
    own = int(offsets[len(cm.links)])  # the links' own spheres come first
    sets = SphereSets(
        model=cm, links=tuple(link for link, _ in bodies), joints=np.array(joints, dtype=int),
        centres=tuple(centres), radii=tuple(radii),
        pairs=pairs, sa=sa.astype(int), sb=sb.astype(int), starts=starts.astype(int), sphere_owner=owner[:own], sphere_local=local[:own],
        sphere_radius=radius[:own], pair_owner=owner, pair_local=local, pair_radius=radius)
    _SETS[id(robot)] = (robot, sets)
    return sets


def _placements(robot: Robot, sets: SphereSets, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The placements (T, J, 4, 4) of the sphere sets' joints at every configuration, and the row of
    each set's joint in them (n_sets,)."""
    model, data = robot.model, robot.data()
    joints, where = np.unique(sets.joints, return_inverse=True)
    H = np.empty((len(q), len(joints), 4, 4))
    for k, qk in enumerate(q):
        pin.forwardKinematics(model, data, qk)
        for i, j in enumerate(joints):
            H[k, i] = data.oMi[int(j)].homogeneous
    return H, where


def _bounding_balls(sets: SphereSets) -> tuple[np.ndarray, np.ndarray]:
    """Per sphere set, a ball holding all its spheres: centre in its joint frame (n_sets, 3) and
    radius (n_sets,) [m]."""
    centre = np.array([c.mean(axis=0) for c in sets.centres])
    radius = np.array([float((np.linalg.norm(c - m, axis=1) + r).max())
                       for c, r, m in zip(sets.centres, sets.radii, centre, strict=True)])
    return centre, radius


def sphere_pair_distances(robot: Robot, sets: SphereSets, q: np.ndarray, within: float = math.inf) -> np.ndarray:
    """Distance of every sphere pair of every checked link pair at every configuration: (T, S) [m]
    (negative: the spheres overlap); pair ``p``'s block starts at ``sets.starts[p]``.

    ``within`` (a broad phase): a link pair whose two sets' bounding balls are at least ``within``
    apart at a configuration is not computed there (its entries are inf; every one of its sphere
    pairs is that far apart). Screening and the checks after a solve look only at pairs closer
    than the screening distance; on Talos this skips the distances of ~95 % of the pairs."""
    if len(sets.sa) == 0:
        return np.full((len(q), 0), np.inf)
    H, where = _placements(robot, sets, q)
    rsum = sets.pair_radius[sets.sa] + sets.pair_radius[sets.sb]
    o = where[sets.pair_owner]  # the joint (row of H) of every sphere
    if math.isinf(within):
        Hs = H[:, o]
        world = np.einsum("tsij,sj->tsi", Hs[..., :3, :3], sets.pair_local) + Hs[..., :3, 3]
        diff = world[:, sets.sa] - world[:, sets.sb]
        return np.sqrt(np.einsum("tsi,tsi->ts", diff, diff)) - rsum
    centre, radius = _bounding_balls(sets)
    Hb = H[:, where]  # (T, n_sets, 4, 4)
    balls = np.einsum("tnij,nj->tni", Hb[..., :3, :3], centre) + Hb[..., :3, 3]
    a, b = sets.pairs[:, 0], sets.pairs[:, 1]
    gap = np.linalg.norm(balls[:, a] - balls[:, b], axis=-1) - radius[a] - radius[b]  # (T, P)
    out = np.full((len(q), len(sets.sa)), np.inf)
    tp, pp = np.nonzero(gap < within)  # the (knot, link pair) entries to compute
    if len(tp) == 0:
        return out
    sizes = np.diff(np.append(sets.starts, len(sets.sa)))[pp]
    first = np.repeat(np.cumsum(sizes) - sizes, sizes)  # each entry's offset within its block
    t = np.repeat(tp, sizes)
    si = np.repeat(sets.starts[pp], sizes) + np.arange(int(sizes.sum())) - first
    ia, ib = sets.sa[si], sets.sb[si]
    Hs = H[:, o]  # every sphere placed once per knot (a few hundred), then gathered per entry
    world = np.einsum("tsij,sj->tsi", Hs[..., :3, :3], sets.pair_local) + Hs[..., :3, 3]
    out[t, si] = np.linalg.norm(world[t, ia] - world[t, ib], axis=1) - rsum[si]
    return out


def meet_exemptions(lay: LayoutData, sets: SphereSets) -> np.ndarray | None:
    """The (knot, checked link pair) entries (T, P) bool that planned self-contacts leave out, or
    None when the spec has none. A target whose frame ``meets`` another (a clap's hands,
    :attr:`tasks.specs.FrameTarget.meets`) exempts every pair of a link of its frame's part and a
    link of the other frame's part (:meth:`robots.Robot.meet_links`: the links on the frame's joint
    or below it, a hand's from ``[collisions] meet_joints`` joints higher up; G1's head, on the
    torso, only its own link), over the target's knots and :data:`MEET_PADDING` seconds around
    them: the two parts may touch there, and the target's tolerance is what keeps them from
    passing through each other."""
    meets = [t for t in lay.spec.targets if t.meets is not None]
    if not meets or len(sets.pairs) == 0:
        return None
    robot = lay.robot
    t = np.asarray(lay.t)
    out = np.zeros((len(t), len(sets.pairs)), dtype=bool)
    links = np.asarray(sets.links)
    la, lb = links[sets.pairs[:, 0]], links[sets.pairs[:, 1]]
    for target in meets:
        mine, theirs = robot.meet_links(target.frame, str(target.meets)), robot.meet_links(str(target.meets), target.frame)
        a, b = sorted(mine), sorted(theirs)
        pairs = (np.isin(la, a) & np.isin(lb, b)) | (np.isin(la, b) & np.isin(lb, a))
        ks = knots_of(t, target.time, target.window, lay.N)
        near = (t >= t[min(ks)] - MEET_PADDING - 1e-9) & (t <= t[max(ks)] + MEET_PADDING + 1e-9)
        out[np.ix_(near, pairs)] = True
    return out


def exempt_distances(lay: LayoutData, sets: SphereSets, distances: np.ndarray) -> np.ndarray:
    """``distances`` (T, S) per sphere pair with the entries of planned self-contacts
    (:func:`meet_exemptions`) set to inf (a copy; ``distances`` itself when there are none)."""
    ex = meet_exemptions(lay, sets)
    if ex is None or not ex.any():
        return distances
    sizes = np.diff(np.append(sets.starts, len(sets.sa)))
    out = distances.copy()
    out[np.repeat(ex, sizes, axis=1)[: len(out)]] = np.inf
    return out


def pair_distances(robot: Robot, sets: SphereSets, q: np.ndarray) -> np.ndarray:
    """Sphere-set distance of every checked link pair at every configuration: (T, P) [m]."""
    if len(sets.pairs) == 0:
        return np.full((len(q), 0), np.inf)
    return np.minimum.reduceat(sphere_pair_distances(robot, sets, q), sets.starts, axis=1)


@dataclass(eq=False)
class SelfCollisionTerm(Term):
    """Squared distances between spheres of two links, one row ``|c_i - c_j|^2 >= (R_i + R_j +
    margin)^2`` [m^2] per chosen sphere pair ``(i, j)``. Structure ``("collision", joint a, joint b,
    n_a, n_b, sphere pairs)``; parameters the centres in the joints' frames, column-major (3, n_a)
    then (3, n_b). ``item`` is the link pair's names."""

    kind: ClassVar[str] = "collision"
    check_kinds: ClassVar[tuple[CheckKind, ...]] = (CheckKind.SELF_COLLISION,)

    @property
    def sphere_pairs(self) -> tuple[tuple[int, int], ...]:
        """The chosen sphere pairs ``(i, j)``: sphere i of link a, sphere j of link b."""
        return self.structure[5]

    @property
    def n_b(self) -> int:
        """The number of spheres of link b."""
        return self.structure[4]

    def _centres(self, p) -> tuple:
        _, _, _, na, nb, _ = self.structure
        return p[0: 3 * na], p[3 * na: 3 * na + 3 * nb]

    def expression(self, p, kin: StageKinematics) -> tuple:
        """(rows, 0) in CasADi (:meth:`Term.expression`)."""
        import casadi as ca

        _, ja, jb, na, nb, chosen = self.structure
        worlds = []
        for j, n, flat in zip((ja, jb), (na, nb), self._centres(p), strict=True):
            R, pos = kin.joints[j]
            worlds.append(ca.repmat(pos, 1, n) + ca.mtimes(R, ca.reshape(flat, 3, n)))
        wa, wb = worlds
        return ca.vertcat(*[ca.sumsqr(wa[:, i] - wb[:, j]) for i, j in chosen]), 0

    def residual(self, kin: NumericKinematics) -> np.ndarray:
        """The rows in numpy (:meth:`Term.residual`)."""
        _, ja, jb, na, nb, chosen = self.structure
        ca_, cb_ = (np.asarray(flat, dtype=float).reshape(n, 3) for flat, n in zip(self._centres(self.params), (na, nb),
                                                                                  strict=True))
        wa = ca_ @ kin.joint(ja).rotation.T + kin.joint(ja).translation
        wb = cb_ @ kin.joint(jb).rotation.T + kin.joint(jb).translation
        return np.array([float(np.dot(wa[i] - wb[j], wa[i] - wb[j])) for i, j in chosen])

    @classmethod
    def report(cls, ctx: ReportContext) -> list[Check]:
        """The closest checked link pair over the plan (:func:`self_collision_check`), when
        ``settings.self_collision``."""
        return [self_collision_check(ctx.lay, ctx.q, ctx.settings)] if ctx.settings.collision.self_collision else []


class Rows(PairRows):
    """The collision rows of a layout, per checked link pair: the sphere pairs (indices into the
    pair's block) and the knots that carry rows (frozen: :meth:`PairRows.merged` returns a new one)."""


def collision_rows_of(lay: LayoutData, sets: SphereSets) -> Rows:
    """The :class:`Rows` of the ``collision`` terms already in a layout."""
    index = {name: i for i, name in enumerate(sets.pair_names)}
    spheres: dict[int, set[int]] = {}
    knots: dict[int, set[int]] = {}
    for t in lay.terms:
        if not isinstance(t, SelfCollisionTerm) or t.item not in index:
            continue
        pi = index[t.item]
        spheres.setdefault(pi, set()).update(i * t.n_b + j for i, j in t.sphere_pairs)
        knots.setdefault(pi, set()).add(t.knot)
    return Rows(spheres, knots)


def select(lay: LayoutData, sets: SphereSets, distances: np.ndarray, threshold: float,
           only: np.ndarray | None = None) -> Rows:
    """Rows for the link pairs closer than ``threshold`` at some variable knot (``distances``:
    (T, S) per sphere pair): per link pair, every sphere pair closer than ``threshold`` at such a
    knot (and every sphere pair marked in ``only``), on those knots widened by
    :data:`KNOT_PADDING`. ``only`` (T, S) bool, when given, restricts the link pairs to those with
    a marked entry. All close sphere pairs, not only the closest: a solve that pushes one sphere
    pair apart slides the limb onto its neighbour, and each such round builds a solver and solves
    again (docs/collisions.md)."""
    if len(sets.starts) == 0:
        return Rows()
    ex = meet_exemptions(lay, sets)
    d = exempt_distances(lay, sets, distances).copy()
    d[:2] = np.inf
    d[lay.N:] = np.inf
    pair_min = np.minimum.reduceat(d, sets.starts, axis=1)
    close_pairs = (pair_min < threshold).any(axis=0)
    if only is not None:
        only = only.copy()
        only[:2] = False
        only[lay.N:] = False
        close_pairs &= np.add.reduceat(only.any(axis=0), sets.starts) > 0
    ends = np.append(sets.starts[1:], len(sets.sa))
    rows_spheres: dict[int, set[int]] = {}
    rows_knots: dict[int, set[int]] = {}
    for pi in np.flatnonzero(close_pairs):
        a, b = sets.starts[pi], ends[pi]
        block = d[:, a:b]
        ks = np.flatnonzero(block.min(axis=1) < threshold)
        spheres = {int(i) for i in np.flatnonzero((block[ks] < threshold).any(axis=0))}
        if only is not None:
            spheres |= {int(i) for i in np.flatnonzero(only[:, a:b].any(axis=0))}
        knots: set[int] = set()
        for k in ks:
            knots.update(range(max(2, int(k) - KNOT_PADDING), min(lay.N - 1, int(k) + KNOT_PADDING) + 1))
        if ex is not None:  # no rows where the pair is a planned self-contact
            knots -= {int(k) for k in np.flatnonzero(ex[:, pi])}
        rows_spheres[int(pi)] = spheres
        rows_knots[int(pi)] = knots
    return Rows(rows_spheres, rows_knots)


IDLE_TOLERANCE = 0.005  # [m] a pair whose guess comes no closer than its rest distance less this is idle
IDLE_BUFFER = 0.005  # [m] ... provided the guess keeps it at least the margin plus this apart


def idle_pairs(lay: LayoutData, sets: SphereSets, distances: np.ndarray, margin: float) -> np.ndarray:
    """The checked link pairs (P,) bool that the initial guess leaves *idle*: at every variable knot
    every computed sphere pair (``distances`` (T, S), :func:`sphere_pair_distances`) is no closer
    than at rest (the start posture, knot 0) less :data:`IDLE_TOLERANCE`, and at least ``margin`` +
    :data:`IDLE_BUFFER`. Talos's ankles and hips stay within the screening distance with both feet
    down (19.5 and 24 mm at rest) and got a few hundred rows on every task that no solve needed; an
    idle pair gets no rows, and the check after each solve gives it rows if the solution brings it
    within the margin (docs/collisions.md)."""
    if len(sets.starts) == 0:
        return np.zeros(0, dtype=bool)
    rest = distances[0]
    d = distances[2:lay.N]
    finite = np.isfinite(d)
    moving = finite & ((d < rest[None, :] - IDLE_TOLERANCE) | (d < margin + IDLE_BUFFER))
    return ~(np.add.reduceat(moving.any(axis=0), sets.starts) > 0)


def with_collision_terms(lay: L, sets: SphereSets, rows: Rows, pairs: list[int], margin: float) -> L:
    """A copy of ``lay`` whose ``collision`` terms of link ``pairs`` are (re)written from ``rows``: one
    term per pair and knot, a row per selected sphere pair ``|c_i - c_j|^2 >= (R_i + R_j + margin)^2``
    (``lay`` is not changed)."""
    robot = lay.robot
    names = {pi: sets.pair_names[pi] for pi in pairs}
    terms = [t for t in lay.terms if not (isinstance(t, SelfCollisionTerm) and t.item in names.values())]
    for pi in pairs:
        a, b = (int(x) for x in sets.pairs[pi])
        ca_, cb_ = sets.centres[a], sets.centres[b]
        nb = len(cb_)
        chosen = tuple((i // nb, i % nb) for i in sorted(rows.spheres[pi]))
        bound = np.array([(sets.radii[a][i] + sets.radii[b][j] + margin) ** 2 for i, j in chosen])
        label = f"self-collision {body_part(robot, names[pi][0])} / {body_part(robot, names[pi][1])}"
        for k in sorted(rows.knots[pi]):
            terms.append(SelfCollisionTerm(
                knot=k,
                structure=(SelfCollisionTerm.kind, int(sets.joints[a]), int(sets.joints[b]), len(ca_), nb, chosen),
                params=np.concatenate([ca_.ravel(), cb_.ravel()]),  # (3, n) column-major: x, y, z per sphere
                lower=bound, upper=np.full(len(chosen), math.inf),
                label=label, item=names[pi], phase=lay.phase_name(k),
            ))
    return lay.with_terms(terms)


def missing_rows(lay: LayoutData, sets: SphereSets, rows: Rows, distances: np.ndarray, margin: float,
                 screening: float) -> Rows:
    """Rows to add after a solve: for each sphere pair closer than the margin (less
    :data:`CHECK_TOLERANCE`) at a knot where it has no row, that pair's sphere pairs closer than
    the screening distance, on padded knots."""
    distances = exempt_distances(lay, sets, distances)
    has = np.zeros(distances.shape, dtype=bool)
    for pi, sp in rows.spheres.items():
        ks = sorted(rows.knots[pi])
        for i in sp:
            has[ks, sets.starts[pi] + i] = True
    violated = (distances < margin - CHECK_TOLERANCE) & ~has
    if not violated[2:lay.N].any():
        return Rows()
    return select(lay, sets, distances, screening, only=violated)


def strip_collision_terms(lay: L) -> L:
    """A copy of ``lay`` without its collision terms (the same class: kinematic or dynamic)."""
    return lay.with_terms([t for t in lay.terms if not isinstance(t, SelfCollisionTerm)])


# -- report ------------------------------------------------------------------------------------


def closest(robot: Robot, sets: SphereSets, q: np.ndarray, t: np.ndarray,
            exempt: np.ndarray | None = None) -> tuple[float, float, tuple[str, str]]:
    """(distance [m], time [s], link pair) of the closest checked pair over a motion, leaving out
    the ``exempt`` (T, P) entries (planned self-contacts, :func:`meet_exemptions`)."""
    if len(sets.pairs) == 0:
        return math.inf, 0.0, ("", "")
    d = np.minimum.reduceat(sphere_pair_distances(robot, sets, q, within=CLOSEST_WITHIN), sets.starts, axis=1)
    if exempt is not None:
        d[exempt[: len(d)]] = np.inf
    if not d.min() < CLOSEST_WITHIN:  # nothing that close: every pair (the pairs not computed are farther)
        d = pair_distances(robot, sets, q)
        if exempt is not None:
            d[exempt[: len(d)]] = np.inf
    k, pi = np.unravel_index(int(np.argmin(d)), d.shape)
    return float(d[k, pi]), float(t[k]), sets.pair_names[int(pi)]


def self_collision_check(lay: LayoutData, q: np.ndarray, settings: PlannerSettings) -> Check:
    """The plan's ``self-collision`` check: the closest pair of the collision model and its distance;
    it fails when the sphere sets interpenetrate by more than ``CHECK_TOLERANCE``."""
    robot = lay.robot
    sets = sphere_sets(robot)
    d, time, (a, b) = closest(robot, sets, q, lay.t, meet_exemptions(lay, sets))
    if not math.isfinite(d):
        return Check.constraint(name="self-collision (no pair to check)", kind=CheckKind.SELF_COLLISION,
                                violation=0.0, tolerance=CHECK_TOLERANCE, unit="m", time=0.0)
    name = (f"self-collision (closest: {body_part(robot, a)} / {body_part(robot, b)}, {a} / {b}, "
            f"{d * 1000:.0f} mm)")
    return Check.constraint(name=name, kind=CheckKind.SELF_COLLISION, violation=max(0.0, -d),
                            tolerance=CHECK_TOLERANCE, unit="m", time=time, subject=f"{a}/{b}")


# -- diagnosis ---------------------------------------------------------------------------------


_DIRECTIONS = (("forward", "back"), ("left", "right"), ("up", "down"))


def _target_time(target, horizon: float) -> float:
    if target.window is not None:
        return 0.5 * (target.window[0] + target.window[1])
    return horizon if target.time is None else target.time


def _advice(lay: LayoutData, side_hint: str, time: float, obstacle: str) -> str:
    """What to change, from the spec's hard position targets: the target nearest in time to the
    collision, preferring the colliding limb's hand. A reach with one hand gets "reach less far
    right, or with the left hand" (the direction it moves in most); when both hands have targets
    (a clap, crossed arms) switching hands means nothing: "move the left hand's target
    'left hand clap #1' away from the torso"."""
    robot, spec = lay.robot, lay.spec
    data = robot.data()
    pin.framesForwardKinematics(robot.model, data, lay.q_ref)
    base = data.oMf[robot.frame_id("base")]
    hands = {robot.profile.frame(f"{s}_hand"): s for s in ("left", "right") if robot.has_role(f"{s}_hand")}
    horizon = float(lay.t[-1])
    best = None
    sides_with_targets = set()
    for target in spec.targets:
        if target.position is None or target.priority.name != "HARD":
            continue
        frame = robot.profile.frame(target.frame) or target.frame
        side = hands.get(frame)
        if side is not None:
            sides_with_targets.add(side)
        start = data.oMf[robot.frame_id(target.frame)].translation
        move = base.rotation.T @ (np.array(target.position) - start)
        axis = int(np.argmax(np.abs(move)))
        word = _DIRECTIONS[axis][0 if move[axis] > 0 else 1]
        score = (side == side_hint, -abs(_target_time(target, horizon) - time), float(np.linalg.norm(move)))
        if best is None or score > best[0]:
            best = (score, word, side, target.name)
    if best is None:
        return "move less far, or change the posture"
    _, word, side, name = best
    if side is None:
        return f"move {name!r} less far {word}"
    if len(sides_with_targets) > 1:
        return f"move the {side} hand's target {name!r} away from the {obstacle}"
    other = "right" if side == "left" else "left"
    return f"reach less far {word}, or with the {other} hand"


def collision_diagnosis(lay: L, settings: PlannerSettings, solve: Callable[[L], tuple]) -> str:
    """When the plan with collision rows failed: solve without them; if that motion brings a pair
    within the margin, the collision is the cause, said in task terms (empty string otherwise).
    ``solve`` solves a layout from its initial guess without a compile and returns
    :func:`planner.trajopt.solve.solve_layout`'s ``(dq, stats, raw)`` (passed in: the solver imports
    the term modules, so they do not import it back)."""
    from planner.trajopt.symbolic import chart_to_configuration

    if not any(isinstance(t, SelfCollisionTerm) for t in lay.terms):
        return ""
    dq, stats, _ = solve(strip_collision_terms(lay))
    if not stats.status.ok:
        return ""
    robot = lay.robot
    q = np.array([chart_to_configuration(lay.robot.model, lay.q_ref, d) for d in dq])
    sets = sphere_sets(robot)
    d, time, (a, b) = closest(robot, sets, q, lay.t, meet_exemptions(lay, sets))
    if d >= settings.collision.margin:
        return ""
    pa, pb = body_part(robot, a), body_part(robot, b)
    if pb.startswith(("left", "right")) and not pa.startswith(("left", "right")):
        pa, pb = pb, pa  # the moving limb first
    side = pa.split()[0] if pa.startswith(("left", "right")) else ""
    what = "pass through" if d < 0 else f"come within {max(d, 0.0) * 1000:.0f} mm of"
    return f"{pa} would {what} the {pb} at t = {time:.1f} s ({a} / {b}): {_advice(lay, side, time, pb)}"
