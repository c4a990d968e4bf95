"""Feed-forward joint friction (planner/wbc/friction.py) against the URDF's own ``<dynamics
damping friction>`` tags, read here with an XML parser (the simulation keeps exactly these,
sim/model.py), not through Pinocchio."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pinocchio as pin

from planner.wbc.friction import RETURN_RATE, JointFriction

SCALE = 0.8


def _urdf_friction(robot):
    """(damping, Coulomb friction, joint names) of the actuated joints, from the URDF text."""
    tags = {}
    for joint in ET.parse(robot.urdf_path).getroot().findall("joint"):  # not the <transmission> ones
        dyn = joint.find("dynamics")
        tags[joint.get("name")] = (0.0, 0.0) if dyn is None else (float(dyn.get("damping", 0.0)),
                                                                  float(dyn.get("friction", 0.0)))
    names = [robot.model.names[j] for j in range(2, robot.model.njoints)]
    return np.array([tags[n][0] for n in names]), np.array([tags[n][1] for n in names]), names


def test_compensation_is_the_scaled_simulated_friction(talos):
    """Moving every joint at 1 rad/s along the plan the compensation is 0.8 x (damping * 1 +
    Coulomb friction) of the URDF (tanh saturated); a joint at rest on its plan gets none;
    a joint behind its plan is pushed towards it; Talos's head yaw gets 0.8 x 1 N m."""
    damping, coulomb, names = _urdf_friction(talos)
    assert coulomb[names.index("head_2_joint")] == 1.0 and coulomb[names.index("leg_left_4_joint")] == 0.0
    jf = JointFriction(talos, SCALE)
    q = talos.q_standing.copy()
    v_ref = np.zeros(talos.nv)
    v_ref[6:] = 1.0
    tau = jf.torques(q, np.zeros(talos.nv), q, v_ref)
    np.testing.assert_allclose(tau, SCALE * (damping + coulomb), rtol=1e-6, atol=1e-9)
    assert np.all(jf.torques(q, np.zeros(talos.nv), q, np.zeros(talos.nv)) == 0.0)
    behind = q.copy()
    dq = np.zeros(talos.nv)
    dq[6:] = -0.05  # the measured joints 0.05 rad below the plan
    behind = pin.integrate(talos.model, q, dq)
    tau = jf.torques(behind, np.zeros(talos.nv), q, np.zeros(talos.nv))
    w = RETURN_RATE * 0.05
    np.testing.assert_allclose(tau, SCALE * (damping * w + coulomb * np.tanh(w / 0.02)), rtol=1e-6, atol=1e-9)
    limits = 0.1 * np.ones(talos.nv - 6)
    clipped = jf.add(np.zeros(talos.nv - 6), q, np.zeros(talos.nv), q, v_ref, limits)
    assert np.all(np.abs(clipped) <= limits + 1e-12)


def test_no_friction_no_compensation(g1):
    """G1's URDF states no joint friction: nothing is added."""
    damping, coulomb, _ = _urdf_friction(g1)
    assert not damping.any() and not coulomb.any()
    jf = JointFriction(g1, SCALE)
    assert not jf.active
    tau = np.arange(g1.nv - 6, dtype=float)
    assert jf.add(tau, g1.q_standing, np.zeros(g1.nv), g1.q_standing, np.ones(g1.nv), np.full(g1.nv - 6, 1e3)) is tau
