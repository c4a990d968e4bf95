"""Robot models and their named frames: the humanoids wbmp plans for.

Example:
    >>> from robots import load_robot
    >>> talos = load_robot("talos")
    >>> talos.frame("left_foot")
    'left_sole_link'
"""

from robots.exceptions import FrameNotFound, ProfileError, RobotError, RobotNotFound
from robots.model import DEFAULT_ROBOT, Robot, available_robots, level_soles, load_robot
from robots.profile import ROLES, ExtraFrame, RobotProfile, SoleRectangle, builtin_profiles

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
    "available_robots",
    "builtin_profiles",
    "level_soles",
    "load_robot",
]
