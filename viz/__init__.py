"""Make plans visible: meshcat live viewer, one-file HTML replay, PNG plots, progress display.

Public entry points (pure functions over explicit objects; no module-level viewer):

- :func:`write_html` -- standalone HTML replay (no server, nothing fetched).
- :func:`serve` -- live meshcat viewer on 127.0.0.1 looping the motion.
- :func:`write_plots` -- PNGs: CoM/ZMP vs support polygon, joints vs limits, torques, forces,
  keyframes.
- :func:`plot_keypoints` -- a retargeted motion's keypoints against its source (``wbmp retarget --plot``).
- :mod:`viz.progress` -- a small stderr progress display (bar, quiet or JSON lines).

The entry points are imported lazily, so ``import viz.progress`` stays cheap (no meshcat,
matplotlib or Pinocchio import).
"""

from __future__ import annotations

from robots.lazy import lazy_face

__all__ = ["KeypointPlot", "VizError", "check_distinct", "check_output_dir", "check_output_file", "plot_keypoints",
           "serve", "write_html", "write_plots"]

_LAZY = {"write_html": "viz.html", "serve": "viz.live", "write_plots": "viz.plots", "VizError": "viz.exceptions",
         "KeypointPlot": "viz.retarget_plot", "plot_keypoints": "viz.retarget_plot", "check_distinct": "viz.files",
         "check_output_dir": "viz.files", "check_output_file": "viz.files"}


__getattr__, __dir__ = lazy_face(__name__, _LAZY)
