"""Friction per surface in MuJoCo (issue 33): a contact of the robot with the world takes the surface's
own friction coefficient, not the larger of the two geoms' (MuJoCo's rule without priorities), so a
surface less grippy than the soles is as slippery in the simulation as in the plan
(:func:`tasks.terrain.with_surface_friction`). The figures are MuJoCo's own contacts, read after
``mj_forward`` with G1 standing: its soles on a floor of one friction and on a slab of another,
and a free box on the floor (two world geoms: the larger of theirs, as :mod:`tasks.primitives.push`
assumes). The plan's side: ``tests/tasks/test_surface_friction.py``.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from sim.model import FLOOR, OBJECT_PREFIX, build_model
from tasks.scene import Scene, SceneObject

FLOOR_MU, SLAB_MU, BOX_MU = 0.4, 0.3, 0.9  # all unlike G1's profile 0.7


@pytest.fixture(scope="module")
def contacts(g1):
    data_pin = g1.model.createData()
    pin.framesForwardKinematics(g1.model, data_pin, g1.q_standing)
    right = data_pin.oMf[g1.model.getFrameId(g1.frame("right_foot"))].translation
    slab = SceneObject(name="slab", shape="box", size=(0.4, 0.25, 0.02), position=(right[0], right[1] - 0.05, -0.01),
                       friction=SLAB_MU, walkable=True)
    box = SceneObject(name="box", shape="box", size=(0.2, 0.2, 0.2), position=(0.8, 0.0, 0.1), movable=True,
                      mass=1.0, friction=BOX_MU)
    sim = build_model(g1, scene=Scene(objects=(slab, box), floor_friction=FLOOR_MU))
    data = sim.data()
    q = np.array(g1.q_standing)
    q[2] -= 1e-3  # the soles 1 mm into the floor and the slab: MuJoCo reports their contacts
    sim.set_state(data, q)
    model = sim.model
    name = {g: model.geom(g).name for g in range(model.ngeom)}
    out: dict[tuple[str, str], list[float]] = {}
    for c in data.contact[: data.ncon]:
        a, b = sorted((name[int(c.geom1)], name[int(c.geom2)]))
        out.setdefault((a, b), []).append(float(c.friction[0]))
    return out


def _touching(contacts, sole_side: str, world: str) -> list[float]:
    return [mu for (a, b), mus in contacts.items() for mu in mus
            if world in (a, b) and any(sole_side in n and "sole" in n for n in (a, b))]


def test_a_sole_on_the_floor_takes_the_floors_friction(contacts):
    mus = _touching(contacts, "left", FLOOR)
    assert mus and np.allclose(mus, FLOOR_MU), contacts  # not max(0.4, 0.7) = 0.7


def test_a_sole_on_a_slab_takes_the_slabs_friction(contacts):
    mus = _touching(contacts, "right", OBJECT_PREFIX + "slab")
    assert mus and np.allclose(mus, SLAB_MU), contacts


def test_two_world_bodies_take_the_larger_of_their_frictions(contacts):
    mus = [mu for (a, b), m in contacts.items() for mu in m if {a, b} == {FLOOR, OBJECT_PREFIX + "box"}]
    assert mus and np.allclose(mus, max(BOX_MU, FLOOR_MU)), contacts
