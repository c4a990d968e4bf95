"""What a first-ever solver build skips or moves away, checked against independent references:
the sparse operators without scipy, the placements from one cached SX function, no kinematic stage
Hessians for a dynamic layout, and the forked background worker detached from the caller."""

from __future__ import annotations

import os
from pathlib import Path

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest
from scipy.sparse import coo_matrix

from planner.trajopt import cache, transcription
from planner.trajopt.centroidal.layout import to_dynamic_layout
from planner.trajopt.layout import make_layout
from planner.trajopt.settings import PlannerSettings
from planner.trajopt.symbolic import SymbolicKinematics, chart_to_configuration
from tasks.actions import Action
from tasks.compose import compile_actions
from tests.tolerances import SYMBOLIC_ATOL


@pytest.mark.parametrize("shape", [(7, 5), (40, 13), (1, 1), (0, 3), (3, 0)])
def test_sparse_operator_equals_scipy(rng, shape):
    """Triplets with duplicates (one set summing to about zero, kept as an entry) give scipy's
    pattern and values."""
    n = 60 if shape[0] * shape[1] else 0
    rows = rng.integers(0, max(shape[0], 1), n)
    cols = rng.integers(0, max(shape[1], 1), n)
    values = rng.normal(size=n)
    if n:  # a duplicate pair that cancels: scipy keeps the explicit zero, so must we
        rows, cols = np.append(rows, [rows[0], rows[0]]), np.append(cols, [cols[0], cols[0]])
        values = np.append(values, [2.5, -2.5 - values[0]])
    ours = transcription._sparse(rows, cols, values, shape)
    ref = coo_matrix((values, (rows, cols)), shape=shape).tocsc()
    ref.sum_duplicates()
    expected = ca.DM(ref)
    assert ours.sparsity() == expected.sparsity()  # the pattern, explicit zeros included
    # values: sums of up to ~5 duplicates, added in another order than scipy's (the planner's
    # operators have at most two per entry, whose sum does not depend on the order)
    np.testing.assert_allclose(np.array(ours.nonzeros()), np.array(expected.nonzeros()), rtol=0, atol=1e-12)


def test_cached_placements_equal_the_walk_and_pinocchio(talos):
    """The placements from the per-model SX function are the tree walk's, bit for bit, and
    Pinocchio's placements of ``q_ref (+) dq``."""
    model, data = talos.model, talos.data()
    kin = SymbolicKinematics(model)
    q_sym, dq_sym = ca.SX.sym("q", model.nq), ca.SX.sym("dq", model.nv)
    cached = ca.Function("c", [q_sym, dq_sym], [x for R, p in kin.joint_placements(q_sym, dq_sym) for x in (R, p)])
    walked = ca.Function("w", [q_sym, dq_sym], [x for R, p in kin.walk(q_sym, dq_sym) for x in (R, p)])
    assert cached.n_nodes() == walked.n_nodes()
    rng = np.random.default_rng(7)
    for _ in range(3):
        q_ref = pin.randomConfiguration(model, -np.ones(model.nq), np.ones(model.nq))
        dq = 0.3 * rng.normal(size=model.nv)
        a, b = cached(q_ref, dq), walked(q_ref, dq)
        for x, y in zip(a, b, strict=True):
            np.testing.assert_array_equal(np.array(x), np.array(y))
        pin.forwardKinematics(model, data, chart_to_configuration(model, q_ref, dq))
        for i in range(1, model.njoints):
            np.testing.assert_allclose(np.array(a[2 * i]), data.oMi[i].rotation, atol=SYMBOLIC_ATOL)
            np.testing.assert_allclose(np.array(a[2 * i + 1]).ravel(), data.oMi[i].translation, atol=SYMBOLIC_ATOL)


def test_dynamic_build_makes_no_kinematic_stage_hessian(g1):
    """A dynamic layout's NLP takes its Hessian from the centroidal assembly: the kinematic stage
    Hessians are never built for it; a kinematic layout of the same spec builds them."""
    spec = compile_actions([Action(name="jump", params={"height": 0.05})], g1, dt=0.1)
    transcription._STAGES.clear()
    dyn = to_dynamic_layout(make_layout(spec, g1), PlannerSettings().centroidal)
    _, derivatives, _ = transcription.build_nlp(dyn)
    assert "hess_lag" in derivatives  # the dynamic one
    assert derivatives["hess_lag"].sparsity_out(0).size1() == derivatives["grad_f"].size1_in(0)
    stages = list(transcription._STAGES.values())
    assert stages and all(st._hess is None for st in stages)
    transcription._STAGES.clear()
    _, kin_derivatives, nl = transcription.build_nlp(make_layout(spec, g1))
    assert kin_derivatives["hess_lag"].sparsity_out(0).size1() == nl.n_x
    assert transcription._STAGES and all(st._hess is not None for st in transcription._STAGES.values())


@pytest.mark.skipif(not Path("/proc/self/fd").is_dir(), reason="needs /proc")
def test_background_worker_is_detached(tmp_path):
    """The forked worker runs in its own session at a lower priority with its standard streams on
    /dev/null (a caller reading this process's output through a pipe does not wait for it), and
    removes its build folder."""
    folder = tmp_path / "build"
    folder.mkdir()
    report = tmp_path / "report.txt"

    def work() -> bool:
        fds = [os.readlink(f"/proc/self/fd/{fd}") for fd in (0, 1, 2)]
        report.write_text(f"{' '.join(fds)}\n{os.getsid(0)} {os.getpid()}\n{os.nice(0)}\n")
        return True

    before = os.nice(0)
    cache._fork_worker(folder, work)
    assert cache.wait_for_background(timeout=60) == [0]
    fds, session, nice = report.read_text().splitlines()
    assert fds.split() == [os.devnull] * 3
    sid, pid = session.split()
    assert sid == pid and int(pid) != os.getpid()  # a session leader: its own session
    assert int(nice) == min(19, before + cache.BACKGROUND_NICE)
    assert not folder.exists()
