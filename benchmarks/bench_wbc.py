"""Benchmark of the whole-body controller and the closed-loop simulation (a script, not a test).

Measures on Talos, with the task of the TSID comparison (two 6D sole contacts, CoM,
posture, one moving hand):

1. the controller tick in closed loop in MuJoCo (wall clock and thread CPU time, median / p99),
   with a breakdown (Pinocchio numerics, QP update + solve),
2. the real-time factor of the whole loop (``sim.simulate``: controller + physics + logging),
3. the same recorded QPs solved by proxsuite (persistent, warm-started) and by every
   backend that ``qpsolvers`` finds installed (each call builds the problem anew).

Usage::

    .venv/bin/python benchmarks/bench_wbc.py [--seconds 3] [--json out.json] [--plan handmade|trajopt] [--no-peers]

The machine is shared: wall-clock numbers are noisy, so the thread CPU time is printed too.
TSID's tick on the same task runs beside ours, in its own environment (``.venv-tsid``, made by
``bash benchmarks/peers/setup.sh tsid``); without it the output says so.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import mujoco  # noqa: E402
import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402

from planner.wbc import WbcSettings, WholeBodyController  # noqa: E402
from robots import load_robot  # noqa: E402
from sim import SimSettings, build_model, simulate  # noqa: E402
from sim.handmade import arm_plan  # noqa: E402
from wbmp.bench.machine import machine_info  # noqa: E402

TARGET_MEDIAN_US = 150.0
TARGET_P99_US = 400.0
TARGET_RTF = 2.0


def _stats(samples: list[float]) -> dict[str, float]:
    a = 1e6 * np.asarray(samples)
    return {
        "median_us": float(np.median(a)),
        "p99_us": float(np.percentile(a, 99)),
        "mean_us": float(a.mean()),
    }


def make_plan(robot, kind: str, seconds: float):
    """The benchmark motion: a hand-made right-hand raise, or the trajectory optimizer's wave."""
    if kind == "trajopt":
        from planner import plan as trajopt_plan
        from tasks.actions import Action
        from tasks.compose import compile_actions

        return trajopt_plan(
            compile_actions([Action(name="reach", params={"direction": "forward"})], robot), robot
        )
    return arm_plan(robot, duration=seconds, dt=0.05)


