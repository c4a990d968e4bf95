"""The collision rows a layout carries, per link pair or per scene object: a frozen record (a
collision round returns a new one, :meth:`PairRows.merged`; the one it was given is not changed)."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from collections.abc import Set as AbstractSet
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, TypeVar

R = TypeVar("R", bound="PairRows")


@dataclass(frozen=True)
class PairRows:
    """Per pair (a link pair's or a scene object's index): the spheres or sphere pairs with rows
    (indices into the pair's block) and the knots that carry them. Read-only: the mappings are
    views and their values frozen sets; the constructor takes any mapping of iterables.

    Attributes:
        spheres: Per pair, the spheres (sphere pairs) with rows.
        knots: Per pair, the knots that carry them (the same keys, in the same order).
    """

    spheres: Mapping[int, AbstractSet[int]] = field(default_factory=dict)
    knots: Mapping[int, AbstractSet[int]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        spheres = {int(k): frozenset(int(i) for i in v) for k, v in self.spheres.items()}
        knots = {int(k): frozenset(int(i) for i in v) for k, v in self.knots.items()}
        if list(spheres) != list(knots):
            raise ValueError(f"rows: spheres and knots name different pairs ({sorted(spheres)} / {sorted(knots)})")
        object.__setattr__(self, "spheres", MappingProxyType(spheres))
        object.__setattr__(self, "knots", MappingProxyType(knots))

    def __reduce__(self) -> tuple[Any, ...]:
        return type(self), (dict(self.spheres), dict(self.knots))

    def merged(self: R, other: PairRows) -> tuple[R, list[int]]:
        """These rows with ``other``'s added (a new record; ``self`` itself when none changed), and
        the pairs whose rows changed (in ``other``'s order)."""
        spheres, knots = dict(self.spheres), dict(self.knots)
        changed = []
        empty: frozenset[int] = frozenset()
        for pi in other.spheres:
            s0, k0 = spheres.get(pi, empty), knots.get(pi, empty)
            s1, k1 = s0 | other.spheres[pi], k0 | other.knots[pi]
            if (s1, k1) != (s0, k0):
                spheres[pi], knots[pi] = s1, k1
                changed.append(pi)
        return (type(self)(spheres, knots) if changed else self), changed

    def split(self: R, pairs: Iterable[int]) -> tuple[R, R]:
        """(the rows of the pairs not in ``pairs``, the rows of those in ``pairs``), each in this
        record's order."""
        chosen = set(pairs)
        keep = [pi for pi in self.spheres if pi not in chosen]
        take = [pi for pi in self.spheres if pi in chosen]
        return (type(self)({pi: self.spheres[pi] for pi in keep}, {pi: self.knots[pi] for pi in keep}),
                type(self)({pi: self.spheres[pi] for pi in take}, {pi: self.knots[pi] for pi in take}))

    @property
    def empty(self) -> bool:
        """No rows."""
        return not self.spheres
