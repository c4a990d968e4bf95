"""The solution library (planner/trajopt/library.py): a stored solution of the same structure seeds
a dynamic plan's solve, never a worse start than the task's own guess, never trusted unchecked.

G1 side steps (two steps left, ~1 s a plan): the 8 cm plan's solution seeds the 6 cm plan, which
then takes 9 IPOPT iterations instead of 20 (measured 2026-11-24) and reaches an objective within
a per cent of the cold plan's. The suite runs with the library off (tests/conftest.py); these tests
switch it on in their own cache folders.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from planner import CacheSettings, PlannerSettings, SolverSettings, plan, plan_with_library
from planner.trajopt import library
from planner.trajopt.api import _formulation, add_screened_terms
from planner.trajopt.cache import clear_memory_cache, solver_key
from planner.trajopt.solver_output import SolverOutput
from tasks.compose import compile_actions

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")


def _side(g1, length: float):
    return compile_actions([{"action": "step", "params": {"direction": "left", "length": length, "count": 2}}], g1)


def _files(folder) -> list:
    return sorted((folder / "seeds").glob("*/*.npz"))


@pytest.fixture(autouse=True)
def _fresh_memory():
    library.clear_memory()
    yield
    library.clear_memory()


@pytest.fixture(scope="module")
def cold(g1):
    """The 6 cm plan from its own guess (library off)."""
    return plan(_side(g1, 0.06), g1, settings=PlannerSettings(cache=CacheSettings(solution_library="off")))


def _output(x, lam_g) -> SolverOutput:
    """A solve's output with these variables and row multipliers (zero bound multipliers)."""
    return SolverOutput(x=x, lam_x=np.zeros_like(x), lam_g=lam_g, g=np.zeros_like(lam_g), lbg=np.zeros_like(lam_g),
                        ubg=np.zeros_like(lam_g), nlp_layout=None)


def _layout(g1, spec, settings):
    lay, settings = _formulation(spec, g1, settings)
    guess = lay.initial_guess(settings)
    lay, _ = add_screened_terms(lay, settings, guess)
    return lay, settings, guess


def test_a_neighbour_seeds_the_solve_and_read_mode_stores_nothing(g1, cold, tmp_path):
    source = plan_with_library(_side(g1, 0.08), g1,
                  settings=PlannerSettings(cache=CacheSettings(cache_dir=str(tmp_path), solution_library="on")))
    assert source.stats.seed == ""  # an empty library
    files = _files(tmp_path)
    assert len(files) == 1
    library.clear_memory()  # another process: read from the folder, and build the solver again
    clear_memory_cache()
    seeded = plan_with_library(_side(g1, 0.06), g1,
                  settings=PlannerSettings(cache=CacheSettings(cache_dir=str(tmp_path), solution_library="read")))
    assert seeded.stats.seed.startswith("library (distance ")
    # the solver was fetched to test the seed: its build is in the stats, not the solve's memory hit
    assert seeded.stats.cache == "built" and seeded.stats.build_time > 0.2, seeded.stats
    assert seeded.ok and cold.ok  # every check of the plan (Pinocchio numerics), as for any plan
    assert seeded.stats.iterations <= cold.stats.iterations - 5, (seeded.stats.iterations, cold.stats.iterations)
    assert abs(seeded.stats.objective - cold.stats.objective) <= 0.01 * abs(cold.stats.objective)
    assert _files(tmp_path) == files  # "read" stored nothing
    off = plan_with_library(_side(g1, 0.06), g1,
               settings=PlannerSettings(cache=CacheSettings(cache_dir=str(tmp_path), solution_library="off")))
    assert off.stats.seed == "" and off.stats.iterations == cold.stats.iterations
    np.testing.assert_array_equal(off.q, cold.q)  # off: the history-free result


def test_damaged_and_foreign_files_are_removed_not_used(g1, cold, tmp_path):
    settings = PlannerSettings(cache=CacheSettings(cache_dir=str(tmp_path), solution_library="on"))
    lay, full, _ = _layout(g1, _side(g1, 0.06), settings)
    folder = tmp_path / "seeds" / solver_key(lay, full)
    folder.mkdir(parents=True)
    (folder / "0123456789abcdef.npz").write_bytes(b"not a zip file")
    np.savez(folder / "fedcba9876543210.npz", x=np.array([None], dtype=object))  # a pickle inside
    wrong = library.Seed(np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3), np.zeros((2, 2)))
    np.savez(folder / f"{wrong.digest}.npz", descriptor=wrong.descriptor, guess=wrong.guess, x=wrong.x,
             lam_x=wrong.lam_x, lam_g=wrong.lam_g, dq=wrong.dq)  # well-formed, the wrong sizes
    p = plan_with_library(_side(g1, 0.06), g1, settings=settings)
    assert p.stats.seed == "" and p.stats.iterations == cold.stats.iterations
    assert [f.name for f in _files(tmp_path)] == [f"{library.Seed(library.descriptor(lay), *[np.zeros(0)] * 5).digest}.npz"]
    assert p.ok


