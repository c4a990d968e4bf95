"""wbmp: whole-body motion planning for humanoid robots from a sentence.

This package is the command line and the pipeline that wires the layers together:
``language`` -> ``tasks`` -> ``planner`` -> ``sim`` -> ``viz``.
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy and CasADi load OpenBLAS: see planner/__init__.py

# The one place the version is written: pyproject.toml reads it from here at build time
# ([tool.setuptools.dynamic]), so a checkout and an installed copy agree, and every command is
# spared importlib.metadata's look-up (~0.05 s at start-up).
__version__ = "0.3.0.dev0"
