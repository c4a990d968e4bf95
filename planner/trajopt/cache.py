"""Solver cache: build each NLP structure once, reuse it in memory and across processes.

Key: a hash of the model (:func:`planner.trajopt.symbolic.model_hash`), the layout's structure
(:meth:`planner.trajopt.layout.Layout.structure`), the solver options, the CasADi version and the
planner sources that shape the NLP (:func:`code_hash`). Values (targets, placements, bounds) are parameters, so every spec
with the same structure shares one solver.

* In memory: a dict of live ``nlpsol`` objects (``cache = "memory"``).
* On disk (``settings.compile``): the NLP's functions (cost, constraints, their derivatives,
  the Lagrangian Hessian) are generated as C by CasADi, compiled by the system ``gcc`` into a
  shared library, and loaded with IPOPT through ``nlpsol(name, "ipopt", library)``
  (``cache = "disk"``). With ``settings.background_compile`` a forked child generates the C
  code and compiles it while this process solves in memory. At most one build runs per cache,
  and only with the memory it needs (:mod:`planner.trajopt.builds`); a structure that finds a
  build running, or too little memory, is solved in memory and built by its next solve. Each entry is a directory ``<cache_dir>/planner/<key>/`` with the
  library, its manifest (``meta.json``: key, size and checksum of the library, problem sizes)
  and a ``verified`` marker. An entry is checked before anything is loaded into this process
  (:mod:`planner.trajopt.cache_disk`: a truncated or forged library must not crash it); a damaged one
  is removed with one warning and rebuilt, never trusted.
* On disk, serialized (``settings.serialize``: the dynamic plans, whose C code takes minutes to
  compile and is no faster than CasADi's virtual machine): the NLP function and its three
  derivative functions written by CasADi's serializer into ``<key>/nlp.casadi`` (manifest
  ``"format": "casadi"``), read back and handed to ``nlpsol`` in the next process
  (``cache = "disk"``): the same functions, so the same iterates bit for bit. Reading the Talos
  4-step solver (~140 MB) costs ~1.2 s of CPU instead of ~3 s of building it. The building process
  writes the entry from a forked child (``settings.background_compile``) while it solves.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import os
import shutil
import signal
import subprocess
import tempfile
import threading
import time
from collections import OrderedDict
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import casadi as ca

from planner.trajopt import builds, cache_disk
from planner.trajopt.cache_disk import LIBRARY, META, SERIALIZED, EntryDamaged
from planner.trajopt.layout import Layout
from planner.trajopt.settings import PlannerSettings
from planner.trajopt.symbolic import model_hash
from robots import mark_used, trim_cache, write_text_atomic

if TYPE_CHECKING:
    from planner.trajopt.transcription import Solver

FORMULATION_VERSION = "3"  # bump when build_nlp changes the NLP for the same structure
MEMORY_ENTRIES = 24  # solvers kept alive in a process (least recently used dropped first)
_MEMORY: OrderedDict[str, Solver] = OrderedDict()
_LOCK = threading.Lock()
_SOURCES = (  # relative to planner/trajopt/: the files that determine the compiled structure
    "symbolic.py", "layout_data.py", "layout.py", "term.py", "terms.py", "kinds.py", "collision.py", "scene_collision.py",
    "transcription.py", "ipopt.py", "cache.py",
    "centroidal/settings.py", "centroidal/physics.py", "centroidal/contacts.py", "centroidal/pattern.py",
    "centroidal/heading.py", "centroidal/tracking.py", "centroidal/data.py", "centroidal/nlp.py", "centroidal/layout.py", "cache_disk.py",
)


@functools.cache
def code_hash() -> str:
    """Hash of the planner sources that shape the NLP: an edited formulation never loads an
    entry compiled from the old one."""
    h = hashlib.sha256()
    for name in _SOURCES:
        h.update((Path(__file__).parent / name).read_bytes())
    return h.hexdigest()[:16]


def solver_key(lay: Layout, settings: PlannerSettings) -> str:
    """Hash of everything that shapes the solver (not the parameter values)."""
    from planner.trajopt.ipopt import ipopt_options

    h = hashlib.sha256()
    h.update(FORMULATION_VERSION.encode())
    h.update(code_hash().encode())
    h.update(ca.__version__.encode())
    h.update(model_hash(lay.robot.model).encode())
    h.update(repr(lay.structure()).encode())
    h.update(json.dumps(ipopt_options(settings), sort_keys=True).encode())
    if settings.cache.serialize and not settings.cache.compile:
        h.update(b"serialized")  # another kind of entry than a compiled one
    return h.hexdigest()[:24]


def clear_memory_cache() -> None:
    """Forget every in-process solver (the next plan rebuilds or loads from disk)."""
    with _LOCK:
        _MEMORY.clear()


def get_solver(lay: Layout, settings: PlannerSettings, progress: Callable[[str], None] | None = None):
    """The solver of a layout's structure: from memory, from disk, or freshly built."""
    from planner.trajopt.ipopt import ipopt_options
    from planner.trajopt.transcription import Solver, build_nlp

    key = solver_key(lay, settings)
    if settings.cache.use_cache:
        with _LOCK:
            hit = _MEMORY.get(key)
            if hit is not None:
                _MEMORY.move_to_end(key)
        if hit is not None:
            return Solver(function=hit.function, nlp_layout=hit.nlp_layout, origin="memory")
    t0 = time.perf_counter()
    solver = None
    entry = Path(settings.cache.cache_dir) / "planner" / key
    disk = settings.cache.use_cache and settings.cache.compile
    serial = settings.cache.use_cache and settings.cache.serialize and not disk
    if disk or serial:
        cache_disk.sweep(entry.parent)  # stale temporary build folders (once per process)
    if disk:
        solver = _load_entry(lay, entry, key, settings, progress)
    elif serial:
        solver = _load_serialized(lay, entry, key, settings, progress)
    if solver is None:
        if progress:
            progress("building the solver for this task structure (first time; cached afterwards)")
        nlp, derivatives, nl = build_nlp(lay)
        if disk and cache_disk.usable_folder(entry.parent):
            solver = _compile_entry(entry, key, nlp, derivatives, nl, settings, progress)
            compiled = _load_entry(lay, entry, key, settings, None)
            if compiled is not None:
                compiled.origin = "built"
                solver = compiled
        if solver is None:
            function = ca.nlpsol("wbmp_plan", "ipopt", nlp, {**ipopt_options(settings), **derivatives})
            solver = Solver(function=function, nlp_layout=nl, origin="built")
            if serial and cache_disk.usable_folder(entry.parent):
                _store_serialized(entry, key, nlp, derivatives, nl, settings)
    solver.build_time = time.perf_counter() - t0
    if settings.cache.use_cache:
        with _LOCK:
            _MEMORY[key] = solver
            while len(_MEMORY) > MEMORY_ENTRIES:
                _MEMORY.popitem(last=False)
    return solver


