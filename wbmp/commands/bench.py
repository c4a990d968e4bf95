"""``wbmp bench``: time every stage of the pipeline on each task class, optionally beside peers.

For each task class (squat, wave, reach, bow, balance, walk, turn, jump) on one robot:

- parse time (sentence -> actions) and spec build (actions -> TaskSpec), medians over repeats;
- NLP build and solve, first-ever (empty temporary solver cache, nothing in memory), cached
  cold (a new process loading the compiled solver from that cache) and warm (same process);
- IPOPT iterations, the worst constraint violation of the plan's report;
- controller tick median/p99 and simulation real-time factor (MuJoCo, whole-body controller);
- end-to-end wall time of ``wbmp solve`` in a new process (cached solver).

A stage whose layer is missing, or a task class whose primitive the planner cannot plan yet,
is reported as ``n/a (not implemented)``; any other failure of a stage is recorded with its
one-line message and the benchmark goes on. ``--peers`` adds Crocoddyl and TSID figures from
``benchmarks/results/peers/`` (made by ``make bench-peers``) and the ratios ours/peer.
The non-quick run also measures solve time against the horizon length and the robot size,
and draws them (PNG).

Timings are wall-clock [s] unless the key ends in ``_us`` [µs]; see benchmarks/README.md for
the JSON keys.

Exit codes: 0 when every task class that ran passed (one marked ``n/a (not implemented)`` does
not count); otherwise the code ``wbmp solve`` gives, for the first failing task class of the
table: 3 its spec could not be built, 4 its plan failed (infeasible, iteration limit, solver
error), 5 its simulation check failed or crashed (or its end-to-end ``wbmp solve`` exited with
that code). The report is printed, and ``--json``/``--markdown`` written, in every case: a
benchmark whose tasks fail is a failure of the planner or the simulation, not a result to
publish. ``--from`` applies the same rule to the re-read result. Bad options (``--repeats 0``,
``--dt nan``, ``--tasks ""``, an unknown task class, an empty ``--robot``, an output path that
is a folder or a link...) are refused with exit 2 before any work; an unknown robot with 3.
``--max-iterations 1`` makes every plan fail for real (IPOPT stops after one iteration).
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime as _dt
import json
import math
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from wbmp.errors import CliError, ExitCode, check_signals

SCHEMA = "wbmp-bench/1"

#: Task class -> sentence given to the parser (and to ``wbmp solve``).
TASKS: dict[str, str] = {
    "squat": "squat down 10 cm",
    "wave": "wave your right hand",
    "reach": "reach forward with your right hand 20 cm",
    "bow": "bow",
    "balance": "stand on your left foot",
    "walk": "take two steps forward",
    "turn": "turn left 90 degrees",
    "jump": "jump 5 cm",
}
QUICK_TASKS = ("squat", "reach")
SCALING_N = (20, 40, 80, 120, 160)
SCALING_ROBOTS = ("g1", "talos", "romeo")
#: Which peer figure each of our task classes is compared with.
PEER_TASKS = {"squat": "squat", "reach": "reach", "walk": "walk", "jump": "jump"}
NOT_IMPLEMENTED = "n/a (not implemented)"
MAX_REPEATS = 50  # each repeat of a task also starts a new process (cached cold) and a `wbmp solve`
MAX_ITERATIONS = 10_000  # --max-iterations (the planner's default is 100)
MIN_DT, MAX_DT = 0.005, 0.5  # [s] --dt, as tasks.limits allows for a spec's knot spacing
MAX_RESULT_BYTES = 64 * 1024 * 1024  # a --from result is ~20 kB
#: Per-task keys of the JSON (documented in benchmarks/README.md).
TASK_KEYS = (
    "sentence", "status", "message", "actions", "horizon_s", "knots", "parse_s", "spec_s",
    "nlp_build_s", "solve_first_s", "first_total_s", "cache_first", "nlp_load_cold_s", "solve_cold_s",
    "cold_total_s", "cold_process_s", "cache_cold", "solve_warm_s", "warm_total_s", "cache_warm",
    "iterations", "solver_status", "n_variables", "n_constraints", "max_violation", "max_violation_unit",
    "max_violation_check", "checks_ok", "tick_median_us", "tick_p99_us", "realtime_factor", "sim_wall_s",
    "certified", "certificate_reason", "e2e_s", "e2e_mode", "e2e_exit_code",
)


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "bench", help="time parse, spec, NLP build, solve, controller and simulation per task class",
        description="Benchmark every stage of the pipeline on each task class (medians over repeats),\n"
                    "optionally beside Crocoddyl and TSID (--peers, after `make bench-peers`).\n"
                    "Timings on a shared machine are noisy: the load average is recorded.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n"
               "  wbmp bench --quick\n"
               "  wbmp bench --json out.json --peers\n"
               "  wbmp bench --tasks squat --repeats 1 --no-sim --no-e2e --json smoke.json\n"
               "exit codes:\n"
               "  0      every task class that ran passed (n/a (not implemented) ones do not count)\n"
               "  3/4/5  a task class failed: the code of the first one, as `wbmp solve` gives it\n"
               "         (3 spec, 4 plan, 5 simulation check); the report is printed and\n"
               "         --json/--markdown are written anyway\n"
               "  2      a bad option (checked before any work); 130/143 Ctrl-C/SIGTERM",
    )
    p.add_argument("--quick", action="store_true",
                   help=f"{', '.join(QUICK_TASKS)} only, 1 repeat, one simulation, no scaling study (< 2 min)")
    p.add_argument("--robot", default="talos", help="robot name (default: talos)")
    p.add_argument("--json", metavar="FILE", default=None, help="also write the results as JSON here")
    p.add_argument("--peers", action="store_true",
                   help="add Crocoddyl/TSID figures (benchmarks/results/peers/*.json) and ratios ours/peer")
    p.add_argument("--peers-dir", default=None, help="folder of the peer results (default: benchmarks/results/peers)")
    p.add_argument("--tasks", default=None, help=f"comma-separated task classes (default: all: {','.join(TASKS)})")
    p.add_argument("--repeats", type=int, default=None,
                   help=f"repeats per timing, 1 to {MAX_REPEATS} (default 3, quick 1)")
    p.add_argument("--dt", type=float, default=None,
                   help=f"override the knot spacing of every spec [s], {MIN_DT:g} to {MAX_DT:g} (smoke tests)")
    p.add_argument("--max-iterations", type=int, default=None, metavar="N",
                   help=f"IPOPT iteration limit of every plan, 1 to {MAX_ITERATIONS} (default: the planner's); "
                        "1 makes every plan fail (tests the failure path and the exit code)")
    p.add_argument("--no-compile", action="store_true",
                   help="build solvers in memory (CasADi SX) instead of compiling them with gcc (smoke tests)")
    p.add_argument("--no-sim", action="store_true", help="skip the controller/simulation stage")
    p.add_argument("--no-e2e", action="store_true", help="skip the end-to-end `wbmp solve` runs")
    p.add_argument("--no-first", action="store_true",
                   help="skip the first-ever build (use and fill the user's solver cache instead)")
    p.add_argument("--scaling", dest="scaling", action="store_true", default=None,
                   help="run the scaling study (default: on unless --quick)")
    p.add_argument("--no-scaling", dest="scaling", action="store_false")
    p.add_argument("--plot", metavar="PNG", default=None,
                   help="scaling plot file (default: next to --json, else bench_scaling.png)")
    p.add_argument("--from", dest="from_json", metavar="FILE", default=None,
                   help="do not run: re-read a result JSON (re-apply --peers, print, write --json/--markdown)")
    p.add_argument("--markdown", metavar="FILE", default=None, help="also write a short Markdown summary table")
    p.add_argument("--quiet", action="store_true", help="no progress messages on stderr")
    p.set_defaults(run=run)


# --------------------------------------------------------------------------------------------
# machine facts


def cpu_model() -> str:
    """CPU model name (``/proc/cpuinfo``), else the platform's processor string."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def machine_info() -> dict[str, Any]:
    """CPU, cores, load average, library versions and thread settings of this process."""
    versions: dict[str, str] = {}
    for mod in ("pinocchio", "casadi", "proxsuite", "mujoco", "numpy", "numba"):
        try:
            versions[mod] = str(__import__(mod).__version__)
        except Exception:  # noqa: BLE001 - a missing library is just not listed
            pass
    try:
        affinity: int | None = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        affinity = os.cpu_count()
    threads: dict[str, Any] = {k: os.environ[k] for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
               if k in os.environ}
    try:
        import threadpoolctl  # type: ignore[import-not-found]

        threads["blas_pools"] = {i["internal_api"]: i["num_threads"] for i in threadpoolctl.threadpool_info()}
    except Exception:  # noqa: BLE001
        pass
    return {
        "cpu_model": cpu_model(),
        "cores": os.cpu_count(),
        "cores_usable": affinity,
        "hostname": platform.node(),
        "python": platform.python_version(),
        "loadavg": [round(x, 2) for x in os.getloadavg()],
        "versions": versions,
        "threads": {"solver": 1, "controller": 1, **threads},
    }


