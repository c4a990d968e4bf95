"""Retargeted clips on talos, planned, simulated with the whole-body controller in MuJoCo and
certified; the executed figures (recomputed by the command from the simulated configurations)
within the bounds the issue sets for an executed motion, with the measured margins."""

from __future__ import annotations

from pathlib import Path

import pytest

from wbmp.retarget import RetargetRequest, retarget

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "motions"


@pytest.fixture(autouse=True)
def _no_compilation(monkeypatch, tmp_path):
    monkeypatch.setenv("WBMP_COMPILE", "0")
    monkeypatch.setenv("WBMP_CACHE_DIR", str(tmp_path / "cache"))


def _certified(clip: str, start: float, end: float):
    result = retarget(RetargetRequest(clip=str(EXAMPLES / clip), robot="talos", start=start, end=end))
    assert result.plan.ok
    plan = result.figures
    assert plan.skate <= 2.0 and plan.penetration <= 1.0 and plan.float_ <= 5.0  # the plan: the bounds
    assert result.execution is not None
    assert result.execution.certificate.ok, result.execution.certificate.reason
    return result


def test_a_squat_is_executed_and_the_meshes_name_what_is_left():
    """The squat's first 2 s (going down), executed in MuJoCo: its feet slip and sink by millimetres
    (MuJoCo's soft contacts: 6.9 mm skate, 3.6 mm penetration measured), hands tracked to
    centimetres, every certificate line passes but the one on the meshes: at the bottom of the
    human's deep squat talos's thigh passes into its pelvis (15-18 mm of hull depth, coal), a pair
    the planner's sphere model does not keep apart yet, so it is not certified (issue 37)."""
    from planner.results import CheckKind

    result = retarget(RetargetRequest(clip=str(EXAMPLES / "13_29_squat.bvh"), robot="talos", start=0.0, end=2.0))
    assert result.plan.ok
    plan = result.figures
    assert plan.skate <= 2.0 and plan.penetration <= 1.0 and plan.float_ <= 5.0  # the plan: the bounds
    ex = result.exec_figures
    assert ex.skate <= 10.0 and ex.penetration <= 6.0 and ex.float_ <= 5.0
    assert result.figures.per_keypoint["left_hand"] < 0.05
    failed = [c for c in result.execution.certificate.checks if not c.ok]
    assert [c.kind for c in failed] == [CheckKind.SELF_COLLISION_MESH], [c.name for c in failed]
    assert "pelvis" in failed[0].name and "thigh" in failed[0].name
    report = result.report()["retarget"]
    assert report["execution"]["foot_skate_mm"] == ex.skate and report["skeleton"].startswith("CMU MotionBuilder")


@pytest.mark.long
def test_the_whole_chicken_dance_is_certified():
    """The whole 4.25 s clip (both feet down, arms and hips busy): certified; measured 0.9 mm skate,
    2.0 mm penetration executed, 2.2 cm mean tracking error planned."""
    result = _certified("18_15_dance.bvh", 0.0, 4.25)
    assert result.exec_figures.skate <= 5.0 and result.exec_figures.penetration <= 6.0
    assert result.figures.tracking_mean < 0.04


@pytest.mark.long
def test_a_squat_is_certified_on_g1():
    """G1 (scale 0.77): the squat's first 2 s certified; measured 3.4 mm skate, 2.4 mm penetration."""
    result = retarget(RetargetRequest(clip=str(EXAMPLES / "13_29_squat.bvh"), robot="g1", start=0.0, end=2.0))
    assert result.plan.ok and result.execution.certificate.ok, result.execution.certificate.reason
    assert result.figures.skate <= 2.0 and result.figures.penetration <= 1.0
    assert result.exec_figures.skate <= 5.0 and result.exec_figures.penetration <= 6.0
