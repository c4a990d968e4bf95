"""The robot's collision model: one capsule per link, fitted to the URDF collision geometry.

Each link's collision geometry (meshes and primitives of ``robot.collision_model``) is gathered
in its parent joint's frame and enclosed by a capsule (or two, cut across a principal axis, when
that saves a quarter of the volume, or, for a wide link, makes the capsules much thinner:
:func:`fit_link`): the axis is the principal direction of
the vertices, the axis line passes through the centre of the smallest circle (approximately)
enclosing their projection on the perpendicular plane, the radius is the largest distance of a
vertex to that line, and the segment is the shortest one whose capsule still holds every vertex.
The capsule therefore *encloses* the geometry (``tests/robots/test_collision.py`` checks every
vertex): distances between capsules never exceed the distances between the meshes.

The pairs to check are every pair of links minus

* ``"srdf"``: the SRDF's ``<disable_collisions>`` pairs (example-robot-data ships an SRDF for
  talos, romeo and icub);
* ``"adjacent"``: links on the same joint, or on a joint and its parent joint;
* ``"touching at rest"``: pairs whose meshes (coal distances) are closer than :data:`REST_MARGIN`,
  or whose capsules' sphere sets are closer than :data:`REST_SPHERE_MARGIN`, in the standing
  posture (a motion starts there: such a pair could not be kept a margin apart, or, the capsules
  being larger than the meshes, not moved at all);
* ``"profile"``: the profile's ``[collisions] remove`` list;

plus the profile's ``[collisions] add`` list. The fit is cached on disk (JSON, keyed by the URDF,
SRDF and profile content and :data:`FIT_VERSION`) under ``$WBMP_CACHE_DIR`` (else
``~/.cache/wbmp``) in ``collision/``; a damaged cache file is rebuilt. See ``docs/collisions.md``.

The capsules themselves (data, fit, distances) are in :mod:`robots.capsules`; their names are
re-exported here.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import itertools
import json
import math
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

# The capsules' data, fit and distances live in robots.capsules; their names stay importable here.
from robots.capsules import (  # noqa: F401 (re-exported)
    CYLINDER_SAMPLES,
    MIN_SPHERE_SPACING,
    RADIUS_GAIN,
    SPHERE_SPACING,
    SPLIT_GAIN,
    WIDE_RADIUS,
    Capsule,
    CollisionModel,
    _pair,
    _volume,
    axis_capsules,
    capsule_distance,
    capsule_world,
    fit_capsule,
    fit_link,
    geometry_points,
    link_points,
    mesh_distances,
    pair_distances,
    pair_sphere_distance,
    segment_distance,
    sphere_distance,
)
from robots.safeio import read_json
from robots.store import write_text_atomic

if TYPE_CHECKING:
    from robots.model import Robot

FIT_VERSION = 8  # bump when the fitting or the pair selection changes: the cache is keyed by it
REST_MARGIN = 0.01  # [m] pairs whose meshes are closer than this in the standing posture are skipped ...
REST_SPHERE_MARGIN = 0.01  # [m] ... and pairs whose (conservative) sphere sets are closer than this
COVER_RANGE = 0.05  # [m] pairs whose own capsules' sphere sets are closer than this at rest may use other covers ...
COVER_GAIN = 0.005  # [m] ... when those are at least this much farther apart there
SKIP_REASONS = ("srdf", "adjacent", "touching at rest", "profile")


# -- pairs -------------------------------------------------------------------------------------


def srdf_path(robot: Robot) -> str | None:
    """The SRDF of a robot: example-robot-data's for a loader robot, else the profile's."""
    profile = robot.profile
    if profile.loader is not None:
        from robots.model import _loader_paths

        try:
            return _loader_paths(profile.where, profile.loader)[1]
        except Exception:  # noqa: BLE001 - no SRDF: nothing to skip
            return None
    return profile.srdf


def srdf_disabled_pairs(path: str | None) -> set[tuple[str, str]]:
    """The ``<disable_collisions link1 link2>`` pairs of an SRDF (sorted pairs; empty if unreadable)."""
    if not path:
        return set()
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError, ValueError):
        return set()
    out = set()
    for el in root.iter("disable_collisions"):
        a, b = el.get("link1"), el.get("link2")
        if a and b and a != b:
            out.add(_pair(a, b))
    return out



def _adjacent(model: pin.Model, ja: int, jb: int) -> bool:
    return ja == jb or model.parents[ja] == jb or model.parents[jb] == ja


def _check_table(robot: Robot, links: list[str]) -> None:
    """Every link the profile's ``[collisions]`` table names has collision geometry."""
    from robots.exceptions import ProfileError
    from robots.profile import _suggest

    table = robot.profile.collisions
    named = [(f"collisions.{key}[{i}]", link) for key in ("add", "remove")
             for i, pair in enumerate(getattr(table, key)) for link in pair]
    named += [(f"collisions.body_parts.{link}", link) for link, _ in table.body_parts]
    for key, link in named:
        if link not in links:
            raise ProfileError(f"{robot.profile.where}: {key}: the robot has no link {link!r} with collision "
                               f"geometry{_suggest(link, links)}")


