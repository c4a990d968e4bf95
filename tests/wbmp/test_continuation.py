"""Where "then <sentence>" can start (wbmp.continuation.end_state): a real squat plan's last knot
at rest on both feet is a start; a simulation that ended elsewhere or failed, a last phase on one
foot, and an object held or moved are not (refused in task words, or planned together)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from language import parse
from planner import plan
from planner.trajopt.settings import CacheSettings, PlannerSettings
from sim import Execution
from sim.certificate import Certificate
from tasks.compose import compile_actions, fit_actions
from wbmp.continuation import DRIFT, EndState, end_state


@pytest.fixture(scope="module")
def squat(talos):
    spec = compile_actions(fit_actions(parse("squat").actions, talos), talos)
    return spec, plan(spec, talos, settings=PlannerSettings(cache=CacheSettings(solution_library="off")))


def feet(robot):
    return robot.frame("left_foot"), robot.frame("right_foot")


def executed(q_end: np.ndarray, *, ok: bool = True, reason: str = "") -> Execution:
    """The simulation's arrays as a motion file keeps them, ending at ``q_end``."""
    q = np.vstack([q_end, q_end])
    return Execution(t=np.array([0.0, 0.001]), q=q, v=np.zeros((2, q.shape[1] - 1)), tau=None,
                           certificate=Certificate(ok=ok, checks=(), reason=reason))


def test_a_standing_end_is_the_next_start(talos, squat):
    spec, p = squat
    end = end_state(spec, p, executed(p.q[-1]), feet(talos), talos.profile.sole)
    assert end.kind == "start" and np.allclose(end.q, p.q[-1], atol=0.0)
    assert EndState.from_dict(end.to_dict()) == end
    assert end_state(spec, p, None, feet(talos)).kind == "start"  # not simulated: the plan alone


def test_a_simulation_that_ended_elsewhere_is_refused(talos, squat):
    spec, p = squat
    q = np.array(p.q[-1])
    q[0] += 2 * DRIFT
    end = end_state(spec, p, executed(q), feet(talos))
    assert end.kind == "refused" and "ended 0.10 m and 0 deg away from the planned end" in end.reason
    end = end_state(spec, p, executed(p.q[-1], ok=False, reason="fell at t = 1.2 s"), feet(talos))
    assert end.kind == "refused" and "did not pass its simulation check (fell at t = 1.2 s)" in end.reason


def test_ending_on_one_foot_is_refused(talos, squat):
    spec, p = squat
    last = spec.phases[-1]
    one = dataclasses.replace(last, contacts=tuple(c for c in last.contacts if c.frame != feet(talos)[1]))
    end = end_state(dataclasses.replace(spec, phases=(*spec.phases[:-1], one)), p, None, feet(talos))
    assert end.kind == "refused" and "right foot off the ground" in end.reason


def test_holding_an_object_plans_the_two_together(talos):
    from tasks.scene import load_scene

    scene = load_scene("examples/scenes/kitchen.json")
    spec = compile_actions(fit_actions(parse("walk to the cup and pick it up").actions, talos), talos, scene=scene)
    end = end_state(spec, None, None, feet(talos))  # decided by the spec: no plan needed
    assert end.kind == "together" and "holding the" in end.reason and end.q is None


def test_a_centre_of_mass_off_the_feet_is_refused(talos, squat):
    spec, p = squat
    com = np.array(p.com)
    com[-1, 0] += 0.2  # 20 cm forward: beyond the toes
    end = end_state(spec, dataclasses.replace(p, com=com), None, feet(talos), talos.profile.sole)
    assert end.kind == "refused" and "cm outside its feet" in end.reason
