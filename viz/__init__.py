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

from robots import lazy_face

if TYPE_CHECKING:
    from viz.exceptions import (
        OutputError,
        OutputPathError,
        OutputWriteError,
        ViewerError,
        VizError,
        VizInputError,
    )
    from viz.files import (
        Staging,
        atomic_write,
        atomic_write_text,
        signals_held,
    )
    from viz.html import meshcat_bundle, page_data, render_page, write_html
    from viz.live import serve
    from viz.plots import PLOT_FILES, write_plots
    from viz.progress import make_progress
    from viz.retarget_plot import KeypointPlot, plot_keypoints

__all__ = [
    "PLOT_FILES",
    "KeypointPlot",
    "OutputError",
    "OutputPathError",
    "OutputWriteError",
    "Staging",
    "ViewerError",
    "VizError",
    "VizInputError",
    "atomic_write",
    "atomic_write_text",
    "make_progress",
    "meshcat_bundle",
    "page_data",
    "plot_keypoints",
    "render_page",
    "serve",
    "signals_held",
    "write_html",
    "write_plots",
]

_LAZY = {
    "KeypointPlot": "viz.retarget_plot",
    "OutputError": "viz.exceptions",
    "OutputPathError": "viz.exceptions",
    "OutputWriteError": "viz.exceptions",
    "PLOT_FILES": "viz.plots",
    "Staging": "viz.files",
    "ViewerError": "viz.exceptions",
    "VizError": "viz.exceptions",
    "VizInputError": "viz.exceptions",
    "atomic_write": "viz.files",
    "atomic_write_text": "viz.files",
    "signals_held": "viz.files",
    "make_progress": "viz.progress",
    "meshcat_bundle": "viz.html",
    "page_data": "viz.html",
    "plot_keypoints": "viz.retarget_plot",
    "render_page": "viz.html",
    "serve": "viz.live",
    "write_html": "viz.html",
    "write_plots": "viz.plots",
}


__getattr__, __dir__ = lazy_face(__name__, _LAZY)
