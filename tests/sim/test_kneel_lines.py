"""The certificate's region-contact lines (:mod:`sim.seat`) for a knee on the floor, on synthetic runs
without MuJoCo (the runs of ``tests/sim/test_seat_lines.py``): the floor is the knee's object (no
scene), its MuJoCo floor touches count for the contact time, the unplanned-contact line lets the
knee and its thigh touch the floor while the plan holds the knee, and nothing else. Fast twin (with
``tests/tasks/test_kneel.py``) of ``tests/sim/test_kneel.py``."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from planner import CheckKind
from sim.certify import unplanned_contacts_check
from sim.seat import floor_touch_planned, seat_checks
from tasks.primitives.geometry import Stance
from tasks.primitives.kneel import kneeling
from tasks.specs import Contact, Phase, TaskSpec
from tests.sim.test_seat_lines import N, _lines, _run


@pytest.fixture(scope="module")
def knelt(talos):
    k = kneeling(talos, Stance.standing(talos), "right")
    left = Contact(frame=talos.frame("left_foot"), placement=Stance.standing(talos).sole("left"))
    spec = TaskSpec(robot="talos", phases=(Phase(name="kneeling", duration=1.0, contacts=(left, k.contact)),))
    return SimpleNamespace(q=k.q, contacts=(k.contact,)), spec


def _floor_run(talos, k, spec, touches, *, held=slice(None)):
    """The run of ``_run`` with MuJoCo floor touches ``(tick, link)`` and the plan holding the knee over
    ``held`` of the 1 s (two plan samples 0.5 s apart: sample 0 is t < 0.5 s)."""
    run = _run(talos, k, spec, contacts=[])
    active = np.ones((2, 2), dtype=bool)
    active[:, 1] = False
    active[held, 1] = True
    run.ref.active = active
    run.ref.dt = 0.5
    run.ref.plan.t = np.array([0.0, 0.5])
    run.other_contacts = tuple((float(run.t[i]), link) for i, link in touches)
    run.foot_frames = ("left_sole_link", "right_sole_link")
    run.contact_flags = np.zeros((2, N), dtype=bool)
    return run


def test_a_knee_on_the_floor_gets_where_slip_and_time_lines_and_no_others_line(talos, knelt):
    k, spec = knelt
    knee = k.contacts[0].frame
    lines = _lines(seat_checks(_floor_run(talos, k, spec, [(i, knee) for i in range(N)])))
    assert set(lines) == {(CheckKind.SEAT_PLACEMENT, knee), (CheckKind.SEAT_SLIP, knee), (CheckKind.SEAT_CONTACT, knee)}
    assert all(c.ok for c in lines.values())
    assert lines[(CheckKind.SEAT_CONTACT, knee)].name == f"{knee} on the floor: contact time"
    assert lines[(CheckKind.SEAT_CONTACT, knee)].value == pytest.approx(1.0)
    half = _lines(seat_checks(_floor_run(talos, k, spec, [(i, knee) for i in range(0, N, 2)])))
    assert half[(CheckKind.SEAT_CONTACT, knee)].value == pytest.approx(0.5, abs=0.01)
    assert not half[(CheckKind.SEAT_CONTACT, knee)].ok


def test_only_the_held_knee_and_its_thigh_may_touch_the_floor(talos, knelt):
    k, spec = knelt
    knee = k.contacts[0].frame
    touches = [(600, knee), (700, "leg_right_3_link"), (800, "torso_2_link"), (900, "leg_right_6_link")]
    run = _floor_run(talos, k, spec, touches)
    assert floor_touch_planned(run) == [True, True, False, False]  # the torso and the lifted foot are not planned
    meas: Any = SimpleNamespace(knots=np.zeros(N, dtype=int))  # the one field the line reads
    line = unplanned_contacts_check(run, meas)
    assert not line.ok and line.value == 2.0 and "torso_2_link touched the floor at t = 0.80 s" in line.message
    clean = unplanned_contacts_check(_floor_run(talos, k, spec, touches[:2]), meas)
    assert clean.ok
    early = _floor_run(talos, k, spec, [(100, knee)], held=slice(1, 2))  # held from 0.5 s: a touch at 0.1 s is not
    assert floor_touch_planned(early) == [False]
    assert not unplanned_contacts_check(early, meas).ok
