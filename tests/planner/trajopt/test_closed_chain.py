"""Two hands holding one object (planner/trajopt/layout.py ``closed_chain_terms``): the layout puts a
``frame_rel`` term at every variable knot of the shared hold where the hands are not both pinned by
6D targets (the lowering between the lift and the put-down), its rows are what Pinocchio gives for
the object's centre as placed by each hand and for the hands' relative orientation, and the press
targets themselves satisfy it (the closed chain agrees with the grasp). No solve: fast."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin

from language import parse
from planner.trajopt.layout import CHAIN_TOLERANCE, make_layout
from planner.trajopt.terms import stage_function
from tasks.compose import compile_actions
from tasks.scene import load_scene
from tests.planner.trajopt.fd import check_stage_rows

BOX_ON_COUNTER = Path(__file__).resolve().parents[3] / "examples" / "scenes" / "box_on_counter.json"


def _rot_vee(M: np.ndarray) -> np.ndarray:
    return 0.5 * np.array([M[2, 1] - M[1, 2], M[0, 2] - M[2, 0], M[1, 0] - M[0, 1]])


def test_two_hands_on_one_box_are_a_closed_chain_over_the_hold(talos):
    scene = load_scene(BOX_ON_COUNTER)
    spec = compile_actions(list(parse("pick up the red box with both hands, then put it down").actions), talos,
                           scene=scene)
    a, b = spec.grasps
    lay = make_layout(spec, talos)
    chain = [t for t in lay.terms if t.kind == "frame_rel"]
    expected_knots = [k for k in lay.variable_knots if a.start - 1e-9 <= lay.t[k] <= a.end + 1e-9]
    windows = {t.name.split(": ", 1)[1]: t.window for t in spec.targets if t.frame == a.frame and t.window}
    lift_end, down_start = windows["left hand lifts the red box"][1], windows["left hand puts the red box down"][0]
    gap = [k for k in expected_knots if lift_end + 1e-9 < lay.t[k] < down_start - 1e-9]  # the lowering: no targets
    press = [k for k in expected_knots if lay.t[k] <= windows["left hand presses the red box"][1] + 1e-9]
    knots = {t.knot for t in chain}
    assert set(gap) <= knots and len(gap) > 10  # every knot of the lowering
    assert knots <= set(expected_knots) and not knots & set(press)  # the press pins both hands already
    assert all(t.structure[3] and t.n_rows == 6 for t in chain)  # position and orientation rows
    assert np.all(chain[0].upper[:3] < CHAIN_TOLERANCE) and np.all(chain[0].upper[:3] > 0.5 * CHAIN_TOLERANCE / np.sqrt(3))

    # the press targets (both hands, at the grasp's start) satisfy the chain: one box centre, their own rotation
    press = {t.frame: t for t in spec.targets if t.name.endswith("presses the red box")}
    Ma, Mb = (pin.SE3(pin.rpy.rpyToMatrix(*press[g.frame].rpy), np.array(press[g.frame].position)) for g in (a, b))
    centre_a, centre_b = Ma.act(np.array(a.offset)), Mb.act(np.array(b.offset))
    assert np.linalg.norm(centre_a - centre_b) < 1e-3, (centre_a, centre_b)
    np.testing.assert_allclose(chain[0].params[6:15].reshape(3, 3).T, Ma.rotation.T @ Mb.rotation, atol=1e-9)

    # the rows against Pinocchio at random configurations, and their Jacobian against finite differences
    fn = stage_function(lay, [lay.terms.index(chain[0])], "chain_stage")
    p = chain[0].params
    fa, fb = talos.frame_id(a.frame), talos.frame_id(b.frame)
    R_rel = p[6:15].reshape(3, 3).T
    data = talos.model.createData()

    def reference(q):
        pin.framesForwardKinematics(talos.model, data, q)
        A, B = data.oMf[fa], data.oMf[fb]
        want = np.concatenate([A.act(np.array(a.offset)) - B.act(np.array(b.offset)),
                               _rot_vee(R_rel.T @ A.rotation.T @ B.rotation)])
        assert np.abs(want[:3]).max() > 0.01  # a random posture breaks the chain: the rows are not trivially 0
        return want

    check_stage_rows(fn, talos, p, reference, seed=3, atol=1e-10)


def test_one_hand_holding_an_object_is_no_chain(talos):
    scene = load_scene(BOX_ON_COUNTER)
    spec = compile_actions(list(parse("pick up the red box").actions), talos, scene=scene)
    assert len(spec.grasps) == 1
    assert not [t for t in make_layout(spec, talos).terms if t.kind == "frame_rel"]
