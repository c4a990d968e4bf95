"""The solution library: earlier solutions of one solver structure seed the next solve of it.

A dynamic plan solved from its heading guess (:func:`planner.trajopt.centroidal.guess.heading_guess`)
spends about half of its IPOPT iterations removing the guess's infeasibility (Talos, four steps:
8 of 19). An earlier solution of the *same structure* (the same solver key,
:func:`planner.trajopt.cache.solver_key`: robot, knots, contact pattern, collision rows, options)
whose values are near (another step length, other placements or targets) is a better start, and
its multipliers start IPOPT's duals too (``warm_start_init_point``, which dynamic plans set): the
Talos four steps of 0.15 m from the solution of 0.12 m take 11 iterations instead of 19
(``docs/performance.md``, "The solution library").

What a seed holds: the layout's values (:func:`descriptor`: the terms' parameters and bounds, the
contact geometry; what tells two tasks of one structure apart), the solution ``x``, its
multipliers ``lam_x`` and ``lam_g``, and its chart displacements ``dq`` (N+1, nv), about which the
whole-body momentum rows are linearized for the seeded solve, and the initial guess of the layout
it solved. The nearest seed (Euclidean distance of the descriptors) is used; the solve starts from
its solution moved by the difference of the two layouts' initial guesses (:meth:`Seed.start`).

A seed only chooses where IPOPT starts; the plan is checked as always. A seeded solve that fails
(or whose plan fails a check) is done again from the task's own guess
(:func:`planner.trajopt.api.solve`), so a seed never turns a plan that would succeed into a failure.
It can change *which* local optimum a plan finds (another seed, another start): a history-free
result comes with ``solution_library="off"`` (``$WBMP_SOLUTION_LIBRARY=off``, ``wbmp solve
--no-cache``).

Where: in this process (at most :data:`MEMORY_KEYS` structures) and on disk, one folder per
solver key, ``<cache_dir>/seeds/<key>/``, with at most :data:`ENTRIES` files
``<descriptor digest>.npz`` (the oldest go first); the cache's size cap and ``wbmp cache`` treat
the folder as one entry. A file is read with ``allow_pickle=False`` and used only when its arrays
have the shapes of this structure and are finite; anything else is removed, never trusted.
Read and written by :func:`planner.plan_with_library` only (:func:`planner.plan` reads no library).
Modes (:attr:`planner.PlannerSettings.solution_library`): ``on`` (use and store), ``read`` (use,
store nothing: benchmarks of a fixed library), ``off``.

Escalations. A plan whose collision round added rows after its first solve ends with another
structure than it started with, so the next plan of the starting structure would find no seeds
(they are stored under the final one) and pay the round again. The library remembers the
collision rows the plan ended with, in the starting structure's folder (``escalation.json``:
link pair ``"a/b"`` -> sphere pairs and knots; scene object piece ``"scene:<key>"`` -> robot
spheres and knots, since session 17: the kitchen pick-up's round adds a table piece, and a record
of its link pairs alone left that round, and its second solve from no seed, to every later plan of
the structure); the next plan gets them before its first solve
(:func:`planner.trajopt.api.plan_with_library`) and so has the final structure and its seeds. Talos "walk
forward two steps then wave your right hand": 82 iterations in three solves; the 12 cm variant
after it, 14 in one. A record that is not one is removed; one that names a pair, sphere pair or
knot the layout does not have is not used. Rows only ever add constraints the check after each
solve would demand anyway.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import tempfile
import threading
import time
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from planner.trajopt.layout import Layout
from planner.trajopt.solver_output import SolverOutput
from robots import FileTooLarge, NotRegularFile, read_npz, read_text, trim_cache, write_text_atomic

FOLDER = "seeds"  # below the cache folder (robots.store.CACHE_FOLDERS)
ENTRIES = 8  # seeds kept per structure
MEMORY_KEYS = 16  # structures whose seeds this process keeps in memory
_FIELDS = ("descriptor", "guess", "x", "lam_x", "lam_g", "dq")
_MAX_FILE_BYTES = 64 << 20

_LOCK = threading.Lock()
_MEMORY: OrderedDict[str, dict[str, Seed]] = OrderedDict()  # key -> digest -> seed


@dataclass(frozen=True, eq=False)
class Seed:
    """One stored solution of a structure.

    Attributes:
        descriptor: The layout values it solved (:func:`descriptor`).
        guess: That layout's own initial guess (n_x,).
        x: The solution (n_x,).
        lam_x, lam_g: Its multipliers (n_x,), (n_g,).
        dq: Its chart displacements (N+1, nv).
        distance: Distance of its descriptor to the layout it seeds (set by :func:`find_seed`).
    """

    descriptor: np.ndarray
    guess: np.ndarray
    x: np.ndarray
    lam_x: np.ndarray
    lam_g: np.ndarray
    dq: np.ndarray
    distance: float = float("nan")

    def start(self, guess: np.ndarray) -> np.ndarray:
        """Where a layout whose own initial guess is ``guess`` starts: the stored solution moved by
        the difference of the two guesses (the feet's placements, the base's path: Talos four
        steps of 0.15 m from the solution of 0.12 m, 8 iterations instead of 11 unmoved)."""
        return self.x + (guess - self.guess)

    @property
    def digest(self) -> str:
        """Name of its file: a hash of its descriptor."""
        return hashlib.sha256(np.ascontiguousarray(self.descriptor).tobytes()).hexdigest()[:16]


def descriptor(lay: Layout) -> np.ndarray:
    """The values that tell two layouts of one structure apart: the reference posture, weights
    and knot spacing, each term's parameters and finite bounds, and (dynamic layouts) the contact
    geometry. Two layouts of one solver key give vectors of one length."""
    spec = lay.spec
    parts = [np.asarray(lay.q_ref, dtype=float), np.array([spec.smoothness_weight, spec.posture_weight, lay.dt])]
    for term in lay.terms:
        parts += [np.ravel(term.params), np.ravel(term.lower), np.ravel(term.upper)]
    pattern = getattr(lay, "pattern", None)
    if pattern is not None:
        parts.append(np.ravel(pattern().parameter_values))
    out = np.concatenate([np.asarray(p, dtype=float).ravel() for p in parts])
    return np.where(np.isfinite(out), out, 0.0)


def _folder(cache_dir: str, key: str) -> Path:
    return Path(cache_dir) / FOLDER / key


def _seed_files(folder: Path) -> list[Path]:
    """The seed files of a structure's folder, oldest first (as they are dropped); OSError when the
    folder cannot be listed."""
    return sorted((p for p in folder.iterdir() if p.suffix == ".npz" and not p.name.startswith(".")),
                  key=lambda p: p.stat().st_mtime_ns)


def _valid(seed: Seed, n_d: int, n_x: int, n_g: int, dq_shape: tuple[int, int]) -> bool:
    shapes = ((seed.descriptor, (n_d,)), (seed.guess, (n_x,)), (seed.x, (n_x,)), (seed.lam_x, (n_x,)), (seed.lam_g, (n_g,)),
              (seed.dq, dq_shape))
    return all(a.shape == s and a.dtype == np.float64 and np.isfinite(a).all() for a, s in shapes)


def _read(path: Path) -> Seed | None:
    """A seed file's arrays (no pickles, no other names), or None when it cannot be read."""
    try:  # a regular file of bounded size only (a FIFO or a link to /dev/zero is damaged)
        arrays = read_npz(path, _MAX_FILE_BYTES, names=_FIELDS)
    except (OSError, ValueError):  # unreadable, truncated, not a zip, other members: a miss
        return None
    return Seed(arrays["descriptor"], arrays["guess"], arrays["x"], arrays["lam_x"], arrays["lam_g"], arrays["dq"])


