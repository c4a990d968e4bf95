"""The trajectory optimizer: a TaskSpec laid out on a knot grid, transcribed into a CasADi NLP,
solved with IPOPT, checked with Pinocchio numerics.

Modules, in import order (each imports only the ones above it; tests/test_layering.py checks):

* ``symbolic``: CasADi kinematics from a Pinocchio model, over the tangent chart;
* ``settings``: :class:`PlannerSettings`, composed of one small frozen dataclass per concern
  (solver, cache, collision, tolerances; ``centroidal.settings``: its dynamic part);
* ``term``: a term at one knot and the registry of term kinds; ``kinds``: the kinematic kinds,
  one class each (``collision``, ``scene_collision``: the collision kinds; docs/terms.md);
* ``layout_data``: a layout's data (:class:`LayoutData`, what the term modules below the
  layout take); ``layout``: spec -> knot grid -> per-knot terms (:class:`Layout`, the kinematic formulation);
  ``formulation``: the protocol a formulation implements; ``nominal``: the warm start;
* ``terms``: the stage functions of the terms at a knot; ``transcription``: the NLP and its
  derivatives, bounds and parameters;
* ``ipopt``: the backend's options and statuses; ``cache``: compiled solvers in memory and on
  disk; ``solve``: one solve of a layout;
* ``checks``: the constraint report and prechecks; ``report``: a solution as a ``Plan``;
  ``diagnose``: a failed plan in task terms;
* ``centroidal``: the dynamic formulation (contact forces, CoM dynamics);
* ``api``: :func:`plan`, the entry point (also ``planner.plan``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from robots import lazy_face

if TYPE_CHECKING:
    from planner.trajopt.api import plan
    from planner.trajopt.settings import PlannerSettings

_EXPORTS = {"PlannerSettings": "planner.trajopt.settings", "plan": "planner.trajopt.api"}  # loaded on first access

__all__ = ["PlannerSettings", "plan"]


__getattr__, __dir__ = lazy_face(__name__, _EXPORTS)
