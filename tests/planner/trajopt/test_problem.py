"""A layout is frozen: its fields cannot be assigned, a changed layout is a new one, and what it
builds lazily (the support polygons, the dynamic parts) neither shows as a field nor changes one."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from planner.trajopt.centroidal.layout import to_dynamic_layout
from planner.trajopt.layout import make_layout, support_polygon
from tests.planner.planning_cases import squat_spec


@pytest.fixture(scope="module")
def squat_layout(talos):
    return make_layout(squat_spec(talos, 0.1), talos)


@pytest.mark.parametrize("name", ["terms", "frame_ids", "N", "q_ref", "spec", "_memo", "something_new"])
def test_assigning_a_layouts_field_raises(squat_layout, name):
    """Every field (and any new attribute) of a kinematic and a dynamic layout refuses assignment."""
    dyn = to_dynamic_layout(squat_layout)
    for lay in (squat_layout, dyn):
        with pytest.raises(dataclasses.FrozenInstanceError):
            setattr(lay, name, [])
    with pytest.raises(dataclasses.FrozenInstanceError):
        dyn.linearized_about = np.zeros((dyn.N + 1, dyn.robot.nv))  # type: ignore[misc]


def test_with_terms_is_a_new_layout_sharing_what_was_built(squat_layout):
    """A layout's terms are a tuple (no append from outside); ``with_terms`` makes a new layout of the
    same class with the new terms, sharing the support polygon the original built (the same array,
    not rebuilt)."""
    assert isinstance(squat_layout.terms, tuple)
    structure = squat_layout.structure()
    hull = support_polygon(squat_layout, 3)
    assert hull.shape[0] >= 4  # both soles: a polygon
    half = squat_layout.with_terms(list(squat_layout.terms[: len(squat_layout.terms) // 2]))
    assert type(half) is type(squat_layout) and isinstance(half.terms, tuple)
    assert len(half.terms) == len(squat_layout.terms) // 2 and half.structure() != structure
    assert support_polygon(half, 3) is hull


def test_a_dynamic_layouts_momentum_point_is_a_field_of_a_new_layout(squat_layout):
    """The momentum point given to ``with_momentum_point`` is the copy's; the original keeps its
    initial guess's point (built once, the same array on every call)."""
    dyn = to_dynamic_layout(squat_layout)
    guess, pattern = dyn.momentum_point(), dyn.pattern()
    assert dyn.momentum_point() is guess and dyn.linearized_about is None
    point = np.full((dyn.N + 1, dyn.robot.nv), 0.01)
    moved = dyn.with_momentum_point(point, 0.02)
    np.testing.assert_array_equal(moved.momentum_point(), point)
    assert moved.momentum_residual == 0.02 and np.isnan(dyn.momentum_residual)
    assert dyn.momentum_point() is guess and moved.pattern() is pattern  # built before the copy: shared
