"""Composition: a list of actions becomes one :class:`~tasks.specs.TaskSpec`.

Actions run one after another (``then``); an action with ``overlay=True`` runs at the same
time as the action before it (``wave while squatting`` is ``[squat, wave(overlay=True)]``).
An action and the overlays that follow it form a *group*:

- every action of a group starts at the group's start and is stretched to the longest one
  (a wave overlaid on a shorter squat makes the squat slower, never the wave faster);
- two actions of a group must not drive the same body part (legs and CoM, torso, head, left
  arm, right arm): ``squat`` + ``lean`` or ``wave right`` + ``reach right`` are refused;
- at most one action of a group may change the contacts (balance, step, walk, turn, jump), and
  the group's phases are that action's (or the first action's); the actions after it start
  from where its feet end (``Fragment.end_stance``). Nothing may be overlaid on an action that
  moves the feet (step, walk, turn): the overlay's targets are fixed where the robot stands.

The spec starts and ends with ``stand_time`` of standing still on both feet, and groups are
separated by ``transition_time`` of double support: every action starts from and returns to
the standing posture (squats end at the standing CoM height, hands are brought back to rest),
so the transitions go through the standing posture. All times are on the knot grid of ``dt``.

Balance across the parts: the spec is ``dynamic`` when any action is (step, walk, turn, jump), so
the planner's CoM dynamics and contact forces cover the whole sequence, the parts before and
after the walk included; and a group whose actions leave the CoM alone (arms, head) holds it
at its standing point over the current feet, a cost of weight :data:`STILL_WEIGHT` (a fast wave
otherwise sways the body, and the plan's full-dynamics ZMP leaves the soles). Sizes an action does not
state are fitted to the robot first (:func:`fit_actions`).

Objects: an action's ``object`` reference ("the red box") is resolved against the ``scene``
(:func:`ground_actions`, :mod:`tasks.grounding`) before anything is compiled, and each group's
grounded objects learn where the robot stands when the group starts (a ``walk_to`` after a walk
starts from where that walk ended). The horizon check before compiling takes such an action from
the standing stance; the spec's real horizon is checked again at the end.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any, cast

import numpy as np
import pinocchio as pin

from robots import Robot
from tasks.actions import Action, get_action
from tasks.exceptions import BeyondCapability, GroundingError, TaskDefinitionError
from tasks.grounding import Grounded, ground, strip_reference
from tasks.limits import MAX_ACTIONS, MAX_HORIZON, horizon_message
from tasks.primitives import (
    DEFAULT_DT,
    Fragment,
    Stance,
    compile_action,
    get_primitive,
    knot_time,
    nominal_duration,
    standing_geometry,
)
from tasks.primitives.base import fit_defaults
from tasks.primitives.grasp import CARRY_WEIGHT, carry_posture
from tasks.scene import Scene, SceneObject, rotation, slope_objects, stairs_objects
from tasks.specs import (
    CoMBounds,
    CoMTarget,
    Contact,
    FrameTarget,
    Grasp,
    JointTarget,
    Phase,
    Priority,
    StartState,
    TaskSpec,
)
from tasks.terrain import with_surface_friction

STAND_TIME = 0.6  # [s] standing still at the start and at the end
TRANSITION_TIME = 0.3  # [s] standing between two groups of actions
DT_MAX = 0.1  # [s] coarser grids cannot resolve a wave
STILL_WEIGHT = 1e4  # cost weight of the CoM's standing point while only arms or head move [1/m^2]
STILL_TOLERANCE = 0.01  # [m] reported distance of that soft target (not a constraint)
WAYPOINT_WEIGHT = 100.0  # cost weight of each joint's standing angle at a transition [1/rad^2]

PART_WORDS = {"legs": "the legs", "com": "the centre of mass", "torso": "the torso", "head": "the head",
              "left_arm": "the left arm", "right_arm": "the right arm"}


def group_actions(actions: Sequence[Action]) -> list[list[tuple[int, Action]]]:
    """Split actions into groups: an action followed by its overlays, with 0-based indices."""
    groups: list[list[tuple[int, Action]]] = []
    for i, a in enumerate(actions):
        if a.overlay:
            if not groups:
                raise TaskDefinitionError(
                    f"action 1 ({a.name}) is an overlay but nothing runs before it; "
                    "an overlay runs alongside the previous action"
                )
            groups[-1].append((i, a))
        else:
            groups.append([(i, a)])
    return groups


def _as_action(a: Action | Mapping[str, Any], i: int) -> Action:
    if isinstance(a, Action):
        return a
    if isinstance(a, Mapping):
        return Action.from_dict(a)
    raise TaskDefinitionError(f"action {i + 1}: expected an Action or an action object, got {a!r}")


def _where(i: int, action: Action, n: int) -> str:
    return f"action {i + 1} ({action.name}): " if n > 1 else ""


def _check_parts(group: list[tuple[int, Action]]) -> None:
    seen: dict[str, tuple[int, Action]] = {}
    for i, a in group:
        for part in sorted(get_primitive(a.name).parts(dict(a.params))):
            if part in seen:
                j, b = seen[part]
                raise TaskDefinitionError(
                    f"action {i + 1} ({a.name}) cannot run at the same time as action {j + 1} ({b.name}): "
                    f"both drive {PART_WORDS.get(part, part)}; run them one after the other (\"then\")"
                )
            seen[part] = (i, a)


def _stand_phase(name: str, duration: float, robot: Robot, stance: Stance, seated: tuple[Contact, ...] = ()) -> Phase:
    """Both soles down, plus the contacts an action left held (``seated``: the thighs on a seat)."""
    contacts = tuple(Contact(frame=robot.frame(f"{s}_foot"), placement=stance.sole(s)) for s in ("left", "right"))
    return Phase(name=name, duration=duration, contacts=contacts + seated)


def standing_waypoint(robot: Robot, label: str, time: float, *, weight: float = WAYPOINT_WEIGHT) -> tuple[JointTarget, ...]:
    """Joint targets (costs) that bring every one-dof joint to its standing angle at ``time``.

    The standing posture is defined by joint angles, so the waypoint holds wherever the feet
    are (after a turn too); the base follows from the stance contacts.
    """
    model = robot.model
    out = []
    for j in range(2, model.njoints):
        joint = model.joints[j]
        if joint.nv != 1:
            continue
        out.append(JointTarget(name=f"{label}: {model.names[j]} at standing", joint=model.names[j],
                               value=float(robot.q_standing[joint.idx_q]), time=time, weight=weight))
    return tuple(out)


def _check_arguments(actions: Sequence[Action | Mapping[str, Any]], dt: float, stand_time: float,
                     transition_time: float) -> None:
    """:func:`compile_actions`' numbers and action count in range, else a TaskDefinitionError."""
    if not (isinstance(dt, (int, float)) and 0.005 <= dt <= DT_MAX):
        raise TaskDefinitionError(f"dt must be in [0.005, {DT_MAX:g}] s, got {dt!r}")
    for what, value in (("stand_time", stand_time), ("transition_time", transition_time)):
        if not (isinstance(value, (int, float)) and 0.0 <= value <= 10.0):
            raise TaskDefinitionError(f"{what} must be in [0, 10] s, got {value!r}")
    if len(actions) > MAX_ACTIONS:
        raise TaskDefinitionError(
            f"{len(actions)} actions; wbmp plans at most {MAX_ACTIONS} actions at a time: split the instruction "
            "into several shorter ones"
        )


