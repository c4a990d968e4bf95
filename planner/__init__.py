"""Trajectory optimization (CasADi + IPOPT) and whole-body control for TaskSpecs.

The public face of the planner; each name is imported on first access (``import planner`` stays
cheap: CasADi, numba and proxsuite load only when a name that needs them is used)::

    from planner import plan, PlannerSettings, Plan

* :func:`plan` (:mod:`planner.trajopt.api`) turns a ``TaskSpec`` into a :class:`Plan`;
  :class:`PlannerSettings` configures it. Its steps are public too: :func:`formulate` builds the
  frozen :class:`Problem` of (spec, robot, settings), :func:`solve` solves it from an explicit
  :class:`WarmStart` (or its own guess) into a :class:`Solution`.
* :class:`Plan`, :class:`SolverStats`, :class:`SolveStatus`, :class:`Check` and :class:`CheckKind`
  (:mod:`planner.results`) report it (``ConstraintCheck`` is :class:`Check`'s former name).
* :class:`WholeBodyController` and :class:`WbcSettings` (:mod:`planner.wbc`) track it.
* :class:`PlannerError` and its subclasses are what the planner raises.

Subpackages: ``planner.trajopt`` (the trajectory optimizer; ``planner.trajopt.centroidal``, its
dynamic formulation) and ``planner.wbc`` (the whole-body controller). See docs/architecture.md.
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

from robots import lazy_face

# One BLAS thread unless the user says otherwise (before CasADi loads IPOPT's OpenBLAS): the NLPs are
# too small to gain from a second thread, and when the other core is busy (another solve, a test
# worker, a compile) OpenBLAS's threads wait for each other. Talos reaching into a table, refused:
# 108 s of wall time for 37 s of CPU with the default threads, 21 s with one (docs/performance.md).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

if TYPE_CHECKING:
    from planner.exceptions import (
        ControllerError,
        PlannerError,
        PlanningFailed,
        SpecNotForRobot,
        StagewiseUnsupported,
        UnsupportedModel,
    )
    from planner.results import Check, CheckKind, ConstraintCheck, Plan, SolverStats, SolveStatus
    from planner.trajopt.api import (
        Problem,
        Solution,
        WarmStart,
        formulate,
        plan,
        plan_with_library,
        solve,
    )
    from planner.trajopt.builds import BUILD_MEMORY, MEMORY_MARGIN, build_status, describe_build
    from planner.trajopt.cache import clear_memory_cache
    from planner.trajopt.centroidal.settings import CentroidalSettings
    from planner.trajopt.centroidal.zmp import (
        full_dynamics_wrench,
        support_excursion,
        support_heights,
        zmp_of_wrenches,
    )
    from planner.trajopt.settings import (
        CacheSettings,
        CollisionSettings,
        PlannerSettings,
        SolverSettings,
        Tolerances,
        default_cache_dir,
    )
    from planner.wbc.controller import WholeBodyController
    from planner.wbc.friction import JointFriction
    from planner.wbc.kernel import kernel_ready
    from planner.wbc.reference import PlanReference
    from planner.wbc.settings import WbcSettings

_EXPORTS = {  # public name -> module that defines it
    "BUILD_MEMORY": "planner.trajopt.builds",
    "CacheSettings": "planner.trajopt.settings",
    "CentroidalSettings": "planner.trajopt.centroidal.settings",
    "Check": "planner.results",
    "CheckKind": "planner.results",
    "CollisionSettings": "planner.trajopt.settings",
    "ConstraintCheck": "planner.results",
    "ControllerError": "planner.exceptions",
    "JointFriction": "planner.wbc.friction",
    "MEMORY_MARGIN": "planner.trajopt.builds",
    "Plan": "planner.results",
    "PlanReference": "planner.wbc.reference",
    "PlannerError": "planner.exceptions",
    "PlannerSettings": "planner.trajopt.settings",
    "PlanningFailed": "planner.exceptions",
    "SolveStatus": "planner.results",
    "SolverSettings": "planner.trajopt.settings",
    "SolverStats": "planner.results",
    "Tolerances": "planner.trajopt.settings",
    "UnsupportedModel": "planner.exceptions",
    "WbcSettings": "planner.wbc.settings",
    "WholeBodyController": "planner.wbc.controller",
    "build_status": "planner.trajopt.builds",
    "clear_memory_cache": "planner.trajopt.cache",
    "default_cache_dir": "planner.trajopt.settings",
    "describe_build": "planner.trajopt.builds",
    "full_dynamics_wrench": "planner.trajopt.centroidal.zmp",
    "kernel_ready": "planner.wbc.kernel",
    "plan": "planner.trajopt.api",
    "plan_with_library": "planner.trajopt.api",
    "Problem": "planner.trajopt.api",
    "Solution": "planner.trajopt.api",
    "WarmStart": "planner.trajopt.api",
    "formulate": "planner.trajopt.api",
    "solve": "planner.trajopt.api",
    "support_excursion": "planner.trajopt.centroidal.zmp",
    "support_heights": "planner.trajopt.centroidal.zmp",
    "zmp_of_wrenches": "planner.trajopt.centroidal.zmp",
    "SpecNotForRobot": "planner.exceptions",
    "StagewiseUnsupported": "planner.exceptions",
}

__all__ = [  # what `from ... import *` and the TYPE_CHECKING imports above cover
    "BUILD_MEMORY",
    "MEMORY_MARGIN",
    "CacheSettings",
    "CentroidalSettings",
    "Check",
    "CheckKind",
    "CollisionSettings",
    "ConstraintCheck",
    "ControllerError",
    "JointFriction",
    "Plan",
    "PlanReference",
    "PlannerError",
    "PlannerSettings",
    "PlanningFailed",
    "Problem",
    "Solution",
    "SolveStatus",
    "SolverSettings",
    "SolverStats",
    "SpecNotForRobot",
    "StagewiseUnsupported",
    "Tolerances",
    "UnsupportedModel",
    "WarmStart",
    "WbcSettings",
    "WholeBodyController",
    "build_status",
    "clear_memory_cache",
    "default_cache_dir",
    "describe_build",
    "formulate",
    "full_dynamics_wrench",
    "kernel_ready",
    "plan",
    "plan_with_library",
    "solve",
    "support_excursion",
    "support_heights",
    "zmp_of_wrenches",
]


__getattr__, __dir__ = lazy_face(__name__, _EXPORTS)