def choose_covers(capsules: dict[str, list[Capsule]], alternatives: dict[str, list[Capsule]],
                  pairs: list[tuple[str, str]], data: pin.Data,
                  unchecked: set[tuple[str, str]]) -> dict[tuple[str, str], tuple[int, int]]:
    """Per pair whose own capsules' sphere sets are closer than :data:`COVER_RANGE` at the joint
    placements ``data.oMi`` (the standing posture), the covers of its two links (0: their own
    capsules; k: alternative k) whose sphere sets are farthest apart there, kept only when that is
    at least :data:`COVER_GAIN` farther than with the own capsules. Any cover encloses its link,
    so the pair's sphere-set distance still never exceeds the meshes' at any posture; choosing at
    rest gives the cover tight on the side where the other link is (Talos's hanging forearm beside
    the pelvis: 13 mm -> 75 mm; the meshes are 93 mm apart). Pairs farther apart keep the own
    capsules, the tightest overall (the arms crossing in front of the torso).

    A link keeps its own capsules in a pair when a link on its joint and the pair's other link are
    ``unchecked`` (touching at rest): its own capsules are then what keeps the other link off
    that neighbour's mesh (G1's chest logo, on the torso, keeps the shoulders off the torso)."""
    out: dict[tuple[str, str], tuple[int, int]] = {}
    joint_of = {link: caps[0].joint for link, caps in capsules.items()}
    on_joint: dict[int, list[str]] = {}
    for link, j in joint_of.items():
        on_joint.setdefault(j, []).append(link)

    def free(link: str, other: str) -> bool:  # may ``link`` take another cover against ``other``?
        return not any(_pair(t, other) in unchecked for t in on_joint[joint_of[link]] if t != other)

    for a, b in pairs:
        own = min(sphere_distance(c1, c2, data) for c1 in capsules[a] for c2 in capsules[b])
        if own >= COVER_RANGE:
            continue
        options_a = [(0, capsules[a])] + [(c.cover, [c]) for c in alternatives.get(a, []) if free(a, b)]
        options_b = [(0, capsules[b])] + [(c.cover, [c]) for c in alternatives.get(b, []) if free(b, a)]
        best = (own, (0, 0))
        for (ka, ca), (kb, cb) in itertools.product(options_a, options_b):
            d = min(sphere_distance(c1, c2, data) for c1 in ca for c2 in cb)
            if d > best[0]:
                best = (d, (ka, kb))
        if best[0] >= own + COVER_GAIN:
            out[(a, b)] = best[1]
    return out


