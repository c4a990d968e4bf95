"""Does a spec apply to a robot? Checked before any solver is built (exit 3, not 4).

A :class:`~tasks.specs.TaskSpec` is valid on its own; :func:`check_spec_for_robot` checks what
needs the robot: every frame it names exists, every joint target names a one-dof joint, no
contact is placed below the ground, and the first phase's contacts are where the robot stands
(the motion starts at rest from the spec's start state, else the standing posture). Each error is a
:class:`~tasks.exceptions.TaskDefinitionError` naming the field (``spec.joint_targets[0].joint``)
and how to fix it; the CLI maps it to exit code 3 (invalid spec).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import pinocchio as pin

from robots import FrameNotFound, Robot
from tasks.exceptions import SceneConflict, TaskDefinitionError
from tasks.limits import GROUND_TOLERANCE, START_TOLERANCE
from tasks.scene import (
    SCENE_MARGIN,
    Scene,
    _frame_words,
    _point,
    _relation,
    _where,
    closest_object,
    on_top,
    rotation,
    signed_distance,
)
from tasks.specs import TaskSpec


def check_spec_for_robot(spec: TaskSpec, robot: Robot) -> None:
    """Raise :class:`TaskDefinitionError` when ``spec`` cannot apply to ``robot``.

    Checks, in order: contact, target and grasp frames exist on the robot; joint targets name a
    one-dof joint of it; contacts are not below the ground (z >= -``GROUND_TOLERANCE``); the
    first phase's contacts match the standing soles within ``START_TOLERANCE`` (1 mm / 1 mrad).
    """
    model = robot.model
    for i, phase in enumerate(spec.phases):
        for j, contact in enumerate(phase.contacts):
            where = f"spec.phases[{i}].contacts[{j}]"
            _frame_id(robot, contact.frame, f"{where}.frame")
            z = contact.placement.position[2]
            if z < -GROUND_TOLERANCE:
                raise TaskDefinitionError(
                    f"{where}.placement: z = {z:g} m puts contact {contact.frame!r} below the ground (z = 0); "
                    f"a contact is on the ground or above it (at most {GROUND_TOLERANCE:g} m below)"
                )
    for i, target in enumerate(spec.targets):
        _frame_id(robot, target.frame, f"spec.targets[{i}].frame")
    for i, grasp in enumerate(spec.grasps):
        _frame_id(robot, grasp.frame, f"spec.grasps[{i}].frame")
    for i, jt in enumerate(spec.joint_targets):
        where = f"spec.joint_targets[{i}].joint"
        if not model.existJointName(jt.joint):
            names = [n for n in model.names[1:] if model.joints[model.getJointId(n)].nv == 1]
            raise TaskDefinitionError(
                f"{where}: robot {robot.name!r} has no joint {jt.joint!r}{_close(jt.joint, names)}"
            )
        if model.joints[model.getJointId(jt.joint)].nv != 1:
            raise TaskDefinitionError(
                f"{where}: joint {jt.joint!r} of {robot.name} is not a one-dof joint; a joint target sets "
                "one angle"
            )
    _check_start(spec, robot)


def check_spec_in_scene_for_robot(spec: TaskSpec, robot: Robot, *, margin: float = SCENE_MARGIN) -> None:
    """Refuse hand targets and footsteps inside the spec's scene objects, soles included.

    :func:`tasks.robot_check.check_spec_in_scene` with the robot's sole corners for every contact on
    a foot frame: a sole that overlaps an object (within ``margin``) is refused as well as one
    whose frame origin is inside it.

    Raises:
        SceneConflict: naming the object (exit 4, infeasible in that scene).
    """
    if spec.scene is None or not spec.scene.objects:
        return
    from robots import sole_corners

    roles = {robot.frame_id(f"{side}_{part}"): (side, part) for side in ("left", "right") for part in ("foot", "hand")}
    points, labels = {}, {}
    regions = {c.frame for p in spec.phases for c in p.contacts if c.region is not None}
    for frame in {*spec.contact_frames(), *(t.frame for t in spec.targets)}:
        side_part = roles.get(robot.frame_id(frame))
        if side_part is None:
            if frame in regions:  # a knee on the floor: "the right leg's leg_right_4_link placement ... puts it inside"
                labels[frame] = _limb(robot, frame)
            continue
        labels[frame] = f"{side_part[0]} {side_part[1]}"
        if side_part[1] == "foot":
            points[frame] = sole_corners(robot.profile.sole, side_part[0])
    check_spec_in_scene(spec, margin=margin, contact_points=points, labels=labels)


def _limb(robot: Robot, frame: str) -> str:
    """``right leg's leg_right_4_link``: the limb (a foot's or a hand's chain) that holds a frame."""
    model = robot.model
    name = model.frames[robot.frame_id(frame)].name
    joint = model.frames[robot.frame_id(frame)].parentJoint
    for side in ("left", "right"):
        for role, limb in (("foot", "leg"), ("hand", "arm")):
            if robot.has_role(f"{side}_{role}") and joint in model.supports[model.frames[robot.frame_id(f"{side}_{role}")].parentJoint]:
                return f"{side} {limb}'s {name}"
    return name


