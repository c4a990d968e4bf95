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
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime as _dt
import json
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

from wbmp.errors import CliError, ExitCode

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
        description="Benchmark every stage of the pipeline on each task class (medians over repeats), "
                    "optionally beside Crocoddyl and TSID (--peers, after `make bench-peers`). "
                    "Timings on a shared machine are noisy: the load average is recorded.",
        epilog="examples: wbmp bench --quick   wbmp bench --json out.json --peers   "
               "wbmp bench --tasks squat --repeats 1 --no-sim --no-e2e --json smoke.json",
    )
    p.add_argument("--quick", action="store_true",
                   help=f"{', '.join(QUICK_TASKS)} only, 1 repeat, one simulation, no scaling study (< 2 min)")
    p.add_argument("--robot", default="talos", help="robot name (default: talos)")
    p.add_argument("--json", metavar="FILE", default=None, help="also write the results as JSON here")
    p.add_argument("--peers", action="store_true",
                   help="add Crocoddyl/TSID figures (benchmarks/results/peers/*.json) and ratios ours/peer")
    p.add_argument("--peers-dir", default=None, help="folder of the peer results (default: benchmarks/results/peers)")
    p.add_argument("--tasks", default=None, help=f"comma-separated task classes (default: all: {','.join(TASKS)})")
    p.add_argument("--repeats", type=int, default=None, help="repeats per timing (default 3, quick 1)")
    p.add_argument("--dt", type=float, default=None, help="override the knot spacing of every spec [s] (smoke tests)")
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
        affinity = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        affinity = os.cpu_count()
    threads = {k: os.environ[k] for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
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


def _settings(cache_dir: str):
    from planner import PlannerSettings

    compile_ = os.environ.get("WBMP_BENCH_COMPILE", "1") != "0"
    return PlannerSettings(cache_dir=cache_dir, compile=compile_)


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
               simulate: bool, e2e: bool, user_cache: str, log: Callable[[str], None]) -> dict[str, Any]:
    """All stages of one task class; never raises (failures are recorded per stage)."""
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
        from planner.trajopt.cache import clear_memory_cache
        from planner import plan as plan_motion
    except Exception as exc:  # noqa: BLE001
        return fail("planner import", exc)

    cache_dir = tempfile.mkdtemp(prefix=f"wbmp-bench-{name}-") if first else user_cache
    try:
        settings = _settings(cache_dir)
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
        cold = [_cold_process(sentence, robot_name, cache_dir, dt) for _ in range(repeats)]
        cold = [c for c in cold if c is not None]
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
            rec["message"] = (rec["message"] + "; " if rec["message"] else "") + f"simulate: {_one_line(exc)}"

    # end to end ---------------------------------------------------------------------------------
    if e2e and plan.ok:
        try:
            rec.update(_end_to_end(sentence, robot_name, cache_dir, spec, repeats, simulate))
        except Exception as exc:  # noqa: BLE001
            rec["message"] = (rec["message"] + "; " if rec["message"] else "") + f"e2e: {_one_line(exc)}"
    if first:
        shutil.rmtree(cache_dir, ignore_errors=True)
    return rec


def _child_env(cache_dir: str) -> dict[str, str]:
    env = dict(os.environ)
    env["WBMP_CACHE_DIR"] = cache_dir
    return env


def _cold_process(sentence: str, robot_name: str, cache_dir: str, dt: float | None) -> dict | None:
    """Plan in a new Python process with the solver cache on disk (cached cold)."""
    payload = json.dumps({"sentence": sentence, "robot": robot_name, "cache_dir": cache_dir, "dt": dt})
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
    plan = plan_motion(spec, robot, settings=_settings(args["cache_dir"]), throw=False)
    s = plan.stats
    print(json.dumps({"build_time": s.build_time, "solve_time": s.solve_time, "cache": s.cache,
                      "iterations": s.iterations, "ok": bool(plan.ok)}))
    return 0


def _end_to_end(sentence: str, robot_name: str, cache_dir: str, spec, repeats: int, simulate: bool) -> dict:
    """Wall time of ``wbmp solve`` in a new process (sentence; the spec file when sentences are not wired)."""
    base = _wbmp_command() + ["solve"]
    extra = ["--robot", robot_name, "--quiet"] + ([] if simulate else ["--no-sim"])
    env = _child_env(cache_dir)
    times, mode, code = [], "sentence", None
    spec_file = None
    for _ in range(max(1, repeats)):
        cmd = base + [sentence] + extra if mode == "sentence" else base + ["--spec", spec_file] + extra
        proc, wall = _timed(lambda: subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=900,
                                                   check=False))
        if mode == "sentence" and proc.returncode == ExitCode.USAGE and "not available" in proc.stderr:
            from tasks.serialize import spec_to_json

            mode = "spec"
            fd, spec_file = tempfile.mkstemp(suffix=".json", prefix="wbmp-bench-spec-")
            with os.fdopen(fd, "w") as f:
                f.write(spec_to_json(spec))
            cmd = base + ["--spec", spec_file] + extra
            proc, wall = _timed(lambda: subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=900,
                                                       check=False))
        code = proc.returncode
        times.append(wall)
    if spec_file:
        os.unlink(spec_file)
    return {"e2e_s": _median(times), "e2e_mode": mode, "e2e_exit_code": code}


