"""Solver cache: build each NLP structure once, reuse it in memory and across processes.

Key: a hash of the model (:func:`planner.symbolic.model_hash`), the layout's structure
(:meth:`planner.formulation.Layout.structure`), the solver options and the versions of CasADi
and of this formulation. Values (targets, placements, bounds) are parameters, so every spec
with the same structure shares one solver.

* In memory: a dict of live ``nlpsol`` objects (``cache = "memory"``).
* On disk (``settings.compile``): the NLP's functions (cost, constraints, their derivatives,
  the Lagrangian Hessian) are generated as C by CasADi, compiled by the system ``gcc`` into a
  shared library, and loaded with IPOPT through ``nlpsol(name, "ipopt", library)``
  (``cache = "disk"``). Each entry is a directory ``<cache_dir>/planner/<key>/`` with the
  library, the index bookkeeping (``meta.json``) and a checksum of the library; an entry
  whose checksum, key or files do not match is deleted and rebuilt, never trusted.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path

import casadi as ca
import numpy as np

from planner.formulation import Layout
from planner.settings import PlannerSettings
from planner.symbolic import model_hash

FORMULATION_VERSION = "1"  # bump when build_nlp changes the NLP for the same structure
_MEMORY: dict[str, object] = {}
_LOCK = threading.Lock()


def solver_key(lay: Layout, settings: PlannerSettings) -> str:
    """Hash of everything that shapes the solver (not the parameter values)."""
    from planner.trajopt import ipopt_options

    h = hashlib.sha256()
    h.update(FORMULATION_VERSION.encode())
    h.update(ca.__version__.encode())
    h.update(model_hash(lay.robot.model).encode())
    h.update(repr(lay.structure()).encode())
    h.update(json.dumps(ipopt_options(settings), sort_keys=True).encode())
    return h.hexdigest()[:24]


def clear_memory_cache() -> None:
    """Forget every in-process solver (the next plan rebuilds or loads from disk)."""
    with _LOCK:
        _MEMORY.clear()


def get_solver(lay: Layout, settings: PlannerSettings, progress: Callable[[str], None] | None = None):
    """The solver of a layout's structure: from memory, from disk, or freshly built."""
    from planner.trajopt import Solver, build_nlp, ipopt_options

    key = solver_key(lay, settings)
    if settings.use_cache:
        with _LOCK:
            hit = _MEMORY.get(key)
        if hit is not None:
            return Solver(function=hit.function, nlp_layout=hit.nlp_layout, origin="memory")
    t0 = time.perf_counter()
    solver = None
    entry = Path(settings.cache_dir) / "planner" / key
    if settings.use_cache and settings.compile:
        solver = _load_entry(entry, key, settings, progress)
    if solver is None:
        if progress:
            progress("building the solver for this task structure (first time; cached afterwards)")
        nlp, nl = build_nlp(lay)
        if settings.use_cache and settings.compile:
            solver = _compile_entry(entry, key, nlp, nl, settings, progress)
        if solver is None:
            function = ca.nlpsol("wbmp_plan", "ipopt", nlp, ipopt_options(settings))
            solver = Solver(function=function, nlp_layout=nl, origin="built")
    solver.build_time = time.perf_counter() - t0
    if settings.use_cache:
        with _LOCK:
            _MEMORY[key] = solver
    return solver


# -- disk entries -----------------------------------------------------------------------------

LIBRARY = "nlp.so"
META = "meta.json"


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _load_entry(entry: Path, key: str, settings: PlannerSettings, progress):
    from planner.trajopt import NlpLayout, Solver, ipopt_options

    lib, meta_path = entry / LIBRARY, entry / META
    if not entry.exists():
        return None
    try:
        meta = json.loads(meta_path.read_text())
        if meta.get("key") != key or meta.get("sha256") != _sha(lib):
            raise ValueError("key or checksum mismatch")
        nl = NlpLayout(n_x=int(meta["n_x"]), n_g=int(meta["n_g"]), term_rows=list(meta["term_rows"]),
                       velocity_rows=int(meta["velocity_rows"]),
                       velocity_joints=np.array(meta["velocity_joints"], dtype=int))
        if progress:
            progress("loading the compiled solver from the cache")
        function = ca.nlpsol("wbmp_plan", "ipopt", str(lib), ipopt_options(settings))
        if function.size1_in(0) != nl.n_x:
            raise ValueError("size mismatch")
        return Solver(function=function, nlp_layout=nl, origin="disk")
    except Exception:  # noqa: BLE001 - any defect in an entry means: rebuild it
        shutil.rmtree(entry, ignore_errors=True)
        return None


def _compile_entry(entry: Path, key: str, nlp: dict, nl, settings: PlannerSettings, progress):
    """Generate C code for the NLP, compile it, store it atomically; None if gcc fails."""
    from planner.trajopt import Solver, ipopt_options

    gcc = shutil.which("gcc")
    if gcc is None:
        return None
    entry.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{key}.", dir=entry.parent))
    try:
        if progress:
            progress("generating C code for the solver")
        builder = ca.nlpsol("wbmp_plan", "ipopt", nlp, ipopt_options(settings))
        cwd = os.getcwd()
        os.chdir(tmp)
        try:
            builder.generate_dependencies("nlp.c")
        finally:
            os.chdir(cwd)
        if progress:
            progress("compiling the solver with gcc (first time for this task structure)")
        cmd = [gcc, "-fPIC", "-shared", *settings.compile_flags, "nlp.c", "-o", LIBRARY, "-lm"]
        done = subprocess.run(cmd, cwd=tmp, capture_output=True, text=True, timeout=600)
        if done.returncode != 0:
            return Solver(function=builder, nlp_layout=nl, origin="built")
        (tmp / "nlp.c").unlink()
        meta = {
            "key": key, "sha256": _sha(tmp / LIBRARY), "n_x": nl.n_x, "n_g": nl.n_g,
            "term_rows": nl.term_rows, "velocity_rows": nl.velocity_rows,
            "velocity_joints": [int(i) for i in nl.velocity_joints],
            "casadi": ca.__version__, "created": time.time(),
        }
        (tmp / META).write_text(json.dumps(meta))
        shutil.rmtree(entry, ignore_errors=True)
        try:
            os.replace(tmp, entry)
        except OSError:  # another process stored it first
            shutil.rmtree(tmp, ignore_errors=True)
        return Solver(function=builder, nlp_layout=nl, origin="built")
    except (OSError, subprocess.SubprocessError, RuntimeError):
        shutil.rmtree(tmp, ignore_errors=True)
        return None
    finally:
        if tmp.exists() and tmp != entry:
            shutil.rmtree(tmp, ignore_errors=True)