def closed_loop_ticks(robot, plan, settings: WbcSettings, *, record: bool = False) -> tuple[dict, list]:
    """Run the controller in closed loop at 1 kHz; time every tick.

    With ``record``, a shadow controller without the fast path (proxsuite on every tick) sees the
    same state every 10th tick, outside the timed region: its QPs feed the backend comparison.
    """
    sm = build_model(robot, timestep=0.001)
    d = sm.data()
    ctrl = WholeBodyController(robot, settings)
    shadow = WholeBodyController(robot, replace(settings, fast_path=False)) if record else None
    ref = ctrl.reference_for(plan)
    q = np.array(plan.q[0])
    v = np.zeros(robot.nv)
    sm.set_state(d, q, v)
    ctrl.reset(q, v)
    if shadow is not None:
        shadow.reset(q, v)
    wall, cpu, iters, problems = [], [], [], []
    fast_wall = []
    for i in range(ref.n):
        sm.state(d, q, v)
        t0, c0 = time.perf_counter(), time.thread_time()
        tau = ctrl.compute(i * 0.001, q, v, ref)
        wall.append(time.perf_counter() - t0)
        cpu.append(time.thread_time() - c0)
        iters.append(ctrl.last.iterations)
        if ctrl.last.iterations == 0:
            fast_wall.append(wall[-1])
        if shadow is not None and i % 10 == 0:
            shadow.compute(i * 0.001, q, v, ref)
            problems.append(
                tuple(
                    x.copy() for x in (shadow.H, shadow.g, shadow.A, shadow.b, shadow.C, shadow.l, shadow.u)
                )
            )
        d.ctrl[sm.actuator_select] = tau
        mujoco.mj_step(sm.model, d)
    # breakdown on the final state: the Pinocchio part alone
    model, data = robot.model, robot.data()
    zero = np.zeros(robot.nv)
    fids = [robot.frame_id(r) for r in ("left_foot", "right_foot", "left_hand", "right_hand")]
    pin_times = []
    for _ in range(2000):
        t0 = time.thread_time()
        pin.computeAllTerms(model, data, q, v)
        pin.centerOfMass(model, data, q, v, zero)
        for fid in fids:
            pin.getFrameJacobian(model, data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
            pin.getFrameClassicalAcceleration(
                model, data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
            )
            data.oMf[fid].homogeneous  # noqa: B018 - timed: the property builds the matrix
        pin_times.append(time.thread_time() - t0)
    qp_times = []
    qp = shadow._qp if shadow is not None else None  # the persistent solver, update + solve alone
    if qp is not None:
        for prob in problems:
            t0 = time.thread_time()
            qp.update(*prob, update_preconditioner=False)
            qp.solve()
            qp_times.append(time.thread_time() - t0)
    out = {
        "ticks": len(wall),
        "fast_path_ticks": ctrl.fast_ticks,
        "wall": _stats(wall),
        "cpu": _stats(cpu),
        "fast_path_wall": _stats(fast_wall) if fast_wall else None,
        "qp_iterations_mean": float(np.mean(iters)),
        "pinocchio_cpu": _stats(pin_times),
        "qp_update_solve_cpu": _stats(qp_times) if qp_times else None,
        "qp_size": {"n": ctrl.n, "n_eq": ctrl.n_eq, "n_in": ctrl.n_in},
    }
    return out, problems


def tsid_peer(ticks: int) -> dict:
    """TSID's tick on the same task, in its own environment (``.venv-tsid``), or why it cannot run."""
    sys.path.insert(0, str(ROOT / "benchmarks" / "peers"))
    from run_peers import run_peer

    return run_peer("tsid", ["--ticks", str(ticks)])


def backend_comparison(problems: list) -> dict[str, dict]:
    """Solve the recorded QPs with every qpsolvers backend (cold, one call each) and proxsuite (persistent)."""
    import proxsuite
    import qpsolvers

    results = {}
    H, g, A, b, C, lower, upper = problems[0]
    qp = proxsuite.proxqp.dense.QP(len(g), len(b), len(lower))
    qp.settings.eps_abs = 1e-6
    qp.settings.eps_rel = 0.0
    qp.settings.initial_guess = proxsuite.proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
    qp.init(H, g, A, b, C, lower, upper)
    qp.solve()
    ref_x = []
    times = []
    for prob in problems:
        t0 = time.perf_counter()
        qp.update(*prob, update_preconditioner=False)
        qp.solve()
        times.append(time.perf_counter() - t0)
        ref_x.append(qp.results.x.copy())
    results["proxsuite (persistent, warm start)"] = {**_stats(times), "max_dx": 0.0}
    for solver in qpsolvers.available_solvers:
        times, dx = [], []
        for prob, x_ref in zip(problems, ref_x, strict=True):
            H, g, A, b, C, lower, upper = prob
            finite = lower > -1e19
            G = np.vstack([C, -C[finite]])
            h = np.concatenate([upper, -lower[finite]])
            t0 = time.perf_counter()
            x = qpsolvers.solve_qp(H, g, G, h, A, b, solver=solver)
            times.append(time.perf_counter() - t0)
            dx.append(np.inf if x is None else float(np.abs(x - x_ref).max()))
        results[f"qpsolvers:{solver} (rebuilt each call)"] = {
            **_stats(times),
            "max_dx": float(max(dx)),
        }
    missing = sorted({"daqp", "quadprog", "osqp", "proxqp"} - set(qpsolvers.available_solvers))
    if missing:
        results["not installed"] = {"solvers": missing}
    return results


def realtime_factor(robot, plan) -> dict[str, float]:
    """Whole loop (controller + MuJoCo + logging + certificate) against simulated time."""
    t0 = time.perf_counter()
    ex = simulate(plan, robot, settings=SimSettings(settle_time=0.5))
    total = time.perf_counter() - t0
    return {
        "simulated_s": float(ex.t[-1]),
        "loop_wall_s": ex.wall_time,
        "realtime_factor_loop": ex.realtime_factor,
        "realtime_factor_with_setup_and_certificate": float(ex.t[-1]) / total,
        "certificate_ok": ex.certificate.ok,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=3.0, help="motion length [s]")
    parser.add_argument("--plan", choices=("handmade", "trajopt"), default="handmade")
    parser.add_argument("--json", type=Path, help="write the numbers to this file")
    parser.add_argument("--no-peers", action="store_true", help="do not run TSID (.venv-tsid) beside ours")
    args = parser.parse_args(argv)

    robot = load_robot("talos")
    plan = make_plan(robot, args.plan, args.seconds)
    load = os.getloadavg()[0]
    machine = machine_info()
    print(
        f"Talos, {args.plan} plan of {plan.t[-1]:.1f} s; load average {load:.1f} on {os.cpu_count()} cores"
    )
    ticks, problems = closed_loop_ticks(robot, plan, WbcSettings(), record=True)
    ticks_qp, _ = closed_loop_ticks(robot, plan, WbcSettings(fast_path=False))
    print(
        f"controller tick ({ticks['ticks']} ticks, QP n={ticks['qp_size']['n']} n_eq={ticks['qp_size']['n_eq']} "
        f"n_in={ticks['qp_size']['n_in']}; {ticks['fast_path_ticks']} ticks answered by the fast path, "
        f"{ticks['qp_iterations_mean']:.2f} proxsuite iterations/tick):"
    )
    for kind in ("wall", "cpu"):
        s = ticks[kind]
        flag = (
            "meets"
            if s["median_us"] <= TARGET_MEDIAN_US and s["p99_us"] <= TARGET_P99_US
            else "misses"
        )
        print(
            f"  {kind:<5} median {s['median_us']:7.1f} us  p99 {s['p99_us']:7.1f} us  ({flag} the target "
            f"{TARGET_MEDIAN_US:.0f}/{TARGET_P99_US:.0f} us)"
        )
    s = ticks_qp["wall"]
    print(
        f"  same loop, proxsuite on every tick (fast_path=False): median {s['median_us']:.1f} us  "
        f"p99 {s['p99_us']:.1f} us ({ticks_qp['qp_iterations_mean']:.2f} iterations/tick)"
    )
    print(
        f"  of which Pinocchio numerics  median {ticks['pinocchio_cpu']['median_us']:.1f} us (CPU)"
    )
    if ticks["qp_update_solve_cpu"]:
        print(
            f"  proxsuite update + solve alone (recorded QPs) median {ticks['qp_update_solve_cpu']['median_us']:.1f} us (CPU)"
        )
    tsid = tsid_peer(ticks["ticks"]) if not args.no_peers else {"skipped": "--no-peers"}
    if "median_us" in tsid:
        print(
            f"  TSID {tsid.get('tsid', '?')} (same task, own environment): median {tsid['median_us']:.1f} us  "
            f"p99 {tsid['p99_us']:.1f} us; ours / TSID = {ticks['wall']['median_us'] / tsid['median_us']:.2f}"
        )
    else:
        print(f"  TSID not run: {tsid['skipped']}")
    backends = backend_comparison(problems)
    print(f"QP backends on {len(problems)} recorded ticks (wall):")
    for name, s in backends.items():
        if name == "not installed":
            print(f"  not installed here: {', '.join(s['solvers'])}")
            continue
        print(
            f"  {name:<42} median {s['median_us']:8.1f} us  p99 {s['p99_us']:8.1f} us  max |dx| {s['max_dx']:.1e}"
        )
    rtf = realtime_factor(robot, plan)
    print(
        f"simulation: {rtf['simulated_s']:.2f} s simulated, loop {rtf['realtime_factor_loop']:.2f}x real time "
        f"({rtf['realtime_factor_with_setup_and_certificate']:.2f}x with setup and certificate; target "
        f">= {TARGET_RTF:.0f}x); certificate {'PASS' if rtf['certificate_ok'] else 'FAIL'}"
    )
    if args.json:
        args.json.write_text(
            json.dumps(
                {
                    "machine": machine,
                    "load_average": load,
                    "tick": ticks,
                    "tick_proxsuite_every_tick": ticks_qp,
                    "tsid": tsid,
                    "backends": backends,
                    "simulation": rtf,
                },
                indent=2,
            )
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
