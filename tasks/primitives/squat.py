"""``squat(depth [m], repeat, duration [s])``: lower the centre of mass and stand up again.

Both soles stay at their standing placements. Each repetition is a HARD CoM height target
``standing CoM z - depth`` at its middle (tolerance 1 cm) and the standing height at its end;
the CoM ground projection stays over the support polygon (the spec's CoM bounds).
"""

from __future__ import annotations

from robots import Robot
from tasks.exceptions import TaskDefinitionError
from tasks.primitives.base import Fragment, FragmentBuilder, Primitive

DEPTH_TOLERANCE = 0.01  # [m] allowed CoM height error at the bottom and top of each squat
PARTS = frozenset({"legs", "com"})


def nominal_duration(params: dict, robot: Robot) -> float:
    """``repeat * duration`` [s]."""
    return params["repeat"] * params["duration"]


def check(params: dict, robot: Robot) -> None:
    """The depth must be within the robot's ``squat_depth_max``."""
    limit = robot.profile.squat_depth_max
    if params["depth"] > limit + 1e-12:
        raise TaskDefinitionError(
            f"squat depth {params['depth']:g} m is beyond {robot.name}'s reachable {limit:g} m; "
            f"ask for a depth of at most {limit:g} m"
        )


def limits(robot: Robot) -> dict[str, str]:
    """Robot-specific range of ``depth``."""
    return {"depth": f"at most {robot.profile.squat_depth_max:g} m on {robot.name}"}


def build(b: FragmentBuilder) -> Fragment:
    """One double-support phase with a CoM height target at each bottom and top."""
    n, period, depth = b.params["repeat"], b.params["duration"], b.params["depth"]
    z_stand = b.world_z(float(b.geometry.com[2]))
    for i in range(n):
        b.com_target(f"squat bottom #{i + 1}", (None, None, z_stand - depth), time=(i + 0.5) * period,
                     tolerance=DEPTH_TOLERANCE)
        b.com_target(f"squat top #{i + 1}", (None, None, z_stand), time=(i + 1) * period,
                     tolerance=DEPTH_TOLERANCE)
    b.phase("squat" if n == 1 else f"squat x{n}", n * period)
    return b.finish(PARTS)


PRIMITIVE = Primitive(name="squat", nominal_duration=nominal_duration, build=build,
                      parts=lambda params: PARTS, check=check, limits=limits,
                      size_limits=lambda params, robot: {"depth": robot.profile.squat_depth_max})
