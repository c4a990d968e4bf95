"""Robot models and their named frames: the humanoids wbmp plans for.

Each public name is imported on first access, so ``import robots.safeio`` (the safe file reader
every layer uses) or ``import robots.cache`` do not load Pinocchio through this package's face.

Example:
    >>> from robots import load_robot
    >>> talos = load_robot("talos")
    >>> talos.frame("left_foot")
    'left_sole_link'
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from robots.lazy import lazy_face

if TYPE_CHECKING:
    from robots.contact import polygon_margin, sole_corners_in_world, support_polygon
    from robots.exceptions import FrameNotFound, ProfileError, RobotError, RobotNotFound, WbmpError
    from robots.model import DEFAULT_ROBOT, Robot, available_robots, level_soles, load_robot
    from robots.profile import ROLES, ExtraFrame, RobotProfile, SoleRectangle, builtin_profiles

_EXPORTS = {  # public name -> module that defines it
    "DEFAULT_ROBOT": "robots.model",
    "ROLES": "robots.profile",
    "ExtraFrame": "robots.profile",
    "FrameNotFound": "robots.exceptions",
    "ProfileError": "robots.exceptions",
    "Robot": "robots.model",
    "RobotError": "robots.exceptions",
    "WbmpError": "robots.exceptions",
    "RobotNotFound": "robots.exceptions",
    "RobotProfile": "robots.profile",
    "SoleRectangle": "robots.profile",
    "available_robots": "robots.model",
    "builtin_profiles": "robots.profile",
    "level_soles": "robots.model",
    "polygon_margin": "robots.contact",
    "sole_corners_in_world": "robots.contact",
    "support_polygon": "robots.contact",
    "load_robot": "robots.model",
}

__all__ = [
    "DEFAULT_ROBOT",
    "ROLES",
    "ExtraFrame",
    "FrameNotFound",
    "ProfileError",
    "Robot",
    "RobotError",
    "RobotNotFound",
    "RobotProfile",
    "SoleRectangle",
    "WbmpError",
    "available_robots",
    "builtin_profiles",
    "level_soles",
    "load_robot",
    "polygon_margin",
    "sole_corners_in_world",
    "support_polygon",
]


__getattr__, __dir__ = lazy_face(__name__, _EXPORTS)
