"""The timing runs of ``wbmp bench``: every stage of one task class (parse, spec, first-ever,
cached-cold and warm plans, controller and simulation, end to end), repeats and their medians, the
temporary solver caches, the scaling study, and the whole run (:func:`run_bench`)."""

from __future__ import annotations

import dataclasses
import datetime as _dt
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from wbmp.bench.machine import machine_info, machine_tag
from wbmp.bench.options import check_options
from wbmp.bench.peers import load_peers, peer_ratios
from wbmp.bench.report import plot_scaling
from wbmp.bench.tasks import (
    NOT_IMPLEMENTED,
    SCALING_N,
    SCALING_ROBOTS,
    SCHEMA,
    TASK_KEYS,
    TASKS,
    planner_settings,
    spec_for,
)
from wbmp.errors import ExitCode, check_signals


def _median(xs: list[float]) -> float | None:
    return float(statistics.median(xs)) if xs else None


def _timed(fn: Callable[[], Any]) -> tuple[Any, float]:
    t0 = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0


def _not_implemented(exc: BaseException) -> bool:
    """True when the failure means a capability is missing rather than a bug or an infeasibility."""
    text = str(exc).lower()
    if isinstance(exc, (ImportError, NotImplementedError)):
        return True
    name = type(exc).__name__
    if name in ("UnsupportedInstruction", "UnknownAction", "NotImplementedError"):
        return True
    return any(s in text for s in ("not implemented", "does not model yet", "not available yet", "not supported yet"))


def _one_line(exc: BaseException) -> str:
    msg = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {msg[:300]}"


def _wbmp_command() -> list[str]:
    exe = Path(sys.executable).with_name("wbmp")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "wbmp.cli"]


def _pct(xs, q: float) -> float:
    import numpy as np

    return float(np.percentile(np.asarray(xs, dtype=float), q))


def _plan_record(plan) -> dict[str, Any]:
    s = plan.stats
    worst = max(plan.checks, key=lambda c: (c.violation / c.tolerance) if c.tolerance > 0 else c.violation,
                default=None)
    return {
        "iterations": s.iterations,
        "solver_status": s.status.name.lower(),
        "n_variables": s.n_variables,
        "n_constraints": s.n_constraints,
        "max_violation": None if worst is None else float(worst.violation),
        "max_violation_unit": None if worst is None else worst.unit,
        "max_violation_check": None if worst is None else worst.name,
        "checks_ok": bool(plan.ok),
    }


