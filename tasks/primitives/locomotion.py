"""``step(direction, length, count)``, ``walk(distance, direction)``, ``turn(angle)``.

Each compiles the contact sequence of :mod:`tasks.footsteps` (weight shift, single and double
support per step with the robot's step timing, settling) from the current stance, marks the
fragment dynamic (the planner adds CoM dynamics with contact forces), and asks for the CoM to
end where it is when standing, relative to the final feet (HARD, ``END_TOLERANCE``). The fragment's ``end_stance`` is where
the feet land, so the actions that follow are carried along (after ``turn(pi/2)``,
``forward`` is the new heading).
"""

from __future__ import annotations

import math

from robots import Robot
from tasks.footsteps import (
    ContactSequence,
    footsteps,
    lateral_step_max,
    step_length_limit,
    turn,
    walk,
)
from tasks.primitives.arms import UPPER_ARM_OUT, hold_upper_arms
from tasks.primitives.base import Fragment, FragmentBuilder, Primitive
from tasks.primitives.geometry import Stance, standing_geometry

END_TOLERANCE = 0.02  # [m] CoM ground projection at the end vs the point between the feet
PARTS = frozenset({"legs", "com"})


def _sequence(name: str, params: dict, robot: Robot, stance: Stance | None = None) -> ContactSequence:
    left = None if stance is None else stance.left
    right = None if stance is None else stance.right
    if name == "step":
        return footsteps(robot, params["direction"], params["length"], params["count"], left=left, right=right)
    if name == "walk":
        return walk(robot, params["distance"], params["direction"], left=left, right=right)
    return turn(robot, params["angle"], left=left, right=right)


def _primitive(name: str) -> Primitive:
    def nominal_duration(params: dict, robot: Robot) -> float:
        return _sequence(name, params, robot).duration

    def check(params: dict, robot: Robot) -> None:
        _sequence(name, params, robot)  # raises TaskDefinitionError beyond the robot's limits

    def limits(robot: Robot) -> dict[str, str]:
        prof = robot.profile
        if name == "turn":
            return {}
        key = "length" if name == "step" else "distance"
        text = (f"steps of at most {prof.step_length_max:.2f} m forward/backward, "
                f"{lateral_step_max(robot):.2f} m sideways on {robot.name}")
        return {key: text}

    def build(b: FragmentBuilder) -> Fragment:
        seq = _sequence(name, b.params, b.robot, b.stance)
        # Whole knots per phase (equal steps, not the builder's cumulative rounding): single
        # support rounded, double support rounded down (>= 1 knot), settling takes the rest.
        k = 0
        for phase in seq.phases[:-1]:
            n = phase.duration / b.dt
            k += max(1, math.floor(n + 1e-9) if len(phase.contacts) == 2 else round(n))
            b.phase(phase.name, k * b.dt / b.scale, phase.contacts, swing_height=phase.swing_height)
        last = seq.phases[-1]
        b.phase(last.name, seq.duration, last.contacts, swing_height=last.swing_height)
        end = Stance(left=seq.left, right=seq.right)
        home = end.transform_from_standing(b.robot).act(standing_geometry(b.robot).com)
        b.com_target("CoM back over the feet", (float(home[0]), float(home[1]), None), time=seq.duration,
                     tolerance=END_TOLERANCE)
        b.end_stance = end
        # the upper arms held a little out (a cost): G1's grazed the torso's meshes in MuJoCo
        hold_upper_arms(b, seq.duration, ("left", "right"), out=UPPER_ARM_OUT)
        return b.finish(PARTS, dynamic=True)

    def size_limits(params: dict, robot: Robot) -> dict[str, float]:
        if name == "step":
            return {"length": step_length_limit(robot, params["direction"])}
        return {}  # a walk takes the fewest steps within the limit; a turn any number of swings

    return Primitive(name=name, nominal_duration=nominal_duration, build=build, parts=lambda p: PARTS,
                     check=check, limits=limits, dynamic=True, size_limits=size_limits)


STEP = _primitive("step")
WALK = _primitive("walk")
TURN = _primitive("turn")
