"""Bad input: a damaged solver cache never crashes a plan, never loops on recompiling.

One real entry is compiled once for the module (gcc, a 0.6 s Talos squat); each case copies it
into a fresh cache folder, damages the copy, and plans. A damaged entry must give the same plan
as the healthy one, one warning line, and leave the path free for the rebuilt entry: the
builder's last step (:func:`planner.trajopt.cache_disk.publish`) then puts a fresh build there and the
next plan loads it from disk. In the cheap cases gcc is kept off ``PATH`` (the rebuild would
be a full gcc run each time): the plan then builds its solver in memory, as on a machine
without gcc. Cases that would crash a process without the checks (a truncated library with a
matching checksum, a library whose loading kills the process) run the plan in a child process.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import logging
import os
import random
import shutil
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from planner import CacheSettings, PlannerSettings
from planner.trajopt import cache_disk, plan
from planner.trajopt.api import planned_layout
from planner.trajopt.cache import clear_memory_cache, solver_key
from tests.badinput.conftest import REPO, run_cli, run_cli_process
from tests.planner.planning_cases import squat_spec

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None, reason="the solver cache compiles with gcc")

SQ = REPO / "examples" / "specs" / "squat.json"
DEPTH, DURATION, DT = 0.05, 0.6, 0.1  # the smallest squat: 6 knots
Q_ATOL = 1e-6  # [rad, m] compiled and in-memory solvers reach the same optimum
AS_ROOT = hasattr(os, "geteuid") and os.geteuid() == 0


def small_spec(robot):
    return squat_spec(robot, DEPTH, duration=DURATION, dt=DT)


def settings_for(cache_dir: Path) -> PlannerSettings:
    return PlannerSettings(cache=CacheSettings(cache_dir=str(cache_dir), compile=True, background_compile=False))


class Golden:
    """The healthy entry (a copy kept aside), its key, and the plan it gave."""

    def __init__(self, folder: Path, key: str, q: np.ndarray) -> None:
        self.folder, self.key, self.q = folder, key, q
        self.meta = json.loads((folder / "meta.json").read_text())

    def install(self, cache_dir: Path) -> Path:
        """A healthy copy of the entry in ``cache_dir``; returns the entry's path."""
        entry = cache_dir / "planner" / self.key
        entry.parent.mkdir(parents=True, exist_ok=True)
        shutil.copytree(self.folder, entry, symlinks=True)
        return entry


@pytest.fixture(scope="module")
def golden(tmp_path_factory, talos) -> Golden:
    """Compile the small squat's solver once (gcc) and keep its healthy entry aside."""
    cache_dir = tmp_path_factory.mktemp("golden_cache")
    settings = settings_for(cache_dir)
    spec = small_spec(talos)
    clear_memory_cache()
    first = plan(spec, talos, settings=settings)
    assert first.ok and first.stats.cache == "built"
    key = solver_key(planned_layout(spec, talos, settings), settings)
    entry = cache_dir / "planner" / key
    assert {p.name for p in entry.iterdir()} == {"nlp.so", "meta.json", "verified"}
    assert (entry / "verified").read_text().strip() == hashlib.sha256((entry / "nlp.so").read_bytes()).hexdigest()
    kept = tmp_path_factory.mktemp("golden_entry") / key
    shutil.copytree(entry, kept)
    clear_memory_cache()
    again = plan(spec, talos, settings=settings)
    assert again.stats.cache == "disk"
    np.testing.assert_allclose(again.q, first.q, atol=Q_ATOL)
    return Golden(kept, key, first.q)


@pytest.fixture
def no_gcc(tmp_path, monkeypatch):
    """gcc off PATH: a rebuild happens in memory (a full gcc run per case would take minutes)."""
    empty = tmp_path / "empty_bin"
    empty.mkdir()
    monkeypatch.setenv("PATH", str(empty))
    assert shutil.which("gcc") is None


def cache_warnings(caplog) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.name == "planner.trajopt.cache"]