def _compile_group(group: list[tuple[int, Action]], fragments: list[Fragment], robot: Robot, stance: Stance,
                   t0: float, dt: float, n: int) -> tuple[list[Fragment], Fragment]:
    """The fragments of one group of overlaid actions starting at ``t0`` [s] from ``stance``, and
    the one whose phases the group plays (the one that changes the feet's contacts, else the first);
    ``fragments``: those of the groups before, ``n``: the number of actions.

    Raises:
        TaskDefinitionError: the group's actions cannot run together (the message says why).
    """
    placed = [(i, _holding_hand(_standing_at(a, stance), fragments, robot)) for i, a in group]
    for i, a in placed:
        _check_carried(a, fragments, _where(i, a, n))
    _check_parts(placed)
    length = _group_duration(placed, robot, n)
    group_fragments = []
    for i, a in placed:
        try:
            group_fragments.append(compile_action(a, robot, t0=t0, dt=dt, duration=length,
                                                  stance=stance, label=f"{i + 1} {a.name}"))
        except TaskDefinitionError as e:
            raise type(e)(f"{_where(i, a, n)}{e}") from None
    movers = [f for f in group_fragments if f.changes_contacts]
    if len(movers) > 1:
        a, b = movers[0].action, movers[1].action
        raise TaskDefinitionError(f"{a.name} and {b.name} both change the feet's contacts; run them one after the other")
    owner = movers[0] if movers else group_fragments[0]
    if len(placed) > 1 and owner.end_stance != stance:
        others = ", ".join(f.action.name for f in group_fragments if f is not owner)
        raise TaskDefinitionError(
            f"{others} cannot run while {owner.action.name} moves the feet (its targets are fixed "
            f"where the robot stands); run them one after the other (\"then\")"
        )
    return group_fragments, owner