def _frame_id(robot: Robot, frame: str, where: str) -> int:
    try:
        return robot.frame_id(frame)
    except FrameNotFound as e:
        raise TaskDefinitionError(f"{where}: {e}") from None


def _check_start(spec: TaskSpec, robot: Robot) -> None:
    q = robot.q_standing
    if spec.start is not None:
        nq = robot.model.nq
        if len(spec.start.q) != nq:
            raise TaskDefinitionError(
                f"spec.start.q: {len(spec.start.q)} numbers; {robot.name}'s configuration has {nq} (the base position, "
                f"its quaternion x y z w, then {nq - 7} joint angles in the model's order)")
        q = np.array(spec.start.q, dtype=float)
    first = spec.phases[0]
    if not first.contacts:
        return
    data = robot.data()
    pin.framesForwardKinematics(robot.model, data, q)
    for j, contact in enumerate(first.contacts):
        oMf = data.oMf[robot.frame_id(contact.frame)]
        wanted = pin.SE3(pin.rpy.rpyToMatrix(*contact.placement.rpy), np.array(contact.placement.position, float))
        dp = float(np.linalg.norm(oMf.translation - wanted.translation))
        dr = float(np.linalg.norm(pin.log3(wanted.rotation.T @ oMf.rotation)))
        if dp > START_TOLERANCE or dr > START_TOLERANCE:
            at = ", ".join(_mm(x) for x in oMf.translation)
            rpy = ", ".join(_mm(x) for x in pin.rpy.matrixToRpy(oMf.rotation))
            raise TaskDefinitionError(
                f"spec.phases[0].contacts[{j}]: contact {contact.frame!r} of the first phase {first.name!r} is "
                f"{dp:.3f} m / {dr:.3f} rad away from where {robot.name} stands (position [{at}] m, rpy "
                f"[{rpy}] rad{' in the spec.start state' if spec.start is not None else ''}); the motion starts "
                "there at rest, so the first phase's contacts must be where its feet are"
            )


def _mm(x: float) -> str:
    text = f"{x:.3f}"
    return "0.000" if text == "-0.000" else text


def _close(name: str, names: list[str]) -> str:
    import difflib

    close = difflib.get_close_matches(name, names, n=3, cutoff=0.5)
    return f"; did you mean {', '.join(repr(c) for c in close)}?" if close else ""


__all__ = ["check_spec_for_robot", "check_spec_in_scene_for_robot"]


