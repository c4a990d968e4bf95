"""Terrain: stairs and slopes as walkable boxes, and the surface under a point (height and normal).

A scene file's ``stairs`` element (:class:`Stairs`: count, rise, run, width, position, yaw) is
expanded when the file is read into ``count`` static boxes with ``walkable`` set: step ``i``
(1-based) is a solid block from the floor up to ``i * rise``, ``run`` deep and ``width`` wide,
so the planner, MuJoCo and the viewers see the same geometry without knowing about stairs. The
first block is named ``<name>.1`` with the alias ``<name>`` (so "the stairs" names one object,
the first tread), the others ``<name>.2``, ``<name>.3``, ...

``position`` is the middle of the first riser's bottom edge (where the stairs meet the floor in
front of the robot) and ``yaw`` [rad] the direction the stairs climb (0: along +x).

A ``slopes`` element (:class:`Slope`: angle, length, width, position, yaw, landing) becomes a
walkable box tilted by its angle (its top face the inclined plane, from its bottom edge on the
floor) named ``<name>``, and a flat walkable landing ``<name>.top`` at the top edge's height.

A ``heightmaps`` element (:class:`tasks.heightmap.HeightMap`: a grid of heights in a file) becomes
a walkable ``heightfield`` object; over it the surface is the grid's bilinear interpolation, its
normal the interpolation's gradient (:func:`tasks.scene.field_surface`).

:func:`surface_at` is the height query the footstep primitives use: the highest walkable top face
(of an upright box or cylinder) over a point, or the floor (z = 0), with its upward normal.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass

from tasks.exceptions import SceneConflict
from tasks.heightmap import HeightMap
from tasks.scene import (
    MAX_SLOPE,
    MAX_STEPS,
    Scene,
    SceneObject,
    Slope,
    Stairs,
    field_surface,
    rotation,
    slope_objects,
    stairs_objects,
    to_local,
)
from tasks.specs import Phase

UPRIGHT_COS = math.cos(math.radians(5))  # a top face tilted more than 5 deg is not flat (a step's top)
SLOPE_COS = math.cos(MAX_SLOPE) - 1e-12  # a walkable top face tilted more than MAX_SLOPE is no surface


@dataclass(frozen=True, slots=True)
class Surface:
    """The surface under a point.

    Attributes:
        height: Its height [m] (0: the floor).
        normal: Its upward unit normal in the world.
        name: The object whose top it is (None: the floor).
        friction: Its Coulomb friction coefficient [-].
    """

    height: float
    normal: tuple[float, float, float]
    name: str | None
    friction: float


def top_height(obj: SceneObject) -> float | None:
    """Height of the top face's centre of an upright box or cylinder, or of a walkable one tilted by
    at most :data:`~tasks.scene.MAX_SLOPE` (a slope) [m] (None: no top to stand on)."""
    if obj.shape == "heightfield":
        return obj.size[2]
    R = rotation(obj.rpy)
    if obj.shape not in ("box", "cylinder") or R[2][2] < (SLOPE_COS if obj.walkable else UPRIGHT_COS):
        return None
    half = obj.size[2] / 2 if obj.shape == "box" else obj.size[1] / 2
    return obj.position[2] + R[2][2] * half


def _over(obj: SceneObject, x: float, y: float) -> float | None:
    """Height of the object's top face above (x, y), or None when (x, y) is not over it."""
    if obj.shape == "heightfield":
        under = field_surface(obj, x, y)
        return None if under is None else under[0]
    top = top_height(obj)
    if top is None:
        return None
    R = rotation(obj.rpy)
    n = (R[0][2], R[1][2], R[2][2])
    centre = [obj.position[i] + n[i] * (top - obj.position[2]) / n[2] for i in range(3)]
    # the point on the (possibly slightly tilted) top plane above (x, y)
    z = centre[2] - (n[0] * (x - centre[0]) + n[1] * (y - centre[1])) / n[2]
    lx, ly, _ = to_local(obj, (x, y, z))
    if obj.shape == "box":
        inside = abs(lx) <= obj.size[0] / 2 + 1e-9 and abs(ly) <= obj.size[1] / 2 + 1e-9
    else:
        inside = math.hypot(lx, ly) <= obj.size[0] + 1e-9
    return z if inside else None


