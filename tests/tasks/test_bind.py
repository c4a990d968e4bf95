"""``tasks.bind``: the one step where a spec meets a robot. Roles become the robot's frame names
(checked against the URDF's frames through Pinocchio, not the profile), a spec that names frames
comes back as the same object, and what the robot lacks is refused naming the field."""

from __future__ import annotations

import dataclasses

import pytest

from language import parse
from tasks import FrameTarget, TaskDefinitionError, bind, compile_actions, fit_actions
from tasks.serialize import spec_to_json


@pytest.fixture(scope="module")
def clap(talos):
    """A wave whose hand target is said to meet the other hand (the clap's self-contact)."""
    wave = compile_actions(fit_actions(parse("wave your right hand").actions, talos), talos)
    first = dataclasses.replace(wave.targets[0], meets=talos.frame("left_hand"))
    return dataclasses.replace(wave, targets=(first, *wave.targets[1:]))


def _roles(robot, spec):
    """The spec with each frame it names written as a role, wherever the profile has one for it."""
    role_of = {name: role for role, name in robot.profile.frames}

    def swap(item, *fields):
        changes = {f: role_of[getattr(item, f)] for f in fields if getattr(item, f) in role_of}
        return dataclasses.replace(item, **changes)

    phases = tuple(dataclasses.replace(p, contacts=tuple(swap(c, "frame") for c in p.contacts)) for p in spec.phases)
    return dataclasses.replace(spec, phases=phases, targets=tuple(swap(t, "frame", "meets") for t in spec.targets))


def test_a_spec_naming_frames_comes_back_as_the_same_object(talos, clap):
    assert bind(clap, talos) is clap


def test_roles_become_the_urdf_frame_names(talos, clap):
    by_role = _roles(talos, clap)
    named = {c.frame for p in by_role.phases for c in p.contacts} | {t.frame for t in by_role.targets}
    assert {"left_foot", "right_foot", "right_hand"} <= named and by_role.targets[0].meets == "left_hand"  # the test exercises roles
    bound = bind(by_role, talos)
    assert bound == clap and spec_to_json(bound) == spec_to_json(clap)  # the cache keys do not change
    frames = {talos.model.frames[i].name for i in range(talos.model.nframes)}
    for p in bound.phases:
        assert {c.frame for c in p.contacts} <= frames
    assert {t.frame for t in bound.targets} | {t.meets for t in bound.targets if t.meets} <= frames


def test_a_frame_the_robot_lacks_is_refused_naming_the_field(talos, clap):
    bad = dataclasses.replace(clap, targets=(*clap.targets, FrameTarget(
        name="tail", frame="tail_link", position=(0.3, 0.0, 1.0))))
    with pytest.raises(TaskDefinitionError, match=rf"spec.targets\[{len(clap.targets)}\].frame: .*tail_link"):
        bind(bad, talos)
    meets = dataclasses.replace(clap, targets=(dataclasses.replace(clap.targets[0], meets="third_hand"),
                                               *clap.targets[1:]))
    with pytest.raises(TaskDefinitionError, match=r"spec.targets\[0\].meets: .*third_hand"):
        bind(meets, talos)
