"""``TaskSpec.start`` in the task layer: compiled actions start at the stance of the start state's
soles (Pinocchio's forward kinematics is the reference), the JSON round trip keeps it (and a spec
without one keeps the JSON it had), and a start that does not fit the robot or the first phase is
refused naming the field."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pinocchio as pin
import pytest

from language import parse
from tasks.compose import compile_actions, fit_actions
from tasks.exceptions import TaskDefinitionError
from tasks.robot_check import check_spec_for_robot
from tasks.serialize import spec_from_json, spec_to_dict, spec_to_json
from tasks.specs import StartState


def turned(robot, yaw: float, xy=(0.8, -0.3)) -> np.ndarray:
    q = np.array(robot.q_standing, dtype=float)
    motion = pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, yaw), np.array([*xy, 0.0]))
    q[:7] = pin.SE3ToXYZQUAT(motion * pin.XYZQUATToSE3(q[:7]))
    return q


@pytest.fixture
def start(talos):
    return StartState(q=tuple(float(x) for x in turned(talos, 1.2)))


def test_compiled_actions_start_at_the_soles_of_the_start_state(talos, start):
    spec = compile_actions(fit_actions(parse("wave your right hand, then step forward").actions, talos), talos,
                           start=start)
    assert spec.start == start
    data = talos.data()
    pin.framesForwardKinematics(talos.model, data, np.array(start.q))
    for contact in spec.phases[0].contacts:
        oMf = data.oMf[talos.frame_id(contact.frame)]
        np.testing.assert_allclose(contact.placement.position, oMf.translation, atol=1e-9)
        assert contact.placement.rpy[2] == pytest.approx(math.atan2(oMf.rotation[1, 0], oMf.rotation[0, 0]), abs=1e-9)
    check_spec_for_robot(spec, talos)  # the first phase is where the feet are
    # the step goes forward in the robot's heading (yaw 1.2 rad), not along the world's x axis
    step = [c for ph in spec.phases for c in ph.contacts]
    travel = np.array(step[-1].placement.position) - np.array(spec.phases[0].contacts[0].placement.position)
    heading = np.array([math.cos(1.2), math.sin(1.2)])
    assert float(travel[:2] @ heading) > 0.05


def test_the_json_round_trip_keeps_the_start(talos, start):
    spec = compile_actions(fit_actions(parse("squat").actions, talos), talos, start=start)
    assert spec_from_json(spec_to_json(spec)) == spec
    standing = dataclasses.replace(spec, start=None)
    assert "start" not in spec_to_dict(standing)  # the JSON (and the motion cache key) of a spec as before
    assert spec_from_json(spec_to_json(standing)) == standing


@pytest.mark.parametrize("q, message", [
    ((0.0,) * 7, "must list 8 to"),
    ((0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.9, 0.1), "norm is 0.9"),
    ((0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, math.nan), "finite numbers"),
])
def test_a_bad_start_is_refused(q, message):
    with pytest.raises(TaskDefinitionError, match=message):
        StartState(q=q)


def test_a_start_of_another_robot_or_elsewhere_is_refused(talos, start):
    spec = compile_actions(fit_actions(parse("squat").actions, talos), talos, start=start)
    with pytest.raises(TaskDefinitionError, match=r"spec.start.q: 8 numbers; talos's configuration has 39"):
        check_spec_for_robot(dataclasses.replace(spec, start=StartState(q=(0.0,) * 6 + (1.0, 0.0))), talos)
    elsewhere = StartState(q=tuple(float(x) for x in turned(talos, 1.2, xy=(0.5, -0.3))))
    with pytest.raises(TaskDefinitionError, match=r"phases\[0\].contacts\[0\].*in the spec.start state"):
        check_spec_for_robot(dataclasses.replace(spec, start=elsewhere), talos)
