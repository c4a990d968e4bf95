"""The end of a motion as the start of the next: where "then <sentence>" begins.

A motion ends at rest (the planner's last two knots are equal) in the posture of its last knot.
:func:`end_state` says whether the next motion can start there, and if so gives the
:class:`tasks.specs.StartState` the pipeline plans from (``SolveRequest.start``): the planned
last knot, checked against what the simulation did. The answer is one of three:

- ``start``: the robot stands at rest on both soles, flat on the ground, with nothing in its
  hands and the scene as it was: the next motion starts from that configuration;
- ``together``: it stands, but it holds an object or moved one (the scene the next motion is
  planned in would be out of date): the two motions are planned together, as one, from where
  the first one started;
- ``refused``: it does not stand where a plan can start (it ended on one foot, with a hand on
  something, on a slope, or the simulation ended elsewhere: it fell, slipped or was stopped);
  the reason is said in task words, for the one-line error.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

REST_SPEED = 1e-3  # [m/s, rad/s] the last knot's largest velocity component at rest
FLAT = 0.02  # [rad] a sole's roll or pitch within which it stands flat
DRIFT = 0.05  # [m] the simulated base's distance from the planned end within which it is the same place
TURN = 0.1  # [rad] the simulated base's yaw difference from the planned end likewise
BALANCE_MARGIN = 0.02  # [m] the centre of mass inside the feet's polygon (the primitives' support margin)


@dataclass(frozen=True)
class EndState:
    """Whether and how a motion can be continued (module docstring)."""

    kind: str  # start, together, refused
    q: tuple[float, ...] | None = None  # the start configuration (kind start)
    reason: str = ""  # why not a start (kind together or refused), in task words

    def to_dict(self) -> dict[str, Any]:
        """JSON form (``wbmp serve`` keeps it with the motion)."""
        return {"kind": self.kind, "q": None if self.q is None else list(self.q), "reason": self.reason}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> EndState:
        """The inverse of :meth:`to_dict`."""
        q = data.get("q")
        return cls(kind=str(data["kind"]), q=None if q is None else tuple(float(x) for x in q),
                   reason=str(data.get("reason", "")))


def _yaw(quaternion: np.ndarray) -> float:
    x, y, z, w = (float(c) for c in quaternion)
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def end_state(spec: Any, plan: Any, execution: Any, feet: tuple[str, str], sole: Any = None) -> EndState:
    """Where the motion of ``spec``, planned as ``plan`` and simulated as ``execution`` (None: not
    simulated), leaves the robot; ``feet``: the frame names of its left and right foot; ``sole``:
    its ``robots.contact.SoleRectangle`` (None: the centre of mass is not checked against the feet).

    Objects: a grasp held to the end, or any grasp or push (the object is no longer where the
    scene says), gives ``together``. Everything else that keeps the next plan from starting at
    the last knot gives ``refused``, with the reason.
    """
    last = spec.phases[-1]
    held = [g.object for g in spec.grasps if g.end is None or g.end >= spec.horizon - 1e-9]
    if held:
        return EndState(kind="together", reason=f"the robot ends holding the {held[0]}")
    moved = sorted({g.object for g in spec.grasps} | {p.object for p in spec.pushes})
    if moved:
        return EndState(kind="together", reason=f"the last motion moved the {moved[0]}")
    frames = {c.frame for c in last.contacts}
    missing = [side for side, frame in zip(("left", "right"), feet, strict=True) if frame not in frames]
    if missing:
        return EndState(kind="refused", reason=f"the last motion ends with the {missing[0]} foot off the ground "
                                                 "(its last phase is not standing on both feet)")
    others = sorted(frames - set(feet))
    if others:
        return EndState(kind="refused", reason=f"the last motion ends with {others[0]} touching something "
                                                 "(its last phase holds more than the two feet)")
    for c in last.contacts:
        roll, pitch = c.placement.rpy[0], c.placement.rpy[1]
        if max(abs(roll), abs(pitch)) > FLAT:
            return EndState(kind="refused", reason=f"the last motion ends with {c.frame} tilted by "
                                                     f"{math.degrees(max(abs(roll), abs(pitch))):.1f} deg (on a slope "
                                                     "or a step edge); a motion starts on flat ground")
    q = np.asarray(plan.q[-1], dtype=float)
    v = np.asarray(plan.v[-1], dtype=float) if getattr(plan, "v", None) is not None else np.zeros(1)
    if float(np.max(np.abs(v))) > REST_SPEED:
        return EndState(kind="refused", reason=f"the last motion ends still moving ({float(np.max(np.abs(v))):.3g} "
                                                 "m/s or rad/s at its last knot)")
    if sole is not None and getattr(plan, "com", None) is not None:
        refused = _balance(last, feet, sole, np.asarray(plan.com[-1], dtype=float))
        if refused:
            return EndState(kind="refused", reason=refused)
    if execution is not None:
        certificate = execution.certificate
        if not certificate.ok:
            why = certificate.reason or "a check failed"
            return EndState(kind="refused", reason=f"the last motion did not pass its simulation check ({why}), "
                                                     "so the robot may not stand where it was planned to end")
        done = np.asarray(execution.q[-1], dtype=float)
        drift = float(np.linalg.norm(done[:2] - q[:2]))
        turn = abs(math.remainder(_yaw(done[3:7]) - _yaw(q[3:7]), math.tau))
        if drift > DRIFT or turn > TURN:
            return EndState(kind="refused", reason=f"in the simulation the robot ended {drift:.2f} m and "
                                                     f"{math.degrees(turn):.0f} deg away from the planned end "
                                                     f"(more than {DRIFT:g} m or {math.degrees(TURN):.0f} deg)")
    return EndState(kind="start", q=tuple(float(x) for x in q))


def _balance(last: Any, feet: tuple[str, str], sole: Any, com: np.ndarray) -> str:
    """Why the centre of mass ``com`` (3,) is not over the soles of the phase ``last`` with the
    primitives' margin (the next motion's balance bound), or ""."""
    import pinocchio as pin

    from robots import polygon_margin, sole_corners_in_world, support_polygon

    placements = {c.frame: pin.SE3(pin.rpy.rpyToMatrix(*c.placement.rpy), np.array(c.placement.position))
                  for c in last.contacts}
    polygon = support_polygon([sole_corners_in_world(sole, side, placements[frame])
                               for side, frame in zip(("left", "right"), feet, strict=True)])
    needed = min(BALANCE_MARGIN, 0.25 * min(sole.x_max - sole.x_min, sole.y_max - sole.y_min))
    inside = polygon_margin(polygon, com)
    if inside >= needed - 1e-4:
        return ""
    where = f"{inside * 100:.1f} cm inside the edge of its feet" if inside > 0 else \
        f"{-inside * 100:.1f} cm outside its feet"
    return (f"the last motion ends with the centre of mass {where} (a motion starts with it at least "
            f"{needed * 100:.1f} cm inside)")
