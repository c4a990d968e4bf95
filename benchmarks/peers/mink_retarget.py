"""A GMR-style retargeter: per-frame differential inverse kinematics on mink, no contacts, no dynamics.

Runs in its own environment (``bash benchmarks/peers/setup.sh mink``: mink, MuJoCo and the daqp QP
solver; no wbmp)::

    .venv-mink/bin/python benchmarks/peers/mink_retarget.py TASK.npz OUT.npz

``TASK.npz`` (written by ``benchmarks/peers/peer_mink.py`` in wbmp's environment) holds the
robot's MJCF (its URDF as MuJoCo reads it, with a site ``wbmp_<role>`` at each tracked frame),
the standing configuration (MuJoCo order), and per source frame the scaled target positions of
the tracked bodies (pelvis, torso, head, hands, feet: wbmp's reference) and the heading.

The method is what per-frame retargeters of the GMR family do (written here from that
description, not from their code): frame by frame, starting from the previous frame's solution,
a few iterations of mink's QP-based differential IK (position tasks on the tracked bodies, the
pelvis and feet also oriented: upright, facing the source's heading; a light pull to the standing
posture; the joint limits), then the next frame. Nothing holds a stance foot still, keeps a foot
on or above the floor, or looks at balance, torques or collisions.

``OUT.npz``: ``qpos`` (F, nq) per source frame, ``solve_s`` and ``solve_cpu_s`` (the IK loop's wall
and CPU time), ``load_s``
(building the model), ``iterations`` (total QP solves) and ``versions``.
"""

from __future__ import annotations

import sys
import time

import mink
import mujoco
import numpy as np

ITERATIONS = 10  # QP solves per frame at most (stops earlier once the step is tiny)
STEP_TOL = 1e-4  # [rad or m] per-iteration update norm below which a frame is done
DT = 0.1  # the integration step handed to mink's QP (a gain: each solve moves dt * velocity)
COSTS = {  # role -> (position cost, orientation cost)
    "base": (1.0, 0.5), "torso": (0.5, 0.0), "head": (0.5, 0.0), "left_hand": (1.0, 0.0), "right_hand": (1.0, 0.0),
    "left_foot": (1.0, 0.3), "right_foot": (1.0, 0.3),
}
POSTURE_COST = 1e-2


def yaw_rotation(yaw: float) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def main(task_path: str, out_path: str) -> int:
    task = np.load(task_path, allow_pickle=False)
    t0 = time.perf_counter()
    model = mujoco.MjModel.from_xml_string(str(task["xml"]))
    load_s = time.perf_counter() - t0
    roles = [str(r) for r in task["roles"]]
    targets = np.asarray(task["targets"], dtype=float)  # (F, R, 3)
    heading = np.asarray(task["heading"], dtype=float)  # (F,)
    q0 = np.asarray(task["q0"], dtype=float)
    config = mink.Configuration(model, q0)
    tasks = {}
    for role in roles:
        pos_cost, rot_cost = COSTS[role]
        tasks[role] = mink.FrameTask(frame_name=f"wbmp_{role}", frame_type="site", position_cost=pos_cost,
                                     orientation_cost=rot_cost, lm_damping=1.0)
    posture = mink.PostureTask(model, cost=POSTURE_COST)
    posture.set_target(q0)
    limits = [mink.ConfigurationLimit(model)]
    every = [*tasks.values(), posture]
    out = np.empty((len(targets), model.nq))
    solves = 0
    t0, c0 = time.perf_counter(), time.process_time()
    for f in range(len(targets)):
        rot = yaw_rotation(float(heading[f]))
        for i, role in enumerate(roles):
            tasks[role].set_target(mink.SE3.from_rotation_and_translation(mink.SO3.from_matrix(rot), targets[f, i]))
        for _ in range(ITERATIONS):
            vel = mink.solve_ik(config, every, DT, solver="daqp", damping=1e-3, limits=limits)
            config.integrate_inplace(vel, DT)
            solves += 1
            if np.linalg.norm(vel) * DT < STEP_TOL:
                break
        out[f] = config.q
    solve_s, solve_cpu_s = time.perf_counter() - t0, time.process_time() - c0
    versions = np.array([f"mink {getattr(mink, '__version__', '?')}", f"mujoco {mujoco.__version__}"])
    np.savez(out_path, qpos=out, solve_s=solve_s, solve_cpu_s=solve_cpu_s, load_s=load_s, iterations=solves, versions=versions)
    return 0


if __name__ == "__main__":
    if len(sys.argv) != 3:
        print(__doc__.splitlines()[0] + "\nusage: mink_retarget.py TASK.npz OUT.npz", file=sys.stderr)
        sys.exit(2)
    sys.exit(main(sys.argv[1], sys.argv[2]))
