"""The certificate's region-contact lines (:mod:`sim.seat`) for hands on a table, on synthetic runs
without MuJoCo (the runs of ``tests/sim/test_seat_lines.py``): the touches of a gripper's other
finger count as its hand's, an arm link on the table is allowed, the torso is not. Fast twin (with
``tests/tasks/test_lean.py``) of ``tests/sim/test_lean.py``."""

from __future__ import annotations

from pathlib import Path

import pytest

from planner import CheckKind
from sim.seat import seat_checks
from tasks.primitives.geometry import Stance
from tasks.primitives.lean import leaning
from tasks.scene import load_scene
from tasks.specs import Phase, TaskSpec
from tests.sim.test_seat_lines import N, _feet, _lines, _run

TABLE = Path(__file__).resolve().parents[2] / "examples" / "scenes" / "table.json"


@pytest.fixture(scope="module")
def leant(talos):
    scene = load_scene(TABLE)
    s = leaning(talos, Stance.standing(talos), scene.objects[0])
    spec = TaskSpec(robot="talos", phases=(Phase(name="leaning", duration=1.0, contacts=(*_feet(talos), *s.contacts)),),
                    scene=scene)
    return s, spec


def test_a_hands_fingers_count_as_the_hand_an_arm_may_touch_the_torso_may_not(talos, leant):
    s, spec = leant
    assert [c.frame for c in s.contacts] == ["gripper_left_fingertip_3_link", "gripper_right_fingertip_3_link"]
    touch = [(i, s.contacts[1].frame, "table", -0.001) for i in range(N)]
    touch += [(i, s.contacts[0].frame, "table", -0.001) for i in range(0, N, 2)]  # the left fingertip half the ticks,
    touch += [(i, "gripper_left_fingertip_2_link", "table", -0.001) for i in range(1, N, 2)]  # its other finger the rest
    lines = _lines(seat_checks(_run(talos, s, spec, contacts=touch)))
    assert len(lines) == 7 and all(c.ok for c in lines.values())
    assert lines[(CheckKind.SEAT_CONTACT, s.contacts[0].frame)].value == pytest.approx(1.0)  # 500 + 500 ticks
    alone = [t for t in touch if t[1] != "gripper_left_fingertip_2_link"]
    half = _lines(seat_checks(_run(talos, s, spec, contacts=alone)))[(CheckKind.SEAT_CONTACT, s.contacts[0].frame)]
    assert half.value == pytest.approx(0.5, abs=0.01) and not half.ok
    others = lines[(CheckKind.SEAT_CONTACT, "others")]
    assert others.name == "only the planned links (and their arms) touch the table"
    arm = touch + [(500, "arm_left_5_link", "table", 0.0)]
    assert _lines(seat_checks(_run(talos, s, spec, contacts=arm)))[(CheckKind.SEAT_CONTACT, "others")].ok
    torso = touch + [(500, "torso_2_link", "table", 0.0)]
    bad = _lines(seat_checks(_run(talos, s, spec, contacts=torso)))[(CheckKind.SEAT_CONTACT, "others")]
    assert not bad.ok and "torso_2_link touched the table at t = 0.50 s" in bad.message
