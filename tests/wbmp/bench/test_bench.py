"""``wbmp bench``: the machinery on a tiny configuration, the JSON keys, peers and the plot."""

from __future__ import annotations

import json
import os

import pytest

from wbmp import bench
from wbmp.cli import main

TOP_KEYS = {"schema", "date_utc", "robot", "quick", "repeats", "dt_override", "compiled_solvers", "machine",
            "machine_tag", "tasks", "scaling", "plot", "peers", "ratios", "loadavg_end", "wall_s"}


@pytest.fixture(scope="module")
def smoke(tmp_path_factory):
    """One task, one repeat, a coarse grid, solvers built in memory: the whole pipeline, quickly."""
    out = tmp_path_factory.mktemp("bench") / "smoke.json"
    before = os.environ.get("WBMP_BENCH_COMPILE")
    try:
        code = main(["bench", "--quick", "--tasks", "squat", "--repeats", "1", "--dt", "0.5", "--no-compile",
                     "--no-sim", "--no-e2e", "--peers", "--peers-dir", str(out.parent / "no-peers"),
                     "--json", str(out), "--quiet"])
    finally:
        if before is None:
            os.environ.pop("WBMP_BENCH_COMPILE", None)
        else:
            os.environ["WBMP_BENCH_COMPILE"] = before
    assert code == 0
    return json.loads(out.read_text())


def test_json_has_the_documented_keys(smoke):
    assert TOP_KEYS <= set(smoke)
    assert smoke["schema"] == bench.SCHEMA
    assert set(smoke["tasks"]) == {"squat"}
    assert set(smoke["tasks"]["squat"]) == set(bench.TASK_KEYS)
    m = smoke["machine"]
    assert m["cores"] >= 1 and len(m["loadavg"]) == 3 and m["cpu_model"]
    assert m["threads"]["solver"] == 1


def test_smoke_run_measures_every_planning_stage(smoke):
    r = smoke["tasks"]["squat"]
    assert r["status"] == "ok", r["message"]
    assert r["actions"] == ["squat"]
    assert r["knots"] == round(r["horizon_s"] / 0.5)
    for key in ("parse_s", "spec_s", "nlp_build_s", "solve_first_s", "solve_warm_s", "solve_cold_s"):
        assert r[key] is not None and 0 < r[key] < 120, key
    assert r["parse_s"] < 2.0 and r["spec_s"] < 10.0  # milliseconds-scale stages stay small (loaded machine: wide bounds)
    assert r["cache_warm"] == "memory"  # the second solve in the process reused the solver
    assert r["first_total_s"] >= r["nlp_build_s"] + r["solve_first_s"] - 1e-6
    assert r["cold_process_s"] > r["cold_total_s"]  # a new process also pays imports
    assert 0 < r["iterations"] <= 200 and r["solver_status"] == "solved"
    assert r["checks_ok"] is True and r["max_violation"] >= 0 and r["max_violation_unit"]
    assert r["tick_median_us"] is None and r["e2e_s"] is None  # skipped stages stay empty
    assert smoke["compiled_solvers"] is False and smoke["scaling"] is None


def test_missing_peers_are_reported_not_fatal(smoke):
    peers = smoke["peers"]
    assert peers["crocoddyl"] is None and peers["tsid"] is None
    assert "make bench-peers" in peers["note"]
    assert smoke["ratios"] == {}


def test_peer_ratios_and_table(smoke, tmp_path):
    (tmp_path / "crocoddyl.json").write_text(json.dumps({
        "versions": {"crocoddyl": "3.2.1", "pinocchio": "4.0.0"}, "machine": {"loadavg": [1.0, 1, 1]},
        "tasks": {"squat": {"solve_s": {"median": 2.0}, "iterations": 23}}}))
    (tmp_path / "tsid.json").write_text(json.dumps({"tsid": "1.10.0", "pin": "4.1.0", "median_us": 200.0,
                                                    "p99_us": 300.0}))
    peers = bench.load_peers(tmp_path)
    assert peers["note"] == ""
    tasks = {"squat": dict(smoke["tasks"]["squat"], solve_warm_s=0.5, cold_total_s=1.0, tick_median_us=100.0,
                          tick_p99_us=150.0)}
    ratios = bench.peer_ratios(tasks, peers)
    assert ratios["squat"]["warm_over_crocoddyl"] == pytest.approx(0.25)
    assert ratios["squat"]["cold_over_crocoddyl"] == pytest.approx(0.5)
    assert ratios["squat"]["tick_over_tsid"] == pytest.approx(0.5)
    text = bench.format_table(dict(smoke, tasks=tasks, peers=peers, ratios=ratios))
    assert "warm/croc 0.25x" in text and "tick/tsid 0.50x" in text and "squat" in text


