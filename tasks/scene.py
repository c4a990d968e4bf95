"""Scenes: the world around the robot, as data (a floor plus named objects).

A :class:`Scene` is what ``wbmp solve ... --scene FILE`` loads and what a :class:`~tasks.specs.TaskSpec`
carries in its ``scene`` field. Every object is a primitive shape (or a mesh) at a pose in the
world frame (z up, ground at z = 0, SI units):

* ``box``: ``size = (sx, sy, sz)``, full edge lengths [m], centred on ``position``;
* ``cylinder``: ``size = (radius, length)`` [m], axis along the object's z, centred on ``position``;
* ``sphere``: ``size = (radius,)`` [m];
* ``mesh``: ``mesh`` is a file path (STL/OBJ/DAE) and ``size = (sx, sy, sz)`` its scale;
* ``heightfield``: a height map's ground (:mod:`tasks.heightmap`): ``heights`` the grid [m],
  ``size = (sx, sy, top)`` its extent and highest point, ``position`` its box's centre (from the floor).

``rpy`` is roll-pitch-yaw [rad] with ``R = Rz(y) Ry(p) Rx(r)`` (Pinocchio's convention). A static
object never moves (mass ignored); a movable one is a free body with ``mass`` [kg] and
``friction`` [-]. The planner keeps the robot at least its margin away from every object except
in planned contacts; the simulation adds the objects as MuJoCo geoms (movable ones as free bodies).

Scene files are JSON (``docs/scenes.md``, schema ``docs/scene.schema.json``), read by
:func:`load_scene` with the same hardening as task spec files (:mod:`tasks.serialize`); every
error names the field by its path (``objects[2].size: a box needs 3 positive lengths [m], got
[0.5, -1, 0.8]``). :func:`signed_distance` and :func:`tasks.robot_check.check_spec_in_scene` are the geometry the
tasks layer needs: a hand target or a footstep inside an object is refused before planning.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tasks.exceptions import TaskDefinitionError, field_error
from tasks.heightmap import HeightMap, check_grid, grid_surface, load_heightmaps
from tasks.limits import (
    GROUND_TOLERANCE,
    MAX_ANGLE,
    MAX_DISTANCE,
    MAX_FRICTION,
    MAX_MASS,
    MAX_NAME_LENGTH,
    MAX_OBJECTS,
    MAX_TEXT_LENGTH,
)

SCENE_VERSION = 1
SHAPES = ("box", "cylinder", "sphere", "mesh", "heightfield")
SIZE_LENGTHS = {"box": 3, "cylinder": 2, "sphere": 1, "mesh": 3, "heightfield": 3}
#: What ``size`` holds, per shape, for messages and docs.
SIZE_MEANING = {
    "box": "3 positive lengths [m] (sx, sy, sz)",
    "cylinder": "2 positive lengths [m] (radius, length)",
    "sphere": "1 positive radius [m]",
    "mesh": "3 positive scale factors (sx, sy, sz)",
    "heightfield": "3 positive lengths [m] (sx, sy, top)",
}
#: The planner's clearance from every object [m]: a hand target or a footstep closer than this
#: to an object (or inside it) is refused before planning.
SCENE_MARGIN = 0.01
MAX_STEPS = 50  # treads of one stairs element


def _show(value: Any) -> str:
    if isinstance(value, tuple) and len(value) <= 6 and all(isinstance(v, (int, float)) for v in value):
        return "[" + ", ".join(f"{v:g}" if isinstance(v, float) else repr(v) for v in value) + "]"
    text = repr(value)
    return text if len(text) <= 60 else f"{text[:40]}... ({len(text)} characters)"


def _finite(v: Any) -> bool:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return False
    return isinstance(v, int) or math.isfinite(v)


def _name(field: str, value: Any) -> None:
    if not isinstance(value, str) or not value.strip():
        raise field_error(field, f"must be a non-empty name, got {_show(value)}")
    if len(value) > MAX_NAME_LENGTH:
        raise field_error(field, f"has {len(value)} characters; at most {MAX_NAME_LENGTH}")
    if value != value.strip():
        raise field_error(field, f"{value!r} starts or ends with a space: write {value.strip()!r}")


def _triple(field: str, value: Any, *, bound: float, unit: str) -> None:
    if not isinstance(value, tuple) or len(value) != 3 or not all(_finite(v) and -bound <= v <= bound for v in value):
        raise field_error(field, f"must be 3 finite numbers in [{-bound:g}, {bound:g}] {unit}, got {_show(value)}")


@dataclass(frozen=True, slots=True, kw_only=True)
class SceneObject:
    """One named object of a scene.

    Attributes:
        name: Unique name (``table``), what sentences and messages call it.
        shape: One of ``box``, ``cylinder``, ``sphere``, ``mesh``.
        size: Shape dimensions: box (sx, sy, sz) [m], cylinder (radius, length) [m], sphere (radius,) [m], mesh scale (sx, sy, sz) [-].
        position: Centre of the shape in the world frame [m].
        rpy: Orientation, roll-pitch-yaw [rad].
        colour: RGBA in [0, 1].
        aliases: Other names a sentence may use (``desk``, 桌子).
        movable: A free body (true) or fixed to the world (false).
        mass: [kg], movable objects only (> 0 for them).
        friction: Coulomb friction coefficient [-].
        mesh: Mesh file path (shape ``mesh`` only; in a scene file, relative to the file).
        walkable: Its top face is a floor the feet may stand on (an upright box or cylinder:
            stair treads, a box to step onto); :func:`tasks.terrain.surface_at` finds it.
        seat: Its top face is a seat (a chair's, a bench's): ``sit_down`` sits on it (a static
            upright box; None, left out of the JSON, is false).
        heights: The grid of a ``heightfield`` [m] (rows along +y, columns along +x, spanning
            ``size[:2]`` centred on ``position``; None, left out of the JSON, for other shapes).
    """

    name: str
    shape: str
    size: tuple[float, ...]
    position: tuple[float, float, float]
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    colour: tuple[float, float, float, float] = (0.6, 0.6, 0.6, 1.0)
    aliases: tuple[str, ...] = ()
    movable: bool = False
    mass: float = 0.0
    friction: float = 0.8
    mesh: str | None = None
    walkable: bool = False
    seat: bool | None = field(default=None, metadata={"omit_none": True})
    heights: tuple[tuple[float, ...], ...] | None = field(default=None, metadata={"omit_none": True})

    def __post_init__(self) -> None:
        _name("name", self.name)
        if self.shape not in SHAPES:
            raise field_error("shape", f"must be one of {', '.join(SHAPES)}, got {_show(self.shape)}")
        n = SIZE_LENGTHS[self.shape]
        if (not isinstance(self.size, tuple) or len(self.size) != n
                or not all(_finite(v) and 0 < v <= MAX_DISTANCE for v in self.size)):
            raise field_error("size", f"a {self.shape} needs {SIZE_MEANING[self.shape]}, each at most "
                                       f"{MAX_DISTANCE:g}, got {_show(self.size)}")
        _triple("position", self.position, bound=MAX_DISTANCE, unit="m")
        _triple("rpy", self.rpy, bound=MAX_ANGLE, unit="rad")
        if (not isinstance(self.colour, tuple) or len(self.colour) != 4
                or not all(_finite(v) and 0 <= v <= 1 for v in self.colour)):
            raise field_error("colour", f"must be 4 numbers (red, green, blue, opacity) in [0, 1], "
                                         f"got {_show(self.colour)}")
        if not isinstance(self.aliases, tuple):
            raise field_error("aliases", f"must be a list of names, got {_show(self.aliases)}")
        for i, alias in enumerate(self.aliases):
            _name(f"aliases[{i}]", alias)
            if alias == self.name or alias in self.aliases[:i]:
                raise field_error(f"aliases[{i}]", f"{alias!r} is already a name of this object")
        if not isinstance(self.movable, bool):
            raise field_error("movable", f"must be true or false, got {_show(self.movable)}")
        if not (_finite(self.mass) and 0 <= self.mass <= MAX_MASS):
            raise field_error("mass", f"must be a number in [0, {MAX_MASS:g}] kg, got {_show(self.mass)}")
        if self.movable and not self.mass > 0:
            raise field_error("mass", "a movable object needs a mass > 0 kg (or set movable to false)")
        if not (_finite(self.friction) and 0 < self.friction <= MAX_FRICTION):
            raise field_error("friction", f"must be in (0, {MAX_FRICTION:g}], got {_show(self.friction)}")
        if self.shape == "mesh":
            if not isinstance(self.mesh, str) or not self.mesh.strip():
                raise field_error("mesh", "a mesh object needs the mesh file's path (STL, OBJ or DAE)")
            if len(self.mesh) > MAX_TEXT_LENGTH or "\x00" in self.mesh:
                raise field_error("mesh", f"is not a usable file path: {_show(self.mesh)}")
        elif self.mesh is not None:
            raise field_error("mesh", f"only a mesh object has a mesh file; this one is a {self.shape}")
        if not isinstance(self.walkable, bool):
            raise field_error("walkable", f"must be true or false, got {_show(self.walkable)}")
        if self.walkable and (self.shape not in ("box", "cylinder", "heightfield") or self.movable):
            raise field_error("walkable", f"only a static box or cylinder has a top to walk on; this one is a "
                                           f"{'movable ' if self.movable else ''}{self.shape}")
        if self.seat is not None and not isinstance(self.seat, bool):
            raise field_error("seat", f"must be true or false, got {_show(self.seat)}")
        if (self.shape == "heightfield") != (self.heights is not None):
            raise field_error("heights", "a heightfield needs its grid of heights, and only a heightfield has one")
        if self.heights is not None:
            object.__setattr__(self, "heights", check_grid(self.heights))
            cells = (self.size[0] / (len(self.heights[0]) - 1), self.size[1] / (len(self.heights) - 1))
            if (self.movable or not self.walkable or any(self.rpy) or abs(cells[0] - cells[1]) > 1e-6
                    or abs(self.position[2] - self.size[2] / 2) > 1e-6):
                raise field_error("heights", "a heightfield is static, walkable, not rotated, on the floor, with "
                                              "square cells (write it as a scene's heightmaps element)")
        if self.seat and (self.shape != "box" or self.movable or rotation(self.rpy)[2][2] < math.cos(math.radians(5))):
            raise field_error("seat", f"only a static upright box has a top to sit on; this one is a "
                                       f"{'movable ' if self.movable else ''}{self.shape}"
                                       f"{' tilted by more than 5 deg' if self.shape == 'box' else ''}")

    @property
    def names(self) -> tuple[str, ...]:
        """The name and the aliases."""
        return (self.name, *self.aliases)


def _check_terrain_name(name: object) -> None:
    """A stairs' or a slope's name (its parts are named ``<name>.<part>``)."""
    if not isinstance(name, str) or not name.strip() or len(name) > MAX_NAME_LENGTH - 4:
        raise field_error("name", f"must be a non-empty name of at most {MAX_NAME_LENGTH - 4} characters")


def _check_terrain_placement(position: object, yaw: float, friction: float) -> None:
    """A stairs' or a slope's place on the floor, heading and friction."""
    if (not isinstance(position, tuple) or len(position) != 2
            or not all(_finite(v) and abs(v) <= MAX_DISTANCE for v in position)):
        raise field_error("position", f"must be 2 numbers (x, y) within {MAX_DISTANCE:g} m, got {position!r}")
    if not (_finite(yaw) and abs(yaw) <= MAX_ANGLE):
        raise field_error("yaw", f"must be an angle within {MAX_ANGLE:g} rad, got {yaw!r}")
    if not (_finite(friction) and 0 < friction <= MAX_FRICTION):
        raise field_error("friction", f"must be in (0, {MAX_FRICTION:g}], got {friction!r}")


@dataclass(frozen=True, slots=True, kw_only=True)
class Stairs:
    """A straight flight of stairs on the floor.

    Attributes:
        name: Name of the flight (``stairs``); its treads are ``<name>.1`` ... ``<name>.<count>``.
        count: Number of steps (treads) [-].
        rise: Height of each step [m].
        run: Depth of each tread [m].
        width: Width of the flight [m].
        position: Middle of the first riser's bottom edge, on the floor [m] (x, y).
        yaw: Direction the flight climbs [rad] (0: +x).
        colour: RGBA in [0, 1].
        friction: Coulomb friction coefficient of the treads [-].
        aliases: Other names of the flight (``staircase``, 楼梯), given to its first tread.
    """

    name: str = "stairs"
    count: int = 3
    rise: float = 0.1
    run: float = 0.25
    width: float = 1.0
    position: tuple[float, float] = (0.5, 0.0)
    yaw: float = 0.0
    colour: tuple[float, float, float, float] = (0.55, 0.5, 0.45, 1.0)
    friction: float = 0.8
    aliases: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        _check_terrain_name(self.name)
        if isinstance(self.count, bool) or not isinstance(self.count, int) or not 1 <= self.count <= MAX_STEPS:
            raise field_error("count", f"must be a whole number of steps in [1, {MAX_STEPS}], got {self.count!r}")
        for key in ("rise", "run", "width"):
            v = getattr(self, key)
            if not (_finite(v) and 0 < v <= MAX_DISTANCE):
                raise field_error(key, f"must be a length in (0, {MAX_DISTANCE:g}] m, got {v!r}")
        _check_terrain_placement(self.position, self.yaw, self.friction)

    def tread_name(self, i: int) -> str:
        """Name of step ``i`` (1-based)."""
        return f"{self.name}.{i}"


def stairs_objects(stairs: Stairs) -> tuple[SceneObject, ...]:
    """The flight as ``count`` walkable static boxes, step 1 first."""
    c, s = math.cos(stairs.yaw), math.sin(stairs.yaw)
    out = []
    for i in range(1, stairs.count + 1):
        along = (i - 0.5) * stairs.run
        height = i * stairs.rise
        out.append(SceneObject(
            name=stairs.tread_name(i), shape="box", size=(stairs.run, stairs.width, height),
            position=(stairs.position[0] + c * along, stairs.position[1] + s * along, height / 2),
            rpy=(0.0, 0.0, float(stairs.yaw)), colour=stairs.colour, friction=stairs.friction,
            aliases=(stairs.name, *stairs.aliases) if i == 1 else (), walkable=True,
        ))
    return tuple(out)


MAX_SLOPE = math.radians(25)  # [rad] the steepest walkable surface (a slope's angle, a tilted walkable top)
SEAM = 0.02  # [m] a slope's box reaches this far past its top edge into the landing (no gap between them)


@dataclass(frozen=True, slots=True, kw_only=True)
class Slope:
    """A straight ramp up from the floor (an inclined plane), with a flat landing at its top.

    Attributes:
        name: Name of the ramp (``slope``); its landing is ``<name>.top``.
        angle: Inclination of the ramp [rad], in (0, :data:`MAX_SLOPE`].
        length: Horizontal length of the ramp, from its bottom edge to its top edge [m].
        width: Width of the ramp and its landing [m].
        position: Middle of the ramp's bottom edge, on the floor [m] (x, y).
        yaw: Direction the ramp climbs [rad] (0: +x).
        landing: Depth of the flat landing at the ramp's top (height ``length * tan(angle)``) [m]; 0: none.
        colour: RGBA in [0, 1].
        friction: Coulomb friction coefficient of the ramp and the landing [-].
        aliases: Other names of the ramp (``ramp``, 斜坡).
    """

    name: str = "slope"
    angle: float = math.radians(10)
    length: float = 0.5
    width: float = 1.0
    position: tuple[float, float] = (0.5, 0.0)
    yaw: float = 0.0
    landing: float = 0.5
    colour: tuple[float, float, float, float] = (0.5, 0.55, 0.45, 1.0)
    friction: float = 0.8
    aliases: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        _check_terrain_name(self.name)
        if not (_finite(self.angle) and 0 < self.angle <= MAX_SLOPE + 1e-12):
            raise field_error("angle", f"must be an inclination in (0, {MAX_SLOPE:.4f}] rad (25 deg), got "
                                        f"{_show(self.angle)}")
        for key in ("length", "width"):
            v = getattr(self, key)
            if not (_finite(v) and 0 < v <= MAX_DISTANCE):
                raise field_error(key, f"must be a length in (0, {MAX_DISTANCE:g}] m, got {_show(v)}")
        if not (_finite(self.landing) and 0 <= self.landing <= MAX_DISTANCE):
            raise field_error("landing", f"must be a length in [0, {MAX_DISTANCE:g}] m, got {_show(self.landing)}")
        _check_terrain_placement(self.position, self.yaw, self.friction)

    @property
    def height(self) -> float:
        """Height of the ramp's top edge and of its landing [m]."""
        return self.length * math.tan(self.angle)


