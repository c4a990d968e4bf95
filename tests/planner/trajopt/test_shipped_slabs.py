"""The legs' slab capsules shipped in planner/trajopt/slabs (planner.trajopt.shipped_slabs): the
files carry the robots' current keys, the scene spheres are built from them without fitting, they
cover every collision point of their leg link, a robot with no file is fitted as before, and (long)
they equal the fit exactly.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import planner.trajopt.scene_collision as sc
import planner.trajopt.shipped_slabs as ss
from robots import link_points, load_robot


def _covered(points: np.ndarray, capsules) -> np.ndarray:
    """Each point's largest depth inside the capsules (distance to the axis minus the radius; <= 0: inside)."""
    best = np.full(len(points), np.inf)
    for M, length, radius in capsules:
        local = (points - M.translation) @ M.rotation  # the capsule's axis is its local z, centred
        z = np.clip(local[:, 2], -length / 2, length / 2)
        d = np.linalg.norm(local - np.column_stack([np.zeros((len(z), 2)), z]), axis=1) - radius
        best = np.minimum(best, d)
    return best


def test_the_shipped_slabs_carry_the_current_keys(talos, g1):
    for name, robot in (("talos", talos), ("g1", g1)):
        path = ss.SHIPPED / f"{name}-{ss.slab_key(robot, sc.LEG_SLAB)}.json"
        assert path.is_file(), (f"no shipped slab capsules for {name}'s current key: regenerate with "
                                f"planner.trajopt.scene_collision.write_slabs(robots.load_robot({name!r}))")


def test_the_scene_spheres_come_from_the_shipped_slabs_and_cover_the_legs(talos, monkeypatch):
    monkeypatch.setattr(sc, "_SCENE_SETS", {})

    def no_fit(*args):
        raise AssertionError("fitted although shipped")

    monkeypatch.setattr(sc, "slab_capsules", no_fit)
    sets = sc.scene_sets(talos)
    shipped = ss.shipped_slabs(talos, sc.LEG_SLAB)
    assert shipped is not None and len(shipped) == 10  # leg_1 to leg_5 a side (leg_6 holds the sole)
    points = link_points(talos)
    for link, capsules in shipped.items():
        assert _covered(points[link][1], capsules).max() <= 1e-9, link  # the slabs hold the link's geometry
        i = sets.links.index(link)  # and the scene spheres of the link are theirs
        spheres = sum(len(sc.Capsule(link, 0, M, length, r).spheres()[0]) for M, length, r in capsules)
        assert int(np.sum(sets.sphere_owner == i)) == spheres


def test_a_robot_without_a_shipped_file_is_fitted(talos, monkeypatch, tmp_path):
    monkeypatch.setattr(sc, "_SCENE_SETS", {})
    monkeypatch.setattr(ss, "SHIPPED", tmp_path)
    fitted: list[int] = []

    def fit(points, slab):
        fitted.append(len(points))
        return [(pin.SE3.Identity(), 0.0, 0.1)]

    monkeypatch.setattr(sc, "slab_capsules", fit)
    sc.scene_sets(talos)
    assert len(fitted) == 10


@pytest.mark.long
def test_the_shipped_slabs_equal_the_fit():
    # fast twins: test_the_shipped_slabs_carry_the_current_keys, test_the_scene_spheres_come_from_the_shipped_slabs_and_cover_the_legs
    for name in ("talos", "g1"):
        robot = load_robot(name)
        shipped = ss.shipped_slabs(robot, sc.LEG_SLAB)
        assert shipped is not None
        points = link_points(robot)
        for link, capsules in shipped.items():
            fit = sc.slab_capsules(points[link][1], sc.LEG_SLAB)
            assert len(fit) == len(capsules)
            for (M, length, r), (M2, length2, r2) in zip(fit, capsules, strict=True):
                assert np.array_equal(M.homogeneous, M2.homogeneous) and length == length2 and r == r2, link
