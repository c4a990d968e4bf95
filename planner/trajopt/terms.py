"""The stage functions that evaluate every term of a knot (knots with the same terms share one),
each term through its own CasADi expression (:meth:`planner.trajopt.term.Term.expression`; the
kinds: :mod:`planner.trajopt.kinds`, self-collision, scene collision), and the registry of the
kinds (:func:`term_kinds`)."""

from __future__ import annotations

import casadi as ca

import planner.trajopt.collision
import planner.trajopt.kinds
import planner.trajopt.scene_collision  # noqa: F401 - the modules that define term kinds register them
from planner.trajopt.layout_data import LayoutData
from planner.trajopt.symbolic import SymbolicKinematics
from planner.trajopt.term import TERM_KINDS, StageKinematics, Term


def stage_groups(lay: LayoutData) -> list[tuple[tuple, list[int], list[list[int]]]]:
    """Variable knots grouped by the structure of their terms: (signature, knots, terms per knot)."""
    per_knot: dict[int, list[int]] = {k: [] for k in lay.variable_knots}
    for i, term in enumerate(lay.terms):
        per_knot[term.knot].append(i)
    groups: dict[tuple, tuple[list[int], list[list[int]]]] = {}
    for k, idx in per_knot.items():
        sig = tuple((lay.terms[i].structure, len(lay.terms[i].params), lay.terms[i].n_rows) for i in idx)
        knots, terms = groups.setdefault(sig, ([], []))
        knots.append(k)
        terms.append(idx)
    return [(sig, knots, terms) for sig, (knots, terms) in groups.items()]


def stage_function(lay: LayoutData, term_ids: list[int], name: str) -> ca.Function:
    """SX function ``(dq[nv], q_ref[nq], p) -> (g, cost)`` of the terms at one knot."""
    robot = lay.robot
    kin = SymbolicKinematics(robot.model)
    dq = ca.SX.sym("dq", robot.nv)
    q_ref = ca.SX.sym("q_ref", robot.nq)
    terms = [lay.terms[i] for i in term_ids]
    frame_ids = sorted({f for t in terms for f in t.frames()})
    oMi = kin.joint_placements(q_ref, dq)
    stage = StageKinematics(robot, q_ref, dq, kin.com(oMi),
                            {f: kin.frame_placement(oMi, f)[::-1] for f in frame_ids}, oMi)
    n_p = sum(len(t.params) for t in terms)
    p = ca.SX.sym("p", n_p)
    rows, cost, offset = [], 0, 0
    for t in terms:
        r, c = t.expression(p[offset: offset + len(t.params)], stage)
        offset += len(t.params)
        cost = cost + c
        if r is not None:
            rows.append(r)
    g = ca.vertcat(*rows) if rows else ca.SX.zeros(0)
    return ca.Function(name, [dq, q_ref, p], [g, cost], ["dq", "q_ref", "p"], ["g", "cost"])


def term_kinds() -> dict[str, type[Term]]:
    """Every term kind the planner knows, by name (the kinematic kinds, self-collision and scene
    collision): the registry :data:`planner.trajopt.term.TERM_KINDS` once their modules are loaded."""
    return dict(TERM_KINDS)