def slope_objects(slope: Slope) -> tuple[SceneObject, ...]:
    """The ramp as one walkable static box tilted by ``angle`` (its top face the inclined plane, from
    the bottom edge on the floor to the top edge; thick enough to reach the floor under the top edge),
    then the landing (a walkable box as high as the top edge, ``landing`` deep), if any."""
    c, s = math.cos(slope.yaw), math.sin(slope.yaw)
    ca, sa = math.cos(slope.angle), math.sin(slope.angle)
    along = slope.length / ca  # the ramp's length on the incline
    thick = slope.height / ca + SEAM  # its bottom face meets the floor under the top edge
    # centre: the bottom edge + half the incline along it - half the thickness along the normal
    u, w = along / 2 * ca + thick / 2 * sa, along / 2 * sa - thick / 2 * ca  # in the climbing plane
    ramp = SceneObject(
        name=slope.name, shape="box", size=(along, slope.width, thick),
        position=(slope.position[0] + c * u, slope.position[1] + s * u, w),
        rpy=(0.0, -float(slope.angle), float(slope.yaw)), colour=slope.colour, friction=slope.friction,
        aliases=slope.aliases, walkable=True)
    if slope.landing <= 0:
        return (ramp,)
    d = slope.length + slope.landing / 2
    top = SceneObject(
        name=f"{slope.name}.top", shape="box", size=(slope.landing, slope.width, slope.height),
        position=(slope.position[0] + c * d, slope.position[1] + s * d, slope.height / 2),
        rpy=(0.0, 0.0, float(slope.yaw)), colour=slope.colour, friction=slope.friction, walkable=True)
    return ramp, top


