"""The certificate's scene-collision line on a synthetic stairs run, without MuJoCo: a foot planned on
a tread touches it (planned), the same foot on it before its step or a hand on it does not.

The run is 4 s at 1 kHz with the right sole on ``stairs.1`` twice at every tick of its stance; the
references are the contacts put in by hand. (The line searched its list of planned contacts for each
contact, quadratic: 6 minutes of the first climb's certificate; now one flag per contact.) The climb
in MuJoCo: ``tests/sim/test_stairs_climb.py`` (long).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from sim.certify import scene_collision_check
from tasks.primitives.geometry import Stance
from tasks.scene import load_scene
from tasks.specs import Contact, Phase, Pose, TaskSpec

STAIRS = Path(__file__).resolve().parents[2] / "examples" / "scenes" / "stairs.json"
N = 4_000  # ticks: 4 s at 1 kHz


@dataclass(frozen=True)
class Run:
    robot: object
    ref: object
    settings: object
    t: np.ndarray
    object_names: tuple[str, ...]
    scene_contacts: tuple = ()
    scene_samples: tuple = ()


@pytest.fixture(scope="module")
def climb(talos):
    scene = load_scene(STAIRS)
    st = Stance.standing(talos)
    left, right = (Contact(frame=talos.frame(f"{s}_foot"), placement=st.sole(s)) for s in ("left", "right"))
    x, y, _ = st.sole("right").position
    on_tread = Contact(frame=right.frame, placement=Pose(position=(0.3, y, 0.1)))
    spec = TaskSpec(robot="talos", scene=scene, phases=(
        Phase(name="stand", duration=2.0, contacts=(left, right)),
        Phase(name="right foot on the first tread", duration=2.0, contacts=(left, on_tread))))
    ref = SimpleNamespace(plan=SimpleNamespace(spec=spec, t=np.array([0.0, 4.0])))
    return Run(robot=talos, ref=ref, settings=SimpleNamespace(scene_distance_horizon=0.3), t=np.arange(N) * 1e-3,
               object_names=tuple(o.name for o in scene.objects)), right.frame


def test_a_foot_on_its_tread_is_planned(climb):
    run, foot = climb
    contacts = tuple((k, foot, "stairs.1", -0.001) for k in range(N // 2, N) for _ in (0, 1))
    samples = tuple((k, foot, "stairs.1", 0.0) for k in range(N // 2, N, 10))
    check = scene_collision_check(Run(**{**run.__dict__, "scene_contacts": contacts, "scene_samples": samples}))
    assert check.ok and "planned touch: right sole link / 'stairs.1' at t = 2.00 s" in check.name
    tread = contacts[:10] + ((3_000, foot, "stairs.2", -0.001),)  # the next tread's riser: not planned
    check = scene_collision_check(Run(**{**run.__dict__, "scene_contacts": tread}))
    assert not check.ok and check.time == pytest.approx(3.0) and "stairs.2" in check.name


def test_the_foot_on_the_tread_before_its_step_and_a_hand_on_it_are_not(climb):
    run, foot = climb
    early = ((1_000, foot, "stairs.1", -0.002),)
    check = scene_collision_check(Run(**{**run.__dict__, "scene_contacts": early}))
    assert not check.ok and check.time == pytest.approx(1.0) and "-2" in f"{check.value:.0f}"
    hand = ((3_000, run.robot.frame("right_hand"), "stairs.1", -0.003),)
    check = scene_collision_check(Run(**{**run.__dict__, "scene_contacts": hand}))
    assert not check.ok and check.time == pytest.approx(3.0)
