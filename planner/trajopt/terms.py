"""Term expressions: the CasADi rows and cost of each kind of :class:`~planner.trajopt.layout.Term`, and
the stage functions that evaluate every term of a knot (knots with the same terms share one)."""

from __future__ import annotations

import casadi as ca

from planner.exceptions import PlannerError
from planner.trajopt.layout import Layout, Term
from planner.trajopt.symbolic import SymbolicKinematics, rotation_error
from robots.model import Robot


def stage_groups(lay: Layout) -> list[tuple[tuple, list[int], list[list[int]]]]:
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


def stage_function(lay: Layout, term_ids: list[int], name: str) -> ca.Function:
    """SX function ``(dq[nv], q_ref[nq], p) -> (g, cost)`` of the terms at one knot."""
    robot = lay.robot
    kin = SymbolicKinematics(robot.model)
    dq = ca.SX.sym("dq", robot.nv)
    q_ref = ca.SX.sym("q_ref", robot.nq)
    terms = [lay.terms[i] for i in term_ids]
    frame_ids = sorted({t.structure[1] for t in terms if t.kind in FRAME_KINDS}
                       | {f for t in terms if t.kind == "frame_rel" for f in t.structure[1:3]})
    oMi = kin.joint_placements(q_ref, dq)
    k = {"com": kin.com(oMi), "frames": {f: kin.frame_placement(oMi, f)[::-1] for f in frame_ids}, "dq": dq,
         "oMi": oMi}
    n_p = sum(len(t.params) for t in terms)
    p = ca.SX.sym("p", n_p)
    rows, cost, offset = [], 0, 0
    for t in terms:
        r, c = term_expression(t, p[offset: offset + len(t.params)], k, q_ref, robot)
        offset += len(t.params)
        cost = cost + c
        if r is not None:
            rows.append(r)
    g = ca.vertcat(*rows) if rows else ca.SX.zeros(0)
    return ca.Function(name, [dq, q_ref, p], [g, cost], ["dq", "q_ref", "p"], ["g", "cost"])


FRAME_KINDS = ("contact", "clearance", "frame_pos", "frame_rot")


def term_expression(term: Term, p, kin: dict, q_ref, robot: Robot):
    """(constraint rows or None, cost) of one term, given its parameter symbol ``p``."""
    s = term.structure
    kind = term.kind
    if kind == "contact":
        pos, R = kin["frames"][s[1]]
        R_t = ca.reshape(p[3:12], 3, 3)
        return ca.vertcat(pos - p[0:3], rotation_error(R_t, R)), 0
    if kind == "clearance":
        pos, _ = kin["frames"][s[1]]
        return pos[2], 0
    if kind == "polygon":
        A = ca.reshape(p, s[1], 2)
        return ca.mtimes(A, kin["com"][0:2]), 0
    if kind == "com_box":
        return kin["com"][[i for i, a in enumerate(s[1]) if a]], 0
    if kind in ("frame_pos", "com_pos"):
        if kind == "frame_pos":
            pos, _ = kin["frames"][s[1]]
            axes, mode = s[2], s[3]
        else:
            pos = kin["com"]
            axes, mode = s[1], s[2]
        err = (pos - p[0:3])[[i for i, a in enumerate(axes) if a]]
        return _target_rows(err, mode, p[3])
    if kind == "frame_rot":
        _, R = kin["frames"][s[1]]
        err = rotation_error(ca.reshape(p[0:9], 3, 3), R)
        return _target_rows(err, s[2], p[9])
    if kind == "frame_rel":  # two hands holding one object (planner/trajopt/layout.py closed_chain_terms)
        (pa, Ra), (pb, Rb) = (_frame(kin, f, q_ref, robot) for f in s[1:3])
        rows = [pa + ca.mtimes(Ra, p[0:3]) - pb - ca.mtimes(Rb, p[3:6])]
        if s[3]:
            rows.append(rotation_error(ca.reshape(p[6:15], 3, 3), ca.mtimes(Ra.T, Rb)))
        return ca.vertcat(*rows), 0
    if kind == "collision":
        if "oMi" not in kin:  # a caller that built only frames (the centroidal Hessian): joints from dq
            kin["oMi"] = SymbolicKinematics(robot.model).joint_placements(q_ref, kin["dq"])
        return collision_rows(kin["oMi"], s, p), 0
    if kind == "scene":  # a robot sphere against a scene object (planner/trajopt/scene_collision.py)
        from planner.trajopt.scene_collision import scene_rows

        if "oMi" not in kin:
            kin["oMi"] = SymbolicKinematics(robot.model).joint_placements(q_ref, kin["dq"])
        return scene_rows(kin["oMi"], s, p), 0
    if kind == "joint":
        iv = s[1]
        value = q_ref[iv + 1] + kin["dq"][iv]  # one-dof joints: idx_q = idx_v + 1
        return None, p[1] * (value - p[0]) ** 2
    raise PlannerError(f"internal: unknown term kind {kind!r}")


def _frame(kin: dict, frame_id: int, q_ref, robot: Robot) -> tuple:
    """(position, rotation) of a frame: from the stage's frames, or (a caller that built other frames)
    from the joint placements."""
    if frame_id in kin["frames"]:
        return kin["frames"][frame_id]
    if "oMi" not in kin:
        kin["oMi"] = SymbolicKinematics(robot.model).joint_placements(q_ref, kin["dq"])
    return SymbolicKinematics(robot.model).frame_placement(kin["oMi"], frame_id)[::-1]


def collision_rows(oMi: list, structure: tuple, p):
    """Squared distances between spheres of two links (``collision`` term): ``p`` holds the centres
    in the joints' frames, column-major (3, n_a) then (3, n_b); a row ``|c_i - c_j|^2`` per sphere
    pair ``(i, j)`` of the structure's list."""
    _, ja, jb, na, nb, chosen = structure
    worlds = []
    for j, n, off in ((ja, na, 0), (jb, nb, 3 * na)):
        R, pos = oMi[j]
        local = ca.reshape(p[off: off + 3 * n], 3, n)
        worlds.append(ca.repmat(pos, 1, n) + ca.mtimes(R, local))
    wa, wb = worlds
    return ca.vertcat(*[ca.sumsqr(wa[:, i] - wb[:, j]) for i, j in chosen])


def _target_rows(err, mode: str, weight):
    if mode in ("eq", "box"):
        return err, 0
    return None, weight * ca.sumsqr(err)