def heightmap_object(hm: HeightMap) -> SceneObject:
    """The map as one walkable static ``heightfield`` object: its box from the floor to the map's top
    (at least 1 mm), centred over the grid, the grid in ``heights``."""
    sx, sy = hm.size
    top = max(max(max(r) for r in hm.heights), 1e-3)
    return SceneObject(name=hm.name, shape="heightfield", size=(sx, sy, top),
                       position=(hm.origin[0] + sx / 2, hm.origin[1] + sy / 2, top / 2), colour=hm.colour,
                       friction=hm.friction, aliases=hm.aliases, walkable=True, heights=hm.heights)


def field_surface(obj: SceneObject, x: float, y: float) -> tuple[float, tuple[float, float, float]] | None:
    """Height [m] and upward normal of a ``heightfield`` object's ground over (x, y) (bilinear in its
    cell, :func:`tasks.heightmap.grid_surface`), None outside its grid or for another shape."""
    if obj.heights is None:
        return None
    cell = obj.size[0] / (len(obj.heights[0]) - 1)
    origin = (obj.position[0] - obj.size[0] / 2, obj.position[1] - obj.size[1] / 2)
    return grid_surface(obj.heights, cell, origin, x, y)


@dataclass(frozen=True, slots=True, kw_only=True)
class Scene:
    """A floor plus named objects.

    Attributes:
        name: A label for reports.
        objects: The objects; their names and aliases are unique across the scene.
        floor_friction: Coulomb friction coefficient of the floor [-].
        stairs: Flights of stairs; each adds its treads to ``objects`` (:func:`stairs_objects`;
            an object equal to a tread is that tread, so a scene written out and read back is
            the same scene).
        slopes: Ramps; each adds its ramp and landing to ``objects`` (:func:`slope_objects`, likewise).
        heightmaps: Grids of ground heights; each adds a walkable ``heightfield`` object
            (:func:`heightmap_object`, likewise).
    """

    name: str = ""
    objects: tuple[SceneObject, ...] = ()
    floor_friction: float = 0.8
    stairs: tuple[Stairs, ...] = ()
    slopes: tuple[Slope, ...] = ()
    heightmaps: tuple[HeightMap, ...] = ()

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or len(self.name) > MAX_TEXT_LENGTH:
            raise field_error("name", f"must be a string of at most {MAX_TEXT_LENGTH} characters")
        if not isinstance(self.objects, tuple) or not all(isinstance(o, SceneObject) for o in self.objects):
            raise field_error("objects", "must be a list of objects")
        if not isinstance(self.stairs, tuple) or not all(isinstance(st, Stairs) for st in self.stairs):
            raise field_error("stairs", "must be a list of stairs")
        if not isinstance(self.slopes, tuple) or not all(isinstance(sl, Slope) for sl in self.slopes):
            raise field_error("slopes", "must be a list of slopes")
        treads = tuple(o for st in self.stairs for o in stairs_objects(st))
        treads += tuple(o for sl in self.slopes for o in slope_objects(sl))
        if not isinstance(self.heightmaps, tuple) or not all(isinstance(h, HeightMap) for h in self.heightmaps):
            raise field_error("heightmaps", "must be a list of height maps")
        treads += tuple(heightmap_object(h) for h in self.heightmaps)
        if treads:
            object.__setattr__(self, "objects", tuple(o for o in self.objects if o not in treads) + treads)
        if len(self.objects) > MAX_OBJECTS:
            raise field_error("objects", f"{len(self.objects)} objects; a scene holds at most {MAX_OBJECTS}")
        owner: dict[str, int] = {}
        for i, obj in enumerate(self.objects):
            for k, word in enumerate(obj.names):
                if word in owner:
                    field = f"objects[{i}].name" if k == 0 else f"objects[{i}].aliases[{k - 1}]"
                    raise field_error(field, f"{word!r} already names objects[{owner[word]}] "
                                              f"({self.objects[owner[word]].name!r}); names and aliases "
                                              "are unique in a scene")
                owner[word] = i
        if not (_finite(self.floor_friction) and 0 < self.floor_friction <= MAX_FRICTION):
            raise field_error("floor_friction", f"must be in (0, {MAX_FRICTION:g}], got {_show(self.floor_friction)}")

    def get(self, name: str) -> SceneObject:
        """The object called ``name`` or with that alias (KeyError otherwise)."""
        for obj in self.objects:
            if name in obj.names:
                return obj
        raise KeyError(name)


