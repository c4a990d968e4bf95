"""Bounds on the work asked (tasks/limits.py), and contact/joint errors that are the spec's (exit 3).

A request beyond a bound is refused with the bound and the reason before anything is built:
no solver in the cache, no file, a few MB of memory at most. Where it is refused decides the
exit code, as for every other error (docs/spec-format.md, "Limits"):

- the sentence itself (too many actions, a repeat count too large): the language layer, exit 2;
- the motion (too long, too many phases, knots, targets), from a spec file or compiled from a
  sentence: the tasks layer, exit 3.
"""

from __future__ import annotations

import copy
import json
import tracemalloc

import pytest

from language import parse
from language.exceptions import LanguageError, UnsupportedInstruction
from language.plan import ActionPlan
from robots import load_robot
from tasks import (
    CoMBounds,
    Contact,
    FrameTarget,
    JointTarget,
    Phase,
    Pose,
    TaskDefinitionError,
    TaskSpec,
)
from tasks.actions import Action
from tasks.compose import compile_actions
from tasks.limits import MAX_ACTIONS, MAX_HORIZON, MAX_KNOTS, MAX_PHASES, MAX_TERMS
from tasks.robot_check import check_spec_for_robot
from tasks.serialize import load_spec
from tests.badinput.conftest import REPO, Tree, assert_refused, run_cli
from tests.language.llm_server import Reply, ScriptedServer
from wbmp.errors import ExitCode, classify

SQ = REPO / "examples" / "specs" / "squat.json"
SQ_DATA = json.loads(SQ.read_text(encoding="utf-8"))
FEET = SQ_DATA["phases"][0]["contacts"]


def _spec(**changes) -> dict:
    data = copy.deepcopy(SQ_DATA)
    data.update(changes)
    return data


def _phases(n: int, duration: float) -> list[dict]:
    return [{"name": f"p{i}", "duration": duration, "contacts": FEET} for i in range(n)]


def _joint_targets(n: int) -> list[dict]:
    return [{"name": f"j{i}", "joint": "head_1_joint", "value": 0.0, "time": 1.0} for i in range(n)]


def _windowed_bounds(n: int) -> list[dict]:
    return [{"name": f"b{i}", "support_polygon": False, "window": None} for i in range(n)]


SPEC_CASES = [
    ("phase-1e9-s", _spec(phases=_phases(1, 1e9)), ("1e+09 s", f"at most {MAX_HORIZON:g} s", "split")),
    ("phase-1e5-s", _spec(phases=_phases(1, 1e5)), ("100000 s", "at most 60 s")),
    ("two-40-s-phases", _spec(phases=_phases(2, 40.0)), ("would last 80 s", "at most 60 s", "split")),
    ("1e5-s-in-2000-phases", _spec(phases=_phases(2000, 50.0)), ("2000 phases", f"at most {MAX_PHASES}")),
    ("201-short-phases", _spec(phases=_phases(201, 0.1)), ("201 phases", "at most 200")),
    ("5000-phases", _spec(phases=_phases(5000, 0.01)), ("spec.phases", "5000 items", "at most 3000")),
    ("10-s-on-a-5-ms-grid", _spec(phases=_phases(1, 10.0), dt=0.005, com_targets=[]),
     ("2000 knot intervals", f"at most {MAX_KNOTS}", "raise dt")),
    ("60-s-on-a-50-ms-grid", _spec(phases=_phases(1, 60.0), dt=0.05), ("1200 knot intervals",)),
    ("3001-joint-targets", _spec(joint_targets=_joint_targets(3001)), ("spec.joint_targets", "3001 items")),
    ("3000-items-in-all", _spec(joint_targets=_joint_targets(2999)), ("3001 targets and bounds", "at most 3000")),
    ("bounds-on-every-knot", _spec(phases=_phases(1, 60.0), com_targets=[], com_bounds=_windowed_bounds(30)),
     ("24030 knots", f"at most {MAX_TERMS}")),
    ("9-contacts-in-a-phase",
     _spec(phases=[{"name": "many", "duration": 1.0, "contacts": [
         {"frame": f"frame_{i}", "placement": {"position": [0.0, 0.1 * i, 0.0]}} for i in range(9)]}],
         com_targets=[]),
     ("9 contacts", "at most 8")),
    ("target-time-1e308", _spec(targets=[{"name": "t", "frame": "left_hand", "position": [0, 0, 1], "time": 1e308}]),
     ("time", "[0, 60] s")),
    ("window-to-1e308", _spec(targets=[{"name": "t", "frame": "left_hand", "position": [0, 0, 1],
                                        "window": [0.0, 1e308]}]), ("window", "60")),
]