def _build(robot: Robot) -> CollisionModel:
    model = robot.model
    capsules = []
    alternatives = []
    for link, (joint, pts) in link_points(robot).items():
        own = fit_link(pts)
        for placement, length, radius in own:
            capsules.append(Capsule(link=link, joint=joint, placement=placement, length=length, radius=radius))
        for k, (placement, length, radius) in enumerate(axis_capsules(pts), start=1):
            if len(own) == 1 and abs(length - own[0][1]) < 1e-12 and abs(radius - own[0][2]) < 1e-12:
                continue  # the link's own capsule
            alternatives.append(Capsule(link=link, joint=joint, placement=placement, length=length, radius=radius,
                                        cover=k))
    caps: dict[str, list[Capsule]] = {}
    for c in capsules:
        caps.setdefault(c.link, []).append(c)
    links = list(caps)
    table = robot.profile.collisions
    _check_table(robot, links)
    srdf = srdf_disabled_pairs(srdf_path(robot))
    removed = {_pair(a, b) for a, b in table.remove}
    added = {_pair(a, b) for a, b in table.add}
    skipped: dict[tuple[str, str], str] = {}
    candidates = []
    for a, b in itertools.combinations(sorted(links), 2):
        pair = _pair(a, b)
        if pair in added:
            continue
        if pair in removed:
            skipped[pair] = "profile"
        elif pair in srdf:
            skipped[pair] = "srdf"
        elif _adjacent(model, caps[a][0].joint, caps[b][0].joint):
            skipped[pair] = "adjacent"
        else:
            candidates.append(pair)
    rest_mesh = mesh_distances(robot, robot.q_standing, candidates)
    data = model.createData()
    pin.forwardKinematics(model, data, robot.q_standing)
    pairs = set(added)
    for pair in candidates:
        d_caps = min(sphere_distance(c1, c2, data) for c1 in caps[pair[0]] for c2 in caps[pair[1]])
        if rest_mesh.get(pair, math.inf) < REST_MARGIN or d_caps < REST_SPHERE_MARGIN:
            skipped[pair] = "touching at rest"
        else:
            pairs.add(pair)
    alt: dict[str, list[Capsule]] = {}
    for c in alternatives:
        alt.setdefault(c.link, []).append(c)
    covers = choose_covers(caps, alt, sorted(pairs), data,
                           unchecked={p for p, why in skipped.items() if why == "touching at rest"})
    used = {(link, k) for pair, ks in covers.items() for link, k in zip(pair, ks, strict=True) if k}
    return CollisionModel(robot=robot.name, capsules=tuple(capsules), pairs=tuple(sorted(pairs)),
                          skipped=dict(sorted(skipped.items())),
                          alternatives=tuple(c for c in alternatives if (c.link, c.cover) in used), covers=covers)


# -- the disk cache ----------------------------------------------------------------------------


def cache_dir() -> Path:
    """``$WBMP_CACHE_DIR/collision`` (else ``~/.cache/wbmp/collision``): the root the solver cache uses."""
    from robots.store import cache_folder

    folder = cache_folder("collision")
    assert folder is not None  # no switch: never off
    return folder


def cache_key(robot: Robot) -> str:
    """Hash of what the model depends on: URDF and SRDF content, the profile's collision table, the
    standing posture and :data:`FIT_VERSION`."""
    h = hashlib.sha256()
    h.update(f"fit-v{FIT_VERSION}|{REST_MARGIN}|{REST_SPHERE_MARGIN}|{COVER_RANGE}|{COVER_GAIN}|{robot.name}".encode())
    for path in (robot.urdf_path, srdf_path(robot)):
        if path:
            try:
                h.update(Path(path).read_bytes())
            except OSError:
                h.update(path.encode())
    h.update(robot.profile.collisions.fit_key().encode())
    h.update(np.asarray(robot.q_standing, dtype=float).tobytes())
    return h.hexdigest()[:20]


def _to_json(cm: CollisionModel) -> dict:
    return {
        "fit_version": FIT_VERSION,
        "robot": cm.robot,
        "capsules": [_capsule_json(c) for c in cm.capsules],
        "alternatives": [_capsule_json(c) for c in cm.alternatives],
        "pairs": [list(p) for p in cm.pairs],
        "skipped": [[a, b, why] for (a, b), why in cm.skipped.items()],
        "covers": [[a, b, ka, kb] for (a, b), (ka, kb) in cm.covers.items()],
    }


def _capsule_json(c: Capsule) -> dict:
    return {"link": c.link, "joint": c.joint, "rotation": c.placement.rotation.tolist(),
            "translation": c.placement.translation.tolist(), "length": c.length, "radius": c.radius,
            "cover": c.cover}