def bench_task(name: str, sentence: str, *, robot_name: str, repeats: int, dt: float | None, first: bool,
               simulate: bool, e2e: bool, user_cache: str, log: Callable[[str], None],
               max_iterations: int | None = None) -> dict[str, Any]:
    """All stages of one task class; never raises an Exception (failures are recorded per stage).

    A task whose plan fails is not timed further (no cached-cold process, simulation or
    end-to-end run). Ctrl-C and SIGTERM (BaseExceptions) go through, after removing the
    temporary solver cache.
    """
    rec: dict[str, Any] = dict.fromkeys(TASK_KEYS)
    rec.update(sentence=sentence, status="ok", message="")

    def fail(stage: str, exc: BaseException) -> dict[str, Any]:
        if _not_implemented(exc):
            rec["status"] = NOT_IMPLEMENTED
        else:
            rec["status"] = f"failed at {stage}"
        rec["message"] = f"{stage}: {_one_line(exc)}"
        log(f"{name}: {rec['status']}: {rec['message']}")
        return rec

    # parse + spec ----------------------------------------------------------------------------
    try:
        from language import parse
        from robots import load_robot
        from tasks import compile_actions

        robot = load_robot(robot_name)
        parse_times, spec_times = [], []
        for _ in range(max(5, repeats)):
            actions, tp = _timed(lambda: parse(sentence))
            parse_times.append(tp)
        rec["actions"] = [a.name for a in actions.actions]
        for _ in range(max(3, repeats)):
            spec, ts = _timed(lambda: compile_actions(actions.actions, robot))
            spec_times.append(ts)
        rec["parse_s"], rec["spec_s"] = _median(parse_times), _median(spec_times)
        spec = dataclasses.replace(spec, robot=robot.name, description=sentence)
        if dt is not None:
            spec = dataclasses.replace(spec, dt=dt)
        rec["horizon_s"] = float(spec.horizon)
        rec["knots"] = int(round(spec.horizon / spec.dt))
    except Exception as exc:  # noqa: BLE001 - recorded
        return fail("parse/spec", exc)

    # plan: first-ever, warm, cached cold -----------------------------------------------------
    try:
        from planner import clear_memory_cache
        from planner import plan as plan_motion
    except Exception as exc:  # noqa: BLE001
        return fail("planner import", exc)

    cache_dir = tempfile.mkdtemp(prefix=f"wbmp-bench-{name}-") if first else user_cache
    try:
        try:
            settings = planner_settings(cache_dir, max_iterations)
            clear_memory_cache()
            log(f"{name}: planning ({'first-ever, empty cache' if first else 'user cache'})")
            plan, wall = _timed(lambda: plan_motion(spec, robot, settings=settings, throw=False))
            s = plan.stats
            rec["cache_first"] = s.cache
            rec["nlp_build_s"] = s.build_time
            rec["solve_first_s"] = s.solve_time
            rec["first_total_s"] = wall
            warm_solve, warm_total = [], []
            for _ in range(repeats):
                p2, wall2 = _timed(lambda: plan_motion(spec, robot, settings=settings, throw=False))
                warm_solve.append(p2.stats.solve_time)
                warm_total.append(wall2)
                rec["cache_warm"] = p2.stats.cache
            rec["solve_warm_s"], rec["warm_total_s"] = _median(warm_solve), _median(warm_total)
            rec.update(_plan_record(plan))
            if not plan.ok:
                rec["status"] = "plan failed"
                rec["message"] = " ".join((plan.diagnosis or "constraint report violated").split())[:300]
            log(f"{name}: {s.iterations} iterations, build {s.build_time:.2f} s, solve {s.solve_time:.2f} s, "
                f"warm {rec['solve_warm_s']:.2f} s")
            _cold_record(rec, sentence, robot_name, cache_dir, dt, max_iterations, repeats if plan.ok else 0)
        except Exception as exc:  # noqa: BLE001
            return fail("plan", exc)

        # controller + simulation ----------------------------------------------------------------
        if simulate and plan.ok:
            _bench_simulation(rec, name, plan, robot, spec, log)

        # end to end ---------------------------------------------------------------------------------
        if e2e and plan.ok:
            try:
                rec.update(_end_to_end(sentence, robot_name, cache_dir, spec, repeats, simulate))
            except Exception as exc:  # noqa: BLE001
                rec["message"] = (rec["message"] + "; " if rec["message"] else "") + f"e2e: {_one_line(exc)}"
    finally:  # also on a failed stage, Ctrl-C or SIGTERM: no temporary solver cache left behind
        if first:
            shutil.rmtree(cache_dir, ignore_errors=True)
    return rec


def _cold_record(rec: dict[str, Any], sentence: str, robot_name: str, cache_dir: str, dt: float | None,
                 max_iterations: int | None, repeats: int) -> None:
    """The cached-cold stage of :func:`bench_task` (``repeats`` fresh processes), into ``rec``."""
    cold = [_cold_process(sentence, robot_name, cache_dir, dt, max_iterations)
            for _ in range(repeats)]
    done = [c for c in cold if c is not None]
    if done:
        rec["nlp_load_cold_s"] = _median([c["build_time"] for c in done])
        rec["solve_cold_s"] = _median([c["solve_time"] for c in done])
        rec["cold_total_s"] = _median([c["build_time"] + c["solve_time"] for c in done])
        rec["cold_process_s"] = _median([c["process_s"] for c in done])
        rec["cache_cold"] = done[-1]["cache"]


def _bench_simulation(rec: dict[str, Any], name: str, plan: Any, robot: Any, spec: Any,
                      log: Callable[[str], None]) -> None:
    """The controller + simulation stage of :func:`bench_task`, into ``rec`` (a failure too)."""
    try:
        from sim import simulate as run_sim

        log(f"{name}: simulating {spec.horizon:.1f} s in MuJoCo")
        ex, wall = _timed(lambda: run_sim(plan, robot))
        ticks = ex.tick_times[1:] if len(ex.tick_times) > 1 else ex.tick_times
        rec["tick_median_us"] = 1e6 * _pct(ticks, 50)
        rec["tick_p99_us"] = 1e6 * _pct(ticks, 99)
        rec["realtime_factor"] = float(ex.realtime_factor)
        rec["sim_wall_s"] = wall
        rec["certified"] = bool(ex.certificate.ok)
        rec["certificate_reason"] = getattr(ex.certificate, "reason", "") or ""
    except Exception as exc:  # noqa: BLE001
        rec["status"] = "simulation failed"
        rec["message"] = (rec["message"] + "; " if rec["message"] else "") + f"simulate: {_one_line(exc)}"