@pytest.mark.parametrize(("data", "words"), [c[1:] for c in SPEC_CASES], ids=[c[0] for c in SPEC_CASES])
def test_spec_beyond_a_limit_is_refused_before_any_work(tmp_path, capsys, monkeypatch, data, words):
    """Exit 3 naming the limit; no solver built (the cache folder stays empty), no file written."""
    monkeypatch.setenv("WBMP_CACHE_DIR", str(tmp_path / "cache"))
    spec = tmp_path / "big.json"
    spec.write_text(json.dumps(data), encoding="utf-8")
    tree = Tree(tmp_path)
    out = run_cli(["solve", "--spec", spec, "--no-sim", "--quiet", "--out", tmp_path / "m.npz"], capsys)
    assert_refused(out, 3, "big.json", *words)
    tree.assert_unchanged()


@pytest.mark.parametrize("data", [SPEC_CASES[0][1], SPEC_CASES[3][1], SPEC_CASES[6][1]], ids=["1e9-s", "2000-phases", "5-ms-grid"])
def test_refusal_allocates_almost_nothing(tmp_path, data):
    """The refusal comes before anything sized by the horizon is allocated (the 1e9 s phase asked 99 GiB)."""
    spec = tmp_path / "big.json"
    spec.write_text(json.dumps(data), encoding="utf-8")
    tracemalloc.start()
    try:
        with pytest.raises(TaskDefinitionError):
            load_spec(spec)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 32 * 2**20, f"{peak / 2**20:.1f} MB allocated to refuse it"


def _phase(duration: float) -> Phase:
    return Phase(name="p", duration=duration)


@pytest.mark.parametrize(
    ("build", "words"),
    [
        (lambda: _phase(1e9), "longer than wbmp plans"),
        (lambda: _phase(float("inf")), "duration must be > 0"),
        (lambda: TaskSpec(phases=(_phase(31.0), _phase(31.0))), "would last 62 s"),
        (lambda: TaskSpec(phases=tuple(_phase(0.01) for _ in range(MAX_PHASES + 1))), "phases"),
        (lambda: TaskSpec(phases=(_phase(50.0),), dt=0.01), "knot intervals"),
        (lambda: TaskSpec(phases=(_phase(1.0),), dt=float("nan")), "dt"),
        (lambda: Pose(position=(1e308, 0.0, 0.0)), "position"),
        (lambda: Pose(position=(0.0, 0.0, 0.0), rpy=(0.0, 0.0, float("inf"))), "rpy"),
        (lambda: Contact(frame="left_foot", placement=Pose(position=(0, 0, 0)), friction_coefficient=float("nan")),
         "friction"),
        (lambda: FrameTarget(name="t", frame="left_hand", position=(0, 0, 1), weight=float("inf")), "weight"),
        (lambda: FrameTarget(name="t", frame="left_hand", position=(0, 0, 1), time=10**400), "time"),
        (lambda: JointTarget(name="j", joint="head_1_joint", value=10**400), "value"),
        (lambda: CoMBounds(margin=1e308), "margin"),
    ],
)
def test_spec_values_are_bounded_on_construction(build, words):
    """The dataclasses refuse non-finite and absurd values themselves (any producer, not only files)."""
    with pytest.raises(TaskDefinitionError, match=words) as e:
        build()
    assert "\n" not in str(e.value) and len(str(e.value)) < 400


# ---------------------------------------------------------------------------------------------
# Sentences.

def _chain(clause: str, n: int) -> str:
    return ", then ".join([clause] * n)


SENTENCE_CASES = [
    ("60-chained-squats", _chain("squat", 60), 2, ("60 actions", f"at most {MAX_ACTIONS}", "split")),
    ("21-chained-waves", _chain("wave", 21), 2, ("21 actions",)),
    ("jumps-by-count", "jump 10 times, then jump 10 times, then jump 5 times", 2, ("25 actions",)),
    ("squat-11-times", "squat 11 times", 2, ("11", "maximum 10")),
    ("wave-1000-times", "wave 1000 times", 2, ("1000",)),
    ("20-waves-last-79-s", _chain("wave", 20), 3, ("would last 78.9 s", "at most 60 s", "split the instruction")),
    ("two-slow-squat-sets", _chain("squat 10 times slowly", 2), 3, ("would last", "at most 60 s")),
]