def test_a_seed_that_starts_farther_from_feasibility_than_the_guess_is_not_used(g1, cold, tmp_path):
    settings = PlannerSettings(cache=CacheSettings(cache_dir=str(tmp_path), solution_library="on"))
    lay, full, guess = _layout(g1, _side(g1, 0.06), settings)
    key = solver_key(lay, full)
    rng = np.random.default_rng(0)
    far = guess + rng.normal(0.0, 0.5, guess.shape)  # half a radian / metre of noise everywhere
    raw = _output(far, np.zeros(cold.stats.n_constraints))
    library.store_seed(lay, key, guess, raw, np.zeros((lay.N + 1, g1.nv)), str(tmp_path))
    assert library.has_seeds(key, str(tmp_path))
    p = plan_with_library(_side(g1, 0.06), g1,
             settings=PlannerSettings(cache=CacheSettings(cache_dir=str(tmp_path), solution_library="read")))
    assert p.stats.seed == "" and p.stats.iterations == cold.stats.iterations
    np.testing.assert_array_equal(p.q, cold.q)


def test_a_seeded_solve_that_fails_is_done_again_from_the_guess(g1, tmp_path):
    """A seed that is accepted but whose solve stops at the iteration limit: the task's own guess
    is solved next, and the stats say both."""
    source = PlannerSettings(cache=CacheSettings(cache_dir=str(tmp_path), solution_library="on"))
    plan_with_library(_side(g1, 0.08), g1, settings=source)
    lay8, full8, _ = _layout(g1, _side(g1, 0.08), source)
    stored = next(iter(library._seeds_of(solver_key(lay8, full8), str(tmp_path)).values()))
    short = PlannerSettings(cache=CacheSettings(cache_dir=str(tmp_path), solution_library="read"),
                            solver=SolverSettings(max_iterations=2), diagnose=False)
    lay, full, _ = _layout(g1, _side(g1, 0.06), short)  # another solver key: the options differ
    library.store_seed(lay8, solver_key(lay, full), stored.guess,
                       dataclasses.replace(_output(stored.x, stored.lam_g), lam_x=stored.lam_x), stored.dq,
                       str(tmp_path))
    said: list[str] = []
    p = plan_with_library(_side(g1, 0.06), g1, settings=short, throw=False, progress=said.append)
    assert not p.ok
    assert any(m.startswith("starting from a stored solution") for m in said)
    assert "the solve from the stored solution failed: solving from the task's own guess" in said
    assert "failed: solved again from the task's own guess" in p.stats.seed
    assert p.stats.iterations >= 4  # both solves, 2 iterations each at least


def test_settings_refuse_an_unknown_mode():
    from planner.exceptions import PlannerError

    with pytest.raises(PlannerError, match="solution_library must be 'on', 'read' or 'off'"):
        PlannerSettings(cache=CacheSettings(solution_library="maybe"))


def test_the_environment_variable_sets_the_command_lines_default(monkeypatch):
    """$WBMP_SOLUTION_LIBRARY sets the command line's mode (wbmp/environment.py); the planner's own
    default is off whatever it says (no hidden state: a library call reads no stored solution)."""
    from wbmp.environment import planner_settings

    for value, mode in (("off", "off"), ("0", "off"), ("read", "read"), ("on", "on"), ("", "on")):
        monkeypatch.setenv("WBMP_SOLUTION_LIBRARY", value)
        assert planner_settings().cache.solution_library == mode
        assert PlannerSettings().cache.solution_library == "off"