def _capsule_from_json(c: dict, robot: Robot) -> Capsule:
    R = np.array(c["rotation"], dtype=float)
    p = np.array(c["translation"], dtype=float)
    length, radius, joint, cover = float(c["length"]), float(c["radius"]), int(c["joint"]), int(c["cover"])
    if (R.shape != (3, 3) or p.shape != (3,) or not np.all(np.isfinite(R)) or not np.all(np.isfinite(p))
            or not np.allclose(R.T @ R, np.eye(3), atol=1e-6) or not (length >= 0 and radius > 0)
            or not 0 < joint < robot.model.njoints or not isinstance(c["link"], str) or not 0 <= cover <= 3):
        raise ValueError("bad capsule")
    return Capsule(link=c["link"], joint=joint, placement=pin.SE3(R, p), length=length, radius=radius, cover=cover)


def _from_json(data: dict, robot: Robot) -> CollisionModel:
    """A model from its cache file; ValueError/KeyError/TypeError when anything is off."""
    if data.get("fit_version") != FIT_VERSION or data.get("robot") != robot.name:
        raise ValueError("stale")
    capsules = tuple(_capsule_from_json(c, robot) for c in data["capsules"])
    alternatives = tuple(_capsule_from_json(c, robot) for c in data["alternatives"])
    links = {c.link for c in capsules}
    pairs = tuple(sorted(_pair(str(a), str(b)) for a, b in data["pairs"]))
    skipped = {_pair(str(a), str(b)): str(why) for a, b, why in data["skipped"]}
    covers = {(str(a), str(b)): (int(ka), int(kb)) for a, b, ka, kb in data["covers"]}
    if (not all(a in links and b in links for a, b in pairs) or not set(skipped.values()) <= set(SKIP_REASONS)
            or any(c.cover < 1 for c in alternatives)
            or any(c.cover != 0 for c in capsules)):
        raise ValueError("bad pairs")
    model = CollisionModel(robot=robot.name, capsules=capsules, pairs=pairs, skipped=skipped,
                           alternatives=alternatives, covers=covers)
    for (a, b), (ka, kb) in covers.items():
        if (a, b) not in pairs or any(not model.capsules_of(link, k) for link, k in ((a, ka), (b, kb))):
            raise ValueError("bad covers")
    return model


def write_bundled_fit(robot: Robot) -> Path:
    """Fit ``robot``'s collision model now and store it in :data:`BUNDLED` under its current key
    (run after a change to the URDF, the profile's collision table or the fit:
    ``python -c "from robots.collision import write_bundled_fit; import robots;
    write_bundled_fit(robots.load_robot('talos'))"``); older
    fits of the robot there are removed. Returns the file."""
    path = BUNDLED / f"{robot.name}-{cache_key(robot)}.json"
    text = json.dumps(_to_json(_build(robot)), indent=0, sort_keys=True) + "\n"
    path.parent.mkdir(parents=True, exist_ok=True)
    for old in path.parent.glob(f"{robot.name}-*.json"):
        if old != path:
            old.unlink()
    write_text_atomic(path, text)
    return path


def _write_atomic(path: Path, text: str) -> None:
    """Store a fit; a cache folder that cannot be written only costs the speed-up."""
    with contextlib.suppress(OSError):
        path.parent.mkdir(parents=True, exist_ok=True)
        write_text_atomic(path, text)


_MEMORY: dict[tuple[int, str], CollisionModel] = {}
BUNDLED = Path(__file__).with_name("fits")  # fits shipped with the package: <robot>-<cache_key>.json


def _read_fit(path: Path, robot: Robot) -> CollisionModel | None:
    """The model stored at ``path``; None when there is none or it is damaged or stale."""
    try:
        if path.is_file():  # a regular file of at most 8 MiB (a FIFO or a device is damaged)
            return _from_json(read_json(path, 8 << 20), robot)
    except (OSError, ValueError, KeyError, TypeError, IndexError, AttributeError, RecursionError):
        pass  # damaged, stale or removed meanwhile: rebuilt
    return None


def collision_model(robot: Robot) -> CollisionModel:
    """The collision model of ``robot``: from memory, the disk cache, the fit shipped in
    :data:`BUNDLED` for the same key (a URDF, profile or fit version that changed has another key),
    or fitted now (Talos: ~7 s of CPU); the last two are stored in the disk cache."""
    from robots.store import mark_used, trim_cache

    key = cache_key(robot)
    mem = _MEMORY.get((id(robot), key))
    if mem is not None:
        return mem
    path = cache_dir() / f"{robot.name}-{key}.json"
    cm = _read_fit(path, robot)
    if cm is not None:
        mark_used(path)
    else:
        cm = _read_fit(BUNDLED / path.name, robot) or _build(robot)
        _write_atomic(path, json.dumps(_to_json(cm)))
        trim_cache(path.parent)
    _MEMORY[(id(robot), key)] = cm
    return cm


