"""wbmp: whole-body motion planning for humanoid robots from a sentence.

This package is the command line and the pipeline that wires the layers together:
``language`` -> ``tasks`` -> ``planner`` -> ``sim`` -> ``viz``.
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("wbmp")
except PackageNotFoundError:  # running from a checkout without installing
    __version__ = "0.0.0+unknown"
