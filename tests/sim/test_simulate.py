"""Closed-loop simulation: hand-made plans pass the certificate, broken ones fail for the right reason."""

from __future__ import annotations

import json

import numpy as np
import pytest

from sim import Push, PushParseError, SimSettings, parse_push, simulate
from sim.figures import FIGURES
from sim.handmade import arm_plan, feet_apart_plan, squat_plan, standing_plan, with_torque_limits

GRAVITY = 9.81  # [m/s^2]


MESSAGES: list[str] = []


@pytest.fixture(scope="module")
def stand_run(talos):
    return simulate(
        standing_plan(talos, duration=1.0),
        talos,
        settings=SimSettings(settle_time=0.3),
        progress=MESSAGES.append,
    )


@pytest.fixture(scope="module")
def squat_run(talos):
    return simulate(
        squat_plan(talos, depth=0.15, duration=2.5), talos, settings=SimSettings(settle_time=0.3)
    )


def test_parse_push():
    """'80@1.5' is 80 N at 1.5 s along +x for 0.1 s; bad text raises a one-line ValueError."""
    push = parse_push("80@1.5")
    assert (push.force, push.time, push.duration, push.direction) == (
        80.0,
        1.5,
        0.1,
        (1.0, 0.0, 0.0),
    )
    assert parse_push(" 120.5N @ 0.25s ").force == 120.5
    assert Push(80.0, 1.5) == push  # positional form, as in the CLI docs
    for bad in ("80", "80@", "@1", "eighty@1", "80@-1", "80@1@2", ""):
        with pytest.raises(PushParseError) as err:
            parse_push(bad)
        assert isinstance(err.value, ValueError)
        assert "\n" not in str(err.value) and "FORCE@TIME" in str(err.value)


def test_standing_still_passes_and_forces_carry_the_weight(talos, stand_run):
    """Standing still passes; the floor carries m g; arrays have the documented shapes."""
    ex = stand_run
    assert ex.certificate.ok, ex.certificate.summary()
    n = len(ex.t)
    assert (
        ex.q.shape == (n, talos.nq)
        and ex.v.shape == (n, talos.nv)
        and ex.tau.shape == (n, talos.nv - 6)
    )
    assert ex.com.shape == (n, 3)
    np.testing.assert_allclose(np.linalg.norm(ex.q[:, 3:7], axis=1), 1.0, atol=1e-9)
    np.testing.assert_allclose(np.diff(ex.t), 0.001, atol=1e-12)
    total = sum(f[-200:].mean(axis=0) for f in ex.contact_forces.values())
    np.testing.assert_allclose(
        total, [0.0, 0.0, talos.mass * GRAVITY], atol=0.02 * talos.mass * GRAVITY
    )
    assert ex.certificate.check("left_foot slip").value < 0.002
    fractions = ex.peak_torque_fractions()
    assert list(fractions) == talos.joint_names
    assert max(fractions.values()) == pytest.approx(ex.certificate.check("peak torque").value / 100)
    assert ex.certificate.check("CoM tracking error").value < 0.01


def test_progress_reports_simulated_time(stand_run):
    """The progress callback receives about ten one-line messages, ending with the certification."""
    assert 5 <= len(MESSAGES) <= 12
    assert all(isinstance(m, str) and "\n" not in m for m in MESSAGES)
    assert MESSAGES[0].startswith("simulated 0.") and MESSAGES[-1].endswith("certifying")


def test_certificate_serializes(stand_run):
    """The certificate turns into JSON and a readable multi-line summary."""
    d = json.loads(json.dumps(stand_run.certificate.to_dict()))
    assert d["ok"] is True and d["reason"] == ""
    names = {c["name"] for c in d["checks"]}
    assert {
        "base height",
        "base tilt",
        "unplanned contacts",
        "left_foot slip",
        "right_foot slip",
        "peak torque",
        "CoM tracking error",
        "right_hand tracking error",
    } <= names
    text = stand_run.certificate.summary()
    rows = [line for line in text.splitlines() if line.startswith(("  ok ", "  FAIL "))]
    assert text.startswith("certificate: PASS") and len(rows) == len(d["checks"])
    assert "figures:" in text and set(d["figures"]) == set(FIGURES)  # the evaluation figures (docs/safety.md)