def machine_tag(info: dict[str, Any]) -> str:
    """Short file-name tag of the machine: ``xeon-2.50ghz-2c``."""
    model = info.get("cpu_model", "cpu").lower()
    words = [w for w in model.replace("(r)", "").replace("(tm)", "").replace("@", " ").split()
             if w not in ("intel", "amd", "processor", "cpu", "core")]
    tag = "-".join(words[:1] + [w for w in words[1:] if "ghz" in w])
    return f"{tag or 'cpu'}-{info.get('cores', 0)}c"


# --------------------------------------------------------------------------------------------
# small helpers


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


# --------------------------------------------------------------------------------------------
# one task class


def _settings(cache_dir: str, max_iterations: int | None = None):
    from planner import PlannerSettings

    compile_ = os.environ.get("WBMP_BENCH_COMPILE", "1") != "0"
    extra: dict[str, Any] = {} if max_iterations is None else {"max_iterations": max_iterations}
    return PlannerSettings(cache_dir=cache_dir, compile=compile_, **extra)


def _spec_for(sentence: str, robot, dt: float | None):
    from language import parse
    from tasks.compose import compile_actions

    actions = parse(sentence)
    spec = compile_actions(actions.actions, robot)
    spec = dataclasses.replace(spec, robot=robot.name, description=sentence)
    if dt is not None:
        spec = dataclasses.replace(spec, dt=dt)
    return actions, spec


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
        from tasks.compose import compile_actions

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
        from planner import plan as plan_motion
        from planner.trajopt.cache import clear_memory_cache
    except Exception as exc:  # noqa: BLE001
        return fail("planner import", exc)

    cache_dir = tempfile.mkdtemp(prefix=f"wbmp-bench-{name}-") if first else user_cache
    try:
        try:
            settings = _settings(cache_dir, max_iterations)
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
            runs = [_cold_process(sentence, robot_name, cache_dir, dt, max_iterations)
                    for _ in range(repeats if plan.ok else 0)]
            cold = [c for c in runs if c is not None]
            if cold:
                rec["nlp_load_cold_s"] = _median([c["build_time"] for c in cold])
                rec["solve_cold_s"] = _median([c["solve_time"] for c in cold])
                rec["cold_total_s"] = _median([c["build_time"] + c["solve_time"] for c in cold])
                rec["cold_process_s"] = _median([c["process_s"] for c in cold])
                rec["cache_cold"] = cold[-1]["cache"]
        except Exception as exc:  # noqa: BLE001
            return fail("plan", exc)

        # controller + simulation ----------------------------------------------------------------
        if simulate and plan.ok:
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