def _child_env(cache_dir: str) -> dict[str, str]:
    env = dict(os.environ)
    env["WBMP_CACHE_DIR"] = cache_dir
    env["WBMP_SOLUTION_LIBRARY"] = "off"  # as planner_settings: no plan starts from an earlier one's solution
    return env


def _cold_process(sentence: str, robot_name: str, cache_dir: str, dt: float | None,
                  max_iterations: int | None = None) -> dict | None:
    """Plan in a new Python process with the solver cache on disk (cached cold)."""
    payload = json.dumps({"sentence": sentence, "robot": robot_name, "cache_dir": cache_dir, "dt": dt,
                          "max_iterations": max_iterations})
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "wbmp.bench.cold", payload], capture_output=True, text=True,
                          env=_child_env(cache_dir), timeout=900, check=False)
    elapsed = time.perf_counter() - t0
    if proc.returncode != 0:
        return None
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    out["process_s"] = elapsed
    return out


def _end_to_end(sentence: str, robot_name: str, cache_dir: str, spec, repeats: int, simulate: bool) -> dict:
    """Wall time of ``wbmp solve`` in a new process (sentence; the spec file when sentences are not wired)."""
    base = [*_wbmp_command(), "solve"]
    extra = ["--robot", robot_name, "--quiet"] + ([] if simulate else ["--no-sim"])
    env = _child_env(cache_dir)
    times, mode, code = [], "sentence", None
    with tempfile.TemporaryDirectory(prefix="wbmp-bench-spec-") as folder:  # removed on any exit
        spec_file = str(Path(folder) / "spec.json")
        for _ in range(max(1, repeats)):
            cmd = [*base, sentence, *extra] if mode == "sentence" else [*base, "--spec", spec_file, *extra]
            proc, wall = _timed(lambda: subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=900,  # noqa: B023 - _timed calls it at once
                                                       check=False))
            if mode == "sentence" and proc.returncode == ExitCode.USAGE and "not available" in proc.stderr:
                from tasks import spec_to_json

                mode = "spec"
                Path(spec_file).write_text(spec_to_json(spec))
                cmd = [*base, "--spec", spec_file, *extra]
                proc, wall = _timed(lambda: subprocess.run(cmd, capture_output=True, text=True, env=env,  # noqa: B023 - _timed calls it at once
                                                           timeout=900, check=False))
            code = proc.returncode
            times.append(wall)
    return {"e2e_s": _median(times), "e2e_mode": mode, "e2e_exit_code": code}


# --------------------------------------------------------------------------------------------
# scaling study


def scaling_study(*, repeats: int, log: Callable[[str], None], sentence: str = TASKS["squat"],
                  horizons: tuple[int, ...] = SCALING_N, robots: tuple[str, ...] = SCALING_ROBOTS,
                  cache_dir: str | None = None, max_iterations: int | None = None) -> dict[str, Any]:
    """Warm solve time of the squat against the horizon N (talos) and against the robot (N fixed).

    The horizon is changed through the knot spacing (same motion, finer grid). Each new
    structure is built once (compiled into ``cache_dir``; default a temporary folder, removed
    at the end whatever happens), then solved ``repeats`` times warm.
    """
    if cache_dir is not None:
        return _scaling_study(repeats=repeats, log=log, sentence=sentence, horizons=horizons, robots=robots,
                              cache_dir=cache_dir, max_iterations=max_iterations)
    with tempfile.TemporaryDirectory(prefix="wbmp-bench-scaling-", ignore_cleanup_errors=True) as tmp:
        return _scaling_study(repeats=repeats, log=log, sentence=sentence, horizons=horizons, robots=robots,
                              cache_dir=tmp, max_iterations=max_iterations)


