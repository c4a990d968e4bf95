"""Does a spec apply to a robot? Checked before any solver is built (exit 3, not 4).

A :class:`~tasks.specs.TaskSpec` is valid on its own; :func:`check_spec_for_robot` checks what
needs the robot: every frame it names exists, every joint target names a one-dof joint, no
contact is placed below the ground, and the first phase's contacts are where the robot stands
(the motion starts at rest from the spec's start state, else the standing posture). Each error is a
:class:`~tasks.exceptions.TaskDefinitionError` naming the field (``spec.joint_targets[0].joint``)
and how to fix it; the CLI maps it to exit code 3 (invalid spec).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from robots import FrameNotFound, Robot
from tasks.exceptions import TaskDefinitionError
from tasks.limits import GROUND_TOLERANCE, START_TOLERANCE
from tasks.scene import SCENE_MARGIN, check_spec_in_scene
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

    :func:`tasks.scene.check_spec_in_scene` with the robot's sole corners for every contact on
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
    for frame in {*spec.contact_frames(), *(t.frame for t in spec.targets)}:
        side_part = roles.get(robot.frame_id(frame))
        if side_part is None:
            continue
        labels[frame] = f"{side_part[0]} {side_part[1]}"
        if side_part[1] == "foot":
            points[frame] = sole_corners(robot.profile.sole, side_part[0])
    check_spec_in_scene(spec, margin=margin, contact_points=points, labels=labels)


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