def _child_env(cache_dir: str) -> dict[str, str]:
    env = dict(os.environ)
    env["WBMP_CACHE_DIR"] = cache_dir
    return env


def _cold_process(sentence: str, robot_name: str, cache_dir: str, dt: float | None,
                  max_iterations: int | None = None) -> dict | None:
    """Plan in a new Python process with the solver cache on disk (cached cold)."""
    payload = json.dumps({"sentence": sentence, "robot": robot_name, "cache_dir": cache_dir, "dt": dt,
                          "max_iterations": max_iterations})
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "wbmp.commands.bench", payload], capture_output=True, text=True,
                          env=_child_env(cache_dir), timeout=900, check=False)
    elapsed = time.perf_counter() - t0
    if proc.returncode != 0:
        return None
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    out["process_s"] = elapsed
    return out


def _child_main(payload: str) -> int:
    """Entry of the cached-cold child process: plan once, print the stats as one JSON line."""
    args = json.loads(payload)
    from planner import plan as plan_motion
    from robots import load_robot

    robot = load_robot(args["robot"])
    _, spec = _spec_for(args["sentence"], robot, args.get("dt"))
    plan = plan_motion(spec, robot, settings=_settings(args["cache_dir"], args.get("max_iterations")), throw=False)
    s = plan.stats
    print(json.dumps({"build_time": s.build_time, "solve_time": s.solve_time, "cache": s.cache,
                      "iterations": s.iterations, "ok": bool(plan.ok)}))
    return 0


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
                from tasks.serialize import spec_to_json

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

    settings = _settings(cache_dir, max_iterations)
    out: dict[str, Any] = {"sentence": sentence, "horizon": [], "robots": []}

    def measure(robot, dt: float | None) -> dict[str, Any]:
        _, spec = _spec_for(sentence, robot, dt)
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
    _, base = _spec_for(sentence, talos, None)
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