def test_unknown_task_class_is_a_usage_error(capsys):
    assert main(["bench", "--tasks", "moonwalk", "--quiet"]) == 2
    assert "moonwalk" in capsys.readouterr().err


def test_missing_capability_is_classified_not_implemented():
    from language.exceptions import UnsupportedInstruction
    from planner.exceptions import PlannerError

    assert bench._not_implemented(PlannerError("spec 'jump' asks for CoM dynamics (dynamic=true), which the "
                                               "planner does not model yet"))
    assert bench._not_implemented(UnsupportedInstruction("backflips"))
    assert not bench._not_implemented(PlannerError("right hand target out of reach by 0.31 m at t = 1.2 s"))


def test_machine_tag_is_a_short_file_name():
    tag = bench.machine_tag({"cpu_model": "Intel(R) Xeon(R) Processor @ 2.50GHz", "cores": 2})
    assert tag == "xeon-2.50ghz-2c"


def test_scaling_plot_is_a_png(tmp_path):
    scaling = {"sentence": "squat", "horizon": [
        {"robot": "talos", "knots": n, "solve_s": 0.01 * n, "build_s": 1.0 + 0.01 * n} for n in (20, 40, 80)],
        "robots": [{"robot": "g1", "nv": 35, "knots": 43, "solve_s": 0.3},
                   {"robot": "talos", "nv": 38, "knots": 43, "solve_s": 0.5},
                   {"robot": "romeo", "error": "FrameNotFound: x"}]}
    path = bench.plot_scaling(scaling, tmp_path / "s.png", title="test")
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 5000


def test_markdown_summary_has_one_row_per_task(smoke):
    md = bench.markdown_summary(smoke)
    rows = [line for line in md.splitlines() if line.startswith("| squat")]
    assert len(rows) == 1 and rows[0].count("|") == 11
    assert smoke["machine"]["cpu_model"] in md


def test_from_rereads_a_result_and_rejects_other_files(smoke, tmp_path, capsys):
    src = tmp_path / "r.json"
    src.write_text(json.dumps(smoke))
    md = tmp_path / "r.md"
    assert main(["bench", "--from", str(src), "--markdown", str(md)]) == 0
    assert "| squat |" in md.read_text()
    assert "squat" in capsys.readouterr().out
    bad = tmp_path / "bad.json"
    bad.write_text("{}")
    assert main(["bench", "--from", str(bad)]) == 2
    assert "not a `wbmp bench --json` result" in capsys.readouterr().err


@pytest.mark.parametrize("task", sorted(bench.TASKS))
def test_every_task_sentence_compiles_for_the_default_robot(task, talos):
    """Each task class's sentence parses and compiles on talos (a jump of 8 cm once did not)."""
    from language import parse
    from tasks.compose import compile_actions

    spec = compile_actions(parse(bench.TASKS[task]).actions, talos)
    assert sum(p.duration for p in spec.phases) > 0.0
    assert spec.dynamic == (task in ("balance", "walk", "turn", "jump"))


def test_quick_covers_every_task_class_with_one_repeat():
    """``--quick`` runs all eight task classes (squat, wave, reach, bow, balance, walk, turn,
    jump), one repeat each, unless --tasks narrows it."""
    from wbmp.bench.options import check_options

    names, reps = check_options(tasks=None, quick=True, repeats=None, dt=None, max_iterations=None)
    assert names == ["squat", "wave", "reach", "bow", "balance", "walk", "turn", "jump"] == list(bench.TASKS)
    assert reps == 1
    assert check_options(tasks=["walk"], quick=True, repeats=None, dt=None, max_iterations=None) == (["walk"], 1)