# --------------------------------------------------------------------------------------------------
# Geometry
# --------------------------------------------------------------------------------------------------


def rotation(rpy: Iterable[float]) -> tuple[tuple[float, float, float], ...]:
    """``R = Rz(y) Ry(p) Rx(r)`` as three rows."""
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    return ((cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr),
            (sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr),
            (-sp, cp * sr, cp * cr))


def to_local(obj: SceneObject, point: Iterable[float]) -> tuple[float, float, float]:
    """A world point in the object's frame (``R^T (p - position)``) [m]."""
    d = [a - b for a, b in zip(point, obj.position, strict=True)]
    R = rotation(obj.rpy)
    return (R[0][0] * d[0] + R[1][0] * d[1] + R[2][0] * d[2],
            R[0][1] * d[0] + R[1][1] * d[1] + R[2][1] * d[2],
            R[0][2] * d[0] + R[1][2] * d[1] + R[2][2] * d[2])


def signed_distance(obj: SceneObject, point: Iterable[float]) -> float | None:
    """Distance from a world point to the object's surface [m], negative inside.

    Exact for boxes, cylinders and spheres; None for meshes (their geometry is not read here); over
    a height field the height above its ground (below: negative), elsewhere the distance to its box.
    """
    if obj.shape == "heightfield":
        p = tuple(point)
        under = field_surface(obj, p[0], p[1])
        if under is not None:
            return p[2] - under[0]
    x, y, z = to_local(obj, point)
    if obj.shape == "sphere":
        return math.sqrt(x * x + y * y + z * z) - obj.size[0]
    if obj.shape in ("box", "heightfield"):
        q = [abs(c) - s / 2 for c, s in zip((x, y, z), obj.size, strict=True)]
        outside = math.sqrt(sum(max(c, 0.0) ** 2 for c in q))
        return outside + min(max(q), 0.0)
    if obj.shape == "cylinder":
        radius, length = obj.size
        qr, qz = math.hypot(x, y) - radius, abs(z) - length / 2
        return math.hypot(max(qr, 0.0), max(qz, 0.0)) + min(max(qr, qz), 0.0)
    return None


