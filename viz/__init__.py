"""Make plans visible: meshcat live viewer, one-file HTML replay, PNG plots, progress display.

Public entry points (pure functions over explicit objects; no module-level viewer):

- :func:`write_html` -- standalone HTML replay (no server, nothing fetched).
- :func:`serve` -- live meshcat viewer on 127.0.0.1 looping the motion.
- :func:`write_plots` -- PNGs: CoM/ZMP vs support polygon, joints vs limits, torques, forces,
  keyframes.
- :mod:`viz.progress` -- a small stderr progress display (bar, quiet or JSON lines).
"""

from __future__ import annotations

import warnings

with warnings.catch_warnings():  # pyzmq (imported by meshcat) warns on import under numpy 2
    warnings.simplefilter("ignore", DeprecationWarning)
    import meshcat  # noqa: F401

from viz.html import write_html  # noqa: E402

__all__ = ["write_html"]
