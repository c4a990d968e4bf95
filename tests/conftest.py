"""Session-wide fixtures: robots are loaded once, random draws are seeded."""

from __future__ import annotations

import atexit
import os
import shutil
import signal
import tempfile

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy loads OpenBLAS: see planner/__init__.py

import numpy as np
import pytest
from hypothesis import settings

# The planner's own defaults build solvers in memory and read no stored solution (it reads no
# WBMP_* switch: wbmp/environment.py does, for the command line). These switches keep the command
# line's runs in the tests the same: solvers in memory (no gcc), nothing written to the user's
# solver cache (the cache tests set compile=True and their own cache_dir), and every plan from its
# own guess, whatever the tests before it (in this worker) planned: the solution library
# (planner/trajopt/library.py) would make a dynamic plan's local optimum depend on the order
# pytest-xdist hands out the tests. Its own tests switch it on (tests/planner/trajopt/test_library.py).
os.environ.setdefault("WBMP_COMPILE", "0")
os.environ.setdefault("WBMP_COMPILE_BACKGROUND", "0")  # tests that compile wait for gcc
os.environ.setdefault("WBMP_SOLUTION_LIBRARY", "off")


def _temporary_folder(variable: str, prefix: str) -> None:
    """``variable`` names a new temporary folder unless it is set; the process that made it (the
    pytest-xdist controller: its workers inherit the variable) removes it at exit. Each run used to
    leave its caches behind in /tmp (0.1-0.6 GB a process)."""
    if variable not in os.environ:
        os.environ[variable] = folder = tempfile.mkdtemp(prefix=prefix)
        atexit.register(shutil.rmtree, folder, ignore_errors=True)


_temporary_folder("WBMP_CACHE_DIR", "wbmp-test-cache-")

# Nothing is written into the checkout: no example database (derandomized runs replay nothing
# anyway), and hypothesis's own caches (charmap, constants) go to a temporary folder.
_temporary_folder("HYPOTHESIS_STORAGE_DIRECTORY", "wbmp-test-hypothesis-")
settings.register_profile("ci", derandomize=True, max_examples=60, deadline=None, database=None)
settings.load_profile("ci")

# A suite started in the background by a shell without job control (`make test &` in a script)
# inherits SIGINT ignored, and so would every command the signal tests start: they send Ctrl-C and
# expect it to stop the command. Python's own handler here makes the children start with the default.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)

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


# -- the source tree stays as it was -----------------------------------------------------------

_TOOL_CACHES = ("__pycache__", ".pytest_cache", ".mypy_cache", ".ruff_cache", ".venv", ".egg-info")


def _checkout_entries(root: str) -> set[str] | None:
    """Untracked and ignored paths of the checkout (git's view), less the tools' own caches."""
    import subprocess

    try:
        out = subprocess.run(["git", "status", "--porcelain", "--ignored", "--untracked-files=all"],
                             cwd=root, capture_output=True, text=True, timeout=60, check=True).stdout
    except (OSError, subprocess.SubprocessError):
        return None  # not a git checkout (an sdist): nothing to compare
    paths = {line[3:] for line in out.splitlines() if line[:2] in ("??", "!!")}
    return {p for p in paths if not any(c in p for c in _TOOL_CACHES)}


def pytest_sessionstart(session: pytest.Session) -> None:
    session.config._wbmp_entries = _checkout_entries(str(session.config.rootpath))  # type: ignore[attr-defined]


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    """Fail the run when a test left a file in the checkout (tests write below tmp_path only)."""
    before = getattr(session.config, "_wbmp_entries", None)
    if before is None or getattr(session.config.option, "collectonly", False):
        return
    after = _checkout_entries(str(session.config.rootpath)) or set()
    new = sorted(after - before)
    if new:
        reporter = session.config.pluginmanager.get_plugin("terminalreporter")
        if reporter is not None:
            reporter.ensure_newline()
            reporter.write_line(f"tests wrote into the source tree: {', '.join(new[:20])}", red=True)
        session.exitstatus = pytest.ExitCode.TESTS_FAILED


def pytest_collection_modifyitems(config, items):
    """Tests marked ``long`` (minutes each) run only with WBMP_LONG_TESTS=1 (``make test-long``):
    the suite must stay under 10 minutes on 2 cores."""
    if os.environ.get("WBMP_LONG_TESTS") == "1":
        return
    skip = pytest.mark.skip(reason="minutes long: run with WBMP_LONG_TESTS=1 (make test-long)")
    for item in items:
        if "long" in item.keywords:
            item.add_marker(skip)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    """With ``WBMP_TEST_CPU_LOG=FILE``, append one JSON line per test: its wall time and the CPU
    time of the test process and of the child processes it waited for (set-up, call and
    tear-down). Wall times mislead on a loaded machine; CPU is the suite's budget
    (docs/performance.md, "The test suite's budget")."""
    path = os.environ.get("WBMP_TEST_CPU_LOG")
    if not path:
        yield
        return
    import json
    import resource
    import time

    def cpu() -> tuple[float, float]:
        own, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
        return own.ru_utime + own.ru_stime, kids.ru_utime + kids.ru_stime

    wall0, (own0, kids0) = time.perf_counter(), cpu()
    yield
    own1, kids1 = cpu()
    line = {"test": item.nodeid, "wall": round(time.perf_counter() - wall0, 3),
            "cpu": round(own1 - own0, 3), "cpu_children": round(kids1 - kids0, 3)}
    with open(path, "a", encoding="utf-8") as f:
        f.write(json.dumps(line) + "\n")
