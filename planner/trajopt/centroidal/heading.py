"""The heading guess of a dynamic plan's chart: the base follows the feet, the joints stay at the
reference (the data of a layout only: the dynamic layout's parts are built from it)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from planner.trajopt.layout_data import LayoutData


def heading_guess(lay: LayoutData) -> np.ndarray:
    """Initial guess of the chart displacements (N+1, nv): the base follows the feet.

    At each knot the base keeps its standing pose relative to the *heading* of the placements in
    use (the mean position and yaw of the feet's latest contact placements), interpolated
    linearly in time between consecutive touch-downs; the joints stay at the reference. This
    keeps the contact rotation errors small for turns (the antisymmetric rotation error is
    singular at 90 degrees) and the feet close to their placements for steps.

    Args:
        lay: The layout (``q_ref`` is the standing posture the chart is centred on).

    Returns:
        ``dq`` per knot; knots 0 and 1 are zero.
    """
    robot = lay.robot
    feet = [robot.frame_id(f"{s}_foot") for s in ("left", "right")]
    latest: dict[int, pin.SE3] = {}
    data = robot.data()
    pin.framesForwardKinematics(robot.model, data, lay.q_ref)
    for fid in feet:
        latest[fid] = pin.SE3(data.oMf[fid])
    start = _mean_heading([latest[f] for f in feet])
    headings = []
    for active in lay.contacts_at:
        for fid, (_frame, M) in active.items():
            if fid in latest:
                latest[fid] = M
        headings.append(_mean_heading([latest[f] for f in feet]))
    # smooth the jumps of the heading (a swing moves it at touch-down) by a centred moving average
    H = np.array(headings)
    H[:, 2] = np.unwrap(H[:, 2])
    width = max(1, int(round(0.5 * (lay.N + 1) / max(1, len(lay.spec.phases)))))
    kernel = np.ones(2 * width + 1) / (2 * width + 1)
    padded = np.pad(H, ((width, width), (0, 0)), mode="edge")
    H = np.column_stack([np.convolve(padded[:, i], kernel, mode="valid") for i in range(3)])
    base_ref = lay.q_ref[:3]
    R_ref = pin.Quaternion(lay.q_ref[3:7]).matrix()
    rel = base_ref[:2] - start[:2]
    rel_local = _rz2(-start[2]) @ rel
    dq = np.zeros((lay.N + 1, robot.nv))
    for k in range(2, lay.N + 1):
        x, y, yaw = H[k]
        dyaw = yaw - start[2]
        p = np.array([*(np.array([x, y]) + _rz2(yaw) @ rel_local), base_ref[2]])
        dq[k, :3] = R_ref.T @ (p - base_ref)
        dq[k, 3:6] = R_ref.T @ np.array([0.0, 0.0, dyaw])
    return dq


def _rz2(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s], [s, c]])


def _mean_heading(placements: Sequence[pin.SE3]) -> np.ndarray:
    yaws = [math.atan2(M.rotation[1, 0], M.rotation[0, 0]) for M in placements]
    yaw = math.atan2(sum(math.sin(y) for y in yaws), sum(math.cos(y) for y in yaws))
    mid = np.mean([M.translation[:2] for M in placements], axis=0)
    return np.array([mid[0], mid[1], yaw])