@pytest.mark.parametrize(("text", "code", "words"), [c[1:] for c in SENTENCE_CASES], ids=[c[0] for c in SENTENCE_CASES])
def test_sentence_beyond_a_limit_is_refused(tmp_path_factory, capsys, monkeypatch, text, code, words):
    """Too many actions or repeats: exit 2 (the sentence); a motion too long: exit 3 (the spec).

    The cache is outside the folder that must stay unchanged: a refusal of the spec's duration comes
    after the robot is loaded, and a process that loads it first keeps its geometry in the cache (the
    test passed only when another test of the same worker had loaded the robot before it)."""
    monkeypatch.setenv("WBMP_CACHE_DIR", str(tmp_path_factory.mktemp("cache")))
    tmp_path = tmp_path_factory.mktemp("work")
    tree = Tree(tmp_path)
    out = run_cli(["solve", text, "--no-sim", "--quiet", "--out", tmp_path / "m.npz"], capsys)
    assert_refused(out, code, *words)
    tree.assert_unchanged()


def test_parse_refuses_too_many_actions(capsys):
    out = run_cli(["parse", _chain("bow", MAX_ACTIONS + 1), "--json"], capsys)
    assert_refused(out, 2, f"{MAX_ACTIONS + 1} actions", f"at most {MAX_ACTIONS}")


def test_twenty_actions_are_accepted():
    """The bound is not off by one: exactly MAX_ACTIONS actions parse."""
    assert len(parse(_chain("bow", MAX_ACTIONS))) == MAX_ACTIONS


def test_action_plan_bounds_every_backend():
    """ActionPlan (what every backend returns) and its dictionary form refuse more than MAX_ACTIONS."""
    squat = Action(name="squat")
    with pytest.raises(UnsupportedInstruction, match="21 actions"):
        ActionPlan(actions=(squat,) * 21, backend="rules", text="")
    with pytest.raises(LanguageError, match="10000 actions"):
        ActionPlan.from_dict({"actions": [{"action": "squat"}] * 10_000})


def test_compile_actions_bounds_the_count_and_the_horizon():
    robot = load_robot("talos")
    with pytest.raises(TaskDefinitionError, match="21 actions"):
        compile_actions([Action(name="bow")] * 21, robot)
    with pytest.raises(TaskDefinitionError, match="would last"):
        compile_actions([Action(name="stand", params={"duration": 30.0})] * 2, robot)
    assert compile_actions([Action(name="stand", params={"duration": 30.0})], robot).horizon <= MAX_HORIZON