# -- disk entries -----------------------------------------------------------------------------

ORACLE_FUNCTIONS = ("nlp_f", "nlp_g", "nlp_grad_f", "nlp_jac_g", "nlp_hess_l", "nlp_grad")
LIBRARY_FUNCTIONS = ("nlp", *ORACLE_FUNCTIONS)


def _load_entry(lay: Layout, entry: Path, key: str, settings: PlannerSettings, progress):
    """The entry's compiled solver, or None: missing, or damaged (then removed, with a warning).

    Nothing is mapped into this process before :func:`planner.trajopt.cache_disk.check_files` and
    :func:`planner.trajopt.cache_disk.verify_loadable` passed.
    """
    from planner.trajopt.ipopt import ipopt_options
    from planner.trajopt.transcription import Solver, make_nlp_layout

    try:
        seen = os.lstat(entry)
    except OSError:  # missing; or the cache folder is a file or cannot be searched
        return None
    mark_used(entry)  # its use time, for the size cap: an entry being read is not removed
    try:
        meta, digest = cache_disk.check_files(entry, key, seen)
        nl = make_nlp_layout(lay)
        if (meta["n_x"], meta["n_g"]) != (nl.n_x, nl.n_g):
            raise EntryDamaged(f"{META} is for {meta['n_x']} variables and {meta['n_g']} constraints, "
                               f"not {nl.n_x} and {nl.n_g}")
        cache_disk.verify_loadable(entry, digest, LIBRARY_FUNCTIONS, progress)
        if progress:
            progress("loading the compiled solver from the cache")
        try:
            function = ca.nlpsol("wbmp_plan", "ipopt", str(entry / LIBRARY), ipopt_options(settings))
        except RuntimeError as e:
            first = str(e).strip().splitlines()[0][:200] if str(e).strip() else type(e).__name__
            raise EntryDamaged(f"{LIBRARY} did not load ({first})") from None
        if function.sparsity_in("x0").size1() != nl.n_x or function.sparsity_in("lbg").size1() != nl.n_g:
            raise EntryDamaged(f"{LIBRARY} holds a solver of other sizes than {META} says")
        return Solver(function=function, nlp_layout=nl, origin="disk")
    except EntryDamaged as e:
        cache_disk.discard(entry, seen, str(e))
        return None
    except OSError as e:  # unreadable (permissions), or removed by another process meanwhile
        cache_disk.discard(entry, seen, f"it could not be read: {e.strerror or e}")
        return None