def _remove(path: Path) -> None:
    try:
        path.unlink()
    except OSError:
        pass


def _seeds_of(key: str, cache_dir: str) -> dict[str, Seed]:
    """The seeds of a structure: from memory, else read from its folder once in this process
    (unvalidated: :func:`find_seed` checks them against the layout)."""
    with _LOCK:
        hit = _MEMORY.get(key)
        if hit is not None:
            _MEMORY.move_to_end(key)
            return hit
    seeds: dict[str, Seed] = {}
    folder = _folder(cache_dir, key)
    try:
        names = _seed_files(folder)
    except OSError:
        names = []
    for path in names:
        seed = _read(path)
        if seed is None or path.stem != seed.digest:
            _remove(path)  # damaged or foreign: never trusted
            continue
        seeds[seed.digest] = seed
    with _LOCK:
        _MEMORY[key] = seeds
        while len(_MEMORY) > MEMORY_KEYS:
            _MEMORY.popitem(last=False)
    return seeds


def has_seeds(key: str, cache_dir: str) -> bool:
    """True when structure ``key`` has stored solutions (in memory, or in its folder)."""
    return bool(_seeds_of(key, cache_dir))


def find_seed(lay: Layout, key: str, n_x: int, n_g: int, cache_dir: str) -> Seed | None:
    """The stored solution of structure ``key`` nearest to ``lay`` (with its distance), or None.

    Seeds whose arrays do not fit this structure (``n_x`` variables, ``n_g`` rows, the layout's
    knots and descriptor) are dropped (and their files removed)."""
    seeds = _seeds_of(key, cache_dir)
    if not seeds:
        return None
    mine = descriptor(lay)
    dq_shape = (lay.N + 1, lay.robot.nv)
    best: Seed | None = None
    for digest, seed in list(seeds.items()):
        if not _valid(seed, len(mine), n_x, n_g, dq_shape):
            with _LOCK:
                seeds.pop(digest, None)
            _remove(_folder(cache_dir, key) / f"{digest}.npz")
            continue
        d = float(np.linalg.norm(seed.descriptor - mine))
        if best is None or d < best.distance:
            best = dataclasses.replace(seed, distance=d)
    if best is not None:
        try:
            os.utime(_folder(cache_dir, key))  # used: the cache's size cap removes the least recently used first
        except OSError:
            pass
    return best


