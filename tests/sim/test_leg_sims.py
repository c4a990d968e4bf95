"""Leg motions planned on Talos pass the MuJoCo certificate, their targets met in simulation."""

from __future__ import annotations

import math

import pytest

from sim import SimSettings, simulate

pytestmark = pytest.mark.slow


def _run(robot, name: str, **params):
    from planner import PlannerSettings, plan
    from tasks.actions import Action
    from tasks.compose import compile_actions

    result = plan(compile_actions([Action(name=name, params=params)], robot), robot,
                  settings=PlannerSettings(compile=False))
    return simulate(result, robot, settings=SimSettings(settle_time=0.2))


def test_kick_passes(talos):
    """A forward kick with the right leg: balanced on the left foot, the kick target reached in
    simulation, no slip, no unplanned contact."""
    cert = _run(talos, "kick", leg="right").certificate
    assert cert.ok, cert.summary()
    kicks = [c for c in cert.checks if "kicks forward" in c.name]
    assert kicks and all(c.ok for c in kicks)


def test_quarter_circle_passes(talos):
    """A quarter of a 0.5 m circle to the left (5 swings) passes the certificate."""
    cert = _run(talos, "walk_arc", angle=math.pi / 2).certificate
    assert cert.ok, cert.summary()
    assert any("walk_arc" in c.name and c.ok for c in cert.checks)


def test_standing_on_one_foot_passes_on_g1(g1):
    """G1 stands on its left foot for 1 s: planned with the centroidal dynamics, the CoM reaches
    the stance sole within the target's limit (5.2 cm off when planned kinematically; ``kick``
    shares the weight shift and is dynamic too, tests/tasks/test_legs.py) and the certificate
    passes."""
    cert = _run(g1, "balance", foot="left", duration=1.0).certificate
    assert cert.ok, cert.summary()
    over = [c for c in cert.checks if "CoM over the left sole" in c.name]
    assert over and all(c.ok for c in over)