SERIALIZED_FUNCTIONS = ("nlp", "nlp_grad_f", "nlp_jac_g", "nlp_hess_l")  # in the order stored


def _load_serialized(lay: Layout, entry: Path, key: str, settings: PlannerSettings, progress):
    """The entry's serialized solver, or None: missing, or damaged (then removed, with a warning)."""
    from planner.trajopt.ipopt import ipopt_options
    from planner.trajopt.transcription import Solver, make_nlp_layout

    try:
        seen = os.lstat(entry)
    except OSError:
        return None
    mark_used(entry)  # its use time, for the size cap: an entry being read is not removed
    try:
        meta, _ = cache_disk.check_files(entry, key, seen, expected_format="casadi")
        nl = make_nlp_layout(lay)
        if (meta["n_x"], meta["n_g"]) != (nl.n_x, nl.n_g):
            raise EntryDamaged(f"{META} is for {meta['n_x']} variables and {meta['n_g']} constraints, "
                               f"not {nl.n_x} and {nl.n_g}")
        if progress:
            progress("loading the solver from the cache")
        try:
            reader = ca.FileDeserializer(str(entry / SERIALIZED))
            functions = [reader.unpack() for _ in SERIALIZED_FUNCTIONS]
        except RuntimeError as e:
            first = str(e).strip().splitlines()[0][:200] if str(e).strip() else type(e).__name__
            raise EntryDamaged(f"{SERIALIZED} did not load ({first})") from None
        names = [f.name() if isinstance(f, ca.Function) else type(f).__name__ for f in functions]
        if names != list(SERIALIZED_FUNCTIONS):
            raise EntryDamaged(f"{SERIALIZED} holds {', '.join(names)}, not {', '.join(SERIALIZED_FUNCTIONS)}")
        nlp, grad_f, jac_g, hess_lag = functions
        if nlp.size1_in(0) != nl.n_x or nlp.size1_out(1) != nl.n_g:
            raise EntryDamaged(f"{SERIALIZED} holds a problem of other sizes than {META} says")
        options = {**ipopt_options(settings), "grad_f": grad_f, "jac_g": jac_g, "hess_lag": hess_lag}
        function = ca.nlpsol("wbmp_plan", "ipopt", nlp, options)
        return Solver(function=function, nlp_layout=nl, origin="disk")
    except EntryDamaged as e:
        cache_disk.discard(entry, seen, str(e))
        return None
    except OSError as e:
        cache_disk.discard(entry, seen, f"it could not be read: {e.strerror or e}")
        return None


def _store_serialized(entry: Path, key: str, nlp: dict, derivatives: dict, nl, settings: PlannerSettings) -> None:
    """Write the NLP's functions into a new serialized entry; a failure only means that the next
    process builds again.

    With ``settings.background_compile`` a forked child process writes it (~2 s of CPU and
    ~140 MB for the Talos 4 steps) while this one solves; the child shares nothing with the
    plan afterwards (its own copy of the functions) and ends with ``os._exit``.
    """
    functions = (ca.Function("nlp", [nlp["x"], nlp["p"]], [nlp["f"], nlp["g"]], ["x", "p"], ["f", "g"]),
                 derivatives["grad_f"], derivatives["jac_g"], derivatives["hess_lag"])
    try:
        tmp = Path(tempfile.mkdtemp(prefix=f".{key}.", dir=entry.parent))
        (tmp / cache_disk.BUILDER_PID).write_text(str(os.getpid()))
    except OSError as e:
        cache_disk.warn_unusable(entry.parent, (e.strerror or str(e)).lower())
        return
    if not (settings.cache.background_compile and hasattr(os, "fork")):
        try:
            _write_serialized(tmp, entry, key, functions, nl.n_x, nl.n_g)
        except (OSError, RuntimeError):
            pass
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
        return
    _fork_worker(tmp, lambda: _write_serialized(tmp, entry, key, functions, nl.n_x, nl.n_g))