def forge_manifest(entry: Path, **changes) -> None:
    """Rewrite meta.json so that it agrees with the library now in the entry (and ``changes``)."""
    lib = entry / "nlp.so"
    meta = json.loads((entry / "meta.json").read_text())
    data = lib.read_bytes()
    meta.update(sha256=hashlib.sha256(data).hexdigest(), size=len(data), **changes)
    (entry / "meta.json").write_text(json.dumps(meta))


def replace_file(path: Path, data: bytes) -> None:
    """A new file over the old name (rewriting a mapped library in place crashes its users)."""
    tmp = path.with_name(path.name + ".new")
    tmp.write_bytes(data)
    tmp.replace(path)


def edit_meta(entry: Path, fn) -> None:
    meta = json.loads((entry / "meta.json").read_text())
    fn(meta)
    replace_file(entry / "meta.json", json.dumps(meta).encode())


def _set_link(entry: Path, target: Path) -> None:
    shutil.rmtree(entry)
    entry.symlink_to(target, target_is_directory=True)


def _fresh_copy(entry: Path, name: str) -> Path:
    other = entry.parent.parent.parent / name
    shutil.copytree(entry, other)
    return other


# Each damage: (id, function(entry) -> None, a word the warning must contain).
DAMAGES = [
    ("entry-plain-file", lambda e: (shutil.rmtree(e), e.write_text("not a folder")), "not a folder"),
    ("entry-dangling-symlink", lambda e: _set_link(e, e.parent / "gone"), "symbolic link"),
    ("entry-symlink-to-a-copy", lambda e: _set_link(e, _fresh_copy(e, "elsewhere")), "symbolic link"),
    ("entry-fifo", lambda e: (shutil.rmtree(e), os.mkfifo(e)), "not a folder"),
    ("entry-empty-folder", lambda e: (shutil.rmtree(e), e.mkdir()), "meta.json is missing"),
    ("meta-missing", lambda e: (e / "meta.json").unlink(), "meta.json is missing"),
    ("meta-random-bytes", lambda e: replace_file(e / "meta.json", bytes(range(256)) * 3), "not valid JSON"),
    ("meta-truncated-json", lambda e: replace_file(e / "meta.json", b'{"key": "'), "not valid JSON"),
    ("meta-json-array", lambda e: replace_file(e / "meta.json", b"[1, 2, 3]"), "not a JSON object"),
    ("meta-deeply-nested", lambda e: replace_file(e / "meta.json", b"[" * 30000 + b"]" * 30000),
     "not valid JSON"),
    ("meta-too-large", lambda e: replace_file(e / "meta.json", b"[" * 50000 + b"]" * 50000), "100000 bytes"),
    ("meta-utf16", lambda e: replace_file(e / "meta.json", (e / "meta.json").read_text().encode("utf-16")),
     "not valid JSON"),
    ("meta-another-key", lambda e: edit_meta(e, lambda m: m.update(key="0" * 24)), "another key"),
    ("meta-sha-number", lambda e: edit_meta(e, lambda m: m.update(sha256=12345)), "sha256"),
    ("meta-sha-other", lambda e: edit_meta(e, lambda m: m.update(sha256="ab" * 32)), "checksum"),
    ("meta-size-missing", lambda e: edit_meta(e, lambda m: m.pop("size")), "size"),
    ("meta-size-wrong", lambda e: edit_meta(e, lambda m: m.update(size=m["size"] + 1)), "bytes"),
    ("meta-n_x-bool", lambda e: edit_meta(e, lambda m: m.update(n_x=True)), "n_x"),
    ("meta-n_x-other", lambda e: edit_meta(e, lambda m: m.update(n_x=m["n_x"] + 6)), "variables"),
    ("meta-huge", lambda e: replace_file(e / "meta.json", b" " * 200_000 + (e / "meta.json").read_bytes()),
     "bytes"),
    ("meta-is-a-folder", lambda e: ((e / "meta.json").unlink(), (e / "meta.json").mkdir()), "not a regular file"),
    ("meta-is-a-fifo", lambda e: ((e / "meta.json").unlink(), os.mkfifo(e / "meta.json")), "not a regular file"),
    ("meta-is-a-symlink", lambda e: ((e / "meta.json").rename(e.parent / "m.json"),
                                     (e / "meta.json").symlink_to(e.parent / "m.json")), "not a regular file"),
    ("so-missing", lambda e: (e / "nlp.so").unlink(), "nlp.so is missing"),
    ("so-zero-bytes", lambda e: replace_file(e / "nlp.so", b""), "0 bytes"),
    ("so-zero-bytes-forged", lambda e: (replace_file(e / "nlp.so", b""), forge_manifest(e)), "size"),
    ("so-truncated", lambda e: replace_file(e / "nlp.so", (e / "nlp.so").read_bytes()[:100_000]), "bytes"),
    ("so-random-bytes", lambda e: replace_file(e / "nlp.so", _noise((e / "nlp.so").stat().st_size)),
     "no ELF header"),
    ("so-random-bytes-forged", lambda e: (replace_file(e / "nlp.so", _noise(4096)), forge_manifest(e)),
     "no ELF header"),
    ("so-one-byte-flipped", lambda e: replace_file(e / "nlp.so", _flip_last_byte((e / "nlp.so").read_bytes())),
     "checksum"),
    ("so-is-a-folder", lambda e: ((e / "nlp.so").unlink(), (e / "nlp.so").mkdir()), "not a regular file"),
    ("so-is-a-fifo", lambda e: ((e / "nlp.so").unlink(), os.mkfifo(e / "nlp.so")), "not a regular file"),
    ("so-is-a-symlink", lambda e: ((e / "nlp.so").rename(e.parent / "lib.so"),
                                   (e / "nlp.so").symlink_to(e.parent / "lib.so")), "not a regular file"),
    ("so-another-library-forged", lambda e: (replace_file(e / "nlp.so", _tiny_library(e.parent.parent, "")),
                                             forge_manifest(e), (e / "verified").unlink()), "failed the test load"),
]


