"""Crocoddyl (FDDP, full contact dynamics) on the tasks wbmp benchmarks, on Talos.

Runs in the peers environment made by ``benchmarks/peers/setup.sh`` (crocoddyl 3.2.1 with
pin 4.0.0; the crocoddyl wheel segfaults with pin 4.1), never in the project's .venv::

    .venv-crocoddyl/bin/python benchmarks/peers/crocoddyl_bench.py --repeats 5 --json out.json

Tasks (each rebuilt and solved ``--repeats`` times from the same initial guess: x0 repeated
and quasi-static controls; the median is reported):

- ``squat``: both soles in 6D contact, CoM 10 cm down at mid-horizon and back up at the end,
  N=80 knots of 30 ms (2.4 s).
- ``reach``: both soles in 6D contact, right gripper 20 cm forward of its start, N=60 knots
  of 50 ms (3 s), held over the last third.
- ``walk``: one 2-step walking phase (right then left step, 0.6 m stride split in two,
  10 cm foot clearance, 30 ms knots, 15 swing and 4 double-support knots) from crocoddyl's
  biped helper class.
- ``jump``: a vertical 10 cm jump (9 ground knots, 6 flight knots, 30 ms) from the same class.

``walk`` and ``jump`` run on the full Talos (the model wbmp plans for) and also on
``talos_legs`` (the 12-joint model of crocoddyl's own examples) for reference.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

# Single-threaded, like the figures in the issue, and so that OpenMP threads do not spin against
# each other on a shared 2-core machine (with 2 threads under load a solve took 50x longer).
os.environ.setdefault("OMP_NUM_THREADS", "1")

sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np
from common import Timer, machine_info, summarize, write_json

SQUAT_DEPTH = 0.10  # [m]
REACH_OFFSET = np.array([0.20, 0.0, 0.0])  # [m] in the world frame
MAX_ITER = 200
THREADS = int(os.environ["OMP_NUM_THREADS"])


def _load(name: str):
    import example_robot_data as erd

    robot = erd.load(name)
    model = robot.model
    q0 = model.referenceConfigurations["half_sitting"].copy()
    x0 = np.concatenate([q0, np.zeros(model.nv)])
    return model, x0


def _static_problem(model, x0, n_knots: int, dt: float, task_cost_at):
    """Shooting problem with both soles in 6D contact.

    ``task_cost_at(k, state, nu)`` returns a list of (name, cost, weight) for knot k (k == N for
    the terminal model).
    """
    import crocoddyl
    import pinocchio as pin

    state = crocoddyl.StateMultibody(model)
    actuation = crocoddyl.ActuationModelFloatingBase(state)
    nu = actuation.nu
    feet = [model.getFrameId("left_sole_link"), model.getFrameId("right_sole_link")]
    big = 1e10
    lower = np.concatenate([-big * np.ones(6), model.lowerPositionLimit[7:], -big * np.ones(model.nv)])
    upper = np.concatenate([big * np.ones(6), model.upperPositionLimit[7:], big * np.ones(model.nv)])
    posture_w = np.array([0.0] * 3 + [10.0] * 3 + [0.01] * (model.nv - 6) + [10.0] * model.nv) ** 2

    def action(k: int):
        contacts = crocoddyl.ContactModelMultiple(state, nu)
        for fid in feet:
            c = crocoddyl.ContactModel6D(state, fid, pin.SE3.Identity(), pin.LOCAL, nu, np.array([0.0, 0.0]))
            contacts.addContact(model.frames[fid].name, c)
        costs = crocoddyl.CostModelSum(state, nu)
        costs.addCost(
            "posture",
            crocoddyl.CostModelResidual(
                state, crocoddyl.ActivationModelWeightedQuad(posture_w), crocoddyl.ResidualModelState(state, x0, nu)
            ),
            1e-3 if k < n_knots else 1e-1,
        )
        costs.addCost(
            "limits",
            crocoddyl.CostModelResidual(
                state,
                crocoddyl.ActivationModelQuadraticBarrier(crocoddyl.ActivationBounds(lower, upper)),
                crocoddyl.ResidualModelState(state, x0, nu),
            ),
            1e3,
        )
        if k < n_knots:
            costs.addCost("effort", crocoddyl.CostModelResidual(state, crocoddyl.ResidualModelControl(state, nu)), 1e-4)
        for name, cost, weight in task_cost_at(k, state, nu):
            costs.addCost(name, cost, weight)
        dam = crocoddyl.DifferentialActionModelContactFwdDynamics(state, actuation, contacts, costs)
        return crocoddyl.IntegratedActionModelEuler(dam, dt if k < n_knots else 0.0)

    running = [action(k) for k in range(n_knots)]
    return crocoddyl.ShootingProblem(x0, running, action(n_knots))


def build_squat(model, x0):
    import crocoddyl
    import pinocchio as pin

    n_knots, dt = 80, 0.03
    data = model.createData()
    c0 = pin.centerOfMass(model, data, x0[: model.nq]).copy()
    low = c0 - np.array([0.0, 0.0, SQUAT_DEPTH])

    def task(k, state, nu):
        if k == n_knots // 2:
            return [("com_low", crocoddyl.CostModelResidual(state, crocoddyl.ResidualModelCoMPosition(state, low, nu)), 1e4)]
        if k == n_knots:
            return [("com_up", crocoddyl.CostModelResidual(state, crocoddyl.ResidualModelCoMPosition(state, c0, nu)), 1e4)]
        return []

    def error(xs):
        c_mid = pin.centerOfMass(model, data, np.asarray(xs[n_knots // 2])[: model.nq])
        c_end = pin.centerOfMass(model, data, np.asarray(xs[-1])[: model.nq])
        return {"com_low_error_m": float(np.linalg.norm(c_mid - low)), "com_end_error_m": float(np.linalg.norm(c_end - c0))}

    return _static_problem(model, x0, n_knots, dt, task), error, {"N": n_knots, "dt": dt}


def build_reach(model, x0):
    import crocoddyl
    import pinocchio as pin

    n_knots, dt = 60, 0.05
    hand = model.getFrameId("gripper_right_joint")
    data = model.createData()
    pin.framesForwardKinematics(model, data, x0[: model.nq])
    target = data.oMf[hand].translation.copy() + REACH_OFFSET

    def task(k, state, nu):
        if k < 2 * n_knots // 3:
            return []
        res = crocoddyl.ResidualModelFrameTranslation(state, hand, target, nu)
        return [("hand", crocoddyl.CostModelResidual(state, res), 1e3 if k < n_knots else 1e4)]

    def error(xs):
        pin.framesForwardKinematics(model, data, np.asarray(xs[-1])[: model.nq])
        return {"hand_error_m": float(np.linalg.norm(data.oMf[hand].translation - target))}

    return _static_problem(model, x0, n_knots, dt, task), error, {"N": n_knots, "dt": dt}


def _gait(model):
    from crocoddyl.utils.biped import SimpleBipedGaitProblem

    return SimpleBipedGaitProblem(model, "right_sole_link", "left_sole_link")


def build_walk(model, x0):
    gait = _gait(model)
    problem = gait.createWalkingProblem(x0, 0.6, 0.1, 0.03, 15, 4)
    return problem, lambda xs: {}, {"N": problem.T, "dt": 0.03, "steps": 2}


def build_jump(model, x0):
    gait = _gait(model)
    problem = gait.createJumpingProblem(x0, 0.1, [0.0, 0.0, 0.0], 0.03, 9, 6)
    return problem, lambda xs: {}, {"N": problem.T, "dt": 0.03, "height_m": 0.1}


BUILDERS = {"squat": build_squat, "reach": build_reach, "walk": build_walk, "jump": build_jump}


def run_case(model_name: str, task: str, repeats: int, verbose: bool) -> dict:
    """Build and solve one task ``repeats`` times; timings [s] and solver facts."""
    import crocoddyl

    model, x0 = _load(model_name)
    builds, solves, iters, costs, converged = [], [], [], [], []
    extra: dict = {}
    for _ in range(repeats):
        with Timer() as tb:
            problem, error, meta = BUILDERS[task](model, x0)
            problem.nthreads = THREADS
            solver = crocoddyl.SolverFDDP(problem)
            solver.th_stop = 1e-7
            xs = [x0] * (problem.T + 1)
            us = problem.quasiStatic([x0] * problem.T)
        with Timer() as ts:
            ok = solver.solve(xs, us, MAX_ITER, False)
        builds.append(tb.elapsed)
        solves.append(ts.elapsed)
        iters.append(int(solver.iter))
        costs.append(float(solver.cost))
        converged.append(bool(ok))
        extra = error(solver.xs)
        if verbose:
            print(f"  {model_name:10s} {task:6s} build {tb.elapsed:6.3f} s solve {ts.elapsed:6.3f} s "
                  f"iter {solver.iter:3d} converged {ok}", file=sys.stderr)
    return {
        "robot": model_name,
        "nq": model.nq,
        "nv": model.nv,
        **meta,
        "build_s": summarize(builds),
        "solve_s": summarize(solves),
        "solve_median_s": summarize(solves)["median"],
        "iterations": int(np.median(iters)),
        "converged": all(converged),
        "final_cost": float(np.median(costs)),
        "nthreads": int(getattr(problem, "nthreads", 1)),
        **extra,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--tasks", default="squat,reach,walk,jump")
    parser.add_argument("--no-legs", action="store_true", help="skip the talos_legs reference runs")
    parser.add_argument("--json", default=None, help="write the results to this file")
    parser.add_argument("-v", "--verbose", action="store_true")
    args = parser.parse_args(argv)

    import crocoddyl
    import pinocchio

    before = os.getloadavg()
    results: dict = {}
    for task in args.tasks.split(","):
        results[task] = run_case("talos", task, args.repeats, args.verbose)
        if task in ("walk", "jump") and not args.no_legs:
            results[f"{task}_talos_legs"] = run_case("talos_legs", task, args.repeats, args.verbose)
    payload = {
        "peer": "crocoddyl",
        "solver": "FDDP",
        "versions": {"crocoddyl": crocoddyl.__version__, "pinocchio": pinocchio.__version__},
        "machine": machine_info(),
        "loadavg_before": list(before),
        "repeats": args.repeats,
        "max_iter": MAX_ITER,
        "tasks": results,
    }
    write_json(args.json, payload)
    print(f"crocoddyl {crocoddyl.__version__} (pin {pinocchio.__version__}), load {before[0]:.1f}")
    print(f"{'task':18s} {'robot':10s} {'N':>4s} {'build [s]':>10s} {'solve [s]':>10s} {'iter':>5s} conv")
    for name, r in results.items():
        print(f"{name:18s} {r['robot']:10s} {r['N']:4d} {r['build_s']['median']:10.3f} "
              f"{r['solve_s']['median']:10.3f} {r['iterations']:5d} {r['converged']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