def _fork_worker(tmp: Path, work: Callable[[], bool], slot: builds.Slot | None = None) -> None:
    """Run ``work`` (it fills the temporary build folder ``tmp`` and publishes it) in a forked child.

    The child has its own session (a Ctrl-C of the planning command does not cut it short), the
    default SIGINT/SIGTERM handlers (not the parent's, which raise into its code), its standard
    streams on /dev/null (a caller reading this process's output through a pipe must not wait for
    it), a lower priority (:data:`BACKGROUND_NICE`: on a busy 2-core machine it takes the CPU the
    foreground leaves), removes ``tmp`` when done and ends with ``os._exit`` (none of this process's exit
    handlers). The parent records it in ``_WRITERS`` and in ``tmp``'s builder marker. A held build
    lock ``slot`` passes to the child (the same open file: the parent closes its descriptor, the
    lock stays held until the child and its compiler end), and the lock's text names the child.
    """
    _reap_writers()
    try:
        pid = os.fork()
    except OSError:  # no process to spare (EAGAIN, ENOMEM): the next run builds it
        shutil.rmtree(tmp, ignore_errors=True)
        if slot is not None:
            slot.note(state="ended", phase="not started: fork failed")
            slot.close()
        return
    if pid == 0:  # the child
        code = 1
        try:
            os.setsid()
            for sig in (signal.SIGINT, signal.SIGTERM):
                signal.signal(sig, signal.SIG_DFL)
            null = os.open(os.devnull, os.O_RDWR)
            for fd in (0, 1, 2):
                os.dup2(null, fd)
            if slot is not None:
                slot.note(pid=os.getpid())
            try:  # yield to the foreground: this plan, its simulation, the user's next command
                os.nice(BACKGROUND_NICE)
            except OSError:
                pass
            code = 0 if work() else 1
        finally:  # also on an exception: os._exit ends the child here, silently, with code 1
            shutil.rmtree(tmp, ignore_errors=True)
            if slot is not None:
                slot.note(state="ended", phase="published" if code == 0 else "failed", compiler_pid=None)
            os._exit(code)
    _WRITERS.append(pid)
    if slot is not None:
        slot.close()
    try:  # the folder is the child's now: sweep() must not take it while it lives
        write_text_atomic(tmp / cache_disk.BUILDER_PID, str(pid))
    except OSError:
        pass


def wait_for_background(timeout: float | None = None) -> list[int]:
    """Wait for the background writers and compilers this process forked (tests, benchmarks);
    their exit codes (0: the entry was published). With ``timeout`` [s], the ones still running
    after it are left running and not reported."""
    deadline = None if timeout is None else time.monotonic() + timeout
    codes: list[int] = []
    for pid in list(_WRITERS):
        while True:
            try:
                done, status = os.waitpid(pid, 0 if deadline is None else os.WNOHANG)
            except ChildProcessError:
                _WRITERS.remove(pid)
                break
            if done:
                _WRITERS.remove(pid)
                codes.append(os.waitstatus_to_exitcode(status))
                break
            if deadline is not None and time.monotonic() > deadline:
                break
            time.sleep(0.1)
    return codes


_WRITERS: list[int] = []  # forked writers and compilers not yet reaped
BACKGROUND_NICE = 10  # added to the forked writers' and compilers' nice value (gcc inherits it)


def _reap_writers() -> None:
    """Collect the exit status of the forked writers that ended (no zombies in a long process)."""
    for pid in list(_WRITERS):
        try:
            done, _ = os.waitpid(pid, os.WNOHANG)
        except ChildProcessError:
            done = pid
        if done:
            _WRITERS.remove(pid)


def _write_serialized(tmp: Path, entry: Path, key: str, functions, n_x: int, n_g: int) -> bool:
    """Serialize ``functions`` into ``tmp``, write the manifest and publish ``tmp`` as ``entry``."""
    path = tmp / SERIALIZED
    writer = ca.FileSerializer(str(path))
    for f in functions:
        writer.pack(f)
    del writer  # flushed and closed
    digest = cache_disk.file_sha256(path)
    meta = {"key": key, "format": "casadi", "sha256": digest, "size": path.stat().st_size, "n_x": n_x, "n_g": n_g,
            "casadi": ca.__version__, "created": time.time()}
    return _publish_entry(tmp, entry, key, meta)


