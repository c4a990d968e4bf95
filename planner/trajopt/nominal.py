"""A nominal motion to warm-start the NLP: inverse kinematics at the target times, interpolated.

At every knot that holds a HARD position target (frame or CoM), a damped Gauss-Newton solves
the static inverse kinematics with Pinocchio: the contacts active at that knot fixed in 6D, the
targets' positions reached, the CoM ground projection pulled towards where it stands, and the
smallest change from the standing posture. Between these keyframes (and the rest at both ends)
the tangent displacements are blended with a smoothstep. The result is only an initial guess:
the NLP enforces everything; when the inverse kinematics does not converge the standing posture
is used instead for that keyframe. A keyframe whose frame ends more than :data:`ROT_SEED_ANGLE`
from a HARD orientation target at that knot is solved again with the orientation too
(:func:`_rotation_goals`): G1's "touch your head" put the hand turned by pi from its target, where
the NLP's orientation rows (sines) vanish, and stayed INFEASIBLE there.

With a scene, the keyframes also keep the robot's sphere sets :data:`SCENE_CLEARANCE` away from
its objects (but in planned contacts, and not in motions that grasp or touch an object): a
least-squares row per sphere closer than that, along the
gradient of its exact distance to the whole object. Without them, the keyframe of "reach forward
30 cm" 10 cm over the table put the fingers 6 cm into it, and IPOPT took ~100 of its 150 iterations
to get the arm out (docs/collisions.md).
"""

from __future__ import annotations

from itertools import pairwise

import numpy as np
import pinocchio as pin

from planner.trajopt.kinds import (
    ClosedChainTerm,
    CoMPositionTerm,
    FrameOrientationTerm,
    FramePositionTerm,
)
from planner.trajopt.layout_data import LayoutData
from planner.trajopt.symbolic import configuration_to_chart

IK_ITERATIONS = 30
IK_DAMPING = 1e-3
CONTACT_WEIGHT = 10.0
COM_XY_WEIGHT = 1.0
REGULARIZATION = 1e-2  # pull towards the standing posture, per iteration
ROT_WEIGHT = 0.3  # [m/rad] an orientation error of the hands holding one object against a position error
SCENE_CLEARANCE = 0.02  # [m] keyframe spheres are pushed this far from scene objects (margin + 1 cm)
SCENE_WEIGHT = 1.0  # a scene row's weight against a target's position error
#: [rad] a keyframe whose frame ends farther than this from its HARD orientation target is solved
#: again with the orientation (the NLP's trace row keeps a target within 90 deg, and its sine rows
#: vanish at pi: a guess turned by pi stays there).
ROT_SEED_ANGLE = 0.25


def _keyframe_tasks(lay: LayoutData) -> dict[int, list]:
    """Knot -> list of ('frame', fid, goal, axes) / ('com', goal, axes) hard position targets."""
    out: dict[int, list] = {}
    for term in lay.terms:
        if isinstance(term, FramePositionTerm) and term.hard:
            out.setdefault(term.knot, []).append(("frame", term.frame_id, term.params[:3], term.axes))
        elif isinstance(term, CoMPositionTerm) and term.hard:
            out.setdefault(term.knot, []).append(("com", None, term.params[:3], term.axes))
    return out


def solve_ik(lay: LayoutData, knot: int, tasks: list, q0: np.ndarray | None = None,
             avoid_scene: bool = True, iterations: int = IK_ITERATIONS) -> np.ndarray | None:
    """Configuration meeting the contacts at ``knot`` and ``tasks`` (None if it does not converge),
    from ``q0`` (default: the reference posture), its spheres kept clear of the scene's objects
    (:class:`_SceneRows`) when ``avoid_scene``; when the contacts are not met with them, without;
    at most ``iterations`` Gauss-Newton steps."""
    robot = lay.robot
    model, data = robot.model, robot.data()
    q = np.array(lay.q_ref if q0 is None else q0)
    pin.framesForwardKinematics(model, data, q)
    com_xy0 = pin.centerOfMass(model, data, q)[:2].copy()
    contacts = lay.contacts_at[knot]
    scene = _SceneRows(lay, knot if avoid_scene else None)
    for _ in range(iterations):
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        rows, errs = [], []
        for fid, (_frame, M) in contacts.items():
            J = pin.getFrameJacobian(model, data, fid, pin.ReferenceFrame.LOCAL)
            err = pin.log6(M.actInv(data.oMf[fid])).vector
            rows.append(CONTACT_WEIGHT * pin.Jlog6(M.actInv(data.oMf[fid])) @ J)
            errs.append(CONTACT_WEIGHT * err)
        com = pin.centerOfMass(model, data, q)
        J_com = pin.jacobianCenterOfMass(model, data, q)
        has_com_xy = False
        for task in tasks:
            kind, fid, goal, axes = task
            sel = np.array(axes, dtype=bool)
            if kind == "frame":
                J = pin.getFrameJacobian(model, data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)[:3]
                rows.append(J[sel])
                errs.append((data.oMf[fid].translation - goal)[sel])
            elif kind == "rot":  # goal: a rotation matrix; weighted [m/rad] against the positions
                J = pin.getFrameJacobian(model, data, fid, pin.ReferenceFrame.LOCAL)[3:]
                rows.append(ROT_WEIGHT * J)
                errs.append(ROT_WEIGHT * pin.log3(goal.T @ data.oMf[fid].rotation))
            else:
                rows.append(J_com[sel])
                errs.append((com - goal)[sel])
                has_com_xy |= bool(sel[0] or sel[1])
        if not has_com_xy:
            rows.append(COM_XY_WEIGHT * J_com[:2])
            errs.append(COM_XY_WEIGHT * (com[:2] - com_xy0))
        scene.add(data, rows, errs)
        A = np.vstack(rows)
        e = np.concatenate(errs)
        reg = REGULARIZATION * pin.difference(model, lay.q_ref, q)
        reg[:6] = 0.0
        H = A.T @ A + (IK_DAMPING + REGULARIZATION) * np.eye(model.nv)
        step = -np.linalg.solve(H, A.T @ e + REGULARIZATION * reg)
        q = pin.integrate(model, q, step)
        lo, hi = model.lowerPositionLimit[7:], model.upperPositionLimit[7:]
        q[7:] = np.clip(q[7:], np.where(np.abs(lo) < 1e10, lo, -np.inf), np.where(np.abs(hi) < 1e10, hi, np.inf))
        if np.linalg.norm(step) < 1e-6:
            break
    pin.framesForwardKinematics(model, data, q)
    for fid, (_frame, M) in contacts.items():
        if np.linalg.norm(pin.log6(M.actInv(data.oMf[fid])).vector) > 1e-3:
            return solve_ik(lay, knot, tasks, q0, avoid_scene=False, iterations=iterations) if scene.objects else None
    return q