def test_wbmp_solve_uses_the_library_with_the_motion_cache_only(g1, cold, tmp_path, monkeypatch):
    """``wbmp solve`` plans with the library when the motion cache is on; ``--no-cache`` (no motion
    cache) plans from the task's own guess, whatever the library holds."""
    from wbmp.pipeline import SolveRequest, solve

    monkeypatch.setenv("WBMP_CACHE_DIR", str(tmp_path))
    monkeypatch.setenv("WBMP_SOLUTION_LIBRARY", "on")
    motions = tmp_path / "motions"
    first = solve(SolveRequest(instruction="step left 8 cm twice", robot="g1", simulate=False), cache=True,
                  cache_dir=motions)
    assert first.plan.ok and first.plan.stats.seed == "" and len(_files(tmp_path)) == 1
    request = SolveRequest(instruction="step left 6 cm twice", robot="g1", simulate=False)
    fresh = solve(request, cache=False)
    assert fresh.plan.stats.seed == "" and fresh.plan.stats.iterations == cold.stats.iterations
    seeded = solve(request, cache=True, cache_dir=motions)
    assert seeded.plan.stats.seed.startswith("library")
    assert seeded.plan.stats.iterations <= cold.stats.iterations - 5
    assert seeded.report()["solver"]["seed"] == seeded.plan.stats.seed
    assert "started from a stored solution of this structure: library" in seeded.plan.summary()


def test_a_structure_keeps_its_newest_seeds_only(g1, tmp_path, monkeypatch):
    settings = PlannerSettings(cache=CacheSettings(cache_dir=str(tmp_path), solution_library="on"))
    lay, full, guess = _layout(g1, _side(g1, 0.06), settings)
    key = solver_key(lay, full)
    raw = _output(guess, np.zeros(3))
    dq = np.zeros((lay.N + 1, g1.nv))
    digests = []
    for i in range(library.ENTRIES + 3):
        monkeypatch.setattr(library, "descriptor", lambda _lay, i=i: np.full(4, float(i)))
        library.store_seed(lay, key, guess, raw, dq, str(tmp_path))
        digests.append(library.Seed(np.full(4, float(i)), *[np.zeros(0)] * 5).digest)
    kept = {f.stem for f in _files(tmp_path)}
    assert kept == set(digests[-library.ENTRIES:])  # the oldest three went, on disk
    assert set(library._seeds_of(key, str(tmp_path))) == kept  # and in memory
    library.clear_memory()
    assert set(library._seeds_of(key, str(tmp_path))) == kept  # read back from the folder


@pytest.mark.long  # in make test-long: the 2-core suite stays under 10 minutes (~24 s)
def test_a_structure_that_needed_a_collision_round_gets_its_rows_before_the_first_solve(talos, tmp_path):
    """Talos "walk forward two steps then wave your right hand": the first plan solves more than
    once (82 iterations in three solves on 2026-11-24: its right gripper comes within the margin of
    its right thigh, and a collision round adds 17 link pairs' rows; since 2026-11-29 the round's
    layout is re-linearized in the same step, so no third solve when that suffices). The
    library remembers the rows; the 12 cm variant gets them before its first solve, has the first
    plan's final structure, and starts from its solution (14 iterations, 2026-11-24)."""
    from wbmp.pipeline import SolveRequest, build_spec

    settings = PlannerSettings(cache=CacheSettings(cache_dir=str(tmp_path), solution_library="on"))

    def spec_of(sentence):
        return build_spec(SolveRequest(instruction=sentence, robot="talos", simulate=False), lambda _m: None)[1]

    said: list[str] = []
    first = plan_with_library(spec_of("walk forward two steps then wave your right hand"), talos, settings=settings,
                 progress=said.append)
    assert first.ok
    assert any("came within the collision margin: solving again" in m for m in said)
    records = sorted((tmp_path / "seeds").glob(f"*/{library.ESCALATION}"))
    assert len(records) == 1
    library.clear_memory()  # another process: read from the folder
    said.clear()
    variant = plan_with_library(spec_of("walk forward 2 steps 12 cm then wave your right hand"), talos, settings=settings,
                   progress=said.append)
    assert variant.ok  # every check, the self-collision check on the collision model among them
    assert any(m.startswith("adding the collision rows of") for m in said)
    assert not any("came within the collision margin" in m for m in said)
    assert variant.stats.n_constraints == first.stats.n_constraints  # the first plan's final structure
    assert variant.stats.seed.startswith("library")
    assert variant.stats.iterations <= first.stats.iterations // 3, (variant.stats.iterations, first.stats.iterations)


def test_an_escalation_record_that_does_not_fit_is_not_used(g1, cold, tmp_path):
    settings = PlannerSettings(cache=CacheSettings(cache_dir=str(tmp_path), solution_library="read"))
    lay, full, _ = _layout(g1, _side(g1, 0.06), settings)
    folder = tmp_path / "seeds" / solver_key(lay, full)
    folder.mkdir(parents=True)
    record = folder / library.ESCALATION
    for text in ('{"format": 1, "rows": {"no_link/other_link": {"spheres": [0], "knots": [5]}}}',  # no such pair
                 '{"format": 1, "rows": {"x": {"spheres": [0], "knots": [true]}}}', "{not json"):
        record.write_text(text)
        library.clear_memory()
        said: list[str] = []
        p = plan_with_library(_side(g1, 0.06), g1, settings=settings, progress=said.append)
        assert not any(m.startswith("adding the collision rows") for m in said)
        assert p.stats.n_constraints == cold.stats.n_constraints and p.stats.iterations == cold.stats.iterations
        assert record.exists() == text.startswith('{"format": 1, "rows": {"no_link')  # not a record: removed


