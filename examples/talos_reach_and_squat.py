"""Plan a hand reach while squatting on Talos from a hand-written TaskSpec, then check it.

Run: ``.venv/bin/python examples/talos_reach_and_squat.py [--robot g1] [--html out.html]``
"""

from __future__ import annotations

import argparse

import numpy as np
import pinocchio as pin

from planner import plan
from robots import load_robot
from tasks import CoMTarget, Contact, FrameTarget, Phase, Pose, TaskSpec


def build_spec(robot) -> TaskSpec:
    """Both soles where they stand; the right hand 25 cm forward while the CoM drops 8 cm."""
    data = robot.data()
    pin.framesForwardKinematics(robot.model, data, robot.q_standing)
    feet = tuple(
        Contact(frame=f"{side}_foot", placement=Pose(position=tuple(data.oMf[robot.frame_id(f"{side}_foot")].translation)))
        for side in ("left", "right")
    )
    hand = data.oMf[robot.frame_id("right_hand")].translation + np.array([0.25, 0.0, 0.0])  # [m]
    com_z = pin.centerOfMass(robot.model, data, robot.q_standing)[2] - 0.08  # [m]
    return TaskSpec(
        robot=robot.name,
        phases=(Phase(name="stand", duration=3.0, contacts=feet),),
        targets=(FrameTarget(name="reach", frame="right_hand", position=tuple(hand), time=1.5),),
        com_targets=(CoMTarget(name="lower", position=(None, None, com_z), time=1.5),),
        name="reach and squat",
    )


def main(argv: list[str] | None = None) -> int:
    """Plan, print the constraint report and the reached hand error; 0 when every check holds."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default="talos", help="robot name (default: talos)")
    parser.add_argument("--html", default=None, help="also write an offline HTML replay here")
    args = parser.parse_args(argv)
    robot = load_robot(args.robot)
    result = plan(build_spec(robot), robot)
    print(result.summary())
    k = int(np.argmin(np.abs(result.t - 1.5)))
    data = robot.data()
    pin.framesForwardKinematics(robot.model, data, result.q[k])
    target = np.array(result.spec.targets[0].position)
    print(f"right hand error at t = 1.5 s: {np.linalg.norm(data.oMf[robot.frame_id('right_hand')].translation - target):.4f} m")
    if args.html:
        from viz import write_html

        print(f"wrote {write_html(args.html, robot, result)}")
    return 0 if result.ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
