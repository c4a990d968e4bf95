"""Plans from the trajectory optimizer, executed in MuJoCo, must pass the certificate."""

from __future__ import annotations

import pytest

from sim import SimSettings, simulate

pytestmark = pytest.mark.slow


def _plan(robot, name: str, **params):
    from planner.trajopt import plan
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


@pytest.mark.xfail(
    reason="trajopt's squat moves the CoM 0.125 m sideways (the support-polygon edge less its margin) with the "
    "base rolled 0.23 rad: one knee carries the robot and saturates at 300 N m (reported to the planner)",
    strict=False,
)
def test_squat_passes(talos):
    """The default squat passes the certificate."""
    ex = simulate(_plan(talos, "squat"), talos, settings=SimSettings(settle_time=0.2))
    assert ex.certificate.ok, ex.certificate.summary()


@pytest.mark.xfail(
    reason="trajopt's wave swings the CoM between y = 0.03 and 0.125 m at up to 2.7 m/s^2: the plan's ZMP leaves "
    "the support polygon by 0.15 m and the robot falls (reported to the planner)",
    strict=False,
)
def test_wave_passes(talos):
    """The default wave passes the certificate."""
    ex = simulate(_plan(talos, "wave"), talos, settings=SimSettings(settle_time=0.2))
    assert ex.certificate.ok, ex.certificate.summary()
