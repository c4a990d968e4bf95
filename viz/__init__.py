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

from typing import TYPE_CHECKING

from robots.lazy import lazy_face

if TYPE_CHECKING:
    from viz.exceptions import VizError
    from viz.files import (
        OutputError,
        OutputPathError,
        Staging,
        check_distinct,
        check_output_dir,
        check_output_file,
    )
    from viz.html import page_data, render_page, write_html
    from viz.live import serve
    from viz.plots import PLOT_FILES, write_plots
    from viz.retarget_plot import KeypointPlot, plot_keypoints

__all__ = ["PLOT_FILES", "KeypointPlot", "OutputError", "OutputPathError", "Staging", "VizError", "check_distinct",
           "check_output_dir", "check_output_file", "page_data", "plot_keypoints", "render_page", "serve", "write_html",
           "write_plots"]

_LAZY = {"write_html": "viz.html", "serve": "viz.live", "write_plots": "viz.plots", "VizError": "viz.exceptions",
         # the output-path rules and staged writes every command's files go through (wbmp/outputs.py)
         "OutputError": "viz.files", "OutputPathError": "viz.files", "Staging": "viz.files",
         "check_distinct": "viz.files", "check_output_dir": "viz.files", "check_output_file": "viz.files",
         # the HTML replay in two steps (its data is kept in the motion cache) and the plot files' names
         "page_data": "viz.html", "render_page": "viz.html", "PLOT_FILES": "viz.plots",
         # a retargeted motion's keypoints against the scaled source (wbmp retarget --plot)
         "KeypointPlot": "viz.retarget_plot", "plot_keypoints": "viz.retarget_plot"}


__getattr__, __dir__ = lazy_face(__name__, _LAZY)
