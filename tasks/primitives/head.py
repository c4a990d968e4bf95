"""Head gestures: ``nod(repeat, angle, duration)`` and ``shake_head(repeat, angle, duration)``.

Both turn the head frame (orientation targets, HARD, ``ORIENTATION_TOLERANCE``) like
``turn_head``: a nod pitches it down by ``angle`` and back level ``repeat`` times; a shake yaws
it left and right by ``angle`` ``repeat`` times, then back forward. Robots without neck joints
(G1) are refused ("g1 has no neck joint to nod its head"), and so is an angle beyond the neck's
range in a direction the gesture uses.
"""

from __future__ import annotations

from robots import Robot
from tasks.exceptions import TaskDefinitionError
from tasks.primitives.base import Fragment, FragmentBuilder, Primitive
from tasks.primitives.geometry import neck_range, require_role, standing_geometry
from tasks.primitives.posture import head_turn_axis, turned_head_rotation

ORIENTATION_TOLERANCE = 0.05  # [rad]
SETTLE_TIME = 0.3  # [s] before the first and after the last head pose
DIRECTIONS = {"nod": ("down",), "shake_head": ("left", "right")}
VERB = {"nod": "nod", "shake_head": "shake"}


def _duration(params: dict, robot: Robot) -> float:
    return 2 * SETTLE_TIME + params["repeat"] * params["duration"]


def _check(name: str):
    def check(params: dict, robot: Robot) -> None:
        require_role(robot, "head", name)
        if not standing_geometry(robot).neck_joints:
            raise TaskDefinitionError(f"{robot.name} has no neck joint to {VERB[name]} its head")
        for d in DIRECTIONS[name]:
            r = neck_range(robot, head_turn_axis(robot, d))
            if params["angle"] > r + 1e-9:
                raise TaskDefinitionError(
                    f"{name} angle {params['angle']:g} rad is beyond {robot.name}'s neck range of {r:.2f} rad {d}"
                )
    return check


def _limits(name: str):
    def limits(robot: Robot) -> dict[str, str]:
        if not robot.has_role("head") or not standing_geometry(robot).neck_joints:
            return {"angle": f"not available: {robot.name} has no neck joint"}
        r = min(neck_range(robot, head_turn_axis(robot, d)) for d in DIRECTIONS[name])
        return {"angle": f"at most {r:.2f} rad on {robot.name}"}
    return limits


def _head(b: FragmentBuilder, what: str, direction: str | None, tau: float) -> None:
    rot = b.geometry.rotation("head") if direction is None else turned_head_rotation(b.robot, direction, b.params["angle"])
    b.frame_target(what, "head", rpy=b.world_rotation(rot), time=tau, orientation_tolerance=ORIENTATION_TOLERANCE)


def build_nod(b: FragmentBuilder) -> Fragment:
    """Down and level again, ``repeat`` times."""
    _check("nod")(b.params, b.robot)
    n, d = b.params["repeat"], b.params["duration"]
    for k in range(n):
        _head(b, f"head down #{k + 1}", "down", SETTLE_TIME + (k + 0.5) * d)
        _head(b, f"head level #{k + 1}", None, SETTLE_TIME + (k + 1) * d)
    b.phase("nod", _duration(b.params, b.robot))
    return b.finish(frozenset({"head"}))


def build_shake_head(b: FragmentBuilder) -> Fragment:
    """Left, right, ``repeat`` times, then forward."""
    _check("shake_head")(b.params, b.robot)
    n, d = b.params["repeat"], b.params["duration"]
    for k in range(n):
        _head(b, f"head left #{k + 1}", "left", SETTLE_TIME + (k + 0.25) * d)
        _head(b, f"head right #{k + 1}", "right", SETTLE_TIME + (k + 0.75) * d)
    _head(b, "head forward again", None, SETTLE_TIME + n * d)
    b.phase("shake head", _duration(b.params, b.robot))
    return b.finish(frozenset({"head"}))


NOD = Primitive(name="nod", nominal_duration=_duration, build=build_nod, parts=lambda p: frozenset({"head"}),
                check=_check("nod"), limits=_limits("nod"))
SHAKE_HEAD = Primitive(name="shake_head", nominal_duration=_duration, build=build_shake_head,
                       parts=lambda p: frozenset({"head"}), check=_check("shake_head"), limits=_limits("shake_head"))

PRIMITIVES = (NOD, SHAKE_HEAD)

__all__ = ["NOD", "PRIMITIVES", "SHAKE_HEAD"]
