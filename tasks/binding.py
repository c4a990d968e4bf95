"""Where a spec meets a robot: :func:`bind`, the one step that resolves the frames a spec names.

A :class:`~tasks.specs.TaskSpec` may name a frame by the robot's frame name
(``left_sole_link``) or by a role of its profile (``left_foot``, ``right_hand``; docs/robots.md).
:func:`bind` checks the spec against the robot (:func:`tasks.robot_check.check_spec_for_robot`:
frames and joints exist, contacts on the ground, the start where the robot stands), resolves
every role to the robot's frame name, and checks the resolved spec in its scene
(:func:`tasks.robot_check.check_spec_in_scene_for_robot`). What comes out names only frames of
that robot, so nothing after it (the planner, the simulation, the certificate, the viewers)
resolves a role again. A spec that already names frames comes back as the same object (its
cache keys unchanged).
"""

from __future__ import annotations

import dataclasses
from typing import Any

from robots import FrameNotFound, Robot
from tasks.exceptions import TaskDefinitionError
from tasks.robot_check import check_spec_for_robot, check_spec_in_scene_for_robot
from tasks.specs import TaskSpec


def bind(spec: TaskSpec, robot: Robot) -> TaskSpec:
    """``spec`` checked on ``robot`` and with every frame it names given as the robot's frame name.

    Raises:
        TaskDefinitionError: A frame, a role or a joint the robot lacks, a contact below the
            ground, a start away from where the robot stands (the field is named; exit 3).
        SceneConflict: A hand target or a footstep inside a scene object (exit 4).
    """
    check_spec_for_robot(spec, robot)
    bound = resolve_frames(spec, robot)
    check_spec_in_scene_for_robot(bound, robot)
    return bound


def resolve_frames(spec: TaskSpec, robot: Robot) -> TaskSpec:
    """``spec`` with each role it names (``left_foot``) replaced by the robot's frame name; the
    same object when it names no role. Frames are taken as checked (:func:`bind` checks first)."""
    names = robot.model.frames

    def name(frame: str, where: str) -> str:
        try:
            return names[robot.frame_id(frame)].name
        except FrameNotFound as e:
            raise TaskDefinitionError(f"{where}: {e}") from None

    def each(items: tuple[Any, ...], fields: tuple[str, ...], where: str) -> tuple[Any, ...]:
        out = []
        for i, item in enumerate(items):
            changes = {f: name(getattr(item, f), f"{where}[{i}].{f}") for f in fields if getattr(item, f) is not None}
            changes = {f: v for f, v in changes.items() if v != getattr(item, f)}
            out.append(dataclasses.replace(item, **changes) if changes else item)
        return tuple(out)

    phases = tuple(p if (c := each(p.contacts, ("frame",), f"spec.phases[{i}].contacts")) == p.contacts
                   else dataclasses.replace(p, contacts=c) for i, p in enumerate(spec.phases))
    changes: dict[str, Any] = {"phases": phases, "targets": each(spec.targets, ("frame", "meets"), "spec.targets"),
               "grasps": each(spec.grasps, ("frame",), "spec.grasps"),
               "pushes": each(spec.pushes, ("frame",), "spec.pushes")}
    changes = {k: v for k, v in changes.items() if any(a is not b for a, b in zip(v, getattr(spec, k), strict=True))}
    return dataclasses.replace(spec, **changes) if changes else spec
