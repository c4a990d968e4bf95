"""The pipeline does each step once: the actions are fitted to the robot once (build_spec fits
them to print the sizes it chose; compile_actions does not fit them again), and the spec is the
one compile_actions makes of the raw actions on its own."""

from __future__ import annotations

import tasks.compose as compose
from language import parse
from tasks.compose import compile_actions
from wbmp.pipeline import SolveRequest, build_spec

SENTENCE = "squat 20 cm, then wave your right hand twice"


def test_the_actions_are_fitted_once(talos, monkeypatch):
    calls: list[str] = []
    fit = compose.fit_defaults

    def counted(primitive, action, robot):
        calls.append(action.name)
        return fit(primitive, action, robot)

    monkeypatch.setattr(compose, "fit_defaults", counted)
    robot, spec, actions = build_spec(SolveRequest(instruction=SENTENCE, robot="talos", simulate=False))
    assert actions is not None and [a.name for a in actions.actions] == ["squat", "wave"]
    assert calls == ["squat", "wave"]  # once per action (twice each before: the pipeline, then compile)
    calls.clear()
    alone = compile_actions(parse(SENTENCE).actions, robot, description=SENTENCE)
    assert calls == ["squat", "wave"]  # compile_actions alone still fits what it is given
    assert spec == alone and spec.description == SENTENCE and spec.robot == "talos"


def test_fitted_actions_compile_to_the_same_spec(talos):
    """Fitting is idempotent: compiling fitted actions with fitted=True gives the spec the raw
    actions give (a default beyond the robot's limit comes out as the limit either way)."""
    raw = parse("squat, then take a step forward").actions
    fitted = compose.fit_actions(raw, talos)
    assert compile_actions(fitted, talos, fitted=True) == compile_actions(raw, talos)
    assert compose.fit_actions(fitted, talos) == fitted


def test_a_repeat_from_the_motion_cache_is_not_parsed_again(tmp_path, monkeypatch):
    """The request record keeps the parsed actions: a repeat takes them from there (words and
    defaults included) instead of parsing the sentence again, and loads no robot model."""
    import numpy as np

    import wbmp.pipeline as pipeline

    def request() -> SolveRequest:
        return SolveRequest(instruction="squat 10 cm", robot="talos", simulate=False)

    first = pipeline.solve(request(), cache=True, cache_dir=tmp_path)
    assert first.cached is None and first.cache_key is not None and first.actions is not None

    def refuse(_request):
        raise AssertionError("the sentence was parsed again")

    monkeypatch.setattr(pipeline, "parse_instruction", refuse)
    again = pipeline.solve(request(), cache=True, cache_dir=tmp_path)
    assert again.cached is not None and again.robot is None and again.actions is not None
    assert again.actions == first.actions and again.actions.words == first.actions.words
    assert again.actions.describe() == first.actions.describe()
    assert again.report()["actions"] == first.report()["actions"]
    assert np.array_equal(again.plan.q, first.plan.q)


def test_the_solution_library_does_not_depend_on_hashing_the_robot_files(tmp_path, monkeypatch):
    """With the motion cache, a robot whose files cannot be hashed (the result is then not cached)
    still plans with the user's solution library setting, as every other robot does: whether the
    cache can store a result does not change which plan comes out."""
    import wbmp.environment as environment
    import wbmp.motioncache as motioncache
    import wbmp.pipeline as pipeline

    asked: list[dict] = []
    settings = environment.planner_settings

    def recorded(**overrides):
        asked.append(overrides)
        return settings(**overrides)

    def unreadable(robot):
        raise PermissionError("a mesh file cannot be read")

    monkeypatch.setattr(environment, "planner_settings", recorded)
    monkeypatch.setattr(motioncache, "robot_files", unreadable)
    result = pipeline.solve(SolveRequest(instruction="squat 10 cm", robot="talos", simulate=False),
                            cache=True, cache_dir=tmp_path)
    assert result.plan.ok and result.cache_key is None  # planned, not stored
    assert asked == [{}]  # the user's settings, not solution_library="off"
    asked.clear()
    pipeline.solve(SolveRequest(instruction="squat 10 cm", robot="talos", simulate=False), cache=False)
    assert asked == [{"cache": {"solution_library": "off"}}]  # --no-cache: the request alone, as before


def test_a_fresh_result_is_compressed_once_for_the_cache_and_out(tmp_path):
    """A fresh result stored in the motion cache keeps its motion file's bytes; --out copies its
    arrays' compressed members from them (the same compressed sizes and checksums as the stored
    entry) and writes only the request's JSON members anew; the file reads back to the plan."""
    import zipfile

    import numpy as np

    import wbmp.outputs as outputs
    import wbmp.pipeline as pipeline
    from wbmp.motionfile import load_motion

    cache = tmp_path / "cache"
    result = pipeline.solve(SolveRequest(instruction="squat 10 cm", robot="talos", simulate=False),
                            cache=True, cache_dir=cache)
    assert result.cache_key is not None and result.motion_file is not None
    out = tmp_path / "m.npz"
    outputs.write_outputs(result, out=str(out), cache_dir=cache)
    with zipfile.ZipFile(cache / f"{result.cache_key}.npz") as stored, zipfile.ZipFile(out) as written:
        for name in ("q.npy", "v.npy", "com.npy"):
            a, b = stored.getinfo(name), written.getinfo(name)
            assert (a.CRC, a.compress_size, a.compress_type) == (b.CRC, b.compress_size, b.compress_type), name
    m = load_motion(out)
    assert np.array_equal(m.plan.q, result.plan.q) and m.plan.spec == result.spec
    assert m.report["instruction"] == "squat 10 cm" and m.report["cached"] is False