def extent(obj: SceneObject) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """World axis-aligned bounding box (lower, upper corners) of a box, cylinder or sphere [m]."""
    if obj.shape == "sphere":
        r = obj.size[0]
        half = (r, r, r)
    else:
        local = obj.size if obj.shape in ("box", "heightfield") else (2 * obj.size[0], 2 * obj.size[0], obj.size[1])
        if obj.shape == "mesh":
            local = (0.0, 0.0, 0.0)
        R = rotation(obj.rpy)
        half = tuple(sum(abs(R[i][j]) * local[j] / 2 for j in range(3)) for i in range(3))  # type: ignore[assignment]
    lo = tuple(c - h for c, h in zip(obj.position, half, strict=True))
    hi = tuple(c + h for c, h in zip(obj.position, half, strict=True))
    return lo, hi  # type: ignore[return-value]


def on_top(obj: SceneObject, point: Iterable[float], *, tolerance: float = GROUND_TOLERANCE) -> bool:
    """The point lies on the upward top face of an upright box or cylinder (a support surface), or
    of a walkable one tilted by at most :data:`MAX_SLOPE` (a slope)."""
    if obj.shape == "heightfield":
        p = tuple(point)
        under = field_surface(obj, p[0], p[1])
        return under is not None and abs(p[2] - under[0]) <= tolerance
    steepest = MAX_SLOPE if obj.walkable else math.radians(5)
    if obj.shape not in ("box", "cylinder") or rotation(obj.rpy)[2][2] < math.cos(steepest) - 1e-12:
        return False
    x, y, z = to_local(obj, point)
    top = obj.size[2] / 2 if obj.shape == "box" else obj.size[1] / 2
    if abs(z - top) > tolerance:
        return False
    if obj.shape == "box":
        return abs(x) <= obj.size[0] / 2 and abs(y) <= obj.size[1] / 2
    return math.hypot(x, y) <= obj.size[0]