def test_llm_reply_with_ten_thousand_actions(tmp_path, capsys, monkeypatch):
    """The LLM backend (a real HTTP server on 127.0.0.1) replying 10,000 actions twice: exit 2."""
    monkeypatch.setenv("WBMP_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.delenv("WBMP_LLM_API_KEY", raising=False)
    srv = ScriptedServer(lifetime=60).start()
    try:
        many = [{"action": "squat"}] * 10_000
        srv.script(Reply.plan(many), Reply.plan(many))
        tree = Tree(tmp_path)
        out = run_cli(["solve", "squat a lot", "--parser", "llm", "--llm-url", srv.url, "--llm-model", "m",
                       "--no-sim", "--quiet", "--out", tmp_path / "m.npz"], capsys)
        assert_refused(out, 2, f"at most {MAX_ACTIONS}", "10000")
        tree.assert_unchanged()
        assert len(srv.requests) == 2  # the validation error went back to the model once
        assert f"at most {MAX_ACTIONS}" in json.dumps(srv.requests[1]["json"])
    finally:
        srv.stop()


# ---------------------------------------------------------------------------------------------
# Contact and joint errors are the spec's: exit 3, before planning.

def _with(**changes) -> TaskSpec:
    import dataclasses

    return dataclasses.replace(load_spec(SQ), **changes)


def _feet(dz: float = 0.0, dx: float = 0.0, yaw: float = 0.0, frame: str | None = None) -> tuple[Contact, ...]:
    base = load_spec(SQ).phases[0].contacts
    out = []
    for i, c in enumerate(base):
        p = c.placement.position
        out.append(Contact(frame=frame if (frame and i == 0) else c.frame,
                           placement=Pose(position=(p[0] + dx, p[1], p[2] + dz), rpy=(0.0, 0.0, yaw))))
    return tuple(out)


ROBOT_CASES = [
    ("contact-frame-unknown", lambda: _with(phases=(Phase(name="s", duration=3.0, contacts=_feet(frame="left_wing")),)),
     ("spec.phases[0].contacts[0].frame", "no frame 'left_wing'")),
    ("target-frame-unknown",
     lambda: _with(targets=(FrameTarget(name="t", frame="tail", position=(0.0, 0.0, 1.0), time=1.0),)),
     ("spec.targets[0].frame", "no frame 'tail'")),
    ("joint-unknown", lambda: _with(joint_targets=(JointTarget(name="j", joint="no_such_joint", value=0.1),)),
     ("spec.joint_targets[0].joint", "no joint 'no_such_joint'")),
    ("joint-free-flyer", lambda: _with(joint_targets=(JointTarget(name="j", joint="root_joint", value=0.1),)),
     ("root_joint", "not a one-dof joint")),
    ("contact-far-below-floor",
     lambda: _with(phases=(*load_spec(SQ).phases, Phase(name="down", duration=1.0, contacts=_feet(dz=-5.0)))),
     ("spec.phases[1].contacts[0].placement", "below the ground")),
    ("first-phase-away", lambda: _with(phases=(Phase(name="s", duration=3.0, contacts=_feet(dx=0.05)),)),
     ("spec.phases[0].contacts[0]", "0.050 m", "where talos stands")),
    ("first-phase-turned", lambda: _with(phases=(Phase(name="s", duration=3.0, contacts=_feet(yaw=0.1)),)),
     ("0.100 rad",)),
]


@pytest.mark.parametrize(("build", "words"), [c[1:] for c in ROBOT_CASES], ids=[c[0] for c in ROBOT_CASES])
def test_spec_not_for_the_robot_is_an_invalid_spec(build, words):
    """check_spec_for_robot names the field; its error maps to exit 3 (invalid spec), not 4."""
    with pytest.raises(TaskDefinitionError) as e:
        check_spec_for_robot(build(), load_robot("talos"))
    for w in words:
        assert w in str(e.value)
    assert classify(e.value) == ExitCode.INVALID_SPEC


def test_valid_specs_pass_the_robot_check():
    """The negative control: the examples and compiled sentences apply to their robot."""
    talos = load_robot("talos")
    for name in ("squat.json", "reach.json", "reach_out_of_range.json"):
        check_spec_for_robot(load_spec(REPO / "examples" / "specs" / name), talos)
    for robot in (talos, load_robot("g1")):
        for text in ("wave twice, then squat", "walk 1 m", "turn left 90 degrees", "jump", "bow while waving"):
            check_spec_for_robot(compile_actions(parse(text).actions, robot), robot)


def test_planner_spec_error_maps_to_exit_3():
    from planner.exceptions import PlannerError, SpecNotForRobot

    assert classify(SpecNotForRobot("joint target 'j': robot 'talos' has no joint 'x'")) == ExitCode.INVALID_SPEC
    assert classify(PlannerError("solver failed")) == ExitCode.INFEASIBLE


CLI_ROBOT_CASES = [
    ("contact-frame-unknown", lambda d: d["phases"][0]["contacts"][0].update(frame="left_wing"), ("left_wing",)),
    ("target-frame-unknown", lambda d: d.update(targets=[{"name": "t", "frame": "tail", "position": [0, 0, 1]}]),
     ("tail",)),
    ("joint-unknown", lambda d: d.update(joint_targets=[{"name": "j", "joint": "no_such_joint", "value": 0.1}]),
     ("no_such_joint",)),
    ("first-contact-below-floor", lambda d: d["phases"][0]["contacts"][0]["placement"].update(position=[0, 0.085, -5]),
     ("below the ground",)),
    ("first-contact-away", lambda d: d["phases"][0]["contacts"][0]["placement"].update(position=[0.3, 0.085, 0]),
     ("where talos stands",)),
]


@pytest.mark.parametrize(
    ("change", "words"),
    [c[1:3] for c in CLI_ROBOT_CASES],
    ids=[c[0] for c in CLI_ROBOT_CASES],
)
def test_cli_contact_and_joint_errors_exit_3(tmp_path, capsys, monkeypatch, change, words):
    """Through ``wbmp solve --spec``: exit 3 before planning (the issue saw 4 for joints and contacts)."""
    monkeypatch.setenv("WBMP_CACHE_DIR", str(tmp_path / "cache"))
    data = copy.deepcopy(SQ_DATA)
    change(data)
    spec = tmp_path / "spec.json"
    spec.write_text(json.dumps(data), encoding="utf-8")
    tree = Tree(tmp_path)
    out = run_cli(["solve", "--spec", spec, "--no-sim", "--quiet", "--out", tmp_path / "m.npz"], capsys)
    assert_refused(out, 3, *words)
    tree.assert_unchanged()