def plot_scaling(scaling: dict[str, Any], path: str | Path, title: str = "") -> Path:
    """Two panels: solve time against N (talos) and against the robot's nv; PNG via Agg."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4))
    hz = [r for r in scaling.get("horizon", []) if r.get("solve_s") is not None]
    ax1.plot([r["knots"] for r in hz], [r["solve_s"] for r in hz], "o-", label="solve (warm)")
    ax1.plot([r["knots"] for r in hz], [r["build_s"] for r in hz], "s--", label="build (first)")
    ax1.set_xlabel("knots N")
    ax1.set_ylabel("time [s]")
    ax1.set_title("talos squat: time vs horizon")
    ax1.set_yscale("log")
    ax1.grid(True, which="both", alpha=0.3)
    ax1.legend()
    rb = [r for r in scaling.get("robots", []) if r.get("solve_s") is not None]
    ax2.bar([f"{r['robot']}\nnv={r['nv']}, N={r['knots']}" for r in rb], [r["solve_s"] for r in rb])
    ax2.set_ylabel("solve (warm) [s]")
    ax2.set_title("squat: solve time vs robot")
    ax2.grid(True, axis="y", alpha=0.3)
    if title:
        fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    from viz.files import atomic_write

    path = Path(path)
    try:
        atomic_write(path, lambda fh: fig.savefig(fh, format="png", dpi=100))  # never half-written
    finally:
        plt.close(fig)
    return path


# --------------------------------------------------------------------------------------------
# peers


def default_peers_dir() -> Path:
    """``benchmarks/results/peers`` of the source checkout."""
    return Path(__file__).resolve().parents[2] / "benchmarks" / "results" / "peers"


def load_peers(folder: str | Path | None) -> dict[str, Any]:
    """The latest peer results: {"crocoddyl": {...} | None, "tsid": {...} | None, "note": str}."""
    folder = Path(folder) if folder else default_peers_dir()
    out: dict[str, Any] = {"folder": str(folder), "crocoddyl": None, "tsid": None, "note": ""}
    missing = []
    for name in ("crocoddyl", "tsid"):
        f = folder / f"{name}.json"
        try:
            out[name] = json.loads(f.read_text())
        except (OSError, json.JSONDecodeError):
            missing.append(name)
    if missing:
        out["note"] = f"{' and '.join(missing)} unavailable: run `make bench-peers` (creates their environments)"
    return out


def peer_ratios(tasks: dict[str, dict], peers: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """Ours/peer per task class: solve (warm and cached cold) against Crocoddyl's FDDP solve,
    controller tick median against TSID's."""
    ratios: dict[str, dict[str, Any]] = {}
    croc = (peers.get("crocoddyl") or {}).get("tasks", {})
    tsid = peers.get("tsid") or {}
    for name, rec in tasks.items():
        r: dict[str, Any] = {}
        peer_task = croc.get(PEER_TASKS.get(name, ""), None)
        if peer_task:
            ps = peer_task["solve_s"]["median"]
            r["crocoddyl_solve_s"] = ps
            r["crocoddyl_iterations"] = peer_task.get("iterations")
            if rec.get("solve_warm_s"):
                r["warm_over_crocoddyl"] = rec["solve_warm_s"] / ps
            if rec.get("cold_total_s"):
                r["cold_over_crocoddyl"] = rec["cold_total_s"] / ps
        if tsid.get("median_us") and rec.get("tick_median_us"):
            r["tsid_tick_median_us"] = tsid["median_us"]
            r["tick_over_tsid"] = rec["tick_median_us"] / tsid["median_us"]
        if r:
            ratios[name] = r
    return ratios


# --------------------------------------------------------------------------------------------
# output


def _fmt(x: Any, unit: str = "s", digits: int = 2) -> str:
    if x is None:
        return "-"
    if isinstance(x, bool):
        return "yes" if x else "NO"
    if isinstance(x, float):
        if unit == "ms":
            return f"{1e3 * x:.{digits}f}"
        return f"{x:.{digits}f}"
    return str(x)