def closest_object(scene: Scene, point: Iterable[float]) -> tuple[SceneObject, float] | None:
    """The object nearest to a world point and its signed distance [m] (None: no box/cylinder/sphere)."""
    p = tuple(point)
    best: tuple[SceneObject, float] | None = None
    for obj in scene.objects:
        d = signed_distance(obj, p)
        if d is not None and (best is None or d < best[1]):
            best = (obj, d)
    return best


def _where(obj: SceneObject) -> str:
    if obj.shape == "sphere":
        c = ", ".join(f"{v:.3g}" for v in obj.position)
        return f"the {obj.name} is a sphere of radius {obj.size[0]:.3g} m at ({c})"
    lo, hi = extent(obj)
    span = ", ".join(f"{a} {lo[i]:.3g}..{hi[i]:.3g}" for i, a in enumerate("xyz"))
    return f"the {obj.name} occupies {span} m"


def _point(p: Iterable[float]) -> str:
    return "(" + ", ".join(f"{v:.3g}" for v in p) + ")"


def _frame_words(frame: str) -> str:
    return frame.replace("_", " ")


def _relation(d: float) -> str:
    if d < -1e-9:
        return "inside"
    if d <= 1e-9:
        return "against"
    return f"{d * 100:.1f} cm from"


# --------------------------------------------------------------------------------------------------
# Files
# --------------------------------------------------------------------------------------------------


