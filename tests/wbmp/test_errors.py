"""The exception -> exit-code table (wbmp/errors.py, keyed by class): every public exception class
of the packages has a row and lives in its layer's exception module, docs/cli.md shows the same
table, and each documented code comes from a real exception."""

from __future__ import annotations

import importlib
import inspect
import pkgutil
import re
from pathlib import Path

import pytest

from wbmp.errors import OWN, CliError, ExitCode, Terminated, classify, exit_table, full_name

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


#: Where the classes of the table may live: each layer's exception module, and the stores' and
#: readers' ``OSError`` kinds beside the code that raises them (standard library only).
EXCEPTION_MODULES = {"robots.exceptions", "robots.store", "robots.safeio", "tasks.exceptions",
                     "language.exceptions", "planner.exceptions", "sim.exceptions", "viz.exceptions",
                     "wbmp.errors", "builtins"}


def test_every_exception_class_has_a_row():
    """A new public exception class without a row in exit_table() fails here: decide its exit code.
    A private one (``_Refused``) is caught inside its module and has no row: its nearest base
    with a row decides, should it ever escape."""
    classes = exception_classes()
    assert len(classes) >= 40  # the walk found the layers' exceptions (53 when this was written)
    table = {rule.exception: rule for rule in exit_table()}
    public = {name: cls for name, cls in classes.items() if not cls.__name__.startswith("_")}
    missing = sorted(name for name, cls in public.items() if cls not in table)
    assert not missing, f"add a row to wbmp.errors.exit_table() (and docs/cli.md) for: {missing}"
    private = sorted(name for name, cls in classes.items() if cls in table and cls.__name__.startswith("_"))
    assert not private, f"a private class needs no row: {private}"
    for name, cls in public.items():  # each class decides by its own row, not a base's
        rule = table[cls]
        instance = cls.__new__(cls)
        if rule.code == OWN:
            instance.code = ExitCode.USAGE
        assert classify(instance) == (ExitCode.USAGE if rule.code == OWN else rule.code), name


def test_every_row_is_a_class_once_in_its_layers_exception_module():
    rows = [rule.exception for rule in exit_table()]
    assert len(rows) == len(set(rows)), "a class has two rows"
    for cls in rows:
        assert inspect.isclass(cls) and issubclass(cls, BaseException)
        assert cls.__module__ in EXCEPTION_MODULES, f"move {full_name(cls)} into its layer's exception module"
        assert next(r for r in exit_table() if r.exception is cls).why.strip()


def test_classifying_an_error_loads_no_heavy_module():
    """The table imports the layers' exception modules only: a misspelt sentence's one-line error
    does not load CasADi, MuJoCo or Pinocchio (a fresh interpreter, so nothing is loaded yet)."""
    import subprocess
    import sys

    code = ("import sys\nfrom wbmp.errors import classify, exit_table\nfrom robots import RobotError\n"
            "exit_table(); classify(RobotError('x'))\n"
            "print(sorted(m for m in ('casadi', 'mujoco', 'pinocchio', 'proxsuite', 'coal') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT)
    assert out.stdout.strip() == "[]", out.stdout + out.stderr


def test_docs_show_the_same_table():
    """docs/cli.md lists every row with its code; a row there that the table lacks fails too."""
    text = (ROOT / "docs" / "cli.md").read_text(encoding="utf-8")
    documented = dict(re.findall(r"^\| `([\w.]+)` \| ([^|]+?) \|", text, flags=re.MULTILINE))
    expected = {full_name(rule.exception): ("own (`.code`)" if rule.code == OWN else "1, traceback"
                                            if rule.code is None else str(int(rule.code))) for rule in exit_table()}
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
    from planner import PlanningFailed

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
    from viz import ViewerError

    return ViewerError("the meshcat server did not start within 10 s")


def _vocabulary_error():
    from language import VocabularyError

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
    codes = {int(rule.code) for rule in exit_table() if rule.code not in (None, OWN)}
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
    coded = {rule.exception for rule in exit_table() if rule.code is not None}
    outside = sorted(name for name, cls in exception_classes().items()
                     if cls in coded and not issubclass(cls, WbmpError))
    assert outside == ["wbmp.errors.Terminated"], outside  # SIGTERM: a BaseException, as KeyboardInterrupt is