def _noise(n: int) -> bytes:
    return random.Random(13).randbytes(n)


def _flip_last_byte(data: bytes) -> bytes:
    return data[:-1] + bytes([data[-1] ^ 0xFF])


def _tiny_library(folder: Path, extra: str) -> bytes:
    """A valid shared library (no NLP functions in it), compiled by gcc from a few lines."""
    src = folder / "tiny.c"
    src.write_text(f"{extra}\nint nlp_f(void) {{ return 0; }}\n")
    gcc = shutil.which("gcc", path=os.defpath + os.pathsep + "/usr/bin:/usr/local/bin")
    subprocess.run([gcc, "-shared", "-fPIC", str(src), "-o", str(folder / "tiny.so")], check=True,
                   env={**os.environ, "PATH": os.path.dirname(gcc)})
    return (folder / "tiny.so").read_bytes()


@contextlib.contextmanager
def fifo_guard(*fifos: Path):
    """Fail (instead of hanging) if anything opens one of ``fifos`` for reading: a writer is
    attached as soon as a reader appears, which unblocks it with an empty read."""
    stop = threading.Event()
    opened: list[str] = []

    def watch():
        while not stop.is_set():
            for f in fifos:
                try:
                    fd = os.open(f, os.O_WRONLY | os.O_NONBLOCK)  # ENXIO while nobody reads
                except OSError:
                    continue
                opened.append(f.name)
                os.close(fd)
            stop.wait(0.05)

    fifos = tuple(f for f in fifos if f.is_fifo())
    thread = threading.Thread(target=watch, daemon=True)
    thread.start()
    try:
        yield opened
    finally:
        stop.set()
        thread.join()
    assert not opened, f"a FIFO was opened for reading: {opened}"


def _fifos(entry: Path) -> list[Path]:
    candidates = [entry, entry / "meta.json", entry / "nlp.so"]
    return [p for p in candidates if os.path.lexists(p) and not p.is_symlink() and p.is_fifo()]


def assert_rebuilt_and_reloaded(golden: Golden, cache_dir: Path, entry: Path, talos) -> None:
    """The path is free, a fresh build published there is used by the next plan ('disk')."""
    assert not os.path.lexists(entry), "the damaged entry is still there"
    tmp = cache_dir / "planner" / f".{golden.key}.rebuilt"
    shutil.copytree(golden.folder, tmp)
    assert cache_disk.publish(tmp, entry, golden.key)
    clear_memory_cache()
    again = plan(small_spec(talos), talos, settings=settings_for(cache_dir))
    assert again.stats.cache == "disk"
    np.testing.assert_allclose(again.q, golden.q, atol=Q_ATOL)