def _scaling_study(*, repeats: int, log: Callable[[str], None], sentence: str, horizons: tuple[int, ...],
                   robots: tuple[str, ...], cache_dir: str, max_iterations: int | None) -> dict[str, Any]:
    from planner import plan as plan_motion
    from robots import load_robot

    settings = planner_settings(cache_dir, max_iterations)
    out: dict[str, Any] = {"sentence": sentence, "horizon": [], "robots": []}

    def measure(robot, dt: float | None) -> dict[str, Any]:
        _, spec = spec_for(sentence, robot, dt)
        first = plan_motion(spec, robot, settings=settings, throw=False)
        solves, iters = [], []
        for _ in range(repeats):
            p = plan_motion(spec, robot, settings=settings, throw=False)
            solves.append(p.stats.solve_time)
            iters.append(p.stats.iterations)
        return {"robot": robot.name, "nv": robot.nv, "knots": int(round(spec.horizon / spec.dt)),
                "dt": spec.dt, "build_s": first.stats.build_time, "solve_s": _median(solves),
                "iterations": int(statistics.median(iters)), "n_variables": first.stats.n_variables,
                "n_constraints": first.stats.n_constraints, "ok": bool(first.ok)}

    talos = load_robot("talos")
    _, base = spec_for(sentence, talos, None)
    for n in horizons:
        dt = base.horizon / n
        try:
            log(f"scaling: talos N={n}")
            out["horizon"].append(measure(talos, dt))
        except Exception as exc:  # noqa: BLE001
            out["horizon"].append({"robot": "talos", "knots": n, "error": _one_line(exc)})
    for name in robots:
        try:
            log(f"scaling: {name}")
            out["robots"].append(measure(load_robot(name), None))
        except Exception as exc:  # noqa: BLE001
            out["robots"].append({"robot": name, "error": _one_line(exc)})
    return out


def run_bench(*, robot: str = "talos", tasks: list[str] | None = None, quick: bool = False,
              repeats: int | None = None, dt: float | None = None, simulate: bool = True, e2e: bool = True,
              first: bool = True, scaling: bool | None = None, peers: bool = False,
              peers_dir: str | None = None, plot: str | None = None, max_iterations: int | None = None,
              log: Callable[[str], None] = lambda _: None) -> dict[str, Any]:
    """Run the benchmark and return the result dictionary (the JSON of ``--json``).

    Raises:
        CliError: A bad option (exit 2), checked before any work (:func:`check_options`).
    """
    from planner import default_cache_dir

    names, reps = check_options(tasks=tasks, quick=quick, repeats=repeats, dt=dt, max_iterations=max_iterations)
    # First-ever builds are timed with gcc in the loop (and cached-cold runs need the entry on
    # disk): compile synchronously here and in the child processes, which inherit the variable.
    os.environ["WBMP_COMPILE_BACKGROUND"] = "0"
    if scaling is None:
        scaling = not quick
    info = machine_info()
    t_start = time.perf_counter()
    result: dict[str, Any] = {
        "schema": SCHEMA,
        "date_utc": _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "robot": robot,
        "quick": quick,
        "repeats": reps,
        "dt_override": dt,
        "max_iterations": max_iterations,
        "compiled_solvers": os.environ.get("WBMP_BENCH_COMPILE", "1") != "0",
        "machine": info,
        "machine_tag": machine_tag(info),
        "tasks": {},
    }
    sim_done = False
    for name in names:
        # quick: one simulation (the first task) keeps the run short
        do_sim = simulate and not (quick and sim_done)
        rec = bench_task(name, TASKS[name], robot_name=robot, repeats=reps, dt=dt, first=first and not quick,
                         simulate=do_sim, e2e=e2e and not quick, user_cache=default_cache_dir(), log=log,
                         max_iterations=max_iterations)
        check_signals()  # an interrupt swallowed inside a stage ends the run, not just the stage
        sim_done = sim_done or rec.get("realtime_factor") is not None
        result["tasks"][name] = rec
    result["scaling"] = None
    result["plot"] = None
    if scaling:
        result["scaling"] = scaling_study(repeats=reps, log=log, max_iterations=max_iterations)
        png = plot
        if png is None:
            png = "bench_scaling.png"
        result["plot"] = str(plot_scaling(result["scaling"], png, title=f"{info['cpu_model']}, load "
                                                                         f"{info['loadavg'][0]:.1f}"))
    result["peers"] = None
    result["ratios"] = {}
    if peers:
        result["peers"] = load_peers(peers_dir)
        result["ratios"] = peer_ratios(result["tasks"], result["peers"])
    result["loadavg_end"] = [round(x, 2) for x in os.getloadavg()]
    result["wall_s"] = time.perf_counter() - t_start
    return result

