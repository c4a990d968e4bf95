"""Task specifications and the motion primitives that produce them.

``tasks.specs`` holds the data types (:class:`TaskSpec`, :class:`Phase`, :class:`Contact`,
:class:`FrameTarget`, :class:`CoMTarget`, :class:`CoMBounds`, :class:`JointTarget`);
``tasks.scene`` the world around the robot (:class:`Scene`, :class:`SceneObject`, scene files);
``tasks.serialize`` their exact JSON round-trip; ``tasks.compose.compile_actions`` turns
registry actions into one spec (imported on first access: it loads the primitive registry).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from robots import lazy_face
from tasks.exceptions import (
    BeyondCapability,
    ClipError,
    GroundingError,
    SceneConflict,
    TaskDefinitionError,
    TaskError,
    UnknownAction,
)
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
    from tasks.actions import REGISTRY, Action, ActionSchema, actions_json_schema, get_action
    from tasks.binding import bind, resolve_frames
    from tasks.compose import compile_actions, fit_actions
    from tasks.grounding import ground, strip_reference
    from tasks.limits import MAX_ACTIONS, MAX_REPEAT, MAX_TEXT_LENGTH
    from tasks.mocap import (
        human_motion,
        label_contacts,
        load_skeleton,
        read_bvh,
        recognize_skeleton,
    )
    from tasks.mocap.figures import Tracks, contact_windows, motion_figures, torque_cause, tracks
    from tasks.mocap.retarget import retarget_spec
    from tasks.mocap.skeleton import check_joints
    from tasks.mocap.strength import arm_torque_joints
    from tasks.primitives import PRIMITIVES
    from tasks.robot_check import check_spec_for_robot, check_spec_in_scene_for_robot
    from tasks.scene import on_top
    from tasks.specs import Push, Vec3
    from tasks.terrain import surface_at

_LAZY = {  # public name -> module
    "bind": "tasks.binding",
    "resolve_frames": "tasks.binding",
    "Action": "tasks.actions",
    "ActionSchema": "tasks.actions",
    "MAX_ACTIONS": "tasks.limits",
    "MAX_REPEAT": "tasks.limits",
    "MAX_TEXT_LENGTH": "tasks.limits",
    "PRIMITIVES": "tasks.primitives",
    "Push": "tasks.specs",
    "REGISTRY": "tasks.actions",
    "Vec3": "tasks.specs",
    "actions_json_schema": "tasks.actions",
    "arm_torque_joints": "tasks.mocap.strength",
    "check_joints": "tasks.mocap.skeleton",
    "check_spec_for_robot": "tasks.robot_check",
    "check_spec_in_scene_for_robot": "tasks.robot_check",
    "compile_actions": "tasks.compose",
    "contact_windows": "tasks.mocap.figures",
    "fit_actions": "tasks.compose",
    "get_action": "tasks.actions",
    "ground": "tasks.grounding",
    "human_motion": "tasks.mocap",
    "label_contacts": "tasks.mocap",
    "load_skeleton": "tasks.mocap",
    "motion_figures": "tasks.mocap.figures",
    "on_top": "tasks.scene",
    "read_bvh": "tasks.mocap",
    "recognize_skeleton": "tasks.mocap",
    "retarget_spec": "tasks.mocap.retarget",
    "strip_reference": "tasks.grounding",
    "surface_at": "tasks.terrain",
    "torque_cause": "tasks.mocap.figures",
    "tracks": "tasks.mocap.figures",
    "Tracks": "tasks.mocap.figures",
}

__all__ = [
    "MAX_ACTIONS",
    "MAX_REPEAT",
    "MAX_TEXT_LENGTH",
    "PRIMITIVES",
    "REGISTRY",
    "Action",
    "ActionSchema",
    "BeyondCapability",
    "ClipError",
    "CoMBounds",
    "CoMTarget",
    "Contact",
    "FrameTarget",
    "Grasp",
    "GroundingError",
    "HandTarget",
    "JointTarget",
    "Phase",
    "Pose",
    "Priority",
    "Push",
    "Scene",
    "SceneConflict",
    "SceneObject",
    "StartState",
    "TaskDefinitionError",
    "TaskError",
    "TaskSpec",
    "Tracks",
    "UnknownAction",
    "Vec3",
    "actions_json_schema",
    "arm_torque_joints",
    "bind",
    "check_joints",
    "check_spec_for_robot",
    "check_spec_in_scene_for_robot",
    "compile_actions",
    "contact_windows",
    "fit_actions",
    "get_action",
    "ground",
    "human_motion",
    "label_contacts",
    "load_scene",
    "load_skeleton",
    "load_spec",
    "motion_figures",
    "on_top",
    "read_bvh",
    "recognize_skeleton",
    "resolve_frames",
    "retarget_spec",
    "spec_from_dict",
    "spec_from_json",
    "spec_to_dict",
    "spec_to_json",
    "strip_reference",
    "surface_at",
    "torque_cause",
    "tracks",
]


__getattr__, __dir__ = lazy_face(__name__, _LAZY)