@pytest.mark.parametrize("damage, word", [pytest.param(fn, word, id=name) for name, fn, word in DAMAGES])
def test_damaged_entry_is_detected_removed_and_rebuilt(golden, talos, tmp_path, no_gcc, caplog, damage, word):
    """Each damage: the plan succeeds with the healthy result, one warning line names the
    problem, the damaged entry is gone, and the rebuilt entry is loaded by the next plan."""
    cache_dir = tmp_path / "cache"
    entry = golden.install(cache_dir)
    damage(entry)
    clear_memory_cache()
    caplog.set_level(logging.WARNING, logger="planner.trajopt.cache")
    with fifo_guard(*_fifos(entry)):
        result = plan(small_spec(talos), talos, settings=settings_for(cache_dir))
    assert result.ok and result.stats.cache == "built"
    np.testing.assert_allclose(result.q, golden.q, atol=Q_ATOL)
    messages = cache_warnings(caplog)
    assert len(messages) == 1, messages
    assert "\n" not in messages[0] and "damaged" in messages[0] and word in messages[0], messages[0]
    assert str(entry) in messages[0]
    assert_rebuilt_and_reloaded(golden, cache_dir, entry, talos)


def test_symlinked_entry_removes_the_link_not_its_target(golden, talos, tmp_path, no_gcc, caplog):
    """An entry that is a symlink to a folder elsewhere: the link goes, the folder stays intact."""
    cache_dir = tmp_path / "cache"
    entry = golden.install(cache_dir)
    target = _fresh_copy(entry, "theirs")
    _set_link(entry, target)
    clear_memory_cache()
    plan(small_spec(talos), talos, settings=settings_for(cache_dir))
    assert not os.path.lexists(entry)
    assert sorted(p.name for p in target.iterdir()) == ["meta.json", "nlp.so", "verified"]


@pytest.mark.skipif(AS_ROOT, reason="root reads a chmod 000 folder anyway")
def test_unreadable_entry_folder_is_removed_and_rebuilt(golden, talos, tmp_path, no_gcc, caplog):
    """A chmod 000 entry folder (ours, in a writable cache): made removable, removed, rebuilt."""
    cache_dir = tmp_path / "cache"
    entry = golden.install(cache_dir)
    entry.chmod(0)
    clear_memory_cache()
    caplog.set_level(logging.WARNING, logger="planner.trajopt.cache")
    result = plan(small_spec(talos), talos, settings=settings_for(cache_dir))
    assert result.ok and result.stats.cache == "built"
    assert len(cache_warnings(caplog)) == 1
    assert_rebuilt_and_reloaded(golden, cache_dir, entry, talos)


@pytest.mark.parametrize("marker", [None, b"", b"garbage\n", b"0" * 64 + b"\n"], ids=["missing", "empty",
                                                                                     "garbage", "other-hash"])
def test_missing_or_wrong_marker_costs_one_probe_and_is_rewritten(golden, talos, tmp_path, no_gcc, caplog, marker):
    """A healthy library without its 'verified' marker is not damage: a child process loads it,
    the plan uses it ('disk', no warning), and the marker names its checksum again."""
    cache_dir = tmp_path / "cache"
    entry = golden.install(cache_dir)
    if marker is None:
        (entry / "verified").unlink()
    else:
        (entry / "verified").write_bytes(marker)
    clear_memory_cache()
    caplog.set_level(logging.WARNING, logger="planner.trajopt.cache")
    result = plan(small_spec(talos), talos, settings=settings_for(cache_dir))
    assert result.stats.cache == "disk" and not cache_warnings(caplog)
    np.testing.assert_allclose(result.q, golden.q, atol=Q_ATOL)
    assert (entry / "verified").read_text().strip() == golden.meta["sha256"]


# -- cases that would kill the process: run the plan in a child ---------------------------------

