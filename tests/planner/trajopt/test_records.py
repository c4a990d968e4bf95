"""The planner's records are read-only: the collision rows a layout carries (``Rows``,
``SceneRows``: a round returns new ones) and what a solve returns beside the motion
(``SolverOutput``, was a dict of seven string keys). Pure Python, no solve."""

from __future__ import annotations

import dataclasses
import pickle

import numpy as np
import pytest

from planner.trajopt.collision import Rows
from planner.trajopt.scene_collision import SceneRows
from planner.trajopt.solver_output import SolverOutput


def test_rows_cannot_be_changed_in_place():
    rows = Rows({3: {1, 2}}, {3: [5, 6]})
    assert rows.spheres[3] == frozenset({1, 2}) and rows.knots[3] == frozenset({5, 6})
    with pytest.raises(TypeError):
        rows.spheres[4] = frozenset({0})  # type: ignore[index]
    with pytest.raises(AttributeError):
        rows.spheres[3].add(9)  # type: ignore[attr-defined]
    with pytest.raises(dataclasses.FrozenInstanceError):
        rows.spheres = {}  # type: ignore[misc]
    with pytest.raises(ValueError, match="different pairs"):
        Rows({3: {1}}, {4: {5}})


def test_merged_returns_a_new_record_and_the_changed_pairs_in_the_others_order():
    rows = Rows({3: {1}}, {3: {5}})
    more = Rows({7: {0}, 3: {1}, 2: {4}}, {7: {9}, 3: {6}, 2: {8}})
    merged, changed = rows.merged(more)
    assert changed == [7, 3, 2]  # the order the terms are written in: it shapes the NLP
    assert dict(rows.spheres) == {3: {1}} and dict(rows.knots) == {3: {5}}  # the input: untouched
    assert list(merged.spheres) == [3, 7, 2] and merged.knots[3] == {5, 6}
    again, none = merged.merged(more)
    assert again is merged and none == []
    scene, objects = SceneRows().merged(SceneRows({1: {4}}, {1: {2}}))
    assert type(scene) is SceneRows and objects == [1] and not scene.empty and SceneRows().empty


def test_split_keeps_the_order_and_a_record_survives_pickling():
    rows = Rows({5: {0}, 1: {1}, 3: {2}}, {5: {2}, 1: {3}, 3: {4}})
    kept, taken = rows.split([3, 5])
    assert list(kept.spheres) == [1] and list(taken.spheres) == [5, 3] and taken.knots[3] == {4}
    back = pickle.loads(pickle.dumps(rows))
    assert type(back) is Rows and back == rows and list(back.spheres) == [5, 1, 3]


def test_a_solvers_output_is_read_only_and_its_own():
    x = np.arange(4.0)
    out = SolverOutput(x=x, lam_x=np.zeros(4), lam_g=np.ones((2, 1)), g=np.zeros(2), lbg=np.zeros(2),
                       ubg=np.ones(2), nlp_layout=None)
    x[0] = 99.0  # the caller's array: not the record's
    assert out.x[0] == 0.0 and out.lam_g.shape == (2,)  # flattened, as the solver's (n, 1) outputs come
    with pytest.raises(ValueError):
        out.x[1] = 1.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        out.x = x  # type: ignore[misc]
    assert out.x_stagewise is None


def test_a_stage_hessian_is_built_once_per_structure_and_equals_a_fresh_build(g1):
    """The dynamic NLP's per-stage Hessian functions come from a per-process cache keyed by the
    robot and the terms' structure (a collision round's second build reuses the stage types it
    did not change): the same structure with other values gets the same function, another
    structure its own (named after its key), and a cached function evaluates as one built afresh."""
    import casadi as ca

    from planner.trajopt.centroidal import nlp
    from planner.trajopt.layout import make_layout
    from tasks import Action, compile_actions

    lay = make_layout(compile_actions([Action(name="squat", params={"depth": 0.1})], g1), g1)
    by_knot: dict[int, list] = {}
    for t in lay.terms:
        by_knot.setdefault(t.knot, []).append(t)
    mid = by_knot[lay.N // 2][:3]  # a few terms: a small Hessian to build
    assert len(mid) == 3
    fn, n_p, n_g = nlp._stage_hessian(g1, mid)
    assert n_p == sum(len(t.params) for t in mid) and n_g == sum(t.n_rows for t in mid)
    moved = [dataclasses.replace(t, params=np.asarray(t.params) + 0.01) for t in mid]
    assert nlp._stage_hessian(g1, moved)[0] is fn  # values are parameters: the same function
    fewer, _, _ = nlp._stage_hessian(g1, mid[1:])
    assert fewer is not fn and fewer.name() != fn.name()
    key = next(k for k, v in nlp._STAGE_HESSIANS.items() if v[0] is fn)
    del nlp._STAGE_HESSIANS[key]
    fresh, _, _ = nlp._stage_hessian(g1, mid)
    assert fresh is not fn
    rng = np.random.default_rng(3)
    args = [rng.normal(0.0, 0.2, fn.size_in(i)) for i in range(fn.n_in())]
    args[1] = g1.q_standing  # a valid reference configuration (unit quaternion)
    for a, b in zip(fn(*args), fresh(*args), strict=True):  # the stage's Hessian and its CoM multiplier part
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    assert isinstance(fn, ca.Function)