def is_slope(obj: SceneObject) -> bool:
    """A walkable top tilted by more than 5 deg (a ramp: walked up in strides, the soles tilted), or a
    height map's ground (walked in strides, each sole on the ground under it)."""
    if obj.shape == "heightfield":
        return True
    return obj.walkable and top_height(obj) is not None and rotation(obj.rpy)[2][2] < UPRIGHT_COS


def sole_rpy(normal: tuple[float, float, float], yaw: float) -> tuple[float, float, float]:
    """Roll, pitch, yaw of a sole lying flat on a surface of upward unit ``normal`` and heading
    ``yaw`` [rad]: its z axis the normal, its x axis the heading projected vertically onto the
    surface (seen from above the sole points along the heading: its yaw is ``yaw``)."""
    n = [float(c) for c in normal]
    h = [math.cos(yaw), math.sin(yaw), 0.0]
    x = [h[0], h[1], -(h[0] * n[0] + h[1] * n[1]) / n[2]]
    norm = math.sqrt(sum(a * a for a in x))
    x = [a / norm for a in x]
    y = [n[1] * x[2] - n[2] * x[1], n[2] * x[0] - n[0] * x[2], n[0] * x[1] - n[1] * x[0]]
    # R = [x y n] = Rz(yaw) Ry(pitch) Rx(roll): R20 = -sin(pitch), R21 = cos(pitch) sin(roll), ...
    pitch = math.asin(max(-1.0, min(1.0, -x[2])))
    return (math.atan2(y[2], n[2]) + 0.0, pitch + 0.0, math.atan2(x[1], x[0]) + 0.0)  # no -0.0


def surface_at(scene: Scene | None, x: float, y: float) -> Surface:
    """The highest walkable surface over (x, y): a walkable object's top face, or the floor.

    Only objects with ``walkable`` set count (a table top over the point is not a floor for the
    feet); the floor is z = 0 with the normal +z and the scene's ``floor_friction``.
    """
    best = Surface(0.0, (0.0, 0.0, 1.0), None, 0.8 if scene is None else scene.floor_friction)
    if scene is None:
        return best
    for obj in scene.objects:
        if not obj.walkable:
            continue
        z = _over(obj, x, y)
        if z is not None and (z > best.height or (best.name is None and z >= best.height - 1e-9)):
            under = field_surface(obj, x, y)
            R = rotation(obj.rpy)
            normal = under[1] if under is not None else (R[0][2], R[1][2], R[2][2])
            best = Surface(float(z), normal, obj.name, obj.friction)
    return best


def with_surface_friction(phases: Sequence[Phase], scene: Scene | None, robot_friction: float,
                          robot_name: str = "the robot") -> tuple[Phase, ...]:
    """The phases with each sole contact (a contact without a region or a friction of its own) on a
    surface less grippy than the robot's soles given that surface's friction coefficient: the
    planner's friction cones and the controller's then use it (MuJoCo takes the surface's own,
    :mod:`sim.model`). Contacts on surfaces at least as grippy are left as they are (the profile's).

    Raises:
        SceneConflict: a sole placed on a surface too slippery to stand on at its incline (Coulomb:
            ``friction < tan(incline)``), named with the incline and the friction it would need.
    """
    if scene is None:
        return tuple(phases)
    out = []
    for phase in phases:
        contacts = []
        for c in phase.contacts:
            if c.region is None and c.friction_coefficient is None:
                under = surface_at(scene, float(c.placement.position[0]), float(c.placement.position[1]))
                incline = math.acos(max(-1.0, min(1.0, under.normal[2])))
                if under.friction < math.tan(incline):
                    where = "the floor" if under.name is None else f"the {under.name}"
                    raise SceneConflict(
                        f"{where} is too slippery for {robot_name} to stand on at its {math.degrees(incline):.1f} deg "
                        f"incline: that needs a friction coefficient of at least {math.tan(incline):.2f}, it has "
                        f"{under.friction:g}; give the surface more friction or a gentler slope", under.name or "floor")
                if under.friction < robot_friction:
                    c = dataclasses.replace(c, friction_coefficient=float(under.friction))
            contacts.append(c)
        out.append(dataclasses.replace(phase, contacts=tuple(contacts)) if contacts != list(phase.contacts) else phase)
    return tuple(out)


__all__ = ["MAX_SLOPE", "MAX_STEPS", "HeightMap", "Slope", "Stairs", "Surface", "is_slope", "slope_objects", "sole_rpy",
           "stairs_objects", "surface_at", "top_height", "with_surface_friction"]