def scene_to_dict(scene: Scene) -> dict[str, Any]:
    """The JSON-compatible dictionary form of a scene file (with ``version``)."""
    from tasks.jsonio import to_plain

    return {"version": SCENE_VERSION, **to_plain(scene)}


def _strip_root(message: str) -> str:
    """``scene.objects[2].size: ...`` -> ``objects[2].size: ...`` (a scene file's own paths)."""
    if message.startswith("scene."):
        return message[len("scene."):]
    return message


def scene_from_dict(data: Any, *, base: str | Path | None = None) -> Scene:
    """Build a scene from its dictionary form (a scene file's content).

    Args:
        data: The parsed JSON.
        base: Folder that relative mesh paths are relative to (the scene file's); None keeps them.

    Raises:
        TaskDefinitionError: naming the field by its path (``objects[2].size: ...``).
    """
    import dataclasses

    from tasks.jsonio import _kind, _show, from_plain

    if not isinstance(data, dict):
        raise TaskDefinitionError(f"scene: expected a JSON object ({{...}}) at the top level, got {_kind(data)}")
    data = load_heightmaps(dict(data), base)
    version = data.pop("version", SCENE_VERSION)
    if isinstance(version, bool) or version != SCENE_VERSION:
        raise TaskDefinitionError(f"version: {_show(version)} is not supported (expected {SCENE_VERSION})")
    try:
        scene = from_plain(Scene, data, "scene")
    except TaskDefinitionError as e:
        raise TaskDefinitionError(_strip_root(str(e))) from None
    if base is not None:
        objects = tuple(
            dataclasses.replace(o, mesh=str((Path(base) / o.mesh).resolve())) if o.mesh is not None else o
            for o in scene.objects
        )
        scene = dataclasses.replace(scene, objects=objects)
    return scene