PLAN_IN_CHILD = f"""
import sys
import numpy as np
from robots import load_robot
from planner import CacheSettings, PlannerSettings
from planner.trajopt import plan
from tests.planner.planning_cases import squat_spec
talos = load_robot("talos")
settings = PlannerSettings(cache=CacheSettings(cache_dir=sys.argv[1], compile=True, background_compile=False))
result = plan(squat_spec(talos, {DEPTH}, duration={DURATION}, dt={DT}), talos, settings=settings)
np.save(sys.argv[2], result.q)
print(result.stats.cache, result.ok)
"""


def _truncate_forged(entry: Path, *, marker: bool) -> None:
    """A library cut short, with a manifest (and optionally a marker) that agree with it."""
    data = (entry / "nlp.so").read_bytes()
    replace_file(entry / "nlp.so", data[: len(data) * 3 // 4])
    forge_manifest(entry)
    if marker:
        (entry / "verified").write_text(json.loads((entry / "meta.json").read_text())["sha256"] + "\n")
    else:
        (entry / "verified").unlink()


def _crashing_library(entry: Path, tmp_path: Path) -> None:
    """A valid shared library whose loading kills the process (a constructor that segfaults),
    with a matching manifest: only loading it in another process can tell."""
    boom = "#include <signal.h>\n__attribute__((constructor)) static void boom(void) { raise(SIGSEGV); }"
    replace_file(entry / "nlp.so", _tiny_library(tmp_path, boom))
    forge_manifest(entry)
    (entry / "verified").unlink()


@pytest.mark.parametrize("kind", ["truncated-forged", "truncated-forged-with-marker", "crashes-when-loaded"])
def test_entry_that_would_crash_the_process_is_refused(golden, tmp_path, kind):
    """A truncated nlp.so whose manifest (and marker) match it, or a library that kills whoever
    loads it: the planning process exits normally with the healthy plan and one warning."""
    cache_dir = tmp_path / "cache"
    entry = golden.install(cache_dir)
    if kind == "crashes-when-loaded":
        _crashing_library(entry, tmp_path)
        word = "crashed the test load"
    else:
        _truncate_forged(entry, marker=kind.endswith("marker"))
        word = "cut short"
    empty = tmp_path / "empty_bin"
    empty.mkdir()
    out = tmp_path / "q.npy"
    proc = subprocess.run([sys.executable, "-c", PLAN_IN_CHILD, str(cache_dir), str(out)], cwd=REPO,
                          env={**os.environ, "PATH": str(empty)}, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, f"exit {proc.returncode}: {proc.stderr[-2000:]}"
    assert proc.stdout.split() == ["built", "True"]
    np.testing.assert_allclose(np.load(out), golden.q, atol=Q_ATOL)
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert "Traceback" not in proc.stderr
    warned = [ln for ln in lines if ln.startswith("wbmp: warning: solver cache entry")]
    assert len(warned) == 1 and word in warned[0], proc.stderr
    assert not os.path.lexists(entry)


def test_probe_reports_the_signal_of_a_truncated_library(golden, tmp_path):
    """The child-process probe itself: a healthy library loads; a truncated one is reported as a
    crash (SIGBUS here) instead of taking the caller down."""
    functions = ("nlp", "nlp_f", "nlp_g", "nlp_grad_f", "nlp_jac_g", "nlp_hess_l", "nlp_grad")
    assert cache_disk.probe(golden.folder / "nlp.so", functions) is None
    cut = tmp_path / "cut.so"
    data = (golden.folder / "nlp.so").read_bytes()
    cut.write_bytes(data[: len(data) // 2])
    problem = cache_disk.probe(cut, functions)
    assert problem is not None and problem.startswith("crashed the test load"), problem


@given(fraction=st.floats(min_value=0.0, max_value=1.0, exclude_max=True))
def test_any_truncation_is_found_without_loading(golden, tmp_path_factory, fraction):
    """Wherever a library is cut, the header check finds it (no mapping, no probe needed)."""
    data = (golden.folder / "nlp.so").read_bytes()
    n = int(len(data) * fraction)
    path = tmp_path_factory.getbasetemp() / "cut_any.so"
    path.write_bytes(data[:n])
    assert cache_disk.elf_problem(path, n) is not None
    assert cache_disk.elf_problem(golden.folder / "nlp.so", len(data)) is None


# -- the CLI -----------------------------------------------------------------------------------


def _squat_json_entry(golden: Golden, cache_dir: Path) -> Path:
    """The entry path `wbmp solve --spec SQ` uses, holding the small squat's library truncated,
    with a manifest and marker forged to match (the issue's bus error)."""
    from robots import load_robot
    from tasks.serialize import load_spec

    spec = load_spec(SQ)
    robot = load_robot(spec.robot)
    settings = PlannerSettings(cache=CacheSettings(cache_dir=str(cache_dir), compile=True))
    lay = planned_layout(spec, robot, settings)
    from planner.trajopt.transcription import make_nlp_layout

    nl = make_nlp_layout(lay)
    key = solver_key(lay, settings)
    entry = cache_dir / "planner" / key
    entry.parent.mkdir(parents=True)
    shutil.copytree(golden.folder, entry)
    _truncate_forged(entry, marker=True)
    edit_meta(entry, lambda m: m.update(key=key, n_x=nl.n_x, n_g=nl.n_g))
    return entry


@pytest.mark.long  # in make test-long: the 2-core suite stays under 10 minutes (~28 s; the plain-file entry rebuilt by gcc and the damaged entries cover the repair)
@pytest.mark.slow
def test_cli_solve_with_a_truncated_library_exits_0_and_repairs_the_cache(golden, tmp_path):
    """`wbmp solve --spec squat.json --no-sim` on the issue's damaged cache: exit 0, one warning,
    no traceback; gcc rebuilds the entry, and the next run loads it from disk without a warning."""
    cache_dir = tmp_path / "cache"
    entry = _squat_json_entry(golden, cache_dir)
    env = {"WBMP_CACHE_DIR": str(cache_dir), "WBMP_COMPILE": "1", "WBMP_COMPILE_BACKGROUND": "0"}
    # --no-cache: this is about the solver cache (the motion cache would answer the second run).
    first = run_cli_process(["solve", "--spec", SQ, "--no-sim", "--json", "--no-cache"], env=env, cwd=tmp_path)
    assert first.code == 0 and "Traceback" not in first.err, first.err[-2000:]
    warned = [ln for ln in first.err.splitlines() if ln.startswith("wbmp: warning:")]
    assert len(warned) == 1 and str(entry) in warned[0] and "cut short" in warned[0], first.err
    assert json.loads(first.out)["solver"]["cache"] == "built"
    meta = json.loads((entry / "meta.json").read_text())
    assert meta["size"] == (entry / "nlp.so").stat().st_size and cache_disk.elf_problem(entry / "nlp.so", meta["size"]) is None
    second = run_cli_process(["solve", "--spec", SQ, "--no-sim", "--json", "--no-cache"], env=env, cwd=tmp_path)
    assert second.code == 0 and "wbmp: warning" not in second.err
    assert json.loads(second.out)["solver"]["cache"] == "disk"
    assert not [p for p in entry.parent.iterdir() if p.name.startswith(".")], "temporary folder left"


@pytest.mark.parametrize("where", ["file", "below-a-file", "planner-is-a-file"])
def test_cli_solve_with_an_unusable_cache_folder_plans_in_memory(tmp_path, monkeypatch, capsys, caplog, where):
    """WBMP_CACHE_DIR naming a file (or a path below one): exit 0, the plan, one warning."""
    blocker = tmp_path / "blocker"
    blocker.write_text("a file")
    cache_dir = {"file": blocker, "below-a-file": blocker / "cache", "planner-is-a-file": tmp_path}[where]
    if where == "planner-is-a-file":
        (tmp_path / "planner").write_text("a file")
    monkeypatch.setenv("WBMP_CACHE_DIR", str(cache_dir))
    monkeypatch.setenv("WBMP_COMPILE", "1")
    monkeypatch.setenv("WBMP_COMPILE_BACKGROUND", "0")
    clear_memory_cache()
    caplog.set_level(logging.WARNING, logger="planner.trajopt.cache")
    outcome = run_cli(["solve", "--spec", SQ, "--no-sim", "--json"], capsys)
    assert outcome.code == 0 and "Traceback" not in outcome.err
    assert json.loads(outcome.out)["solver"]["cache"] == "built"
    messages = cache_warnings(caplog)
    assert len(messages) == 1 and "not usable" in messages[0] and "WBMP_CACHE_DIR" in messages[0], messages
    assert blocker.read_text() == "a file"


def test_unusable_cache_folder_warns_once_per_process(talos, tmp_path, caplog):
    """Two plans (memory cleared between) with a cache folder that is a file: one warning."""
    blocker = tmp_path / "blocker"
    blocker.write_text("x")
    settings = settings_for(blocker)
    caplog.set_level(logging.WARNING, logger="planner.trajopt.cache")
    for _ in range(2):
        clear_memory_cache()
        assert plan(small_spec(talos), talos, settings=settings).stats.cache == "built"
    assert len(cache_warnings(caplog)) == 1


@pytest.mark.skipif(AS_ROOT, reason="root writes into a read-only folder anyway")
def test_read_only_cache_folder_plans_in_memory(talos, tmp_path, caplog):
    """A cache folder without write permission: the plan runs in memory with one warning."""
    cache_dir = tmp_path / "ro"
    (cache_dir / "planner").mkdir(parents=True)
    (cache_dir / "planner").chmod(0o500)
    caplog.set_level(logging.WARNING, logger="planner.trajopt.cache")
    clear_memory_cache()
    try:
        assert plan(small_spec(talos), talos, settings=settings_for(cache_dir)).ok
    finally:
        (cache_dir / "planner").chmod(0o700)
    assert len(cache_warnings(caplog)) == 1
    assert list((cache_dir / "planner").iterdir()) == []


# -- stale temporary build folders ----------------------------------------------------------------


def _dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def _temp_folder(parent: Path, name: str, *, age: float, pid: int | None, now: float) -> Path:
    folder = parent / name
    folder.mkdir(parents=True)
    (folder / "nlp.c").write_text("/* half a build */")
    if pid is not None:
        (folder / "builder.pid").write_text(str(pid))
    os.utime(folder, (now - age, now - age))
    return folder


HOUR = 3600.0


@pytest.mark.parametrize("age, builder, removed", [
    (2 * HOUR, "dead", True),
    (2 * HOUR, "missing", True),
    (2 * HOUR, "garbage", True),
    (2 * HOUR, "alive", False),
    (60.0, "dead", False),
    (60.0, "missing", False),
    (3 * 24 * HOUR, "alive", True),
], ids=["old-dead", "old-no-pid", "old-garbage-pid", "old-alive", "fresh-dead", "fresh-no-pid",
        "abandoned-alive"])
def test_sweep_removes_stale_temporary_folders_only(tmp_path, age, builder, removed):
    """A temporary build folder goes when it is older than an hour and its builder is gone (or
    older than a day); a recent one or one whose builder runs stays. Entries are untouched."""
    now = time.time()
    pid = {"dead": _dead_pid(), "alive": os.getpid(), "missing": None, "garbage": None}[builder]
    planner_dir = tmp_path / "planner"
    folder = _temp_folder(planner_dir, "." + "a" * 24 + ".x1y2", age=age, pid=pid, now=now)
    if builder == "garbage":
        (folder / "builder.pid").write_text("not a pid\n")
        os.utime(folder, (now - age, now - age))
    entry = planner_dir / ("b" * 24)
    entry.mkdir()
    (entry / "meta.json").write_text("{}")
    other = planner_dir / ".keep-me"
    other.write_text("not ours")
    os.utime(other, (now - 10 * 24 * HOUR,) * 2)
    swept = cache_disk.sweep(planner_dir, now=now)
    assert os.path.lexists(folder) is not removed
    assert swept == ([folder.name] if removed else [])
    assert (entry / "meta.json").read_text() == "{}" and other.read_text() == "not ours"


def test_plan_sweeps_stale_folders_and_moved_aside_entries(golden, talos, tmp_path, no_gcc):
    """Using the cache cleans it: a stale temporary folder of a dead builder and a damaged entry
    moved aside earlier are removed by the next plan; the healthy entry is used ('disk')."""
    cache_dir = tmp_path / "cache"
    entry = golden.install(cache_dir)
    now = time.time()
    stale = _temp_folder(entry.parent, f".{golden.key}.old", age=5 * HOUR, pid=_dead_pid(), now=now)
    aside = entry.parent / f".damaged.{golden.key}.1.2"
    aside.mkdir()
    (aside / "nlp.so").write_bytes(b"x")
    clear_memory_cache()
    assert plan(small_spec(talos), talos, settings=settings_for(cache_dir)).stats.cache == "disk"
    assert not stale.exists() and not aside.exists()
    assert sorted(p.name for p in entry.parent.iterdir()) == [golden.key]


def test_sweep_runs_once_per_folder_and_process(tmp_path):
    """The sweep is a listing per process and folder, not per plan."""
    now = time.time()
    planner_dir = tmp_path / "planner"
    planner_dir.mkdir()
    assert cache_disk.sweep(planner_dir, now=now) == []
    late = _temp_folder(planner_dir, "." + "c" * 24 + ".late", age=5 * HOUR, pid=None, now=now)
    assert cache_disk.sweep(planner_dir, now=now) == [] and late.exists()


# -- concurrent writers -------------------------------------------------------------------------


@pytest.mark.parametrize("in_the_way", ["nothing", "plain-file", "dangling-symlink", "damaged-folder"])
def test_concurrent_publishers_leave_one_healthy_entry(golden, talos, tmp_path, no_gcc, in_the_way):
    """Eight builders publish the same entry at once, whatever was in the way: each reports a
    good entry, one complete build is in place, and the next plan loads it."""
    cache_dir = tmp_path / "cache"
    planner_dir = cache_dir / "planner"
    planner_dir.mkdir(parents=True)
    entry = planner_dir / golden.key
    if in_the_way == "plain-file":
        entry.write_text("x")
    elif in_the_way == "dangling-symlink":
        entry.symlink_to(planner_dir / "gone")
    elif in_the_way == "damaged-folder":
        golden.install(cache_dir)
        replace_file(entry / "nlp.so", b"garbage")
    builds = []
    for i in range(8):
        tmp = planner_dir / f".{golden.key}.b{i}"
        shutil.copytree(golden.folder, tmp)
        (tmp / "build-id").write_text(str(i))
        builds.append(tmp)
    barrier = threading.Barrier(len(builds))
    results: list[bool] = []

    def publish(tmp):
        barrier.wait()
        results.append(cache_disk.publish(tmp, entry, golden.key))

    threads = [threading.Thread(target=publish, args=(b,)) for b in builds]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert results == [True] * len(builds)
    cache_disk.check_files(entry, golden.key)
    placed = int((entry / "build-id").read_text())
    assert not builds[placed].exists(), "the entry in place is one complete build"
    clear_memory_cache()
    assert plan(small_spec(talos), talos, settings=settings_for(cache_dir)).stats.cache == "disk"


# -- one real rebuild with gcc ----------------------------------------------------------------------


@pytest.mark.slow
def test_plain_file_entry_is_rebuilt_by_gcc_once_then_loaded(golden, talos, tmp_path, caplog):
    """The issue's recompile loop: an entry that is a plain file. The first plan rebuilds it with
    gcc (one warning), the second loads it from disk (no warning, no compilation)."""
    cache_dir = tmp_path / "cache"
    entry = golden.install(cache_dir)
    shutil.rmtree(entry)
    entry.write_text("not a folder")
    caplog.set_level(logging.WARNING, logger="planner.trajopt.cache")
    clear_memory_cache()
    first = plan(small_spec(talos), talos, settings=settings_for(cache_dir))
    assert first.ok and first.stats.cache == "built" and len(cache_warnings(caplog)) == 1
    assert entry.is_dir() and (entry / "verified").is_file()
    cache_disk.check_files(entry, golden.key)
    caplog.clear()
    clear_memory_cache()
    second = plan(small_spec(talos), talos, settings=settings_for(cache_dir))
    assert second.stats.cache == "disk" and not cache_warnings(caplog)
    np.testing.assert_allclose(second.q, golden.q, atol=Q_ATOL)
