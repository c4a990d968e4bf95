"""The self-collision line on the URDF meshes (sim/meshcheck.py): every link pair the planner's
collision model leaves out, checked with coal on sampled configurations."""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin
import pytest

import sim.loop as loop
from planner.results import CheckKind
from sim import SimSettings, simulate
from sim.handmade import joint_plan, standing_plan
from sim.meshcheck import MeshPairs, mesh_self_collision_check

#: Talos's left hand swung into its left hip (tests/sim/test_collisions.py): the gripper's meshes
#: are inside the hip's at the top of the bump.
HAND_INTO_HIP = {"arm_left_1_joint": -0.75, "arm_left_2_joint": 0.1, "arm_left_3_joint": -1.2,
                 "arm_left_4_joint": -0.33}


@pytest.fixture(scope="module")
def standing_run(talos):
    seen = {}
    certify = loop.certify

    def keep(run, objects=None):
        seen["run"] = run
        return certify(run, objects)

    loop.certify = keep
    try:
        ex = simulate(standing_plan(talos, duration=1.0), talos, settings=SimSettings(settle_time=0.1))
    finally:
        loop.certify = certify
    return ex, seen["run"]


def test_standing_passes_and_the_line_is_in_the_certificate(standing_run):
    ex, _ = standing_run
    (line,) = [c for c in ex.certificate.checks if c.kind is CheckKind.SELF_COLLISION_MESH]
    assert line.ok and "more pairs apart" in line.name


def test_hand_through_hip_is_found_on_the_meshes(talos, standing_run):
    """The hand-into-hip motion, checked on every pair (none left to the collision model): the line
    fails where coal finds the meshes passing into each other deeper than the 5 mm limit, naming
    the gripper and the hip link; an independent all-pairs coal check of the full collision model
    (Pinocchio's computeCollisions) finds those meshes intersecting there, and not before the
    first configuration it finds touching."""
    _, run = standing_run
    plan = joint_plan(talos, HAND_INTO_HIP, duration=3.0, name="hand into hip")
    moved = dataclasses.replace(run, t=np.asarray(plan.t), q=np.asarray(plan.q), collision_pairs=())
    line = mesh_self_collision_check(moved, period=0.05)
    assert not line.ok and line.kind is CheckKind.SELF_COLLISION_MESH
    assert "leg_left_3_link" in line.message and "gripper_left" in line.message, line.message

    gmodel = talos.collision_model.copy()
    gmodel.addAllCollisionPairs()
    gdata = gmodel.createData()
    data = talos.model.createData()
    model = talos.model
    objs = gmodel.geometryObjects
    base = MeshPairs(talos, plan.q[0])
    at_rest = {(base.links[p.first], base.links[p.second]) for p in base.gmodel.collisionPairs}

    def touching(q) -> bool:
        pin.computeCollisions(model, data, gmodel, gdata, q, False)
        for k, cp in enumerate(gmodel.collisionPairs):
            a, b = objs[cp.first], objs[cp.second]
            names = (model.frames[a.parentFrame].name, model.frames[b.parentFrame].name)
            if gdata.collisionResults[k].isCollision() and (names in at_rest or names[::-1] in at_rest):
                return True
        return False

    first = next(float(t) for t, q in zip(plan.t, plan.q, strict=True) if touching(q))
    assert first - 0.051 <= line.time  # never before the meshes touch
    assert touching(plan.q[int(np.argmin(np.abs(plan.t - line.time)))])  # and they do where it says
    assert line.value < line.limit  # deeper than the limit [mm, negative]