def _publish_entry(tmp: Path, entry: Path, key: str, meta: dict) -> bool:
    """Write the manifest ``meta`` into the filled build folder ``tmp`` (last: an entry without it
    is rebuilt), publish it as ``entry`` and apply the size cap of the whole cache (least recently
    used entries go); True when a good entry is in place afterwards."""
    (tmp / META).write_text(json.dumps(meta))
    (tmp / cache_disk.BUILDER_PID).unlink(missing_ok=True)
    published = cache_disk.publish(tmp, entry, key)
    trim_cache(entry.parent)
    return published


def _compile_entry(entry: Path, key: str, nlp: dict, derivatives: dict, nl, settings: PlannerSettings,
                   progress):
    """Build the solver, generate C code for its functions, compile, store atomically.

    Returns the in-memory solver (compiled or not); a failed compilation only means that the
    next process builds again. The build runs only when it holds the cache's build lock and the
    memory is there (:func:`planner.trajopt.builds.claim`, :func:`~planner.trajopt.builds.memory_refusal`);
    otherwise the structure is recorded as skipped, and the plan runs in memory.
    """
    from planner.trajopt.ipopt import ipopt_options
    from planner.trajopt.transcription import Solver

    builder = ca.nlpsol("wbmp_plan", "ipopt", nlp, {**ipopt_options(settings), **derivatives})
    solver = Solver(function=builder, nlp_layout=nl, origin="built")
    gcc = shutil.which(settings.cache.compiler)
    if gcc is None:
        return solver
    slot = _claim_build(entry.parent, key, settings, progress)
    if slot is None:
        return solver
    tmp = None
    try:
        tmp = Path(tempfile.mkdtemp(prefix=f".{key}.", dir=entry.parent))
        (tmp / cache_disk.BUILDER_PID).write_text(str(os.getpid()))  # for sweep(): whose folder it is
    except OSError as e:  # an unwritable cache directory: plan in memory
        cache_disk.warn_unusable(entry.parent, (e.strerror or str(e)).lower())
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
        slot.close()
        return solver
    cache = settings.cache
    build = _Build(gcc=gcc, flags=tuple(cache.compile_flags), timeout=cache.compile_timeout,
                   margin=cache.build_memory_margin, slot=slot)
    if settings.cache.background_compile and hasattr(os, "fork"):
        # Generate the C code and compile it in a forked child: this plan runs on the in-memory
        # solver now, and the next process with this structure loads the compiled one (the code
        # generation alone is ~1-1.5 s of CPU for Talos, gcc 5-70 s here).
        if progress:
            progress("compiling the solver in the background for the next run")
        folder = tmp
        _fork_worker(folder, lambda: _generate_c(folder, nlp, builder, slot) and _finish_entry(
            folder, entry, key, nl.n_x, nl.n_g, build), slot=slot)
        return solver
    try:
        if progress:
            progress("generating C code for the solver")
        _generate_c(tmp, nlp, builder, slot)
        if progress:
            progress(f"compiling the solver with {Path(gcc).name} {' '.join(settings.cache.compile_flags)} "
                     "(first time for this task structure)")
        _finish_entry(tmp, entry, key, nl.n_x, nl.n_g, build)
        return solver
    except (OSError, RuntimeError):
        return solver
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
        slot.note(state="ended")
        slot.close()


@dataclasses.dataclass(frozen=True, slots=True)
class _Build:
    """How one solver build compiles: the compiler, its flags, the time limit [s], the memory a
    running compiler leaves (``margin`` [bytes]: below half of it the compiler is stopped), and the
    held build lock (None: none is held, as in the direct calls of the tests)."""

    gcc: str
    flags: tuple[str, ...]
    timeout: float
    margin: int = 0
    slot: builds.Slot | None = None


def _claim_build(folder: Path, key: str, settings: PlannerSettings, progress) -> builds.Slot | None:
    """The build lock of the cache folder for ``key``, or None (then the skip and its reason are
    recorded, and said through ``progress``): another build runs, or the memory is not there."""
    if not cache_disk.usable_folder(folder):
        return None
    reason = builds.memory_refusal(settings.cache.build_memory, settings.cache.build_memory_margin)
    claimed: builds.Slot | str = reason if reason else builds.claim(folder, key)
    if isinstance(claimed, builds.Slot):
        return claimed
    builds.record_skip(folder, key, claimed)
    if progress:
        progress(f"not compiling the solver now ({claimed}); the next run of this task structure "
                 "compiles it")
    return None


