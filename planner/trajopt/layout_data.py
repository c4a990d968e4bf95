"""The data of a layout: one spec on one robot laid out on the knot grid, without the formulation.

:class:`LayoutData` is what the free functions of the term modules read (the nominal motion, the
self- and scene-collision rows, the centroidal pieces); :class:`planner.trajopt.layout.Layout` adds
the formulation protocol's methods on top. The modules below the layout take this data, so none of
them imports the layout back (not even for its type).

A layout is frozen: its fields cannot be assigned (``FrozenInstanceError``); a changed layout is a
new one (:meth:`LayoutData.with_terms`, the dynamic data's ``with_momentum_point``). What a layout
builds lazily from its own fields (the phases' support polygons, the dynamic parts) is kept in a
private per-layout memo (:meth:`LayoutData.memo`): built once, invisible to callers, never changing
what the fields say.
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any, Self, TypeVar

import numpy as np
import pinocchio as pin

from planner.trajopt.term import Term
from robots import Robot
from tasks import TaskSpec

T = TypeVar("T")


@dataclass(frozen=True, eq=False)
class LayoutData:
    """The problem of one spec on one robot, as data.

    Attributes:
        robot: The robot.
        spec: The spec.
        N: Number of intervals (knots 0..N).
        dt: Knot spacing [s].
        t: Knot times (N+1,) [s].
        phase_of_knot: Phase index per knot (the later phase at a boundary).
        contacts_at: Per knot, the contacts active there (frame id -> (spec frame, placement)).
        frame_ids: Frame ids the terms use, in a fixed order.
        terms: Every term (a tuple: a layout's terms change only in a new layout, :meth:`with_terms`).
        q_ref: Reference (= start) configuration (nq,).
    """

    robot: Robot
    spec: TaskSpec
    N: int
    dt: float
    t: np.ndarray
    phase_of_knot: list[int]
    contacts_at: list[dict[int, tuple[str, pin.SE3]]]
    frame_ids: list[int]
    terms: tuple[Term, ...]
    q_ref: np.ndarray
    _memo: dict[str, Any] = field(default_factory=dict, init=False, repr=False)

    def memo(self, name: str, build: Callable[[], T]) -> T:
        """The part ``name`` of this layout, built by ``build()`` on first use and kept (a part is a
        function of the layout's fields only: the memo is a cache, not state)."""
        memo = self._memo
        if name not in memo:
            memo[name] = build()
        return memo[name]

    def _changed(self, **fields: Any) -> Self:
        """A copy (the same class) with ``fields`` replaced and the parts built so far, which do not
        depend on them, shared; this layout is not changed. The one place a layout's fields are set
        after ``__init__`` (a frozen dataclass: through ``object.__setattr__``, on the new copy only)."""
        out = copy.copy(self)
        for name, value in fields.items():
            object.__setattr__(out, name, value)
        object.__setattr__(out, "_memo", dict(self._memo))
        return out

    @property
    def variable_knots(self) -> range:
        """Knots whose dq is a decision variable."""
        return range(2, self.N)

    def free_knot(self, k: int) -> int:
        """The knot whose variables define knot ``k`` (N maps to N-1)."""
        return min(k, self.N - 1)

    def structure(self) -> tuple:
        """Hashable structure of the NLP (no numeric values)."""
        return (
            self.N,
            tuple(self.frame_ids),
            tuple((t.knot, t.structure, len(t.params), t.n_rows) for t in self.terms),
        )

    def with_terms(self, terms: Iterable[Term]) -> Self:
        """A copy of this layout (the same class, its cached parts shared) with ``terms`` instead of
        its own; this one is not changed (the collision rounds build their layouts this way)."""
        return self._changed(terms=tuple(terms))

    def phase_name(self, k: int) -> str:
        """Name of the phase at knot ``k``."""
        return self.spec.phases[self.phase_of_knot[k]].name