def test_squat_tracks_the_com(talos, squat_run):
    """A 15 cm IK squat passes; the CoM follows its plan within 2 cm, the soles stay put."""
    cert = squat_run.certificate
    assert cert.ok, cert.summary()
    assert cert.check("CoM tracking error").value < 0.02
    assert cert.check("CoM target 'squat bottom'").value < 0.02  # measured at t = 1.25 s
    assert cert.check("left_foot slip").value < 0.005
    assert squat_run.com[:, 2].min() < squat_run.com[0, 2] - 0.12  # it really went down


def test_arm_motion_meets_its_target(talos):
    """Raising the right hand 25 cm meets the spec's hand target in the simulation."""
    ex = simulate(arm_plan(talos, duration=2.0), talos, settings=SimSettings(settle_time=0.2))
    assert ex.certificate.ok, ex.certificate.summary()
    check = ex.certificate.check("target 'right hand up'")
    assert check.value < 0.03


def test_feet_forced_apart_fails_on_the_foot(talos):
    """A plan that drags a stance foot 25 cm sideways fails, naming that foot."""
    ex = simulate(
        feet_apart_plan(talos, distance=0.25, duration=1.5),
        talos,
        settings=SimSettings(settle_time=0.1),
    )
    assert not ex.certificate.ok
    assert ex.certificate.reason.startswith("right_foot is 0.2")
    assert "planned stance placement" in ex.certificate.reason
    assert ex.certificate.check("left_foot placement error").ok


def test_torque_limits_at_ten_percent_fail_on_torque(talos):
    """With 10 % of the torque limits, the robot cannot stand: joints saturate, then it falls."""
    weak = with_torque_limits(talos, 0.1)
    ex = simulate(
        standing_plan(weak, duration=1.0),
        weak,
        settings=SimSettings(settle_time=0.0, stop_after_fall=0.05),
    )
    assert not ex.certificate.ok
    # the controller caps torques at 97 % (WbcSettings.torque_scale): saturated there, then it falls
    assert ex.certificate.check("peak torque").value > 96.9
    saturation = [e for e in ex.events if e.kind == "torque_limit"]
    assert saturation and saturation[0].time < min(e.time for e in ex.events if e.kind == "fall")
    assert not ex.certificate.check("base height").ok or not ex.certificate.check("base tilt").ok
    assert any(e.kind == "fall" for e in ex.events)
    assert [e.kind for e in ex.events][0] == "torque_limit"


def test_pushes_small_recovered_large_falls(talos):
    """A 40 N push is absorbed; a 3000 N push for 0.1 s knocks the robot over (reported as a fall)."""
    plan = standing_plan(talos, duration=1.2)
    small = simulate(
        plan, talos, push=Push(force=40.0, time=0.3), settings=SimSettings(settle_time=0.2)
    )
    assert small.certificate.ok, small.certificate.summary()
    assert any(e.kind == "push" for e in small.events)
    big = simulate(
        plan,
        talos,
        push=Push(force=3000.0, time=0.2, duration=0.1),
        settings=SimSettings(settle_time=0.5, stop_after_fall=0.05),
    )
    assert not big.certificate.ok
    assert any(e.kind == "fall" for e in big.events)
    fall = [
        c for c in big.certificate.checks if c.name in ("base height", "base tilt") and not c.ok
    ]
    assert fall and fall[0].message.startswith("fell at t = ")


def test_g1_stands(g1):
    """The same loop certifies G1 standing still (another robot through the same profile)."""
    ex = simulate(standing_plan(g1, duration=0.5), g1, settings=SimSettings(settle_time=0.2))
    assert ex.certificate.ok, ex.certificate.summary()


def test_foot_lift_swings_and_lands(talos):
    """Weight shift, right foot lifted 5 cm in single support and put back: passes; the swing foot
    really leaves the floor and the stance foot then carries the whole weight."""
    import pinocchio as pin

    from sim.handmade import foot_lift_plan

    ex = simulate(foot_lift_plan(talos, height=0.05), talos, settings=SimSettings(settle_time=0.2))
    assert ex.certificate.ok, ex.certificate.summary()
    k = int(np.searchsorted(ex.t, 2.25))  # middle of the single-support phase
    right, left = talos.frame("right_foot"), talos.frame("left_foot")
    np.testing.assert_allclose(ex.contact_forces[right][k], 0.0, atol=1e-9)
    assert ex.contact_forces[left][k][2] == pytest.approx(talos.mass * GRAVITY, rel=0.05)
    data = talos.data()
    pin.framesForwardKinematics(talos.model, data, ex.q[k])
    assert data.oMf[talos.frame_id("right_foot")].translation[2] > 0.04
    assert ex.contact_forces[right][-1][2] > 0.3 * talos.mass * GRAVITY  # landed and loaded again