def store_seed(lay: Layout, key: str, guess: np.ndarray, output: SolverOutput, dq: np.ndarray,
               cache_dir: str) -> None:
    """Keep a solution of structure ``key`` (``output``: the solve's, its ``x``, ``lam_x``, ``lam_g``;
    ``guess``: the layout's own initial guess) in memory and in its folder (atomically; the oldest
    files beyond :data:`ENTRIES` removed). A folder that cannot be written keeps it in memory only."""
    seed = Seed(descriptor(lay), np.array(guess, dtype=float), np.array(output.x, dtype=float),
                np.array(output.lam_x, dtype=float), np.array(output.lam_g, dtype=float), np.array(dq, dtype=float))
    seeds = _seeds_of(key, cache_dir)
    with _LOCK:
        seeds.pop(seed.digest, None)  # the newest last
        seeds[seed.digest] = seed
        while len(seeds) > ENTRIES:
            seeds.pop(next(iter(seeds)))
    folder = _folder(cache_dir, key)
    try:
        new = not folder.is_dir()
        folder.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=".seed.", suffix=".npz", dir=folder)
        try:
            with os.fdopen(fd, "wb") as f:
                np.savez(f, **{name: getattr(seed, name) for name in _FIELDS})
            Path(tmp).replace(folder / f"{seed.digest}.npz")
            now = time.time_ns()  # the file system's clock ticks in milliseconds: two stores would tie
            os.utime(folder / f"{seed.digest}.npz", ns=(now, now))
        except BaseException:
            _remove(Path(tmp))
            raise
        files = _seed_files(folder)
        for path in files[:-ENTRIES] if len(files) > ENTRIES else []:
            _remove(path)
    except OSError:
        return  # a read-only or vanished cache folder: the seed stays in memory
    if new:  # a new entry of the cache (a structure's folder; its files are bounded by ENTRIES)
        trim_cache(folder.parent)


# -- escalations: the collision rows a structure's plans came to need ------------------------------

ESCALATION = "escalation.json"  # in a structure's folder
_MAX_ESCALATION_BYTES = 1 << 20
# link pair "a/b" -> (sphere pairs, knots); scene object piece "scene:<key>" -> (robot spheres, knots)
EscalationRows = dict[str, tuple[set[int], set[int]]]
_ESCALATIONS: OrderedDict[str, EscalationRows | None] = OrderedDict()


def _parse_escalation(text: str) -> EscalationRows | None:
    """The rows of an escalation record, or None when it is not one (any other shape)."""
    try:
        doc = json.loads(text)
    except ValueError:
        return None
    if not isinstance(doc, dict) or doc.get("format") != 1 or not isinstance(doc.get("rows"), dict):
        return None
    out: EscalationRows = {}
    for name, entry in doc["rows"].items():
        if not (isinstance(entry, dict) and set(entry) == {"spheres", "knots"}):
            return None
        values = (entry["spheres"], entry["knots"])
        if not all(isinstance(v, list) and v and all(type(i) is int and 0 <= i < 1 << 20 for i in v) for v in values):
            return None
        out[name] = (set(values[0]), set(values[1]))
    return out or None


def find_escalation(key: str, cache_dir: str) -> EscalationRows | None:
    """The self-collision rows that earlier plans of structure ``key`` ended up needing (a
    collision round added them after the first solve), or None. A record that cannot be read as
    one is removed."""
    with _LOCK:
        if key in _ESCALATIONS:
            _ESCALATIONS.move_to_end(key)
            return _ESCALATIONS[key]
    path = _folder(cache_dir, key) / ESCALATION
    rows = None
    try:
        rows = _parse_escalation(read_text(path, _MAX_ESCALATION_BYTES))
        if rows is None:
            _remove(path)
    except (NotRegularFile, FileTooLarge, UnicodeDecodeError):  # a FIFO, a device, too large: damaged
        _remove(path)
    except OSError:  # missing or unreadable: no record
        rows = None
    with _LOCK:
        _ESCALATIONS[key] = rows
        while len(_ESCALATIONS) > MEMORY_KEYS:
            _ESCALATIONS.popitem(last=False)
    return rows


def store_escalation(key: str, rows: EscalationRows, cache_dir: str) -> None:
    """Remember that plans of structure ``key`` needed the collision ``rows`` (link pair ``"a/b"``
    -> (sphere pairs, knots); scene object piece ``"scene:<key>"`` -> (spheres, knots)): the next
    plan of that structure gets them before its first solve, so that it has the structure of the earlier plans' final solve (and their seeds)."""
    with _LOCK:
        _ESCALATIONS[key] = rows
    text = json.dumps({"format": 1, "rows": {name: {"spheres": sorted(s), "knots": sorted(k)}
                                             for name, (s, k) in sorted(rows.items())}}, sort_keys=True)
    folder = _folder(cache_dir, key)
    try:
        folder.mkdir(parents=True, exist_ok=True)
        write_text_atomic(folder / ESCALATION, text)
    except OSError:
        pass  # a read-only or vanished cache folder: remembered in this process only


def clear_memory() -> None:
    """Forget the seeds and escalations this process holds (the next lookup reads the folders again)."""
    with _LOCK:
        _MEMORY.clear()
        _ESCALATIONS.clear()
