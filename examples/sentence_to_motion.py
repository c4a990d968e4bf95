"""From a sentence to a certified motion, one layer at a time (what ``wbmp solve`` wires up).

Run: ``.venv/bin/python examples/sentence_to_motion.py "深蹲两次" [--robot g1] [--no-sim]``
"""

from __future__ import annotations

import argparse

from language import parse
from planner import plan
from robots import load_robot
from tasks.compose import compile_actions


def main(argv: list[str] | None = None) -> int:
    """Parse, compile, plan and (unless --no-sim) simulate; 0 when planned and certified."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("sentence", nargs="?", default="squat twice, then wave your left hand")
    parser.add_argument("--robot", default="talos", help="robot name (default: talos)")
    parser.add_argument("--no-sim", action="store_true", help="skip the MuJoCo check")
    args = parser.parse_args(argv)

    actions = parse(args.sentence)  # language/: sentence -> registry actions (SI units)
    print(actions.describe())
    robot = load_robot(args.robot)  # robots/: Pinocchio model, frames, standing posture
    spec = compile_actions(actions.actions, robot)  # tasks/: actions -> timed phases and targets
    print(f"task spec: {len(spec.phases)} phases, {len(spec.targets)} frame targets, "
          f"{len(spec.com_targets)} CoM targets over {spec.horizon:.2f} s")
    motion = plan(spec, robot)  # planner/: CasADi + IPOPT
    print(motion.summary())
    if args.no_sim:
        return 0 if motion.ok else 1
    from sim import simulate  # sim/: QP whole-body controller in MuJoCo at 1 kHz

    execution = simulate(motion, robot)
    print(execution.certificate.summary())
    return 0 if motion.ok and execution.certificate.ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