def format_table(result: dict[str, Any]) -> str:
    """The human-readable report."""
    m = result["machine"]
    lines = [
        f"wbmp bench on {result['robot']}  ({m['cpu_model']}, {m['cores']} cores, load {m['loadavg'][0]:.1f} "
        f"at start, {result['loadavg_end'][0]:.1f} at end; {result['repeats']} repeat(s); "
        f"{result['date_utc']})",
        "times in s unless noted; first = empty solver cache, cold = new process with the compiled solver on "
        "disk, warm = same process",
        "",
    ]
    head = (f"{'task':8s} {'parse':>6s} {'spec':>6s} {'build':>6s} {'first':>6s} {'cold':>6s} {'warm':>6s} "
            f"{'iter':>4s} {'viol':>9s} {'tick med/p99 [us]':>17s} {'RTF':>5s} {'cert':>4s} {'e2e':>6s}")
    lines += [head, "", "-" * len(head)]
    lines.pop(-2)
    for name, r in result["tasks"].items():
        if r["status"] == NOT_IMPLEMENTED:
            lines.append(f"{name:8s} {NOT_IMPLEMENTED}: {r['message']}"[:160])
            continue
        if r["status"].startswith("failed"):
            lines.append(f"{name:8s} {r['status']}: {r['message']}"[:160])
            continue
        viol = "-" if r["max_violation"] is None else f"{r['max_violation']:.1e}{r['max_violation_unit'] or ''}"
        tick = "-" if r["tick_median_us"] is None else f"{r['tick_median_us']:.0f}/{_fmt(r['tick_p99_us'], digits=0)}"
        lines.append(
            f"{name:8s} {_fmt(r['parse_s'], 'ms'):>6s} {_fmt(r['spec_s'], 'ms'):>6s} {_fmt(r['nlp_build_s']):>6s} "
            f"{_fmt(r['first_total_s']):>6s} {_fmt(r['cold_total_s']):>6s} {_fmt(r['solve_warm_s']):>6s} "
            f"{_fmt(r['iterations']):>4s} {viol:>9s} {tick:>17s} {_fmt(r['realtime_factor']):>5s} "
            f"{_fmt(r['certified']):>4s} {_fmt(r['e2e_s']):>6s}")
        if r["status"] != "ok":
            lines.append(f"{'':8s} ^ {r['status']}: {r['message']}"[:160])
    lines.append("(parse and spec in ms; build = NLP build incl. compilation; first/cold = build + solve; "
                 "warm = solve; RTF = simulated/wall time)")
    if result.get("quick"):
        origins = sorted({r["cache_first"] for r in result["tasks"].values() if r.get("cache_first")})
        lines.append(f"(quick: 'first' is the first plan of this process from the user's solver cache: "
                     f"{'/'.join(origins) or '-'}; run without --quick for first-ever builds)")
    sc = result.get("scaling")
    if sc:
        lines += ["", f"scaling ({sc['sentence']!r}, warm solve):"]
        for r in sc["horizon"]:
            if "error" in r:
                lines.append(f"  talos N={r['knots']:<4d} error: {r['error']}")
            else:
                lines.append(f"  talos N={r['knots']:<4d} solve {r['solve_s']:.2f} s, build {r['build_s']:.1f} s, "
                             f"{r['iterations']} iter, {r['n_variables']} variables")
        for r in sc["robots"]:
            if "error" in r:
                lines.append(f"  {r['robot']:8s} error: {r['error']}")
            else:
                lines.append(f"  {r['robot']:8s} nv={r['nv']:<3d} N={r['knots']:<4d} solve {r['solve_s']:.2f} s, "
                             f"{r['iterations']} iter, {r['n_variables']} variables")
        if result.get("plot"):
            lines.append(f"  plot: {result['plot']}")
    peers = result.get("peers")
    if peers is not None:
        lines += ["", "peers (their own environments; ratio = ours / peer, < 1 means wbmp is faster):"]
        c = peers.get("crocoddyl")
        if c:
            cm = c.get("machine", {})
            lines.append(f"  crocoddyl {c['versions']['crocoddyl']} FDDP (pin {c['versions']['pinocchio']}), "
                         f"measured {cm.get('date_utc', '?')} at load {cm.get('loadavg', ['?'])[0]}")
        t = peers.get("tsid")
        if t:
            lines.append(f"  tsid {t.get('tsid', '?')} (pin {t.get('pin', '?')}): tick median {t['median_us']:.0f} us, "
                         f"p99 {t['p99_us']:.0f} us")
        for name, r in result.get("ratios", {}).items():
            bits = []
            if "crocoddyl_solve_s" in r:
                bits.append(f"crocoddyl solve {r['crocoddyl_solve_s']:.2f} s ({r.get('crocoddyl_iterations')} it)")
                if "warm_over_crocoddyl" in r:
                    bits.append(f"warm/croc {r['warm_over_crocoddyl']:.2f}x")
                if "cold_over_crocoddyl" in r:
                    bits.append(f"cold/croc {r['cold_over_crocoddyl']:.2f}x")
            if "tick_over_tsid" in r:
                bits.append(f"tick/tsid {r['tick_over_tsid']:.2f}x")
            lines.append(f"  {name:8s} " + ", ".join(bits))
        if peers.get("note"):
            lines.append(f"  note: {peers['note']}")
    return "\n".join(lines)