class _SceneRows:
    """The scene rows of a keyframe: for every robot sphere (the links' own sphere sets) closer than
    its radius + :data:`SCENE_CLEARANCE` to an object it is not in a planned contact with at the
    knot, ``SCENE_WEIGHT * (d - r - SCENE_CLEARANCE)`` with ``d`` the exact distance of its centre
    to the whole object (negative inside) and the row ``n^T J_c`` (``n`` its gradient)."""

    def __init__(self, lay: LayoutData, knot: int | None) -> None:
        from planner.trajopt.scene_collision import (
            contact_exclusions,
            obstacles,
            scene_sets,
            whole_obstacles,
        )

        self.model = lay.robot.model
        spec = lay.spec
        # A grasp or a touch brings the hands to an object on purpose, its targets placed by its
        # primitive: pushing the other links 2 cm away distorted those keyframes (the two-handed box
        # pick-up no longer converged).
        aimed = bool(spec.grasps) or any(t.touch is not None for t in spec.targets)
        self.objects = whole_obstacles(spec.scene) if knot is not None and not aimed else []
        if not self.objects:
            return
        self.sets = scene_sets(lay.robot)
        pieces = obstacles(lay.spec.scene)
        excluded = contact_exclusions(lay, self.sets, pieces)[knot]  # (S, pieces)
        self.allowed = np.array([~excluded[:, [i for i, p in enumerate(pieces) if p.name == ob.name]].any(axis=1)
                                 for ob in self.objects]).T  # (S, objects)
        self.joints = self.sets.joints[self.sets.sphere_owner]

    def add(self, data: pin.Data, rows: list, errs: list) -> None:
        """Append the rows of the spheres too close at ``data``'s placements (joint Jacobians computed)."""
        from planner.trajopt.scene_collision import exact_distance, in_object_frame

        if not self.objects:
            return
        H = np.array([data.oMi[int(j)].homogeneous for j in self.joints])
        world = np.einsum("sij,sj->si", H[:, :3, :3], self.sets.sphere_local) + H[:, :3, 3]
        reach = self.sets.sphere_radius + SCENE_CLEARANCE
        h = 1e-6
        for oi, ob in enumerate(self.objects):
            u = in_object_frame(ob, world)
            d = exact_distance(ob, u)
            for s in np.flatnonzero((d < reach) & self.allowed[:, oi]):
                grad = np.array([exact_distance(ob, u[s] + h * e) - exact_distance(ob, u[s] - h * e)
                                 for e in np.eye(3)]) / (2 * h)
                n = ob.rotation @ grad
                j = int(self.joints[s])
                J = pin.getJointJacobian(self.model, data, j, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
                J_c = J[:3] - pin.skew(world[s] - data.oMi[j].translation) @ J[3:]
                rows.append(SCENE_WEIGHT * (n @ J_c)[None, :])
                errs.append(SCENE_WEIGHT * np.array([d[s] - reach[s]]))


def _smoothstep(s: float) -> float:
    s = min(max(s, 0.0), 1.0)
    return s * s * (3.0 - 2.0 * s)


def nominal_motion(lay: LayoutData) -> np.ndarray:
    """Chart displacements (N+1, nv) of the nominal motion (zeros where no target asks)."""
    nv, N = lay.robot.nv, lay.N
    dq = np.zeros((N + 1, nv))
    tasks = _keyframe_tasks(lay)
    if not tasks:
        return dq
    keys: list[tuple[int, np.ndarray]] = [(1, np.zeros(nv))]
    rotations = _rotation_goals(lay)
    for k in sorted(tasks):
        q = solve_ik(lay, k, tasks[k])
        if q is not None and k in rotations:
            q = _with_rotations(lay, k, tasks[k], rotations[k], q)
        keys.append((k, np.zeros(nv) if q is None else configuration_to_chart(lay.robot.model, lay.q_ref, q)))
    if keys[-1][0] < N - 1:
        keys.append((N - 1, np.zeros(nv)))
    for (k0, d0), (k1, d1) in pairwise(keys):
        for k in range(k0, k1 + 1):
            s = _smoothstep((k - k0) / max(k1 - k0, 1))
            dq[k] = (1 - s) * d0 + s * d1
    _carry_between(lay, dq, tasks)
    dq[:2] = 0.0
    dq[N] = dq[N - 1]
    return dq


def _rotation_goals(lay: LayoutData) -> dict[int, list]:
    """Knot -> ``("rot", fid, rotation, None)`` IK tasks of the HARD orientation targets."""
    out: dict[int, list] = {}
    for t in lay.terms:
        if isinstance(t, FrameOrientationTerm) and t.hard:
            out.setdefault(t.knot, []).append(("rot", t.frame_id, np.array(t.params[:9]).reshape(3, 3).T, None))
    return out


def _with_rotations(lay: LayoutData, knot: int, tasks: list, rotations: list, q: np.ndarray) -> np.ndarray:
    """``q`` (the keyframe from positions), or when a frame there is more than
    :data:`ROT_SEED_ANGLE` from its orientation target, the keyframe solved with the orientations
    too (from the standing posture; ``q`` if that does not converge)."""
    model, data = lay.robot.model, lay.robot.data()
    pin.framesForwardKinematics(model, data, q)
    worst = max(float(np.linalg.norm(pin.log3(R.T @ data.oMf[fid].rotation))) for _, fid, R, _ in rotations)
    if worst <= ROT_SEED_ANGLE:
        return q
    turned = solve_ik(lay, knot, [*tasks, *rotations], iterations=3 * IK_ITERATIONS)
    return q if turned is None else turned


def _carry_between(lay: LayoutData, dq: np.ndarray, tasks: dict[int, list]) -> None:
    """Two hands holding one object (``frame_rel`` terms): the blend of keyframes found from
    positions only turns the hands about the object and spreads them (talos lowering a box: 0.30 to
    0.43 m), which the chain's rows forbid. Every knot from the first to the last that places both
    hands (HARD position and orientation targets) is solved again from the blend with both hands'
    positions and orientations: their targets where they have them, in between on the straight line
    (rotations: the geodesic) between the neighbouring targeted knots, the same fraction for both
    (the object moves rigidly)."""
    from planner.trajopt.symbolic import chart_to_configuration

    model = lay.robot.model
    pose: dict[int, dict[int, list]] = {}  # knot -> frame -> [position, rotation]
    for t in lay.terms:
        if isinstance(t, FramePositionTerm) and t.hard and all(t.axes):
            pose.setdefault(t.knot, {}).setdefault(t.frame_id, [None, None])[0] = np.array(t.params[:3])
        elif isinstance(t, FrameOrientationTerm) and t.hard:
            pose.setdefault(t.knot, {}).setdefault(t.frame_id, [None, None])[1] = np.array(t.params[:9]).reshape(3, 3).T
    chains = [t for t in lay.terms if isinstance(t, ClosedChainTerm)]
    for pair in {t.pair for t in chains}:
        chained = {t.knot for t in chains if t.pair == pair}
        placed = sorted(k for k, fr in pose.items()
                        if all(f in fr and fr[f][0] is not None and fr[f][1] is not None for f in pair))
        span = set(chained)  # with the placed knots that join the chained ones into runs
        grown = True
        while grown:
            more = {j for k in span for j in (k - 1, k + 1) if j in placed and j not in span}
            span |= more
            grown = bool(more)
        for k in sorted(span):
            if k in placed:
                goals = {f: pose[k][f] for f in pair}
            elif k in chained:
                k0 = max((j for j in placed if j < k), default=None)
                k1 = min((j for j in placed if j > k), default=None)
                if k0 is None or k1 is None:
                    continue
                s = _smoothstep((k - k0) / (k1 - k0))
                goals = {f: [(1 - s) * pose[k0][f][0] + s * pose[k1][f][0],
                             pose[k0][f][1] @ pin.exp3(s * pin.log3(pose[k0][f][1].T @ pose[k1][f][1]))] for f in pair}
            else:
                continue
            ik = [task for f in pair for task in (("frame", f, goals[f][0], (True, True, True)), ("rot", f, goals[f][1], None))]
            q = solve_ik(lay, k, ik, chart_to_configuration(model, lay.q_ref, dq[k]))
            if q is not None:
                dq[k] = configuration_to_chart(model, lay.q_ref, q)
