"""The exception -> exit-code table (wbmp/errors.py): every exception class of the packages has a
row, docs/cli.md shows the same table, and each documented code comes from a real exception."""

from __future__ import annotations

import importlib
import inspect
import pkgutil
import re
from pathlib import Path

import pytest

from wbmp.errors import EXIT_TABLE, OWN, CliError, ExitCode, Terminated, classify, full_name

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("robots", "tasks", "language", "planner", "sim", "viz", "wbmp")


def exception_classes() -> dict[str, type]:
    """Every exception class defined in a module of the packages (``module.Class`` -> class)."""
    found: dict[str, type] = {}
    for top in PACKAGES:
        package = importlib.import_module(top)
        names = [top] + [m.name for m in pkgutil.walk_packages(package.__path__, f"{top}.")]
        for name in names:
            if name.rpartition(".")[2] == "__main__":
                continue
            module = importlib.import_module(name)
            for obj in vars(module).values():
                if inspect.isclass(obj) and issubclass(obj, BaseException) and obj.__module__ == name:
                    found[full_name(obj)] = obj
    return found


def test_every_exception_class_has_a_row():
    """A new exception class without a row in EXIT_TABLE fails here: decide its exit code."""
    classes = exception_classes()
    assert len(classes) >= 40  # the walk found the layers' exceptions (44 when this was written)
    rows = {rule.exception for rule in EXIT_TABLE}
    missing = sorted(set(classes) - rows)
    assert not missing, f"add a row to wbmp.errors.EXIT_TABLE (and docs/cli.md) for: {missing}"
    for name, cls in classes.items():  # each class decides by its own row, not a base's
        rule = next(r for r in EXIT_TABLE if r.exception == name)
        instance = cls.__new__(cls)
        if rule.code == OWN:
            instance.code = ExitCode.USAGE
        assert classify(instance) == (ExitCode.USAGE if rule.code == OWN else rule.code), name


def test_every_row_names_a_real_class_once():
    names = [rule.exception for rule in EXIT_TABLE]
    assert len(names) == len(set(names)), "a class has two rows"
    for name in names:
        module, _, cls = name.rpartition(".")
        obj = getattr(importlib.import_module(module), cls)
        assert inspect.isclass(obj) and issubclass(obj, BaseException) and full_name(obj) == name
        assert next(r for r in EXIT_TABLE if r.exception == name).why.strip()


def test_docs_show_the_same_table():
    """docs/cli.md lists every row with its code; a row there that the table lacks fails too."""
    text = (ROOT / "docs" / "cli.md").read_text(encoding="utf-8")
    documented = dict(re.findall(r"^\| `([\w.]+)` \| ([^|]+?) \|", text, flags=re.MULTILINE))
    expected = {rule.exception: ("own (`.code`)" if rule.code == OWN else "1, traceback" if rule.code is None
                                 else str(int(rule.code))) for rule in EXIT_TABLE}
    assert documented == expected


def _language_error():
    from language import parse

    with pytest.raises(Exception) as e:
        parse("   ")
    return e.value


def _robot_error():
    from robots import load_robot

    with pytest.raises(Exception) as e:
        load_robot("no-such-robot")
    return e.value


def _planner_error():
    from planner.exceptions import PlanningFailed

    return PlanningFailed("right hand target 'reach' is 0.21 m beyond reach at t = 1.50 s")


def _controller_error():
    from planner.wbc import WbcSettings

    with pytest.raises(Exception) as e:
        WbcSettings(dt=0.0)
    return e.value


def _sim_error():
    from sim import SimSettings

    with pytest.raises(Exception) as e:
        SimSettings(timestep=0.0)
    return e.value


def _viewer_error():
    from viz.live import ViewerError

    return ViewerError("the meshcat server did not start within 10 s")


def _vocabulary_error():
    from language.exceptions import VocabularyError

    return VocabularyError("vocabulary: action 'squat' needs English and Chinese words")


#: One case per documented code (docs/cli.md): a real exception of the layer and its code.
CASES = [
    (ExitCode.INTERNAL, _viewer_error, "ViewerError"),
    (None, _vocabulary_error, "VocabularyError"),  # a bug: the traceback, then exit 1
    (ExitCode.USAGE, _language_error, "EmptyInstruction"),
    (ExitCode.USAGE, lambda: CliError("bad option", ExitCode.USAGE), "CliError"),
    (ExitCode.INVALID_SPEC, _robot_error, "RobotNotFound"),
    (ExitCode.INVALID_SPEC, lambda: CliError("bad spec", ExitCode.INVALID_SPEC), "CliError"),
    (ExitCode.INFEASIBLE, _planner_error, "PlanningFailed"),
    (ExitCode.SIM_FAILED, _controller_error, "ControllerError"),
    (ExitCode.SIM_FAILED, _sim_error, "SimError"),
    (ExitCode.INTERRUPTED, KeyboardInterrupt, "KeyboardInterrupt"),
    (ExitCode.TERMINATED, Terminated, "Terminated"),
]


@pytest.mark.parametrize(("code", "make", "name"), CASES, ids=[f"{c!s}-{n}" for c, _, n in CASES])
def test_each_documented_code_from_a_real_exception(code, make, name):
    exc = make()
    assert type(exc).__name__ == name
    assert classify(exc) == code


def test_every_documented_code_has_a_row():
    """Each code of docs/cli.md's first table (but 0) is some row's code."""
    text = (ROOT / "docs" / "cli.md").read_text(encoding="utf-8")
    documented = {int(c) for c in re.findall(r"^\| (\d+) \| ", text, flags=re.MULTILINE)}
    assert documented == {int(c) for c in ExitCode}
    codes = {int(rule.code) for rule in EXIT_TABLE if rule.code not in (None, OWN)}
    assert codes == documented - {0}


def test_the_most_specific_class_decides():
    from planner.exceptions import PlannerError, SpecNotForRobot
    from robots.exceptions import FrameNotFound

    class Outsider(FrameNotFound):  # no row: its nearest base decides
        pass

    assert classify(Outsider.__new__(Outsider)) == ExitCode.INVALID_SPEC
    assert classify(SpecNotForRobot("robot 'talos' has no joint 'x'")) == ExitCode.INVALID_SPEC  # before PlannerError
    assert classify(PlannerError("solver failed")) == ExitCode.INFEASIBLE
    assert classify(ValueError("not ours")) is None


def test_one_root_with_one_base_per_layer():
    """Every exception class the layers define derives from ``robots.WbmpError`` (but the internal
    ones the table marks as caught or a bug, and the SIGTERM signal); each layer's base derives
    from it directly, so ``except WbmpError`` catches every error the project raises on purpose."""
    from language import LanguageError
    from planner import PlannerError
    from robots import RobotError, WbmpError
    from sim import SimError
    from tasks import TaskError
    from viz import VizError
    from wbmp.errors import CliError

    for base in (RobotError, TaskError, LanguageError, PlannerError, SimError, VizError, CliError):
        assert WbmpError in base.__bases__, base
    coded = {rule.exception for rule in EXIT_TABLE if rule.code is not None}
    outside = sorted(name for name, cls in exception_classes().items()
                     if name in coded and not issubclass(cls, WbmpError))
    # SIGTERM (a BaseException, as KeyboardInterrupt is), and wbmp serve's own states, answered as
    # HTTP statuses (left to derive from WbmpError when serve's errors are next changed)
    assert outside == ["wbmp.errors.Terminated", "wbmp.serve.corrections.CorrectionError",
                       "wbmp.serve.session.Busy", "wbmp.serve.session.Unavailable"], outside
