"""Plans from the trajectory optimizer, executed in MuJoCo, must pass the certificate."""

from __future__ import annotations

import pytest

from sim import SimSettings, simulate

pytestmark = pytest.mark.slow


def _plan(robot, name: str, **params):
    from planner import plan
    from tasks.actions import Action
    from tasks.compose import compile_actions

    return plan(compile_actions([Action(name=name, params=params)], robot), robot)


def test_reach_forward_passes(talos):
    """A forward reach with the right hand passes, and its targets are met in the simulation."""
    ex = simulate(
        _plan(talos, "reach", direction="forward"), talos, settings=SimSettings(settle_time=0.2)
    )
    cert = ex.certificate
    assert cert.ok, cert.summary()
    targets = [c for c in cert.checks if c.name.startswith("target")]
    assert targets and all(c.ok for c in targets)


def test_squat_passes(talos):
    """The default squat passes the certificate."""
    ex = simulate(_plan(talos, "squat"), talos, settings=SimSettings(settle_time=0.2))
    assert ex.certificate.ok, ex.certificate.summary()


def test_wave_passes(talos):
    """The default wave passes, and its plan balances by itself: with the CoM held still while the
    hand waves (tasks.compose.STILL_WEIGHT) its full-dynamics ZMP stays in the polygon (it left it
    by 0.16 m when the body swayed with the hand)."""
    ex = simulate(_plan(talos, "wave"), talos, settings=SimSettings(settle_time=0.2))
    assert ex.certificate.ok, ex.certificate.summary()
    assert not any(e.kind == "plan_zmp" for e in ex.events)
