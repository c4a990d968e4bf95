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
