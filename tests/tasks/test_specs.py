"""Task specs: validation on construction and exact JSON round-trip (hypothesis)."""

from __future__ import annotations

import json

import pytest
from hypothesis import given
from hypothesis import strategies as st

from tasks import (
    CoMBounds,
    CoMTarget,
    Contact,
    FrameTarget,
    JointTarget,
    Phase,
    Pose,
    Priority,
    TaskDefinitionError,
    TaskSpec,
    spec_from_dict,
    spec_from_json,
    spec_to_dict,
    spec_to_json,
)
from tasks.specs import MAX_KNOTS

coord = st.floats(-2.0, 2.0, allow_nan=False, allow_infinity=False)
vec3 = st.tuples(coord, coord, coord)
opt_vec3 = st.tuples(st.one_of(st.none(), coord), st.one_of(st.none(), coord), st.one_of(st.none(), coord))
names = st.text("abcdefgh_ ", min_size=1, max_size=8)


@st.composite
def specs(draw):
    """Random valid TaskSpecs: 1-4 phases with 0-2 contacts, targets inside the horizon."""
    n = draw(st.integers(1, 4))
    phases = []
    for i in range(n):
        frames = draw(st.lists(st.sampled_from(["left_foot", "right_foot"]), unique=True, max_size=2))
        contacts = tuple(
            Contact(frame=f, placement=Pose(position=draw(vec3), rpy=draw(vec3)),
                    friction_coefficient=draw(st.one_of(st.none(), st.floats(0.1, 2.0))))
            for f in frames
        )
        phases.append(Phase(name=f"p{i}", duration=draw(st.floats(0.1, 3.0)), contacts=contacts))
    horizon = sum(p.duration for p in phases)
    t = st.floats(0.0, horizon * 0.999)
    uniq = draw(st.lists(names, unique=True, min_size=4, max_size=4))
    targets = tuple(
        FrameTarget(name=uniq[0] + str(i), frame="right_hand", position=draw(vec3),
                    rpy=draw(st.one_of(st.none(), vec3)), time=draw(t),
                    priority=draw(st.sampled_from(list(Priority))), tolerance=draw(st.floats(0.0, 0.1)))
        for i in range(draw(st.integers(0, 2)))
    )
    lo = draw(opt_vec3)
    hi = tuple(None if v is None else v + 1.0 for v in lo)
    return TaskSpec(
        robot=draw(st.sampled_from(["talos", "g1"])),
        phases=tuple(phases),
        targets=targets,
        com_targets=(CoMTarget(name=uniq[1], position=(None, None, draw(coord))),),
        com_bounds=(CoMBounds(name=uniq[2], lower=lo, upper=hi, margin=draw(st.floats(0.0, 0.05))),),
        joint_targets=(JointTarget(name=uniq[3], joint="head_1_joint", value=draw(coord)),),
        dt=draw(st.floats(max(0.01, 1.01 * horizon / MAX_KNOTS), 0.2)),  # within the knot limit
        dynamic=draw(st.booleans()),
        description=draw(st.text(max_size=20)),
    )


@given(specs())
def test_spec_json_round_trip(spec):
    """spec_from_json(spec_to_json(s)) == s for every valid spec, through real JSON text."""
    assert spec_from_json(spec_to_json(spec)) == spec
    assert spec_from_dict(json.loads(json.dumps(spec_to_dict(spec)))) == spec


def _phase(**kw):
    return Phase(name="stand", duration=1.0, **kw)


@pytest.mark.parametrize(
    ("build", "message"),
    [
        (lambda: _phase(contacts=(), swing_height=-1.0), "swing_height"),
        (lambda: Phase(name="x", duration=0.0), "duration must be > 0"),
        (lambda: TaskSpec(phases=()), "at least one phase"),
        (lambda: TaskSpec(phases=(_phase(),), dt=2.0), "dt must be"),
        (lambda: FrameTarget(name="a", frame="right_hand"), "position, an rpy"),
        (lambda: FrameTarget(name="a", frame="right_hand", position=(0, 0, float("nan"))), "finite"),
        (lambda: FrameTarget(name="a", frame="right_hand", position=(0, 0, 1), time=1, window=(0, 1)), "not both"),
        (lambda: CoMBounds(lower=(0, None, 1), upper=(1, None, 0)), "exceeds"),
        (lambda: CoMTarget(name="c", position=(None, None, None)), "at least one"),
        (lambda: Contact(frame="left_foot", placement=Pose(position=(0, 0, 0)), friction_coefficient=0.0), "friction"),
        (lambda: TaskSpec(phases=(_phase(),), targets=(FrameTarget(name="a", frame="h", position=(0, 0, 1), time=5.0),)),
         "after the end"),
        (lambda: TaskSpec(phases=(_phase(),), com_targets=(CoMTarget(name="a", position=(0, None, None)),
                                                           CoMTarget(name="a", position=(0, None, None)))),
         "unique"),
    ],
)
def test_invalid_specs_raise_task_definition_error(build, message):
    """Invalid values raise TaskDefinitionError (never AssertionError) naming the problem."""
    with pytest.raises(TaskDefinitionError, match=message):
        build()


def test_json_errors_name_the_path():
    """A typo in a hand-written spec names the key, its path, and the accepted keys."""
    spec = TaskSpec(phases=(_phase(),))
    text = spec_to_json(spec).replace('"swing_height"', '"swing_hight"')
    with pytest.raises(TaskDefinitionError, match=r"spec\.phases\[0\]: unknown key\(s\) \['swing_hight'\]"):
        spec_from_json(text)
    with pytest.raises(TaskDefinitionError, match="line 1"):
        spec_from_json("{not json")
    with pytest.raises(TaskDefinitionError, match="expected a number"):
        spec_from_dict({"phases": [{"name": "a", "duration": "long"}]})


def test_phase_lookup():
    """phase_at and phase_start_times agree with the durations."""
    spec = TaskSpec(phases=(Phase(name="a", duration=1.0), Phase(name="b", duration=0.5), Phase(name="c", duration=2.0)))
    assert spec.horizon == pytest.approx(3.5)
    assert spec.phase_start_times() == (0.0, 1.0, 1.5)
    assert [spec.phase_at(t) for t in (0.0, 0.99, 1.0, 1.49, 1.5, 3.5)] == [0, 0, 1, 1, 2, 2]
