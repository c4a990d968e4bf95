"""Initial guess of a climb: every knot solved by inverse kinematics along an interpolated step.

The heading guess (:func:`planner.trajopt.centroidal.guess.heading_guess`) keeps the joints at the
standing posture and the base at its standing height: on a floor the stance soles are then close
to their placements, but on a step (a sole placed 10 cm up) the guess puts the legs through the
treads, the scene rows screened on it are thousands, and IPOPT must first pull the legs out of the
boxes. When some foot placement is off the floor (terrain, :mod:`tasks.terrain`), every variable
knot is instead solved by the planner's inverse kinematics (:func:`planner.trajopt.nominal.solve_ik`,
from the previous knot's solution):

* the contacts active at the knot fixed in 6D;
* a swinging sole on the path of a step onto a higher (or lower) surface: straight up from its
  lift-off placement to the phase's ``swing_height`` in the first third of the swing, across at
  that height in the second third, straight down onto its landing placement in the last third
  (smoothstep in each third; the orientation turned over the middle third); the same shape as
  the waypoints :func:`tasks.primitives.terrain` asks for;
* the CoM ground projection over the middle of the support polygon, averaged over
  :data:`COM_WINDOW` seconds around the knot (the weight shifts onto the stance foot before a
  lift-off, as the plan does).
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from planner.trajopt.layout_data import LayoutData

FLOOR_TOLERANCE = 1e-6  # [m] a foot placement this close to z = 0 is on the floor
COM_WINDOW = 0.3  # [s] the CoM target averages the support polygon's centre over this window
IK_ITERATIONS = 8  # Gauss-Newton steps per knot, from the previous knot's solution


def on_terrain(lay: LayoutData) -> bool:
    """Some foot placement of the layout is off the floor (z != 0)."""
    robot = lay.robot
    for active in lay.contacts_at:
        for fid, (_frame, M) in active.items():
            if robot.foot_side(robot.model.frames[fid].name) and abs(M.translation[2]) > FLOOR_TOLERANCE:
                return True
    return False


def _smoothstep(s: float) -> float:
    s = min(max(s, 0.0), 1.0)
    return s * s * (3.0 - 2.0 * s)


def swing_pose(M0: pin.SE3, M1: pin.SE3, height: float, s: float) -> pin.SE3:
    """The swinging sole at the fraction ``s`` in [0, 1] of its swing from ``M0`` to ``M1``: up to
    ``height`` [m] (the world's z), across, down (module docstring)."""
    p0, p1 = M0.translation, M1.translation
    top = max(height, p0[2], p1[2])
    if s < 1 / 3:
        z = p0[2] + (top - p0[2]) * _smoothstep(3 * s)
    elif s <= 2 / 3:
        z = top
    else:
        z = top + (p1[2] - top) * _smoothstep(3 * s - 2)
    a = _smoothstep(3 * s - 1)
    xy = (1 - a) * p0[:2] + a * p1[:2]
    R = M0.rotation @ pin.exp3(a * pin.log3(M0.rotation.T @ M1.rotation))
    return pin.SE3(R, np.array([xy[0], xy[1], z]))


def _swings(lay: LayoutData) -> dict[int, dict[int, pin.SE3]]:
    """Knot -> foot frame id -> the swinging sole's guessed pose (feet between two placements)."""
    robot = lay.robot
    feet = [robot.frame_id(f"{side}_foot") for side in ("left", "right")]
    out: dict[int, dict[int, pin.SE3]] = {}
    for fid in feet:
        k = 0
        while k <= lay.N:
            if fid in lay.contacts_at[k]:
                k += 1
                continue
            a = k
            while k <= lay.N and fid not in lay.contacts_at[k]:
                k += 1
            if a == 0 or k > lay.N:  # no lift-off or no landing placement: leave it to the solver
                continue
            M0, M1 = lay.contacts_at[a - 1][fid][1], lay.contacts_at[k][fid][1]
            height = lay.spec.phases[lay.phase_of_knot[(a + k - 1) // 2]].swing_height
            for j in range(a, k):
                out.setdefault(j, {})[fid] = swing_pose(M0, M1, height, (j - a + 1) / (k - a + 1))
    return out


def _com_targets(lay: LayoutData) -> np.ndarray:
    """(N+1, 2): the support polygon's centre per knot, averaged over :data:`COM_WINDOW`."""
    from planner.trajopt.layout import support_polygon

    centres = []
    last = np.zeros(2)
    for k in range(lay.N + 1):
        hull = support_polygon(lay, k)
        if len(hull) >= 3:
            last = hull.mean(axis=0)
        centres.append(last)
    C = np.array(centres)
    width = max(1, int(round(0.5 * COM_WINDOW / lay.dt)))
    padded = np.pad(C, ((width, width), (0, 0)), mode="edge")
    kernel = np.ones(2 * width + 1) / (2 * width + 1)
    return np.column_stack([np.convolve(padded[:, i], kernel, mode="valid") for i in range(2)])


def stepping_guess(lay: LayoutData) -> np.ndarray | None:
    """Chart displacements (N+1, nv) of the interpolated stepping, or None when every foot
    placement is on the floor (the heading guess serves) or a knot's inverse kinematics fails."""
    from planner.trajopt.nominal import solve_ik
    from planner.trajopt.symbolic import configuration_to_chart

    if not on_terrain(lay):
        return None
    model = lay.robot.model
    swings = _swings(lay)
    com = _com_targets(lay)
    dq = np.zeros((lay.N + 1, lay.robot.nv))
    q = np.array(lay.q_ref)
    for k in range(2, lay.N):
        tasks: list = [("com", None, np.array([com[k, 0], com[k, 1], 0.0]), (True, True, False))]
        for fid, M in swings.get(k, {}).items():
            tasks.append(("frame", fid, M.translation, (True, True, True)))
            tasks.append(("rot", fid, M.rotation, None))
        solved = solve_ik(lay, k, tasks, q, avoid_scene=False, iterations=IK_ITERATIONS)
        if solved is None or not np.all(np.isfinite(solved)):
            return None
        q = solved
        dq[k] = configuration_to_chart(model, lay.q_ref, q)
    dq[lay.N] = dq[lay.N - 1]
    if not math.isfinite(float(np.abs(dq).max())):
        return None
    return dq


__all__ = ["on_terrain", "stepping_guess", "swing_pose"]
