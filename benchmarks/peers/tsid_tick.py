"""TSID tick on Talos, the same task as benchmarks/bench_wbc.py (runs in .venv-peers only).

Two 6D sole contacts (4 corner points each, friction pyramids), CoM, posture and one right-hand
SE(3) task; TSID's own Euler integration at 1 kHz (no MuJoCo in this environment). The tick is
``computeProblemData`` + ``SolverHQuadProgFast.solve`` + reading the torques, as in TSID's demos.
Prints the median and p99 [us] and writes JSON with ``--json``.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import pinocchio as pin
import tsid
from example_robot_data import robots_loader

MU = 0.7 / 2**0.5  # the wbmp controller's per-axis pyramid bound (robots/contact.py: mu / sqrt 2, mu = 0.7)
SOLE_X, SOLE_Y = 0.10, 0.06  # wbmp's Talos sole rectangle (half sizes) [m]
W_COM, W_HAND, W_POSTURE, W_FORCE = 10.0, 1.0, 1e-3, 1e-7
KP_COM, KP_HAND, KP_POSTURE, KP_CONTACT = 100.0, 100.0, 100.0, 10.0


def _version() -> str:
    """TSID's version: its module has no __version__, the installed distribution has one."""
    from importlib import metadata

    try:
        return metadata.version("tsid")
    except metadata.PackageNotFoundError:
        return getattr(tsid, "__version__", "?")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ticks", type=int, default=3000)
    parser.add_argument("--json", type=Path)
    args = parser.parse_args(argv)

    loader = robots_loader.ROBOTS["talos"]()
    urdf = str(Path(loader.df_path).resolve())
    pkg = str(Path(loader.model_path).resolve().parents[1])
    robot = tsid.RobotWrapper(urdf, [pkg], pin.JointModelFreeFlyer(), False)
    model = robot.model()
    pin.loadReferenceConfigurations(model, loader.srdf_path, False)
    q = np.array(model.referenceConfigurations["half_sitting"])
    v = np.zeros(robot.nv)
    formulation = tsid.InverseDynamicsFormulationAccForce("tsid", robot, False)
    formulation.computeProblemData(0.0, q, v)
    data = formulation.data()
    corners = np.array(
        [[SOLE_X, SOLE_X, -SOLE_X, -SOLE_X], [SOLE_Y, -SOLE_Y, SOLE_Y, -SOLE_Y], [0.0] * 4]
    )
    normal = np.array([0.0, 0.0, 1.0])
    contacts = []  # TSID keeps C++ references: the Python objects must outlive the formulation
    for name in ("left_sole_link", "right_sole_link"):
        contact = tsid.Contact6d(f"contact_{name}", robot, name, corners, normal, MU, 1.0, 1000.0)
        contact.setKp(KP_CONTACT * np.ones(6))
        contact.setKd(2.0 * np.sqrt(KP_CONTACT) * np.ones(6))
        contact.setReference(robot.framePosition(data, model.getFrameId(name)))
        formulation.addRigidContact(contact, W_FORCE, 1.0, 1)
        contacts.append(contact)
    com_task = tsid.TaskComEquality("task-com", robot)
    com_task.setKp(KP_COM * np.ones(3))
    com_task.setKd(2.0 * np.sqrt(KP_COM) * np.ones(3))
    formulation.addMotionTask(com_task, W_COM, 1, 0.0)
    posture = tsid.TaskJointPosture("task-posture", robot)
    posture.setKp(KP_POSTURE * np.ones(robot.nv - 6))
    posture.setKd(2.0 * np.sqrt(KP_POSTURE) * np.ones(robot.nv - 6))
    formulation.addMotionTask(posture, W_POSTURE, 1, 0.0)
    hand_id = model.getFrameId("gripper_right_base_link")
    hand = tsid.TaskSE3Equality("task-hand", robot, "gripper_right_base_link")
    hand.setKp(KP_HAND * np.ones(6))
    hand.setKd(2.0 * np.sqrt(KP_HAND) * np.ones(6))
    formulation.addMotionTask(hand, W_HAND, 1, 0.0)

    com_ref = tsid.TrajectoryEuclidianConstant("traj_com", robot.com(data))
    posture_ref = tsid.TrajectoryEuclidianConstant("traj_posture", q[7:])
    hand0 = robot.framePosition(data, hand_id)
    hand_ref = tsid.TrajectorySE3Constant("traj_hand", hand0)
    solver = tsid.SolverHQuadProgFast("qp")
    solver.resize(formulation.nVar, formulation.nEq, formulation.nIn)
    com_task.setReference(com_ref.computeNext())
    posture.setReference(posture_ref.computeNext())

    dt = 0.001
    ticks = []
    for i in range(args.ticks):
        t = i * dt
        target = hand0.copy()
        target.translation = hand0.translation + np.array(
            [0.0, 0.0, 0.25 * 0.5 * (1 - np.cos(2 * np.pi * t / 3.0))]
        )
        hand_ref.setReference(target)
        hand.setReference(hand_ref.computeNext())
        t0 = time.perf_counter()
        problem = formulation.computeProblemData(t, q, v)
        sol = solver.solve(problem)
        tau = formulation.getActuatorForces(sol)
        dv = formulation.getAccelerations(sol)
        ticks.append(time.perf_counter() - t0)
        if sol.status != 0:
            print(f"TSID QP failed at tick {i}")
            return 1
        v = v + dt * dv
        q = pin.integrate(model, q, dt * v)
    us = 1e6 * np.array(ticks[100:])
    out = {
        "tsid": _version(),
        "pin": pin.__version__,
        "median_us": float(np.median(us)),
        "p99_us": float(np.percentile(us, 99)),
        "ticks": len(us),
        "last_tau_norm": float(np.linalg.norm(tau)),
    }
    print(
        f"TSID tick (Talos, 2 contacts + CoM + posture + hand): median {out['median_us']:.1f} us, "
        f"p99 {out['p99_us']:.1f} us over {out['ticks']} ticks"
    )
    if args.json:
        args.json.write_text(json.dumps(out, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