def _generate_c(tmp: Path, nlp: dict, builder: ca.Function, slot: builds.Slot | None = None) -> bool:
    """Write ``tmp/nlp.c``: the NLP function and the solver's oracle functions, as C."""
    if slot is not None:
        slot.note(phase="generating C code")
    cg = ca.CodeGenerator("nlp.c")
    cg.add(ca.Function("nlp", [nlp["x"], nlp["p"]], [nlp["f"], nlp["g"]], ["x", "p"], ["f", "g"]))
    for name in ORACLE_FUNCTIONS:
        cg.add(builder.get_function(name))
    cg.generate(f"{tmp}{os.sep}")  # writes <tmp>/nlp.c (no chdir: other threads keep their cwd)
    return True


def _finish_entry(tmp: Path, entry: Path, key: str, n_x: int, n_g: int, build: _Build) -> bool:
    """Compile ``tmp/nlp.c``, probe-load the library in a child process, write the manifest
    and publish ``tmp`` as ``entry`` (True when a good entry is in place afterwards)."""
    # -pipe: no assembly file (0.1-0.5 GB for a Talos solver) between the compiler and the assembler
    cmd = [build.gcc, "-pipe", "-fPIC", "-shared", *build.flags, "nlp.c", "-o", LIBRARY, "-lm"]
    if not _run_gcc(cmd, tmp, build.timeout, margin=build.margin, slot=build.slot):
        if build.slot is not None and build.slot.info.get("stopped"):
            builds.record_skip(entry.parent, key, build.slot.info["stopped"])
        return False
    (tmp / "nlp.c").unlink()
    (tmp / GCC_LOG).unlink(missing_ok=True)
    lib = tmp / LIBRARY
    digest = cache_disk.file_sha256(lib)
    if build.slot is not None:
        build.slot.note(phase="checking the library", compiler_pid=None)
    problem = cache_disk.probe(lib, LIBRARY_FUNCTIONS)
    if problem not in (None, "unavailable"):
        return False  # never publish a library that does not load
    if problem is None:
        (tmp / cache_disk.VERIFIED).write_text(digest + "\n")
    meta = {
        "key": key, "sha256": digest, "size": lib.stat().st_size, "n_x": n_x, "n_g": n_g,
        "casadi": ca.__version__, "flags": list(build.flags), "created": time.time(),
    }
    published = _publish_entry(tmp, entry, key, meta)
    if published:
        builds.clear_skip(entry.parent, key)
    return published


GCC_LOG = "gcc.log"  # the compiler's messages, in the build folder (not published)


def _run_gcc(cmd: list[str], cwd: Path, timeout: float, *, margin: int = 0,
             slot: builds.Slot | None = None) -> bool:
    """Run gcc in its own process group; on timeout kill the group (cc1 included).

    Its temporary files (the object file; the assembly without ``-pipe``) go to ``cwd``, the
    temporary build folder that a failed or abandoned build removes: a gcc killed here or with its
    process used to leave them in the system's /tmp. With a ``margin`` [bytes] the group is also
    killed when ``MemAvailable`` falls below half of it (:func:`planner.trajopt.builds.memory_low`;
    the reason goes to ``slot.info["stopped"]``). The compiler inherits the held build lock
    ``slot``: the lock lasts as long as it, even if this process is killed first. Its messages go to
    ``cwd/gcc.log`` (:data:`GCC_LOG`; a pipe that nobody reads while polling would stall a verbose compiler)."""
    env = {**os.environ, "TMPDIR": str(Path(cwd).resolve())}
    fds = (slot.fd,) if slot is not None and slot.fd >= 0 else ()
    with open(Path(cwd) / GCC_LOG, "wb") as log:
        proc = subprocess.Popen(cmd, cwd=cwd, stdout=subprocess.DEVNULL, stderr=log,
                                start_new_session=True, env=env, pass_fds=fds)
    if slot is not None:
        slot.note(phase="compiling", compiler_pid=proc.pid)
    deadline = time.monotonic() + timeout
    try:
        while True:
            try:
                proc.wait(timeout=max(0.0, min(builds.WATCH_PERIOD, deadline - time.monotonic())))
                break
            except subprocess.TimeoutExpired:
                pass
            low = margin > 0 and builds.memory_low(margin)
            if low or time.monotonic() >= deadline:
                if low and slot is not None:
                    slot.note(stopped=f"stopped while compiling: free memory fell below "
                                      f"{builds.STOP_FRACTION * margin / 1e9:.1f} GB")
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
                return False
    except BaseException:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        raise
    return proc.returncode == 0
