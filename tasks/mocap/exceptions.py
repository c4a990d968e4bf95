"""Exceptions of the motion-capture front end."""

from __future__ import annotations

from tasks.exceptions import TaskDefinitionError


class ClipError(TaskDefinitionError):
    """A motion-capture clip that cannot be used: a damaged or unsupported BVH file, a skeleton
    wbmp does not know, a time window outside the clip or beyond the work bounds (exit 3)."""
