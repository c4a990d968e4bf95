"""Task specifications and the motion primitives that produce them.

``tasks.specs`` holds the data types (:class:`TaskSpec`, :class:`Phase`, :class:`Contact`,
:class:`FrameTarget`, :class:`CoMTarget`, :class:`CoMBounds`, :class:`JointTarget`);
``tasks.serialize`` their exact JSON round-trip.
"""

from tasks.exceptions import TaskDefinitionError, TaskError, UnknownAction
from tasks.serialize import load_spec, spec_from_dict, spec_from_json, spec_to_dict, spec_to_json
from tasks.specs import (
    CoMBounds,
    CoMTarget,
    Contact,
    FrameTarget,
    HandTarget,
    JointTarget,
    Phase,
    Pose,
    Priority,
    TaskSpec,
)

__all__ = [
    "CoMBounds",
    "CoMTarget",
    "Contact",
    "FrameTarget",
    "HandTarget",
    "JointTarget",
    "Phase",
    "Pose",
    "Priority",
    "TaskDefinitionError",
    "TaskError",
    "TaskSpec",
    "UnknownAction",
    "load_spec",
    "spec_from_dict",
    "spec_from_json",
    "spec_to_dict",
    "spec_to_json",
]
