"""Planar polygons of the ground plane: the convex hull of sole corners (support polygons)."""

from __future__ import annotations

import numpy as np


def convex_hull(points: np.ndarray) -> np.ndarray:
    """Counter-clockwise convex hull (H, 2) of points in the ground plane [m].

    Andrew's monotone chain. ``points`` is (n, 2) or (n, 3) (the third column is ignored);
    points closer than 1e-12 m are merged and collinear points are dropped. Fewer than three
    distinct points are returned as they are (sorted).
    """
    pts = sorted({(round(float(x), 12), round(float(y), 12)) for x, y in np.asarray(points, dtype=float)[:, :2]})
    if len(pts) <= 2:
        return np.array(pts, dtype=float).reshape(-1, 2)

    def cross(o, a, b) -> float:
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower: list = []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    upper: list = []
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    return np.array(lower[:-1] + upper[:-1], dtype=float)
