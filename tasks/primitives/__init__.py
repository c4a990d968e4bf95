"""Motion primitives: each registered action compiles to a :class:`Fragment` of a TaskSpec.

``compile_action(action, robot, t0=...)`` checks the action against the robot (e.g. a squat
deeper than the robot's ``squat_depth_max`` is refused with the reachable depth), computes
world-frame targets from the robot's standing posture, and places phases and targets on the
knot grid from ``t0``. :func:`tasks.compose.compile_actions` assembles fragments into one spec.

One module per primitive or family: :mod:`.squat`, :mod:`.wave`, :mod:`.reach`,
:mod:`.posture` (stand, raise_arms, bow, turn_head, lean), :mod:`.balance`, :mod:`.arms` (punch,
hands_on_hips, cross_arms, arms_out, point, arm_circles, shrug, stretch) and :mod:`.meet` (the
hand meets the body: clap, touch, salute; body parts from :mod:`.bodymap`), :mod:`.head` (nod, shake_head), and the dynamic
ones, :mod:`.locomotion` (step, walk, turn) and :mod:`.jump`; the leg motions :mod:`.legs` (kick,
march, walk_arc, lunge, stomp) and :mod:`.hop` (hop, jog), with their shared :mod:`.gait`; the actions
on scene objects without a grasp :mod:`.objects` (walk_to, look_at, point_at); holding one :mod:`.grasp` (pick_up);
handing it over :mod:`.handover` (hand_over); pushing one :mod:`.push` (push); kneeling on the floor
:mod:`.kneel` (kneel, and getting up from it).
"""

from __future__ import annotations

from robots import Robot
from tasks.actions import REGISTRY, Action, get_action
from tasks.exceptions import TaskDefinitionError
from tasks.primitives import (
    arms,
    balance,
    grasp,
    handover,
    head,
    hop,
    jump,
    kneel,
    lean,
    legs,
    locomotion,
    meet,
    objects,
    posture,
    push,
    reach,
    seat,
    squat,
    terrain,
    wave,
)
from tasks.primitives.base import (
    DEFAULT_DT,
    PARTS,
    Fragment,
    FragmentBuilder,
    Primitive,
    knot_time,
    to_knot,
)
from tasks.primitives.geometry import Stance, StandingGeometry, standing_geometry

PRIMITIVES: dict[str, Primitive] = {
    p.name: p
    for p in (
        posture.STAND,
        squat.PRIMITIVE,
        wave.PRIMITIVE,
        *arms.PRIMITIVES,
        *meet.PRIMITIVES,
        *head.PRIMITIVES,
        reach.PRIMITIVE,
        posture.RAISE_ARMS,
        posture.BOW,
        posture.TURN_HEAD,
        posture.LEAN,
        balance.PRIMITIVE,
        locomotion.STEP,
        locomotion.WALK,
        locomotion.TURN,
        jump.PRIMITIVE,
        legs.KICK,
        legs.MARCH,
        legs.WALK_ARC,
        hop.HOP,
        legs.LUNGE,
        legs.STOMP,
        hop.JOG,
        *objects.PRIMITIVES,
        *grasp.PRIMITIVES,
        *handover.PRIMITIVES,
        *push.PRIMITIVES,
        *terrain.PRIMITIVES,
        *seat.PRIMITIVES,
        *lean.PRIMITIVES,
        *kneel.PRIMITIVES,
    )
}

missing = sorted(set(REGISTRY) - set(PRIMITIVES))
if missing:  # pragma: no cover - caught by the tests when a registry entry is added
    raise ImportError(f"actions without a primitive: {missing}")
del missing


def get_primitive(name: str) -> Primitive:
    """The primitive of a registered action name (UnknownAction with suggestions otherwise)."""
    prim = PRIMITIVES.get(name)
    if prim is None:
        get_action(name)  # raises UnknownAction naming close matches
        raise TaskDefinitionError(f"action {name!r} has no primitive")  # pragma: no cover
    return prim


def check_action(action: Action, robot: Robot) -> None:
    """Robot-specific checks of an action's parameters (TaskDefinitionError if out of range)."""
    get_primitive(action.name).check(dict(action.params), robot)


def nominal_duration(action: Action, robot: Robot) -> float:
    """How long ``action`` takes at its requested speed [s] (before snapping to knots)."""
    prim = get_primitive(action.name)
    prim.check(dict(action.params), robot)
    return float(prim.nominal_duration(dict(action.params), robot))


def compile_action(action: Action, robot: Robot, *, t0: float = 0.0, dt: float = DEFAULT_DT,
                   duration: float | None = None, stance: Stance | None = None,
                   label: str | None = None) -> Fragment:
    """Compile one action to a fragment that starts at ``t0``.

    Args:
        action: A registered action with resolved parameters.
        robot: The robot; targets are computed from its standing posture.
        t0: Start time [s], on the knot grid (a multiple of ``dt``).
        dt: Knot spacing [s].
        duration: Stretch the action to this length [s] (never shortened); None = its own.
        stance: Where the robot stands at ``t0``; None = the standing posture.
        label: Prefix of the fragment's target and phase names (default: the action name).

    Returns:
        The fragment: phases from ``t0`` (durations on the knot grid) and targets.

    Raises:
        TaskDefinitionError: a parameter is beyond the robot's limits, the robot lacks what the
            action needs (e.g. a neck), or the primitive is not available yet.
    """
    prim = get_primitive(action.name)
    params = dict(action.params)
    prim.check(params, robot)
    nominal = float(prim.nominal_duration(params, robot))
    builder = FragmentBuilder(action, robot, t0=t0, dt=dt, nominal=nominal, duration=duration,
                              stance=stance or Stance.standing(robot), label=label or action.name)
    return prim.build(builder)


def robot_limits(robot: Robot) -> dict[str, dict[str, str]]:
    """Robot-specific parameter limits per action (for ``wbmp actions --robot``)."""
    out = {}
    for name, prim in PRIMITIVES.items():
        lim = prim.limits(robot)
        if lim:
            out[name] = lim
    return out


__all__ = [
    "DEFAULT_DT",
    "PARTS",
    "PRIMITIVES",
    "Fragment",
    "FragmentBuilder",
    "Primitive",
    "Stance",
    "StandingGeometry",
    "TaskDefinitionError",
    "check_action",
    "compile_action",
    "get_primitive",
    "knot_time",
    "nominal_duration",
    "robot_limits",
    "standing_geometry",
    "to_knot",
]
