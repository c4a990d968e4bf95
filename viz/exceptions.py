"""The viz layer's exception base (the root of the project's errors: ``robots.exceptions.WbmpError``)."""

from __future__ import annotations

from robots import WbmpError


class VizError(WbmpError):
    """Base class of every error of a viewer, a plot or an output file (:class:`viz.files.OutputError`,
    :class:`viz.motion.VizInputError`, :class:`viz.live.ViewerError`)."""


class OutputError(VizError):
    """An output could not be written; the message is one line for the user."""


class OutputPathError(OutputError, ValueError):
    """An output path wbmp will not write; the message names the option, the path and why."""


class OutputWriteError(OutputError):
    """Writing or renaming an output failed (disk full, file too large, folder changed...).

    Nothing was left behind: the temporary files are removed, and so are the outputs this
    command had created.
    """


class ViewerError(RuntimeError, VizError):
    """The live viewer could not start or lost its server."""


class VizInputError(ValueError, VizError):
    """A motion given to a viewer or plot has the wrong shape or is empty."""
