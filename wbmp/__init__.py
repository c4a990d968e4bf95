"""wbmp: whole-body motion planning for humanoid robots from a sentence.

This package is the command line and the pipeline that wires the layers together:
``language`` -> ``tasks`` -> ``planner`` -> ``sim`` -> ``viz``.
"""

import os
from importlib.metadata import PackageNotFoundError, version

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy and CasADi load OpenBLAS: see planner/__init__.py

try:
    __version__ = version("wbmp")
except PackageNotFoundError:  # running from a checkout without installing
    __version__ = "0.0.0+unknown"
