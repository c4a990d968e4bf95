"""The legs' slab capsules of the scene rows (:func:`planner.trajopt.scene_collision.scene_sets`)
shipped for the robots wbmp plans for, so that a process does not fit them again.

Cutting a leg's hull into slabs and fitting a capsule around each (``slab_capsules``: scipy's
convex hull, ``robots.fit_capsule``) cost ~0.6 s of CPU per process for Talos, half of it importing
``scipy.spatial``, in every plan with scene objects (the stairs climb's first time). The capsules
depend only on the robot's collision geometry and the slab thickness, so they are stored here,
``slabs/<robot>-<key>.json``, keyed by the robot's collision-model key (``robots.cache_key``:
URDF, SRDF, the profile's collision table, the fit's version), the slab thickness and
:data:`SLAB_VERSION`. A robot or key with no file is fitted as before. :func:`write_shipped_slabs`
regenerates a robot's file (a test fails until it is run after such a change).
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pinocchio as pin

from robots import Robot, cache_key, write_text_atomic

SLAB_VERSION = 1  # bump when slab_capsules changes: the shipped files then no longer apply
SHIPPED = Path(__file__).with_name("slabs")

Capsules = list[tuple[pin.SE3, float, float]]


def slab_key(robot: Robot, slab: float) -> str:
    """The key of ``robot``'s slab capsules ``slab`` [m] thick."""
    return hashlib.sha256(f"slab-v{SLAB_VERSION}|{slab!r}|{cache_key(robot)}".encode()).hexdigest()[:20]


def shipped_slabs(robot: Robot, slab: float) -> dict[str, Capsules] | None:
    """Link -> its slab capsules (placement, length, radius), from the file of ``robot``'s current
    key; None when there is none (or it cannot be read): fit them."""
    path = SHIPPED / f"{robot.name}-{slab_key(robot, slab)}.json"
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
        return {link: [(pin.SE3(np.array(m, dtype=float).reshape(4, 4)), float(length), float(radius))
                       for m, length, radius in caps] for link, caps in data["links"].items()}
    except (OSError, ValueError, KeyError, TypeError):
        return None


def write_shipped_slabs(robot: Robot, slab: float, links: list[str],
                        fit: Callable[[np.ndarray, float], Capsules]) -> Path:
    """Fit the slab capsules of ``links`` (``fit(points, slab)``, the link's collision points) and
    store them under ``robot``'s current key; the robot's older files are removed. Returns the file.
    Run ``python -c "import robots; from planner.trajopt.scene_collision import write_slabs;
    write_slabs(robots.load_robot('talos'))"`` after a change to the robot or to the fit."""
    from robots import link_points

    points = link_points(robot)
    data = {"robot": robot.name, "slab": slab, "version": SLAB_VERSION,
            "links": {link: [(np.asarray(M.homogeneous).ravel().tolist(), length, radius)
                             for M, length, radius in fit(points[link][1], slab)] for link in links}}
    path = SHIPPED / f"{robot.name}-{slab_key(robot, slab)}.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    for old in path.parent.glob(f"{robot.name}-*.json"):
        if old != path:
            old.unlink()
    write_text_atomic(path, json.dumps(data, indent=0, sort_keys=True) + "\n")
    return path
