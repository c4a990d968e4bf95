"""Motion capture as a task: read a BVH clip, recognise its skeleton, label its foot contacts,
scale it to a robot and build the TaskSpec whose costs track it (docs/retarget.md).

Imports only ``tasks`` and ``robots`` (the layering of docs/architecture.md).
"""

from __future__ import annotations

from tasks.exceptions import ClipError
from tasks.mocap.bvh import BvhClip, read_bvh
from tasks.mocap.skeleton import SkeletonMap, load_skeleton, recognize_skeleton
from tasks.mocap.source import HumanMotion, human_motion, label_contacts

__all__ = ["BvhClip", "ClipError", "HumanMotion", "SkeletonMap", "human_motion", "label_contacts",
           "load_skeleton", "read_bvh", "recognize_skeleton"]
