"""A gcc killed at the compile timeout leaves nothing in the system's temporary folder.

The solver's gcc runs with ``TMPDIR`` set to the temporary build folder (``planner/trajopt/cache.py``
``_run_gcc``; the solver's compile command also has ``-pipe``): a killed cc1 used to leave its
assembly (0.1-0.5 GB for a Talos solver) as /tmp/cc*.s, and a disk filled up with them.
"""

from __future__ import annotations

import shutil

import pytest

from planner.trajopt.cache import _run_gcc

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None, reason="needs gcc")


def _big_c_file(path, n=4000):
    body = "\n".join(f"double f{i}(double x) {{ return x * {i}.5 + f{i - 1}(x) * 0.5; }}" for i in range(1, n))
    path.write_text("double f0(double x) { return x; }\n" + body + "\n")


@pytest.fixture
def folders(tmp_path, monkeypatch):
    """(the system's temporary folder, set as TMPDIR; the solver's build folder), both empty."""
    system_tmp, build = tmp_path / "system-tmp", tmp_path / "build"
    system_tmp.mkdir()
    build.mkdir()
    monkeypatch.setenv("TMPDIR", str(system_tmp))
    return system_tmp, build


def test_a_killed_gcc_leaves_nothing_in_tmpdir(folders):
    system_tmp, build = folders
    _big_c_file(build / "nlp.c")
    gcc = shutil.which("gcc")
    # -O2 on 4,000 chained functions takes seconds: the 0.3 s timeout kills it while it compiles
    ok = _run_gcc([gcc, "-fPIC", "-shared", "-O2", "nlp.c", "-o", "nlp.so"], build, timeout=0.3)
    assert not ok
    assert list(system_tmp.iterdir()) == []


def test_gcc_builds_with_its_temporaries_in_the_build_folder(folders):
    system_tmp, build = folders
    (build / "nlp.c").write_text("double twice(double x) { return 2 * x; }\n")
    assert _run_gcc([shutil.which("gcc"), "-fPIC", "-shared", "nlp.c", "-o", "nlp.so"], build, timeout=120)
    assert (build / "nlp.so").stat().st_size > 0
    assert list(system_tmp.iterdir()) == []
