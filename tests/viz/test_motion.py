"""The numbers behind every view: resampling, rigid placements, ZMP, support polygons."""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin
import pytest

from viz import motion as vm


def test_resample_hits_knots_and_keeps_unit_quaternions(talos, synth_plan):
    m = vm.plan_motion(talos, synth_plan)
    times, qs = vm.resample(talos, m, fps=20.0)  # knots every 0.05 s = exactly every frame
    assert times[0] == 0.0
    assert times[-1] == pytest.approx(synth_plan.t[-1])
    np.testing.assert_allclose(qs, synth_plan.q, atol=1e-12)
    times, qs = vm.resample(talos, m, fps=30.0)
    np.testing.assert_allclose(np.linalg.norm(qs[:, 3:7], axis=1), 1.0, atol=1e-12)
    # a frame between two knots lies between them (base height is monotone on the first half)
    k = 7
    assert synth_plan.q[k + 1, 2] <= qs[np.searchsorted(times, synth_plan.t[k] + 0.02), 2] <= synth_plan.q[k, 2]


def test_geometry_placements_are_rigid_and_scale_restores_pinocchio(talos):
    """Mirrored meshes (negative scale) stay out of the animated transform (docs/visualization.md)."""
    q = talos.q_standing
    T = vm.geometry_placements(talos, q[None, :])[:, 0]
    dets = np.linalg.det(T[:, :3, :3])
    np.testing.assert_allclose(dets, 1.0, atol=1e-9)
    scales = np.array([g.meshScale for g in talos.visual_model.geometryObjects])
    mirrored = int(np.sum(np.any(scales < 0, axis=1)))
    assert mirrored == 13
    data, gdata = talos.data(), pin.GeometryData(talos.visual_model)
    pin.forwardKinematics(talos.model, data, q)
    pin.updateGeometryPlacements(talos.model, data, talos.visual_model, gdata)
    for g in range(len(T)):
        np.testing.assert_allclose(T[g], gdata.oMg[g].homogeneous, atol=1e-12)


def test_convex_hull_and_margin():
    pts = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.5], [0.2, 0.9]], dtype=float)
    hull = vm.convex_hull_2d(pts)
    assert len(hull) == 4
    area = 0.5 * np.sum(hull[:, 0] * np.roll(hull[:, 1], -1) - np.roll(hull[:, 0], -1) * hull[:, 1])
    assert area == pytest.approx(1.0)  # counter-clockwise: positive area
    assert vm.point_in_polygon_margin(np.array([0.5, 0.5]), hull) == pytest.approx(0.5)
    assert vm.point_in_polygon_margin(np.array([0.5, 0.1]), hull) == pytest.approx(0.1)
    assert vm.point_in_polygon_margin(np.array([1.5, 0.5]), hull) == pytest.approx(-0.5)


def test_zmp_equals_com_at_rest_and_shifts_against_acceleration():
    t = np.linspace(0.0, 1.0, 101)
    com = np.tile([0.01, -0.02, 0.9], (len(t), 1))
    np.testing.assert_allclose(vm.zmp_from_com(t, com), com[:, :2], atol=1e-12)
    a = 0.5  # [m/s^2] forward acceleration: the ZMP moves back by z a / g
    com[:, 0] = 0.5 * a * t**2
    zmp = vm.zmp_from_com(t, com)
    np.testing.assert_allclose(zmp[5:-5, 0], com[5:-5, 0] - 0.9 * a / vm.GRAVITY, atol=1e-9)


def test_support_polygon_of_double_support_contains_standing_com(talos, synth_plan):
    (phase,) = vm.support_phases(talos, synth_plan)
    assert len(phase.polygon) == 4  # two aligned soles: a rectangle
    assert set(phase.frames) == {talos.frame("left_foot"), talos.frame("right_foot")}
    margin = vm.point_in_polygon_margin(synth_plan.com[0, :2], phase.polygon)
    assert 0.02 < margin < 0.2
    for corners in phase.soles.values():
        np.testing.assert_allclose(corners[:, 2], 0.0, atol=1e-6)  # soles on the ground


def test_execution_motion_of_an_execution(talos, synth_plan, synth_execution):
    m = vm.execution_motion(talos, synth_execution)
    assert m.label == "simulated"
    assert m.tau.shape == (len(m.t), talos.nv - 6)
    assert set(m.forces) == {talos.frame("left_foot"), talos.frame("right_foot")}
    assert vm.execution_motion(talos, None) is None
    with pytest.raises(vm.VizInputError, match="execution: q"):
        vm.execution_motion(talos, dataclasses.replace(synth_execution, t=np.zeros(3), q=np.zeros((3, 5))))
