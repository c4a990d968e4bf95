"""Task specifications and the motion primitives that produce them.

``tasks.specs`` holds the data types (:class:`TaskSpec`, :class:`Phase`, :class:`Contact`,
:class:`FrameTarget`, :class:`CoMTarget`, :class:`CoMBounds`, :class:`JointTarget`);
``tasks.scene`` the world around the robot (:class:`Scene`, :class:`SceneObject`, scene files);
``tasks.serialize`` their exact JSON round-trip; ``tasks.compose.compile_actions`` turns
registry actions into one spec (imported on first access: it loads the primitive registry).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from robots.lazy import lazy_face
from tasks.exceptions import SceneConflict, TaskDefinitionError, TaskError, UnknownAction
from tasks.scene import Scene, SceneObject, load_scene
from tasks.serialize import load_spec, spec_from_dict, spec_from_json, spec_to_dict, spec_to_json
from tasks.specs import (
    CoMBounds,
    CoMTarget,
    Contact,
    FrameTarget,
    Grasp,
    HandTarget,
    JointTarget,
    Phase,
    Pose,
    Priority,
    StartState,
    TaskSpec,
)

if TYPE_CHECKING:
    from tasks.actions import Action
    from tasks.compose import compile_actions, fit_actions
    from tasks.robot_check import check_spec_for_robot, check_spec_in_scene_for_robot
    from tasks.terrain import surface_at

_LAZY = {  # public name -> module
    "Action": "tasks.actions",
    "check_spec_for_robot": "tasks.robot_check",
    "check_spec_in_scene_for_robot": "tasks.robot_check",
    "compile_actions": "tasks.compose",
    "fit_actions": "tasks.compose",
    "surface_at": "tasks.terrain",
}

__all__ = [
    "Action",
    "CoMBounds",
    "CoMTarget",
    "Contact",
    "FrameTarget",
    "Grasp",
    "HandTarget",
    "JointTarget",
    "Phase",
    "Pose",
    "Priority",
    "Scene",
    "SceneConflict",
    "SceneObject",
    "StartState",
    "TaskDefinitionError",
    "TaskError",
    "TaskSpec",
    "UnknownAction",
    "check_spec_for_robot",
    "check_spec_in_scene_for_robot",
    "compile_actions",
    "fit_actions",
    "load_scene",
    "load_spec",
    "spec_from_dict",
    "spec_from_json",
    "spec_to_dict",
    "spec_to_json",
    "surface_at",
]


__getattr__, __dir__ = lazy_face(__name__, _LAZY)