def markdown_summary(result: dict[str, Any]) -> str:
    """A short Markdown table of the run (for the README), with the machine and load."""
    m = result["machine"]
    ratios = result.get("ratios") or {}
    lines = [
        f"{result['robot']}, {m['cpu_model']}, {m['cores']} cores, load average {m['loadavg'][0]:.1f} "
        f"(start) / {result['loadavg_end'][0]:.1f} (end), {result['date_utc'][:10]}, medians of {result['repeats']}:",
        "",
        "| task | first-ever [s] | cached cold [s] | warm solve [s] | iterations | tick median / p99 [µs] | "
        "real-time factor | certified | Crocoddyl FDDP [s] | warm / Crocoddyl |",
        "| --- | ---: | ---: | ---: | ---: | ---: | ---: | --- | ---: | ---: |",
    ]
    for name, r in result["tasks"].items():
        if r["status"] == NOT_IMPLEMENTED or r["status"].startswith("failed"):
            lines.append(f"| {name} | {r['status']} | | | | | | | | |")
            continue
        rr = ratios.get(name, {})
        tick = "" if r["tick_median_us"] is None else f"{r['tick_median_us']:.0f} / {_fmt(r['tick_p99_us'], digits=0)}"
        croc = f"{rr['crocoddyl_solve_s']:.2f}" if "crocoddyl_solve_s" in rr else ""
        ratio = f"{rr['warm_over_crocoddyl']:.2f}" if "warm_over_crocoddyl" in rr else ""
        cert = "" if r["certified"] is None else ("yes" if r["certified"] else "no")
        lines.append(f"| {name} | {_fmt(r['first_total_s'])} | {_fmt(r['cold_total_s'])} | {_fmt(r['solve_warm_s'])} "
                     f"| {_fmt(r['iterations'])} | {tick} | {_fmt(r['realtime_factor'])} | {cert} | {croc} | {ratio} |")
    tsid = (result.get("peers") or {}).get("tsid")
    if tsid:
        lines.append("")
        lines.append(f"TSID {tsid.get('tsid', '?')} tick (same controller task, pin {tsid.get('pin', '?')}): "
                     f"median {tsid['median_us']:.0f} µs, p99 {tsid['p99_us']:.0f} µs.")
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------------------------
# entry


def check_options(*, tasks: list[str] | None, quick: bool, repeats: int | None, dt: float | None,
                  max_iterations: int | None) -> tuple[list[str], int]:
    """(task classes, repeats) of a run, or :class:`CliError` (exit 2) naming the bad option."""
    names = list(dict.fromkeys(tasks)) if tasks is not None else (list(QUICK_TASKS) if quick else list(TASKS))
    if not names:
        raise CliError(f"--tasks names no task class; choose from {', '.join(TASKS)} (comma-separated)",
                       ExitCode.USAGE)
    unknown = [n for n in names if n not in TASKS]
    if unknown:
        shown = ", ".join(repr(n) if len(n) <= 40 else f"{n[:40]!r}..." for n in unknown[:5])
        raise CliError(f"unknown task class(es) {shown}; choose from {', '.join(TASKS)}", ExitCode.USAGE)
    reps = repeats if repeats is not None else (1 if quick else 3)
    if not 1 <= reps <= MAX_REPEATS:
        raise CliError(f"--repeats must be from 1 to {MAX_REPEATS}, got {reps}", ExitCode.USAGE)
    if dt is not None and not (math.isfinite(dt) and MIN_DT <= dt <= MAX_DT):
        raise CliError(f"--dt must be a knot spacing from {MIN_DT:g} to {MAX_DT:g} s, got {dt:g}", ExitCode.USAGE)
    if max_iterations is not None and not 1 <= max_iterations <= MAX_ITERATIONS:
        raise CliError(f"--max-iterations must be from 1 to {MAX_ITERATIONS}, got {max_iterations}", ExitCode.USAGE)
    return names, reps


