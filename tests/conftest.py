"""Session-wide fixtures: robots are loaded once, random draws are seeded."""

from __future__ import annotations

import os
import tempfile

import numpy as np
import pytest
from hypothesis import settings

# Solvers are built in memory (no gcc) unless a test asks for compilation, and nothing is
# written to the user's solver cache: the cache tests set compile=True and their own cache_dir.
os.environ.setdefault("WBMP_COMPILE", "0")
os.environ.setdefault("WBMP_COMPILE_BACKGROUND", "0")  # tests that compile wait for gcc
os.environ.setdefault("WBMP_CACHE_DIR", tempfile.mkdtemp(prefix="wbmp-test-cache-"))

settings.register_profile("ci", derandomize=True, max_examples=60, deadline=None)
settings.load_profile("ci")

ROBOT_NAMES = ("talos", "g1", "romeo", "icub")


@pytest.fixture(scope="session")
def talos():
    """The default robot, loaded once."""
    from robots import load_robot

    return load_robot("talos")


@pytest.fixture(scope="session")
def g1():
    """Unitree G1, loaded once."""
    from robots import load_robot

    return load_robot("g1")


@pytest.fixture(scope="session", params=ROBOT_NAMES)
def any_robot(request):
    """Each built-in robot in turn, loaded once per session."""
    from robots import load_robot

    return load_robot(request.param)


@pytest.fixture
def rng():
    """A seeded generator: every random draw in the suite is reproducible."""
    return np.random.default_rng(20261121)
