"""The whole-body controller: an inverse-dynamics QP that tracks a Plan (docs/control.md).

Modules, in import order: ``settings`` (:class:`WbcSettings`, :class:`ControllerError`),
``kernel`` (the numba tick arithmetic), ``reference`` (the plan as smooth references),
``controller`` (:class:`WholeBodyController`). Public names load on first access.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from robots import lazy_face

if TYPE_CHECKING:
    from planner.exceptions import ControllerError
    from planner.wbc.controller import TickInfo, WholeBodyController
    from planner.wbc.reference import PlanReference
    from planner.wbc.settings import WbcSettings

_EXPORTS = {  # public name -> module that defines it
    "ControllerError": "planner.exceptions",
    "PlanReference": "planner.wbc.reference",
    "TickInfo": "planner.wbc.controller",
    "WbcSettings": "planner.wbc.settings",
    "WholeBodyController": "planner.wbc.controller",
}

__all__ = [  # what `from ... import *` and the TYPE_CHECKING imports above cover
    "ControllerError",
    "PlanReference",
    "TickInfo",
    "WbcSettings",
    "WholeBodyController",
]


__getattr__, __dir__ = lazy_face(__name__, _EXPORTS)
