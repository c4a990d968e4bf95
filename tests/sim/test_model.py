"""The MuJoCo model built from the URDF matches the Pinocchio model it comes from."""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from sim import build_model
from tasks.scene import Scene, SceneObject

# a scene with something to grasp: talos's fingers move in it (sim/grasp.py)
GRASPABLE = Scene(name="a cup", objects=(SceneObject(name="cup", shape="cylinder", size=(0.04, 0.1),
                                                     position=(0.5, 0.0, 0.05), movable=True, mass=0.2),))


@pytest.fixture(scope="module")
def talos_sim(talos):
    return build_model(talos)


def test_free_joint_and_sizes(talos, talos_sim):
    """The root becomes a free joint; nq/nv and actuator count match Pinocchio (no scene: the
    fingers stay fixed, as in Pinocchio)."""
    m = talos_sim.model
    assert m.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE
    assert (m.nq, m.nv) == (talos.nq, talos.nv)
    assert m.nu == talos.nv - 6
    assert m.opt.timestep == pytest.approx(0.001)


def test_actuator_limits_are_urdf_effort_limits(talos, talos_sim):
    """Each actuator saturates at its joint's URDF effort limit."""
    m = talos_sim.model
    ranges = m.actuator_ctrlrange[talos_sim.actuator_index]
    np.testing.assert_allclose(ranges[:, 1], talos.torque_limits)
    np.testing.assert_allclose(ranges[:, 0], -talos.torque_limits)
    assert bool(np.all(m.actuator_ctrllimited))


def test_floor_and_sole_friction_from_profile(talos, talos_sim):
    """Floor and soles use the profile's friction coefficient."""
    m = talos_sim.model
    mu = talos.profile.friction_coefficient
    assert m.geom_friction[talos_sim.floor_geom, 0] == pytest.approx(mu)
    for g in talos_sim.sole_geoms.values():
        assert m.geom_friction[g, 0] == pytest.approx(mu)


def test_state_round_trip_and_kinematics(talos, talos_sim, rng):
    """A Pinocchio state written to MuJoCo reads back exactly; mass, CoM and soles agree."""
    d = talos_sim.data()
    q = pin.integrate(talos.model, talos.q_standing, 0.1 * rng.standard_normal(talos.nv))
    v = rng.standard_normal(talos.nv)
    talos_sim.set_state(d, q, v)
    q2, v2 = np.zeros(talos.nq), np.zeros(talos.nv)
    talos_sim.state(d, q2, v2)
    np.testing.assert_allclose(q2, q, atol=1e-12)
    np.testing.assert_allclose(v2, v, atol=1e-12)
    data = talos.data()
    assert talos_sim.model.body_subtreemass[1] == pytest.approx(talos.mass, rel=1e-6)  # + 1 mg per massless link
    np.testing.assert_allclose(d.subtree_com[1], pin.centerOfMass(talos.model, data, q), atol=1e-7)
    # MuJoCo's base-frame-mapped velocity gives Pinocchio's kinetic energy
    pin.computeAllTerms(talos.model, data, q, v)
    mujoco.mj_forward(talos_sim.model, d)
    mv = np.zeros(talos_sim.model.nv)  # (the fingers' dofs at rest: they move with their hand, as in Pinocchio)
    mujoco.mj_mulM(talos_sim.model, d, mv, d.qvel)
    assert 0.5 * d.qvel @ mv == pytest.approx(0.5 * v @ data.M @ v, rel=1e-6)


def test_sole_boxes_sit_on_the_sole_frames(talos, talos_sim):
    """At the standing posture the sole boxes' bottom faces lie on z = 0 under the sole frames."""
    d = talos_sim.data()
    talos_sim.set_state(d, talos.q_standing)
    for role, g in talos_sim.sole_geoms.items():
        corners = talos.sole_corners_in_world(talos.q_standing, role.split("_")[0])
        centre = d.geom_xpos[g]
        half = talos_sim.model.geom_size[g]
        np.testing.assert_allclose(centre[:2], corners[:, :2].mean(axis=0), atol=1e-9)
        assert centre[2] - half[2] == pytest.approx(0.0, abs=1e-9)


def test_robot_geoms_touch_only_the_floor(talos_sim):
    """Self-collision is off: robot geoms have contype/conaffinity that only pair with the floor."""
    m = talos_sim.model
    robot = [
        g
        for g in range(m.ngeom)
        if g != talos_sim.floor_geom and (m.geom_contype[g] or m.geom_conaffinity[g])
    ]
    for g1 in robot[:10]:
        for g2 in robot:
            assert not (m.geom_contype[g1] & m.geom_conaffinity[g2])
        assert m.geom_contype[g1] & m.geom_conaffinity[talos_sim.floor_geom]


def test_joint_friction_switch(talos, talos_sim):
    """By default the URDF's joint damping/friction are simulated; joint_friction=False removes them."""
    m = talos_sim.model
    dofs = talos_sim.dof_index
    assert m.dof_damping[dofs].max() > 0 and m.dof_frictionloss[dofs].max() > 0
    bare = build_model(talos, joint_friction=False).model
    assert bare.dof_damping.max() == 0.0 and bare.dof_frictionloss.max() == 0.0


def test_every_builtin_robot_compiles(any_robot):
    """Talos, G1, Romeo and iCub all become MuJoCo models (Collada meshes rebuilt, bad inertias
    repaired) whose mass and CoM match Pinocchio's. In a scene with something to grasp, MuJoCo's
    only extra joints are hinges that a joint equality couples to a Pinocchio joint (talos's
    fingers, 6 a hand: sim/grasp.py); without one there are none (test_free_joint_and_sizes)."""
    sm = build_model(any_robot, scene=GRASPABLE if any_robot.name == "talos" else None)
    m = sm.model
    names = set(any_robot.model.names)
    free = [j for j in range(1, m.njnt) if int(m.jnt_type[j]) == int(mujoco.mjtJoint.mjJNT_FREE)]  # the cup's
    assert len(free) == (1 if any_robot.name == "talos" else 0)
    extra = [j for j in range(m.njnt) if m.joint(j).name not in names and j != 0 and j not in free]
    for j in extra:
        assert int(m.jnt_type[j]) == int(mujoco.mjtJoint.mjJNT_HINGE)
        (e,) = [e for e in range(m.neq) if int(m.eq_type[e]) == int(mujoco.mjtEq.mjEQ_JOINT) and int(m.eq_obj1id[e]) == j]
        assert m.joint(int(m.eq_obj2id[e])).name in names
    assert len(extra) == (12 if any_robot.name == "talos" else 0)
    assert (m.nq, m.nv) == (any_robot.nq + len(extra) + 7 * len(free), any_robot.nv + len(extra) + 6 * len(free))
    assert sm.model.body_subtreemass[1] == pytest.approx(any_robot.mass, rel=1e-5)
    d = sm.data()
    sm.set_state(d, any_robot.q_standing)
    com = pin.centerOfMass(any_robot.model, any_robot.data(), any_robot.q_standing)
    np.testing.assert_allclose(d.subtree_com[1], com, atol=1e-4)