def compile_actions(
    actions: Sequence[Action | Mapping[str, Any]],
    robot: Robot,
    *,
    dt: float = DEFAULT_DT,
    stand_time: float = STAND_TIME,
    transition_time: float = TRANSITION_TIME,
    name: str = "",
    description: str = "",
    scene: Scene | None = None,
    start: StartState | None = None,
    fitted: bool = False,
) -> TaskSpec:
    """Compile a sequence of actions (with overlays) into one TaskSpec for ``robot``.

    Args:
        actions: Actions in order (``Action`` or their dictionary form); ``overlay=True`` runs an
            action alongside the previous one.
        robot: The robot; every target is computed from its standing posture.
        dt: Knot spacing [s] of the spec; every phase boundary and target time is a knot.
        stand_time: Standing still at the start and at the end [s] (rounded up to knots).
        transition_time: Standing between consecutive groups [s] (rounded up to knots; 0 = none).
        name: Spec name (default: the action names joined by ``", then "``).
        description: Free text (e.g. the sentence the actions came from).
        scene: The objects around the robot: an action's ``object`` reference (``walk to the
            table``) is resolved against it (:func:`ground_actions`), and the spec carries it.
        start: Where the robot stands at rest when the motion starts (where the motion before it
            ended); None: the standing posture with its feet centred on x = y = 0. The actions'
            targets follow the stance of its soles, and the spec carries it.
        fitted: The actions come from :func:`fit_actions` for this robot: not fitted again.

    Returns:
        The TaskSpec, whose horizon is the sum of the stand, action and transition times.

    Raises:
        TaskDefinitionError: no action or more than :data:`tasks.limits.MAX_ACTIONS`, an overlay
            first, two overlaid actions driving the same body part, a parameter beyond the robot's
            limits, a primitive not available yet, or a motion longer than
            :data:`tasks.limits.MAX_HORIZON`; the message names the action (``action 2 (squat): ...``)
            when there are several.
        GroundingError: an object reference without a scene, or that names no object or several.
    """
    _check_arguments(actions, dt, stand_time, transition_time)
    given = [_as_action(a, i) for i, a in enumerate(actions)]
    checked = pick_up_first(ground_actions(given if fitted else fit_actions(given, robot), scene), robot)
    if not checked:
        raise TaskDefinitionError("no action to compile; give at least one action")
    n = len(checked)
    groups = group_actions(checked)

    def knots(seconds: float) -> int:
        return int(-(-round(seconds / dt, 6) // 1))  # ceil, robust to 0.6/0.075 = 7.999999

    stance = Stance.standing(robot) if start is None else Stance.at(robot, start.q)
    _check_horizon(groups, robot, n, dt, knots(stand_time), knots(transition_time), stance)
    phases: list[Phase] = []
    waypoints: list[JointTarget] = []
    k = 0
    if knots(stand_time):
        phases.append(_stand_phase("stand", knot_time(knots(stand_time), dt), robot, stance))
        k += knots(stand_time)
        waypoints.extend(standing_waypoint(robot, "start", knot_time(k, dt)))
    fragments: list[Fragment] = []
    still_targets: list[CoMTarget] = []
    seated: tuple[Contact, ...] = ()  # contacts an action left held (sitting): no standing waypoints then
    for gi, group in enumerate(groups):
        if gi > 0 and knots(transition_time):
            n_tr = knots(transition_time)
            phases.append(_stand_phase("transition", knot_time(n_tr, dt), robot, stance, seated))
            if not seated:
                waypoints.extend(standing_waypoint(robot, f"transition {gi}", knot_time(k + n_tr // 2, dt)))
            k += n_tr
        group_fragments, owner = _compile_group(group, fragments, robot, stance, knot_time(k, dt), dt, n)
        still = _still_com(group_fragments, robot, stance, knot_time(k, dt), knot_time(k + round(owner.duration / dt), dt))
        phases.extend(owner.phases)
        k += round(owner.duration / dt)
        stance = owner.end_stance
        seated = owner.end_contacts
        fragments.extend(group_fragments)
        still_targets.extend(still)
    if knots(stand_time):
        if not seated:
            waypoints.extend(standing_waypoint(robot, "stand", knot_time(k, dt)))
        phases.append(_stand_phase("stand", knot_time(knots(stand_time), dt), robot, stance, seated))
        k += knots(stand_time)
    if not seated:
        waypoints.extend(standing_waypoint(robot, "end", knot_time(k, dt)))
    horizon = k * dt
    if horizon > MAX_HORIZON + 1e-9:
        raise TaskDefinitionError(horizon_message(horizon, "split the instruction into several shorter ones"))
    return _spec(robot, phases, fragments, still_targets, waypoints, k * dt, dt=dt,
                 name=name or describe_actions(checked), description=description, scene=scene, start=start)


def _spec(robot: Robot, phases: list[Phase], fragments: list[Fragment], still_targets: list[CoMTarget],
          waypoints: list[JointTarget], horizon: float, *, dt: float, name: str, description: str,
          scene: Scene | None, start: StartState | None) -> TaskSpec:
    """The TaskSpec of the compiled phases and fragments (``horizon`` [s])."""
    margin = standing_geometry(robot).support_margin
    bounds = (CoMBounds(name="balance", support_polygon=True, margin=margin),)
    grasps = _grasps(fragments, horizon)
    return TaskSpec(
        robot=robot.name,
        phases=with_surface_friction(phases, scene, robot.profile.friction_coefficient, robot.name),
        targets=_held_targets(fragments, horizon),
        com_targets=tuple(t for f in fragments for t in f.com_targets) + tuple(still_targets),
        com_bounds=bounds + tuple(b for f in fragments for b in f.com_bounds),
        joint_targets=tuple(t for f in fragments for t in f.joint_targets) + _not_holding(waypoints, grasps, robot, horizon)
        + _carrying(fragments, grasps, robot, horizon),
        dt=dt,
        dynamic=any(f.dynamic for f in fragments),
        name=name,
        description=description,
        scene=scene,
        grasps=grasps,
        pushes=tuple(p for f in fragments for p in f.pushes),
        start=start,
    )

def _held_targets(fragments: list[Fragment], horizon: float) -> tuple[FrameTarget, ...]:
    """The fragments' targets; a held one (``Fragment.holds``: a hand holding an object up) keeps
    its window open until the next action that drives one of the fragment's parts or moves the feet,
    or the end of the motion."""
    out = []
    for f in fragments:
        later = [g.t0 for g in fragments if g.t0 >= f.t_end - 1e-9 and g is not f
                 and (g.changes_contacts or g.parts & (f.parts - {"torso"}))]
        until = min(later, default=horizon)
        for t in f.targets:
            if t.name in f.holds and t.window is not None and until > t.window[1]:
                t = dataclasses.replace(t, window=(t.window[0], round(until, 9)))
            out.append(t)
    return tuple(out)


def _not_holding(waypoints: list[JointTarget], grasps: tuple[Grasp, ...], robot: Robot,
                 horizon: float) -> tuple[JointTarget, ...]:
    """The standing waypoints without those of the joints (torso and arm) that carry a held object
    at their time: standing angles there would drag the whole body under the held hand."""
    model = robot.model
    held: list[tuple[float, float, set[str]]] = []
    for g in grasps:
        joint = model.frames[robot.frame_id(g.frame)].parentJoint
        names = {model.names[j] for j in model.supports[joint] if j > 1}
        held.append((g.start, horizon if g.end is None else g.end, names))
    return tuple(w for w in waypoints
                 if not any(s - 1e-9 <= (w.time or 0.0) <= e + 1e-9 and w.joint in names for s, e, names in held))


def _carrying(fragments: list[Fragment], grasps: tuple[Grasp, ...], robot: Robot,
              horizon: float) -> tuple[JointTarget, ...]:
    """A held object is carried while the feet move: from the start of each action that moves the
    feet while a hand holds it, until the next action that drives that arm (or the release, or the
    end), the torso and arm joints that carry it keep the angles that hold the hand where it lifted
    the object relative to the body (:func:`tasks.primitives.grasp.carry_posture`, costs of weight
    ``CARRY_WEIGHT``): the hand, and the object, move with the body."""
    out: list[JointTarget] = []
    sides = {robot.frame(f"{s}_hand"): s for s in ("left", "right") if robot.has_role(f"{s}_hand")}
    for f in fragments:
        for fg in f.grasps:
            g = next((h for h in grasps if h.name == fg.name), None)
            if g is None:
                continue
            held = [t for t in f.targets if t.name in f.holds and t.position is not None and t.rpy is not None
                    and t.frame == g.frame]
            if not held or g.frame not in sides:
                continue
            end = horizon if g.end is None else g.end
            movers = [m for m in fragments if m.changes_contacts and m.t0 >= f.t_end - 1e-9 and m.t0 < end - 1e-9]
            if not movers:
                continue
            t = held[0]
            hand = pin.SE3(pin.rpy.rpyToMatrix(*cast(tuple, t.rpy)), np.asarray(t.position, dtype=float))
            try:
                angles = carry_posture(robot, sides[g.frame], f.end_stance.transform_from_standing(robot).inverse() * hand)
            except TaskDefinitionError as e:
                raise TaskDefinitionError(f"{f.action.name}: {e}") from None
            arm = f.parts - {"torso"}
            for m in movers:
                later = [n.t0 for n in fragments if n.t0 >= m.t_end - 1e-9 and n.parts & arm]
                until = min([*later, end])
                named = {t.name for t in out}
                for joint, value in angles.items():
                    target = JointTarget(name=f"{m.label}: carry the {g.object}: {joint}", joint=joint, value=value,
                                         window=(m.t0, round(until, 9)), weight=CARRY_WEIGHT)
                    if target.name not in named:  # both hands: the torso's angles come from the first
                        out.append(target)
    return tuple(out)


def _grasps(fragments: list[Fragment], horizon: float) -> tuple[Grasp, ...]:
    """The fragments' grasps; a release (``put_down``: a grasp with a ``place``) closes the grasp
    that holds its object, a hand-over (a grasp with an ``offer``) writes its point into it
    (TaskDefinitionError when none does, or another hand holds it)."""
    out: list[Grasp] = []
    for f in fragments:
        for g in f.grasps:
            if g.place is None and g.offer is None:
                out.append(g)
                continue
            holders = [i for i, h in enumerate(out) if h.object == g.object and h.end is None]
            held = next((i for i in holders if out[i].frame == g.frame), holders[0] if holders else None)
            if held is None:
                then = "hand it to me" if g.offer is not None else "put it down"
                raise TaskDefinitionError(f"{f.action.name}: no hand holds the {g.object}; pick it up first "
                                          f'("pick up the {g.object}, then {then}")')
            if out[held].frame != g.frame:
                raise TaskDefinitionError(f"{f.action.name}: the {g.object} is in the other hand")
            if g.offer is not None:  # hand_over: the same grasp, held out at a point
                out[held] = dataclasses.replace(out[held], offer=g.offer, offer_window=g.offer_window)
            else:
                out[held] = dataclasses.replace(out[held], end=g.end, place=g.place)
    return tuple(out)


HOLDING_ACTIONS = ("put_down", "hand_over")  # actions on the object a hand holds: their "it" is the held one
PRONOUNS = frozenset({"it", "this", "that", "this one", "that one", "它", "这个", "那个"})  # the object said before


def ground_actions(actions: Sequence[Action], scene: Scene | None) -> list[Action]:
    """The actions with every ``object`` reference resolved against ``scene``
    (:class:`tasks.grounding.Grounded`; an action without one is kept as it is). A pronoun
    (:data:`PRONOUNS`: "walk to the box and touch **it**") names the object said before it.

    Raises:
        GroundingError: a reference and no scene, or one that names no object or several; the
            message names the action when there are several (``action 2 (point_at): ...``).
    """
    out: list[Action] = []
    last: SceneObject | None = None  # the object said before: what "it" names
    held: SceneObject | None = None  # the object picked up last: what a put_down's "it" names
    for i, a in enumerate(actions):
        if a.name == "stand" and out and out[-1].name == "sit_down":  # "sit down, then stand up": rise first
            a = Action(name="stand_up", params={}, overlay=a.overlay)
        if a.name == "stand" and out and out[-1].name == "kneel" and set(a.params) <= set(a.defaulted):
            continue  # "kneel down, then get up": the kneel's own rise (it always comes back up)
        if a.name in SEAT_ACTIONS:
            a = _seated(a, scene, out[-1] if out else None, _where(i, a, len(actions)))
        if a.name == "lean_on":
            a = _table(a, scene, _where(i, a, len(actions)))
        if a.name in CLIMB_ACTIONS:
            a = _climbed(a, scene, _where(i, a, len(actions)))
        refs = {k: v for k, v in a.params.items() if get_action(a.name).param(k).kind == "object" and v is not None}
        if not refs:
            out.append(a)
            continue
        params = dict(a.params)
        for key, ref in refs.items():
            if isinstance(ref, Grounded):
                last = ref.obj
                continue
            try:
                if isinstance(ref, str) and strip_reference(ref).lower() in PRONOUNS and scene is not None:
                    if last is None:
                        raise GroundingError(f'"{strip_reference(ref)}" names the object said before, but none was: '
                                             'name it ("touch the box")', strip_reference(ref))
                    from_hand = (key == "object" and a.name in HOLDING_ACTIONS) or key == "carrying"
                    obj = held if from_hand and held is not None else last
                else:
                    obj = ground(ref, scene, action=a.name)
                if obj is not held or a.name not in HOLDING_ACTIONS:
                    last = obj
                if a.name == "pick_up" and key == "object":
                    held = obj
            except GroundingError as e:
                where = _where(i, a, len(actions))
                raise GroundingError(f"{where}{e}", e.reference, e.candidates) from None
            params[key] = Grounded(reference=strip_reference(ref), obj=obj, scene=cast(Scene, scene))  # ground() raised without one
        out.append(Action(name=a.name, params=params, overlay=a.overlay, defaulted=a.defaulted))
    return out


SEAT_ACTIONS = ("sit_down", "stand_up")


def _seated(a: Action, scene: Scene | None, before: Action | None, where: str) -> Action:
    """``sit_down``/``stand_up`` with their seat: the one said, the scene's seat, or the one sat on
    (BeyondCapability: no seat in the scene, one said that is no seat, a stand_up not after a sit_down)."""
    if a.name == "stand_up":
        if before is None or before.name != "sit_down":
            raise BeyondCapability(f'{where}stand up: the robot is not sitting; say "sit down, then stand up" '
                                   "(a motion starts standing)")
        if a.params.get("object") is None:
            return Action(name=a.name, params={**a.params, "object": before.params["object"]}, overlay=a.overlay,
                          defaulted=a.defaulted)
        return a
    seats = [o for o in (scene.objects if scene is not None else ()) if o.seat]
    said = a.params.get("object")
    if said is None:
        if not seats:
            raise BeyondCapability(f"{where}sit down: there is no seat in the scene (a chair or a bench: an object "
                                   'with "seat": true); give a scene with one, e.g. --scene examples/scenes/chair.json')
        return _with_object(a, seats[0], scene)
    if not isinstance(said, Grounded) and scene is not None:
        obj = ground(said, scene, action=a.name)
        if not obj.seat:
            raise BeyondCapability(f"{where}sit down: the {obj.name} is not a seat (give the scene a chair or a "
                                   'bench: an object with "seat": true)')
    return a


def _table(a: Action, scene: Scene | None, where: str) -> Action:
    """``lean_on`` with its table: the one said, or the scene's static upright box (not a seat, not a
    walkable tread) nearest the origin (BeyondCapability: none; the primitive checks the reach)."""
    if a.params.get("object") is not None:
        return a
    tables = sorted((o for o in (scene.objects if scene is not None else ()) if o.shape == "box" and not o.movable
                     and not o.seat and not o.walkable and np.asarray(rotation(o.rpy))[2, 2] > 0.996),
                    key=lambda o: float(np.hypot(o.position[0], o.position[1])))
    if not tables:
        raise BeyondCapability(f"{where}lean on: there is no table in the scene (a static box with a top to lean on); "
                               "give a scene with one, e.g. --scene examples/scenes/table.json")
    return _with_object(a, tables[0], scene)


CLIMB_ACTIONS = ("step_up", "step_down")


def _climbed(a: Action, scene: Scene | None, where: str) -> Action:
    """``step_up``/``step_down`` with what they climb: the object said, or the scene's one flight of
    stairs or slope ("walk up the three steps", "go down two steps": the surfaces, not the steps'
    word) (BeyondCapability: no stairs or slope; GroundingError: several, name one)."""
    if a.params.get("object") is not None:
        return a
    verb = a.name.replace("_", " ")
    if scene is None:
        raise GroundingError(f"{where}{verb}: there is nothing to climb without a scene; give one with stairs or a "
                             "slope, e.g. --scene examples/scenes/stairs.json", verb)
    flights = [stairs_objects(st)[0] for st in scene.stairs] + [slope_objects(sl)[0] for sl in scene.slopes]
    if not flights:
        raise BeyondCapability(f"{where}{verb}: the scene has no stairs or slope; name what to climb "
                               '("step onto the box") or give a scene with some, e.g. --scene examples/scenes/stairs.json')
    if len(flights) > 1:
        names = ", ".join(f.name.split(".")[0] for f in flights)
        raise GroundingError(f'{where}{verb}: the scene has several to climb ({names}): name one ("{verb} the '
                             f'{flights[0].name.split(".")[0]}")', verb, tuple(f.name for f in flights))
    return _with_object(a, flights[0], scene)


def _with_object(a: Action, obj: SceneObject, scene: Scene | None) -> Action:
    """``a`` with its ``object`` grounded to ``obj`` of ``scene`` (an object the sentence left unsaid)."""
    return Action(name=a.name, params={**a.params, "object": Grounded(reference=obj.name, obj=obj,
                                                                     scene=cast(Scene, scene))},
                  overlay=a.overlay, defaulted=a.defaulted)


def pick_up_first(actions: Sequence[Action], robot: Robot) -> list[Action]:
    """The actions with a ``pick_up`` of the same object (and hand, when stated) before each
    ``hand_over`` of an object no earlier action picked up (and no put_down let go of since):
    "hand me the cup" is "pick up the cup, then hand it over"."""
    out: list[Action] = []
    held: set[str] = set()
    for a in actions:
        g = a.params.get("object")
        if isinstance(g, Grounded):
            if a.name == "pick_up":
                held.add(g.obj.name)
            elif a.name == "put_down":
                held.discard(g.obj.name)
            elif a.name == "hand_over" and g.obj.name not in held and g.obj.movable:
                pick = Action(name="pick_up", params={"object": g, "arm": a.params.get("arm")}, overlay=a.overlay)
                out.append(fit_defaults(get_primitive("pick_up"), pick, robot))
                a = Action(name=a.name, params=a.params, defaulted=a.defaulted)
                held.add(g.obj.name)
        out.append(a)
    return out


def _holding_hand(action: Action, fragments: list[Fragment], robot: Robot) -> Action:
    """A put_down without a hand takes the hand that holds its object (after a walk the object's
    side of the body is no guide)."""
    g = action.params.get("object")
    if action.name not in HOLDING_ACTIONS or action.params.get("arm") or not isinstance(g, Grounded):
        return action
    frames = {robot.frame(f"{s}_hand"): s for s in ("left", "right") if robot.has_role(f"{s}_hand")}
    held = [gr for f in fragments for gr in f.grasps if gr.object == g.obj.name]
    if not held or held[-1].place is not None or held[-1].frame not in frames:
        return action
    both = len(held) > 1 and held[-2].start == held[-1].start and held[-2].place is None
    if both and action.name != "put_down":
        raise TaskDefinitionError(f"{action.name}: the {g.obj.name} is held with both hands; handing it over with both "
                                  "hands is not supported yet")
    return Action(name=action.name, params={**action.params, "arm": "both" if both else frames[held[-1].frame]},
                  overlay=action.overlay, defaulted=action.defaulted)


def _check_carried(action: Action, fragments: list[Fragment], where: str) -> None:
    """An object said to be carried ("walk to the table with the cup") must be in a hand already."""
    g = action.params.get("carrying")
    if not isinstance(g, Grounded):
        return
    held = [gr for f in fragments for gr in f.grasps if gr.object == g.obj.name]
    if not held or held[-1].place is not None:
        raise TaskDefinitionError(f'{where}no hand holds the {g.obj.name} to carry; pick it up first ("pick up the '
                                  f'{g.obj.name}, then {action.name.replace("_", " ")} {action.params["object"]} with it")')


def _standing_at(action: Action, stance: Stance) -> Action:
    """``action`` with its grounded objects told where the robot stands when it starts."""
    params = dict(action.params)
    changed = False
    for key, value in params.items():
        if isinstance(value, Grounded) and value.start != stance:
            params[key] = dataclasses.replace(value, start=stance)
            changed = True
    if not changed:
        return action
    return Action(name=action.name, params=params, overlay=action.overlay, defaulted=action.defaulted)


def _still_com(fragments: list[Fragment], robot: Robot, stance: Stance, t0: float, t1: float) -> list[CoMTarget]:
    """A group whose actions leave the CoM alone keeps it where it is when standing (a SOFT
    :class:`CoMTarget` of weight :data:`STILL_WEIGHT` on its ground projection over the window).

    Without it the planner sways the whole body to spread a fast arm motion over more joints: on
    talos a wave swung the CoM ±2.5 cm sideways at the wave's 1.25 Hz, and its full-dynamics ZMP
    (``c - z c''/g`` alone is ±0.14 m) left the soles by 0.16 m (kinematic) or 0.10 m (with the
    centroidal dynamics, after a walk); the controller could not always follow (left sole slipped
    2.4 cm). A cost, not a bound: raising both arms after a walk with a hard ±5 mm (or ±1 cm) box
    made IPOPT stop at its iteration limit.
    """
    if any("com" in f.parts for f in fragments):
        return []  # squat, lean, bow, balance, steps, jump: the action moves the CoM itself
    home = stance.transform_from_standing(robot).act(standing_geometry(robot).com)
    return [CoMTarget(name=f"{fragments[0].label}: CoM still", position=(float(home[0]), float(home[1]), None), window=(t0, t1),
                      priority=Priority.SOFT, weight=STILL_WEIGHT, tolerance=STILL_TOLERANCE)]


def fit_actions(actions: Sequence[Action], robot: Robot) -> list[Action]:
    """The actions with every size they do not state chosen within ``robot``'s limits.

    A default (``Action.defaulted``) beyond the robot's limit becomes the limit, rounded down to
    1 cm or 0.01 rad (:func:`tasks.primitives.base.fit_defaults`); stated values are kept, so one
    beyond the limit is still refused by :func:`compile_actions`, naming the limit.
    """
    return [fit_defaults(get_primitive(a.name), a, robot) for a in actions]


def _group_duration(group: list[tuple[int, Action]], robot: Robot, n: int, placed: bool = True) -> float:
    """Duration [s] of a group of actions played together: its longest action's nominal one. Not
    ``placed`` (a later group: where the robot will stand is not known yet), an action about a scene
    object that cannot be measured from the standing stance counts 0 s (its compilation decides)."""
    durations = [0.0]
    for i, a in group:
        try:
            durations.append(nominal_duration(a, robot))
        except TaskDefinitionError as e:
            if not placed and any(isinstance(v, Grounded) for v in a.params.values()):
                continue
            raise type(e)(f"{_where(i, a, n)}{e}") from None
    return max(durations)


def _check_horizon(groups: list[list[tuple[int, Action]]], robot: Robot, n: int, dt: float, stand_knots: int,
                   transition_knots: int, stance: Stance) -> None:
    """Refuse a motion longer than MAX_HORIZON before compiling any action (same knot rounding); the
    first group's grounded objects know where the robot starts (a descent from a tread)."""
    k = 2 * stand_knots + transition_knots * (len(groups) - 1)
    for j, group in enumerate(groups):
        if j == 0:
            group = [(i, _standing_at(a, stance)) for i, a in group]
        k += int(-(-round(_group_duration(group, robot, n, placed=j == 0) / dt, 6) // 1))
    if k * dt > MAX_HORIZON + 1e-9:
        raise TaskDefinitionError(horizon_message(k * dt, "split the instruction into several shorter ones"))


def describe_actions(actions: Sequence[Action]) -> str:
    """A short text of an action list: ``"wave, then squat while wave"``."""
    out = ""
    for i, a in enumerate(actions):
        if i == 0:
            out = a.name
        elif a.overlay:
            out += f" while {a.name}"
        else:
            out += f", then {a.name}"
    return out


__all__ = ["STAND_TIME", "TRANSITION_TIME", "compile_actions", "describe_actions", "fit_actions", "ground_actions",
           "group_actions", "pick_up_first"]
