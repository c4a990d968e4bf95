"""The controller's friction pyramids take a region contact's friction when it is lower than the
robot profile's (hands on a table: 0.18), and the profile's otherwise (a thigh on a 0.8 seat)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from planner.wbc import WholeBodyController
from robots import pyramid_coefficient
from sim.handmade import standing_plan
from tasks.specs import Contact, Pose


def _mu(talos, friction: float) -> float:
    plan = standing_plan(talos, duration=1.0, dt=0.05)
    pad = Contact(frame=talos.frame("left_hand"), placement=Pose(position=(0.4, 0.4, 0.7), rpy=(0.0, 0.0, 0.0)),
                  friction_coefficient=friction, region=((0.0, 0.0, 0.0), (0.01, 0.0, 0.0), (0.01, 0.01, 0.0), (0.0, 0.01, 0.0)),
                  normal=(0.0, 0.0, 1.0))
    phases = tuple(dataclasses.replace(p, contacts=(*p.contacts, pad)) for p in plan.spec.phases)
    plan = dataclasses.replace(plan, spec=dataclasses.replace(plan.spec, phases=phases))
    ctrl = WholeBodyController(talos)
    q, v = np.array(talos.q_standing, dtype=float), np.zeros(talos.nv)
    ctrl.reset(q, v)
    ctrl.compute(0.0, q, v, plan)
    return ctrl._mu


def test_a_region_contact_with_less_friction_narrows_the_controllers_pyramids(talos):
    assert _mu(talos, 0.18) == pytest.approx(pyramid_coefficient(0.18))
    assert _mu(talos, 0.8) == pytest.approx(pyramid_coefficient(talos.profile.friction_coefficient))