def scene_from_json(text: str, *, base: str | Path | None = None) -> Scene:
    """Parse a scene file's text (same JSON hardening as :func:`tasks.serialize.spec_from_json`)."""
    from tasks.jsonio import parse_json

    return scene_from_dict(parse_json(text, what="scene"), base=base)


def load_scene(path: str | Path) -> Scene:
    """Read a scene JSON file (``docs/scenes.md``).

    Mesh paths are resolved relative to the file's folder, and each mesh file must exist.

    Raises:
        TaskDefinitionError: the file is missing, a directory, unreadable, empty, too large, not
            UTF-8 (or UTF-16/32 with a byte-order mark), not JSON, or not a valid scene; the
            message starts with the file name and names the field (``objects[2].size``).
    """
    from tasks.jsonio import decode_spec_bytes, read_spec_bytes

    raw = read_spec_bytes(path, what="scene")
    where = "standard input" if str(path) == "-" else str(path)
    base = Path.cwd() if str(path) == "-" else Path(path).resolve().parent
    try:
        scene = scene_from_json(decode_spec_bytes(raw), base=base)
        check_scene_meshes(scene, hint=" (a mesh path is relative to the scene file)")
        return scene
    except TaskDefinitionError as e:
        raise TaskDefinitionError(f"{where}: {e}") from None


def check_scene_meshes(scene: Scene | None, prefix: str = "", hint: str = "") -> None:
    """Refuse a scene whose mesh file is missing or not a regular file (a FIFO would hang the
    mesh loaders, a device would be read without end): the rule of ``load_scene``, for a spec
    file that holds its scene."""
    import stat

    for i, obj in enumerate(scene.objects if scene is not None else ()):
        if obj.mesh is None:
            continue
        try:
            regular = stat.S_ISREG(Path(obj.mesh).stat().st_mode)
        except (OSError, ValueError):
            raise TaskDefinitionError(f"{prefix}objects[{i}].mesh: the mesh file {obj.mesh!r} does not exist{hint}") from None
        if not regular:
            raise TaskDefinitionError(f"{prefix}objects[{i}].mesh: {obj.mesh!r} is not a regular file (a FIFO, "
                                      "a device or a folder); give a mesh file (.stl, .obj, .dae)")


__all__ = [
    "MAX_SLOPE",
    "MAX_STEPS",
    "SCENE_MARGIN",
    "SCENE_VERSION",
    "SHAPES",
    "SIZE_LENGTHS",
    "Scene",
    "SceneObject",
    "Slope",
    "Stairs",
    "check_scene_meshes",
    "closest_object",
    "extent",
    "field_surface",
    "heightmap_object",
    "load_scene",
    "on_top",
    "rotation",
    "scene_from_dict",
    "scene_from_json",
    "scene_to_dict",
    "signed_distance",
    "slope_objects",
    "stairs_objects",
    "to_local",
]