# --------------------------------------------------------------------------------------------
# scaling study


def scaling_study(*, repeats: int, log: Callable[[str], None], sentence: str = TASKS["squat"],
                  horizons: tuple[int, ...] = SCALING_N, robots: tuple[str, ...] = SCALING_ROBOTS,
                  cache_dir: str | None = None) -> dict[str, Any]:
    """Warm solve time of the squat against the horizon N (talos) and against the robot (N fixed).

    The horizon is changed through the knot spacing (same motion, finer grid). Each new
    structure is built once (compiled into ``cache_dir``), then solved ``repeats`` times warm.
    """
    from planner import plan as plan_motion
    from robots import load_robot

    cache_dir = cache_dir or tempfile.mkdtemp(prefix="wbmp-bench-scaling-")
    settings = _settings(cache_dir)
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
    shutil.rmtree(cache_dir, ignore_errors=True)
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
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
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


def run_bench(*, robot: str = "talos", tasks: list[str] | None = None, quick: bool = False,
              repeats: int | None = None, dt: float | None = None, simulate: bool = True, e2e: bool = True,
              first: bool = True, scaling: bool | None = None, peers: bool = False,
              peers_dir: str | None = None, plot: str | None = None,
              log: Callable[[str], None] = lambda _: None) -> dict[str, Any]:
    """Run the benchmark and return the result dictionary (the JSON of ``--json``)."""
    from planner.trajopt.settings import default_cache_dir

    # First-ever builds are timed with gcc in the loop (and cached-cold runs need the entry on
    # disk): compile synchronously here and in the child processes, which inherit the variable.
    os.environ["WBMP_COMPILE_BACKGROUND"] = "0"

    names = list(tasks) if tasks else (list(QUICK_TASKS) if quick else list(TASKS))
    unknown = [n for n in names if n not in TASKS]
    if unknown:
        raise CliError(f"unknown task class(es) {', '.join(unknown)}; choose from {', '.join(TASKS)}",
                       ExitCode.USAGE)
    reps = repeats if repeats is not None else (1 if quick else 3)
    if reps < 1:
        raise CliError(f"--repeats must be >= 1, got {reps}", ExitCode.USAGE)
    if scaling is None:
        scaling = not quick
    info = machine_info()
    t_start = time.perf_counter()
    result: dict[str, Any] = {
        "schema": SCHEMA,
        "date_utc": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "robot": robot,
        "quick": quick,
        "repeats": reps,
        "dt_override": dt,
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
                         simulate=do_sim, e2e=e2e and not quick, user_cache=default_cache_dir(), log=log)
        sim_done = sim_done or rec.get("realtime_factor") is not None
        result["tasks"][name] = rec
    result["scaling"] = None
    result["plot"] = None
    if scaling:
        result["scaling"] = scaling_study(repeats=reps, log=log)
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


def run(args: argparse.Namespace) -> int:
    def log(message: str) -> None:
        if not args.quiet:
            print(f"wbmp bench: {message}", file=sys.stderr, flush=True)

    tasks = [t.strip() for t in args.tasks.split(",") if t.strip()] if args.tasks else None
    if args.no_compile:  # read by _settings here and in the cached-cold child processes
        os.environ["WBMP_BENCH_COMPILE"] = "0"
    plot = args.plot
    if plot is None and args.json:
        plot = str(Path(args.json).with_suffix("")) + "_scaling.png"
    if args.from_json:
        try:
            result = json.loads(Path(args.from_json).read_text())
        except (OSError, json.JSONDecodeError) as e:
            raise CliError(f"cannot read the bench result {args.from_json}: {e}", ExitCode.USAGE) from e
        if result.get("schema") != SCHEMA:
            raise CliError(f"{args.from_json} is not a `wbmp bench --json` result ({SCHEMA})", ExitCode.USAGE)
        if args.peers:
            result["peers"] = load_peers(args.peers_dir)
            result["ratios"] = peer_ratios(result["tasks"], result["peers"])
    else:
        result = run_bench(robot=args.robot, tasks=tasks, quick=args.quick, repeats=args.repeats, dt=args.dt,
                           simulate=not args.no_sim, e2e=not args.no_e2e, first=not args.no_first,
                           scaling=args.scaling, peers=args.peers, peers_dir=args.peers_dir, plot=plot, log=log)
    print(format_table(result))
    if args.json:
        path = Path(args.json)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(result, indent=2) + "\n")
        print(f"wrote {path}")
    if args.markdown:
        md = Path(args.markdown)
        md.parent.mkdir(parents=True, exist_ok=True)
        md.write_text(markdown_summary(result))
        print(f"wrote {md}")
    return 0


if __name__ == "__main__":  # the cached-cold child process
    sys.exit(_child_main(sys.argv[1]))
