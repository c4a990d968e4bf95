"""The viz layer's exception base (the root of the project's errors: ``robots.exceptions.WbmpError``)."""

from __future__ import annotations

from robots import WbmpError


class VizError(WbmpError):
    """Base class of every error of a viewer, a plot or an output file (:class:`viz.files.OutputError`,
    :class:`viz.motion.VizInputError`, :class:`viz.live.ViewerError`)."""