def run_bench(*, robot: str = "talos", tasks: list[str] | None = None, quick: bool = False,
              repeats: int | None = None, dt: float | None = None, simulate: bool = True, e2e: bool = True,
              first: bool = True, scaling: bool | None = None, peers: bool = False,
              peers_dir: str | None = None, plot: str | None = None, max_iterations: int | None = None,
              log: Callable[[str], None] = lambda _: None) -> dict[str, Any]:
    """Run the benchmark and return the result dictionary (the JSON of ``--json``).

    Raises:
        CliError: A bad option (exit 2), checked before any work (:func:`check_options`).
    """
    from planner.trajopt.settings import default_cache_dir

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


#: Exit code of a task's status (the statuses not listed, "ok" and NOT_IMPLEMENTED, pass).
_STATUS_CODES = {
    "failed at parse/spec": ExitCode.INVALID_SPEC,
    "failed at planner import": ExitCode.INTERNAL,
    "failed at plan": ExitCode.INFEASIBLE,
    "plan failed": ExitCode.INFEASIBLE,
    "simulation failed": ExitCode.SIM_FAILED,
}


def task_exit_code(rec: dict[str, Any]) -> ExitCode:
    """What ``wbmp solve`` would exit with for one task's record (0 = passed or not implemented)."""
    status = rec.get("status")
    if status in _STATUS_CODES:
        return _STATUS_CODES[status]
    if status not in ("ok", NOT_IMPLEMENTED):
        return ExitCode.INTERNAL  # a status this version does not know
    if status == "ok" and rec.get("certified") is False:
        return ExitCode.SIM_FAILED
    e2e = rec.get("e2e_exit_code")
    if status == "ok" and e2e not in (None, 0):
        return ExitCode(e2e) if e2e in ExitCode._value2member_map_ else ExitCode.INTERNAL
    return ExitCode.OK


def exit_code(result: dict[str, Any]) -> ExitCode:
    """0 when every task that ran passed, else the code of the first failing task (module docstring)."""
    for rec in result["tasks"].values():
        code = task_exit_code(rec)
        if code != ExitCode.OK:
            return code
    return ExitCode.OK


def _read_result(path: str) -> dict[str, Any]:
    """A ``--json`` result re-read for ``--from`` (CliError, exit 2, when it is not one)."""
    import stat

    shown = repr(path) if len(path) <= 200 else f"{path[:200]!r}..."
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))  # a FIFO must not block us
        with os.fdopen(fd, "rb") as fh:
            if not stat.S_ISREG(os.fstat(fd).st_mode):
                raise CliError(f"--from {shown}: not a regular file (give a `wbmp bench --json` result)",
                               ExitCode.USAGE)
            data = fh.read(MAX_RESULT_BYTES + 1)
    except OSError as e:
        raise CliError(f"--from {shown}: cannot read it: {e.strerror or e}", ExitCode.USAGE) from None
    if len(data) > MAX_RESULT_BYTES:
        raise CliError(f"--from {shown}: larger than {MAX_RESULT_BYTES >> 20} MiB; a bench result is a few kB",
                       ExitCode.USAGE)
    try:
        result = json.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, ValueError, RecursionError) as e:
        what = "not UTF-8" if isinstance(e, UnicodeDecodeError) else "nested too deeply" if isinstance(
            e, RecursionError) else f"not JSON ({e})"
        raise CliError(f"--from {shown}: {what}; give a `wbmp bench --json` result", ExitCode.USAGE) from None
    if not isinstance(result, dict) or result.get("schema") != SCHEMA:
        raise CliError(f"{path} is not a `wbmp bench --json` result ({SCHEMA})", ExitCode.USAGE)
    tasks = result.get("tasks")
    if not isinstance(tasks, dict) or not all(isinstance(r, dict) and isinstance(r.get("status"), str)
                                              for r in tasks.values()):
        raise CliError(f"--from {shown}: its 'tasks' are not task records with a 'status'", ExitCode.USAGE)
    return result


