"""Scenes: the world around the robot, as data (a floor plus named objects).

A :class:`Scene` is what ``wbmp solve ... --scene FILE`` loads and what a :class:`~tasks.specs.TaskSpec`
carries in its ``scene`` field. Every object is a primitive shape (or a mesh) at a pose in the
world frame (z up, ground at z = 0, SI units):

* ``box``: ``size = (sx, sy, sz)``, full edge lengths [m], centred on ``position``;
* ``cylinder``: ``size = (radius, length)`` [m], axis along the object's z, centred on ``position``;
* ``sphere``: ``size = (radius,)`` [m];
* ``mesh``: ``mesh`` is a file path (STL/OBJ/DAE) and ``size = (sx, sy, sz)`` its scale.

``rpy`` is roll-pitch-yaw [rad] with ``R = Rz(y) Ry(p) Rx(r)`` (Pinocchio's convention). A static
object never moves (mass ignored); a movable one is a free body with ``mass`` [kg] and
``friction`` [-]. The planner keeps the robot at least its margin away from every object except
in planned contacts; the simulation adds the objects as MuJoCo geoms (movable ones as free bodies).
"""

from __future__ import annotations

from dataclasses import dataclass

SHAPES = ("box", "cylinder", "sphere", "mesh")
SIZE_LENGTHS = {"box": 3, "cylinder": 2, "sphere": 1, "mesh": 3}


@dataclass(frozen=True, slots=True, kw_only=True)
class SceneObject:
    """One named object of a scene.

    Attributes:
        name: Unique name (``table``), what sentences and messages call it.
        shape: One of :data:`SHAPES`.
        size: Shape dimensions [m], see the module docstring.
        position: Centre of the shape in the world frame [m].
        rpy: Orientation, roll-pitch-yaw [rad].
        colour: RGBA in [0, 1].
        aliases: Other names a sentence may use (``desk``, 桌子).
        movable: A free body (True) or fixed to the world (False).
        mass: [kg], movable objects only.
        friction: Coulomb friction coefficient [-].
        mesh: Mesh file path (shape ``mesh`` only).
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


@dataclass(frozen=True, slots=True, kw_only=True)
class Scene:
    """A floor plus named objects.

    Attributes:
        name: A label for reports.
        objects: The objects, names unique.
        floor_friction: Coulomb friction coefficient of the floor [-].
    """

    name: str = ""
    objects: tuple[SceneObject, ...] = ()
    floor_friction: float = 0.8

    def get(self, name: str) -> SceneObject:
        """The object called ``name`` (KeyError otherwise)."""
        for obj in self.objects:
            if obj.name == name:
                return obj
        raise KeyError(name)
