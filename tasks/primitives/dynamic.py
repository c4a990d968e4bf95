"""Placeholders for ``step``, ``walk``, ``turn`` and ``jump``.

They are registered (the language layer knows them and ``wbmp actions`` lists them) but need
the planner's CoM dynamics with contact forces; their compilation lands with the
dynamic-motions work. Until then compiling one raises a clear TaskDefinitionError.

A replacement writes phases with changing contacts through the :class:`FragmentBuilder`
(``b.contacts(...)`` at new placements) and sets ``b.end_stance`` to where the feet end, so
that the following actions are carried along (their targets follow the new heading frame).
"""

from __future__ import annotations

from robots.model import Robot
from tasks.exceptions import TaskDefinitionError
from tasks.primitives.base import Fragment, FragmentBuilder, Primitive


class NotAvailableYet(TaskDefinitionError):
    """A registered primitive whose compilation has not landed yet."""


def _unavailable(name: str):
    def check(params: dict, robot: Robot) -> None:
        raise NotAvailableYet(
            f"{name} is registered but cannot be planned yet: it lands with the dynamic-motions work "
            "(CoM dynamics with contact forces); available now: squat, wave, reach, raise_arms, bow, "
            "turn_head, lean, balance, stand"
        )

    def build(b: FragmentBuilder) -> Fragment:
        check(b.params, b.robot)
        raise AssertionError("unreachable")  # pragma: no cover

    return Primitive(name=name, nominal_duration=lambda params, robot: 1.0, build=build,
                     parts=lambda params: frozenset({"legs", "com"}), check=check, available=False, dynamic=True)


STEP = _unavailable("step")
WALK = _unavailable("walk")
TURN = _unavailable("turn")
JUMP = _unavailable("jump")
