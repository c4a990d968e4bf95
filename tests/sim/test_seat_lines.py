"""The certificate's seat lines (:mod:`sim.seat`) on synthetic runs, without MuJoCo: the fast twin of
``tests/sim/test_sit.py`` (talos sits on ``examples/scenes/chair.json``, certified).

A run here is the sitting configuration of :func:`tasks.primitives.seat.sitting` held for 1 s at
1 kHz, with the thighs' MuJoCo contacts given by hand; the references are the numbers put in (a 3 cm
shift, a 2 cm slide, no contact, a shin on the seat), not the module's arithmetic.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pinocchio as pin
import pytest

from planner import CheckKind
from sim.seat import hip_links, seat_checks
from tasks.primitives.geometry import Stance
from tasks.primitives.seat import sitting
from tasks.scene import load_scene
from tasks.specs import Phase, TaskSpec

CHAIR = Path(__file__).resolve().parents[2] / "examples" / "scenes" / "chair.json"
N = 1000  # ticks (1 s at 1 kHz)


@pytest.fixture(scope="module")
def seated(talos):
    scene = load_scene(CHAIR)
    s = sitting(talos, Stance.standing(talos), scene.objects[0])
    feet = tuple(c for c in _feet(talos))
    spec = TaskSpec(robot="talos", phases=(Phase(name="sitting", duration=1.0, contacts=feet + s.contacts),),
                    scene=scene)
    return s, spec


def _feet(robot):
    from tasks.specs import Contact

    st = Stance.standing(robot)
    return [Contact(frame=robot.frame(f"{side}_foot"), placement=st.sole(side)) for side in ("left", "right")]


def _run(talos, s, spec, *, shift=0.0, slide=0.0, contacts=None):
    """A synthetic run: the sitting q (its base shifted along x by ``shift`` [m], sliding by ``slide``
    [m] over the second), the plan holding every contact at every sample."""
    model, data = talos.model, talos.model.createData()
    q = np.tile(s.q, (N, 1))
    q[:, 0] += shift + slide * np.linspace(0.0, 1.0, N)
    pin.framesForwardKinematics(model, data, s.q)
    frames = [c.frame for c in spec.phases[0].contacts]
    planned = {f: SimpleNamespace(position=np.tile(data.oMf[talos.frame_id(f)].translation, (2, 1)),
                                  rotation=np.tile(data.oMf[talos.frame_id(f)].rotation, (2, 1, 1))) for f in frames}
    ref = SimpleNamespace(plan=SimpleNamespace(spec=spec), index=lambda t: 0 if t < 0.5 else 1,
                          active=np.ones((2, len(frames)), dtype=bool), contact_frames=tuple(frames), frames=planned)
    if contacts is None:
        contacts = [(i, c.frame, "chair", -0.001) for i in range(N) for c in s.contacts]
    return SimpleNamespace(robot=talos, ref=ref, t=np.arange(N) * 1e-3, q=q, scene_contacts=tuple(contacts),
                           settings=SimpleNamespace(placement_limit=0.02, slip_limit=0.01))


def _lines(checks):
    return {(c.kind, c.subject): c for c in checks}


def test_a_seated_run_passes_every_seat_line(talos, seated):
    s, spec = seated
    lines = _lines(seat_checks(_run(talos, s, spec)))
    assert len(lines) == 7 and all(c.ok for c in lines.values())
    for c in s.contacts:
        assert lines[(CheckKind.SEAT_PLACEMENT, c.frame)].value == pytest.approx(0.0, abs=1e-9)
        assert lines[(CheckKind.SEAT_CONTACT, c.frame)].value == pytest.approx(1.0)


def test_a_shift_a_slide_no_contact_and_a_shin_on_the_seat_fail(talos, seated):
    s, spec = seated
    thigh = s.contacts[0].frame
    shifted = _lines(seat_checks(_run(talos, s, spec, shift=0.03)))
    assert shifted[(CheckKind.SEAT_PLACEMENT, thigh)].value == pytest.approx(0.03, abs=1e-6)
    assert not shifted[(CheckKind.SEAT_PLACEMENT, thigh)].ok
    slid = _lines(seat_checks(_run(talos, s, spec, slide=0.02)))
    assert slid[(CheckKind.SEAT_SLIP, thigh)].value == pytest.approx(0.02, abs=1e-6)
    assert not slid[(CheckKind.SEAT_SLIP, thigh)].ok and "slipped 0.020 m on the chair" in slid[(CheckKind.SEAT_SLIP, thigh)].message
    apart = _lines(seat_checks(_run(talos, s, spec, contacts=[])))
    assert apart[(CheckKind.SEAT_CONTACT, thigh)].value == 0.0 and not apart[(CheckKind.SEAT_CONTACT, thigh)].ok
    shin = [(i, c.frame, "chair", -0.001) for i in range(N) for c in s.contacts] + [(500, "leg_left_4_link", "chair", 0.0)]
    other = _lines(seat_checks(_run(talos, s, spec, contacts=shin)))[(CheckKind.SEAT_CONTACT, "others")]
    assert not other.ok and "leg_left_4_link touched the chair at t = 0.50 s" in other.message
    hips = [(i, c.frame, "chair", -0.001) for i in range(N) for c in s.contacts] + [(500, "leg_left_1_link", "chair", 0.0)]
    assert _lines(seat_checks(_run(talos, s, spec, contacts=hips)))[(CheckKind.SEAT_CONTACT, "others")].ok


def test_the_hip_links_of_a_thigh_and_no_lines_without_a_seat(talos, seated):
    s, spec = seated
    run = _run(talos, s, spec)
    assert hip_links(run, "leg_left_3_link") == {"leg_left_1_link", "leg_left_2_link"}  # talos's URDF, by hand
    bare = dataclasses.replace(spec, scene=None)
    assert seat_checks(_run(talos, s, bare)) == []