# -- names for messages ------------------------------------------------------------------------


def _ancestors(model: pin.Model, joint: int) -> list[int]:
    out = []
    while joint > 0:
        out.append(joint)
        joint = model.parents[joint]
    return out


@functools.lru_cache(maxsize=16)
def _body_parts(robot: Robot) -> dict[str, str]:
    model = robot.model
    data = model.createData()
    pin.framesForwardKinematics(model, data, robot.q_standing)
    cm = collision_model(robot)
    overrides = dict(robot.profile.collisions.body_parts)

    def joint_of(role: str) -> int | None:
        frame = robot.profile.frame(role)
        return int(model.frames[model.getFrameId(frame)].parentJoint) if frame else None

    def origin(role: str) -> np.ndarray:
        return data.oMf[robot.frame_id(role)].translation

    def chain(role: str) -> set[int]:
        j = joint_of(role)
        return set(_ancestors(model, j)) if j is not None else set()

    @functools.cache  # asked for every link: computed once per role
    def below(role: str) -> set[int]:  # the joints of the subtree under a role's joint
        j = joint_of(role)
        return {i for i in range(1, model.njoints) if j is not None and j in _ancestors(model, i)}

    base_j = joint_of("base") or 1
    hands = {s: chain(f"{s}_hand") for s in ("left", "right")}
    feet = {s: chain(f"{s}_foot") for s in ("left", "right")}
    head = chain("head")
    common = (hands["left"] & hands["right"]) | (feet["left"] & feet["right"]) | (hands["left"] & feet["left"])
    out: dict[str, str] = {}
    for link in cm.links:
        c = max(cm.capsules_of(link), key=lambda c: _volume(c.length, c.radius))  # the main part
        if c.link in overrides:
            out[c.link] = overrides[c.link]
            continue
        centre = data.oMi[c.joint].act(c.placement.translation)
        j = c.joint
        name = None
        for side in ("left", "right"):
            if j in below(f"{side}_hand"):
                name = f"{side} hand"
            elif j in hands[side] - common:
                start = (origin(f"{side}_shoulder") if robot.has_role(f"{side}_shoulder")
                         else data.oMi[min(hands[side] - common)].translation)
                end = origin(f"{side}_hand")
                f = float(np.dot(centre - start, end - start) / max(np.dot(end - start, end - start), 1e-9))
                name = f"{side} " + ("shoulder" if f < 0.1 else "upper arm" if f < 0.5 else "forearm" if f < 0.85
                                     else "hand")
            elif j in feet[side] - common or j in below(f"{side}_foot"):
                hip = data.oMi[min(feet[side] - common)] if feet[side] - common else data.oMi[j]
                z0, z1 = hip.translation[2], origin(f"{side}_foot")[2]
                f = float((z0 - centre[2]) / max(z0 - z1, 1e-9))
                name = f"{side} " + ("hip" if f < 0.12 else "thigh" if f < 0.5 else "shin" if f < 0.85 else "foot")
            if name:
                break
        if name is None:
            if j == base_j or (j in feet["left"] & feet["right"]):
                name = "pelvis"
            elif j in head - common:
                name = "head" if robot.has_role("head") and centre[2] >= origin("head")[2] - 0.05 else "neck"
            elif j in common or (robot.has_role("torso") and j in chain("torso")):
                name = "torso"
            else:
                name = c.link.replace("_", " ")
        out[c.link] = name
    return out


def body_part(robot: Robot, link: str) -> str:
    """A human name of a link for messages ("left forearm", "pelvis", "right thigh"): derived from
    the robot's roles and kinematic chains, or the profile's ``[collisions] body_parts``."""
    override = dict(robot.profile.collisions.body_parts).get(link)
    if override:
        return override
    return _body_parts(robot).get(link, link.replace("_", " "))
