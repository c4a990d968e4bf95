"""A hand's contact in the controller (leaning on a table): its friction pyramids take the region
contact's friction when it is lower than the robot profile's (a thigh on a 0.8 seat keeps the
profile's 0.7), and its force variables are in a quarter of the unit, so the QP's regularization
keeps the weight on the feet (with the sole's unit it loaded talos's hands until a wrist saturated)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin
import pytest

from planner.wbc import WholeBodyController
from planner.wbc import controller as wbc_controller
from robots import pyramid_coefficient
from sim.handmade import standing_plan
from tasks.specs import Contact, Pose


def _tick(talos, friction: float) -> WholeBodyController:
    """One tick on a standing plan whose left hand also holds a contact where it hangs."""
    plan = standing_plan(talos, duration=1.0, dt=0.05)
    data = talos.model.createData()
    q, v = np.array(talos.q_standing, dtype=float), np.zeros(talos.nv)
    pin.framesForwardKinematics(talos.model, data, q)
    M = data.oMf[talos.frame_id("left_hand")]
    pad = Contact(frame=talos.frame("left_hand"), placement=Pose(position=tuple(M.translation),
                                                                 rpy=tuple(pin.rpy.matrixToRpy(M.rotation))),
                  friction_coefficient=friction, normal=(0.0, 0.0, 1.0),
                  region=((0.0, 0.0, 0.0), (0.01, 0.0, 0.0), (0.01, 0.01, 0.0), (0.0, 0.01, 0.0)))
    phases = tuple(dataclasses.replace(p, contacts=(*p.contacts, pad)) for p in plan.spec.phases)
    plan = dataclasses.replace(plan, spec=dataclasses.replace(plan.spec, phases=phases))
    ctrl = WholeBodyController(talos)
    ctrl.reset(q, v)
    ctrl.compute(0.0, q, v, plan)
    return ctrl


def test_a_region_contact_with_less_friction_narrows_the_controllers_pyramids(talos):
    assert _tick(talos, 0.18)._mu == pytest.approx(pyramid_coefficient(0.18))
    assert _tick(talos, 0.8)._mu == pytest.approx(pyramid_coefficient(talos.profile.friction_coefficient))


def test_a_hands_force_costs_more_so_the_feet_carry_the_weight(talos, monkeypatch):
    hand = talos.model.frames[talos.frame_id("left_hand")].name

    def share() -> float:
        f = _tick(talos, 0.6).contact_forces()
        return float(f[hand][2] / sum(x[2] for x in f.values()))

    quarter = share()
    monkeypatch.setattr(wbc_controller, "HAND_FORCE_UNIT", 1.0)
    alike = share()
    assert alike > 0.07 and quarter < alike / 3  # talos: 10 % of the weight on the hand, then 2.5 %