def _render(result: dict[str, Any], *, markdown: bool, source: str | None) -> tuple[str, str | None]:
    """(table, Markdown or None); a re-read result that cannot be shown is exit 2, not a traceback."""
    try:
        return format_table(result), (markdown_summary(result) if markdown else None)
    except (KeyError, TypeError, ValueError, IndexError, AttributeError) as e:
        if source is None:
            raise
        raise CliError(f"--from {source!r}: an incomplete or damaged bench result ({type(e).__name__}: "
                       f"{str(e)[:100]})", ExitCode.USAGE) from None


def run(args: argparse.Namespace) -> int:
    from viz.files import Staging, check_distinct, check_output_file
    from wbmp.errors import ROBOT_HINT, one_line, require_text
    from wbmp.pipeline import output_errors

    def log(message: str) -> None:
        check_signals()  # a Ctrl-C that CasADi swallowed (a failed solve) stops the run here
        if not args.quiet:
            print(f"wbmp bench: {message}", file=sys.stderr, flush=True)

    # every option checked before any work -------------------------------------------------------
    tasks = [t.strip() for t in args.tasks.split(",") if t.strip()] if args.tasks is not None else None
    require_text(args.peers_dir, "--peers-dir", "give the folder of the peer results, or leave the option out")
    if not args.from_json:
        require_text(args.robot, "--robot", ROBOT_HINT)
        check_options(tasks=tasks, quick=args.quick, repeats=args.repeats, dt=args.dt,
                      max_iterations=args.max_iterations)
    scaling = (not args.quick if args.scaling is None else args.scaling) and not args.from_json
    plot = args.plot
    if plot is None and args.json:
        plot = str(Path(args.json).with_suffix("")) + "_scaling.png"
    elif plot is None and scaling:
        plot = "bench_scaling.png"
    with output_errors():
        outputs = {opt: check_output_file(path, opt) for opt, path in
                   (("--json", args.json), ("--markdown", args.markdown), ("--plot", plot if scaling else None))
                   if path is not None}
        check_distinct(outputs, {"--from": Path(args.from_json)} if args.from_json else None)

    if args.from_json:
        result = _read_result(args.from_json)
        if args.peers:
            result["peers"] = load_peers(args.peers_dir)
            result["ratios"] = peer_ratios(result["tasks"], result["peers"])
    else:
        from robots import load_robot

        load_robot(args.robot)  # an unknown robot is exit 3 now, not eight failed tasks later
        if args.no_compile:  # read by _settings here and in the cached-cold child processes
            os.environ["WBMP_BENCH_COMPILE"] = "0"
        result = run_bench(robot=args.robot, tasks=tasks, quick=args.quick, repeats=args.repeats, dt=args.dt,
                           simulate=not args.no_sim, e2e=not args.no_e2e, first=not args.no_first,
                           scaling=scaling, peers=args.peers, peers_dir=args.peers_dir, plot=plot,
                           max_iterations=args.max_iterations, log=log)
    table, md = _render(result, markdown=bool(args.markdown), source=args.from_json)
    print(table)
    with output_errors(), Staging() as staging:  # both files or neither
        if args.json:
            text = json.dumps(result, indent=2) + "\n"
            staging.add(outputs["--json"], lambda fh: fh.write(text.encode("utf-8")))
        if md is not None:
            staging.add(outputs["--markdown"], lambda fh: fh.write(md.encode("utf-8")))
        written = staging.commit()
    for path in written:
        print(f"wrote {path}")
    code = exit_code(result)
    if code != ExitCode.OK:
        failed = [name for name, rec in result["tasks"].items() if task_exit_code(rec) != ExitCode.OK]
        first = result["tasks"][failed[0]]
        status = first.get("status")
        if status == "ok":
            status = ("simulation check failed" if first.get("certified") is False
                      else f"`wbmp solve` exited {first.get('e2e_exit_code')}")
        why = first.get("certificate_reason") or first.get("message") or "-"
        print(f"wbmp bench: error: {len(failed)} of {len(result['tasks'])} task classes failed "
              f"({', '.join(failed)}); {failed[0]}: {status}: {one_line(str(why), 300)}",
              file=sys.stderr, flush=True)
    return int(code)


if __name__ == "__main__":  # the cached-cold child process
    sys.exit(_child_main(sys.argv[1]))