def test_an_escalation_record_adds_its_rows(g1, cold, tmp_path):
    from planner.trajopt.collision import sphere_sets

    sets = sphere_sets(g1)
    settings = PlannerSettings(cache=CacheSettings(cache_dir=str(tmp_path), solution_library="read"))
    lay, full, _ = _layout(g1, _side(g1, 0.06), settings)
    name = "/".join(sets.pair_names[0])
    library.store_escalation(solver_key(lay, full), {name: ({0}, {10, 11, 12})}, str(tmp_path))
    library.clear_memory()
    said: list[str] = []
    p = plan_with_library(_side(g1, 0.06), g1, settings=settings, progress=said.append)
    assert "adding the collision rows of 1 link pair(s) that earlier plans of this task structure needed" in said
    assert p.stats.n_constraints == cold.stats.n_constraints + 3  # one sphere pair at three knots
    assert p.ok
    # plan() reads no library, whatever the settings say: the plan from the task alone, byte for byte
    said.clear()
    pure = plan(_side(g1, 0.06), g1, settings=settings, progress=said.append)
    assert not any(m.startswith("adding the collision rows") for m in said)
    assert pure.stats.n_constraints == cold.stats.n_constraints and np.array_equal(pure.q, cold.q)
    # ... and the record passed in is the library's, explicitly: the library's plan, byte for byte
    given = plan(_side(g1, 0.06), g1, settings=settings, collision_rows={name: ({0}, {10, 11, 12})})
    assert given.stats.n_constraints == p.stats.n_constraints and np.array_equal(given.q, p.q)


def test_a_record_holds_scene_rows_and_gives_them_back(g1):
    """A record names a scene object's rows ``"scene:<piece key>"`` beside the link pairs: applied, the
    layout has SceneCollisionTerms for exactly that sphere of that piece at those knots (read back from
    the terms, not from the record), ``recorded_rows`` of it holds the record; a record naming a
    piece the scene does not have is not used. (The kitchen pick-up's round adds a table piece:
    without it in the record the round, and a second solve from no seed, came back every time.)"""
    from pathlib import Path

    from planner.trajopt.api import Problem, _with_recorded_rows, recorded_rows
    from planner.trajopt.collision import Rows, sphere_sets
    from planner.trajopt.scene_collision import SceneCollisionTerm, obstacles
    from tasks.scene import load_scene

    scene = load_scene(Path(__file__).resolve().parents[3] / "examples" / "scenes" / "kitchen.json")
    spec = dataclasses.replace(_side(g1, 0.06), scene=scene)
    lay, settings = _formulation(spec, g1, PlannerSettings())  # no guess, no screening: only the rows given
    problem = Problem(lay, settings, np.zeros(0), Rows())
    assert not any(isinstance(t, SceneCollisionTerm) for t in problem.layout.terms)
    table = next(ob for ob in obstacles(scene) if ob.name == "table")
    pair = "/".join(sphere_sets(g1).pair_names[0])
    record = {f"scene:{table.key}": ({3}, {10, 11, 12}), pair: ({0}, {10, 11})}
    said: list[str] = []
    recalled, fits = _with_recorded_rows(problem, record, said.append)
    assert fits and said == ["adding the collision rows of 1 link pair(s) and 1 object(s) that earlier plans of this "
                             "task structure needed"]
    terms = [t for t in recalled.layout.terms if isinstance(t, SceneCollisionTerm)]
    assert sorted(t.knot for t in terms) == [10, 11, 12] and {t.item for t in terms} == {table.key}
    assert all(len(t.lower) == 1 for t in terms)  # one sphere, one row
    back = recorded_rows(recalled.layout, recalled.settings)
    assert back[f"scene:{table.key}"] == ({3}, {10, 11, 12}) and back[pair] == ({0}, {10, 11})
    assert problem.layout.terms is not recalled.layout.terms  # the problem given is not changed
    stranger, fits = _with_recorded_rows(problem, {"scene:no_such_piece": ({0}, {10})}, None)
    assert not fits and stranger is problem