def check_spec_in_scene(spec: TaskSpec, *, margin: float = SCENE_MARGIN,
                        contact_points: Mapping[str, Any] | None = None,
                        labels: Mapping[str, str] | None = None) -> None:
    """Refuse a spec whose hand targets or footsteps lie inside a scene object (or within ``margin``).

    A frame target's position (every axis counted) closer than ``margin`` to an object (but the one
    it touches, ``touch``), or a
    contact whose placement (and, when ``contact_points`` gives them for its frame, the points
    ``(k, 3)`` in the contact frame, e.g. the sole corners), lifted by ``2 * margin`` along the
    contact normal (the foot above its sole), comes closer than ``margin`` to an object, raises :class:`~tasks.exceptions.SceneConflict` naming the object. A contact whose
    points all lie on the top face of an upright box or cylinder stands on it: a support, not a
    conflict. Meshes are not checked here (the planner keeps the robot clear of them).

    Args:
        spec: The spec, with its scene.
        margin: The planner's clearance [m].
        contact_points: Per contact frame, points in the contact frame [m] (the sole corners).
        labels: Per frame, the words messages use (``right hand``); default: the frame name.

    Raises:
        SceneConflict: message in task terms, ``the right hand target (0.45, -0.2, 0.8) of 'reach' is
            inside the table (...)``; exit code 4 (infeasible).
    """
    scene = spec.scene
    if scene is None or not scene.objects:
        return
    words = dict(labels or {})

    def label(frame: str) -> str:
        return words.get(frame, _frame_words(frame))

    for target in spec.targets:
        if target.position is None or not all(target.axes):
            continue
        others = scene if target.touch is None else Scene(objects=tuple(o for o in scene.objects if o.name != target.touch))
        hit = closest_object(others, target.position)
        if hit is not None and hit[1] < margin:
            obj, d = hit
            raise SceneConflict(
                f"the {label(target.frame)} target {_point(target.position)} of {target.name!r} is {_relation(d)} "
                f"the {obj.name} ({_where(obj)}; the robot keeps {margin:g} m away from objects): move the "
                f"target out of the {obj.name}, or the {obj.name} in the scene", obj.name)
    seen: set[tuple[str, tuple[float, ...], tuple[float, ...]]] = set()
    for phase in spec.phases:
        for contact in phase.contacts:
            key = (contact.frame, contact.placement.position, contact.placement.rpy)
            if key in seen:
                continue
            seen.add(key)
            R = rotation(contact.placement.rpy)
            local: list[tuple[float, ...]] = [(0.0, 0.0, 0.0)]
            if contact_points is not None and contact.frame in contact_points:
                local += [tuple(float(c) for c in p) for p in contact_points[contact.frame]]
            points = [tuple(contact.placement.position[i] + sum(R[i][j] * lp[j] for j in range(3)) for i in range(3))
                      for lp in local]
            # the foot is above its sole: test the sole points lifted by twice the margin along the
            # contact normal (a sole under an object's bottom face is inside it, not "against" it)
            lifted = [tuple(p[i] + 2 * margin * R[i][2] for i in range(3)) for p in points]
            for obj in scene.objects:
                dists = [signed_distance(obj, p) for p in lifted]
                if any(d is None for d in dists):
                    continue
                d = min(x for x in dists if x is not None)
                if d >= margin or all(on_top(obj, p) for p in points):
                    continue
                said = obj.name.split(".")[0]  # a flight's tread stairs.2: "the stairs"; a slope's landing: "the slope"
                fix = (f"climb onto it: 'walk up the {said}' or 'step onto the {said}'"
                       if obj.walkable and contact.region is None else f"move the {obj.name} in the scene")
                raise SceneConflict(
                    f"the {label(contact.frame)} placement {_point(contact.placement.position)} in phase "
                    f"{phase.name!r} puts {'it' if contact.region is not None else 'the sole'} "
                    f"{_relation(d)} the {obj.name} ({_where(obj)}; the robot keeps "
                    f"{margin:g} m away from objects): step elsewhere, or {fix}",
                    obj.name)
