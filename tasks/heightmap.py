"""Height maps: uneven ground as a grid of heights (a scene's ``heightmaps``, docs/scenes.md).

A :class:`HeightMap` is a rectangular grid of heights above the floor [m]: ``heights[i][j]`` is the
ground's height at ``(origin[0] + j * cell, origin[1] + i * cell)`` (row ``i`` along +y, column
``j`` along +x, row 0 at the origin), read from a ``.npy`` or ``.csv`` file (``file``, relative to
the scene file) or given inline (``heights``). Between the grid points the ground is the bilinear
interpolation of the four corners of its cell (:func:`grid_surface`: height and upward normal);
MuJoCo collides with the same grid as a height field (two triangles per cell: within
``|h00 + h11 - h01 - h10| / 4`` of the bilinear surface inside a cell, equal on the grid points and
on a plane). When a scene is built each map becomes a walkable static object of shape
``heightfield`` (:func:`tasks.scene.heightmap_object`), so the footsteps, MuJoCo and the viewers see
it like the other terrain.

The grid is validated (one-line errors naming the field, exit 3): 2 to :data:`MAX_GRID` points a
side, every row as long as the first (no ragged grid), every height a finite number in
``[0, MAX_HEIGHT]`` (the map rises from the floor: no pits), a cell of ``[MIN_CELL, MAX_CELL]``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tasks.exceptions import TaskDefinitionError, field_error
from tasks.limits import MAX_DISTANCE, MAX_FRICTION, MAX_NAME_LENGTH, MAX_TEXT_LENGTH

MAX_GRID = 256  # grid points along a side
MAX_HEIGHT = 2.0  # [m] the highest point of a height map
MIN_CELL, MAX_CELL = 0.005, 1.0  # [m] the spacing of the grid points
GRID_SUFFIXES = (".npy", ".csv")
MAX_GRID_BYTES = 16 * 1024 * 1024  # a grid file (256 x 256 float64 .npy: 0.5 MB)

Grid = tuple[tuple[float, ...], ...]


def _number(v: Any) -> bool:
    return not isinstance(v, bool) and isinstance(v, (int, float))


def check_grid(heights: Any, where: str = "heights") -> Grid:
    """The grid as a tuple of rows of floats, or TaskDefinitionError naming the first problem:
    not a list of rows, fewer than 2 or more than :data:`MAX_GRID` points a side, a ragged row, a
    height that is not a finite number in [0, :data:`MAX_HEIGHT`] m."""
    if not isinstance(heights, (tuple, list)) or not all(isinstance(r, (tuple, list)) for r in heights):
        raise field_error(where, "must be a grid: a list of rows of heights [m]")
    if not 2 <= len(heights) <= MAX_GRID:
        raise field_error(where, f"has {len(heights)} row(s); a height map needs 2 to {MAX_GRID} rows")
    width = len(heights[0])
    for i, row in enumerate(heights):
        if len(row) != width:
            raise field_error(where, f"row {i} has {len(row)} heights, row 0 has {width}: the grid must be "
                                "rectangular (every row as long)")
    if not 2 <= width <= MAX_GRID:
        raise field_error(where, f"has {width} column(s); a height map needs 2 to {MAX_GRID} columns")
    for i, row in enumerate(heights):
        for j, h in enumerate(row):
            if not _number(h) or not math.isfinite(h):
                raise field_error(where, f"row {i}, column {j} is {h!r}, not a number: every grid point needs a "
                                    "finite height [m]")
            if not 0.0 <= h <= MAX_HEIGHT:
                raise field_error(where, f"row {i}, column {j} is {h:g} m; heights are in [0, {MAX_HEIGHT:g}] m "
                                    "(the map rises from the floor: no pits)")
    return tuple(tuple(float(h) for h in row) for row in heights)


def read_grid(path: str | Path, where: str = "file") -> Grid:
    """The heights of a ``.npy`` (a 2-D array) or ``.csv`` (rows of comma-separated numbers) file."""
    import numpy as np

    p = Path(path)
    if p.suffix.lower() not in GRID_SUFFIXES:
        raise field_error(where, f"{str(path)!r} is not a .npy or .csv file of heights")
    try:
        if not p.is_file():
            raise field_error(where, f"the grid file {str(path)!r} does not exist (a path is relative to the scene file)")
        if p.stat().st_size > MAX_GRID_BYTES:
            raise field_error(where, f"{str(path)!r} is larger than {MAX_GRID_BYTES // 2**20} MB; "
                                f"a grid holds at most {MAX_GRID} x {MAX_GRID} heights")
        if p.suffix.lower() == ".npy":
            array = np.load(p, allow_pickle=False)
        else:
            text = p.read_text(encoding="utf-8")
            rows = [line for line in text.splitlines() if line.strip() and not line.lstrip().startswith("#")]
            array = [[float(v) for v in line.split(",")] for line in rows]
    except TaskDefinitionError:
        raise
    except (OSError, ValueError, UnicodeDecodeError) as e:
        raise field_error(where, f"cannot read the grid in {str(path)!r} ({str(e).splitlines()[0][:80]}): "
                            "give a 2-D .npy array or a .csv of comma-separated heights") from None
    if isinstance(array, np.ndarray):
        if array.ndim != 2 or array.dtype.kind not in "fiu":
            raise field_error(where, f"{str(path)!r} holds a {array.ndim}-D {array.dtype} array; give a 2-D array "
                                "of heights [m]")
        array = array.tolist()
    return check_grid(array, where)


def grid_surface(heights: Grid, cell: float, origin: tuple[float, float], x: float,
                 y: float) -> tuple[float, tuple[float, float, float]] | None:
    """Height [m] and upward unit normal of the bilinear surface over (x, y), None outside the grid."""
    u, v = (x - origin[0]) / cell, (y - origin[1]) / cell
    ncol, nrow = len(heights[0]), len(heights)
    if not (-1e-9 <= u <= ncol - 1 + 1e-9 and -1e-9 <= v <= nrow - 1 + 1e-9):
        return None
    j, i = min(max(int(math.floor(u)), 0), ncol - 2), min(max(int(math.floor(v)), 0), nrow - 2)
    fu, fv = u - j, v - i
    h00, h01, h10, h11 = heights[i][j], heights[i][j + 1], heights[i + 1][j], heights[i + 1][j + 1]
    z = (1 - fu) * (1 - fv) * h00 + fu * (1 - fv) * h01 + (1 - fu) * fv * h10 + fu * fv * h11
    dx = ((1 - fv) * (h01 - h00) + fv * (h11 - h10)) / cell
    dy = ((1 - fu) * (h10 - h00) + fu * (h11 - h01)) / cell
    norm = math.sqrt(1.0 + dx * dx + dy * dy)
    return z, (-dx / norm, -dy / norm, 1.0 / norm)


@dataclass(frozen=True, slots=True, kw_only=True)
class HeightMap:
    """A grid of ground heights (a scene file's ``heightmaps`` element).

    Attributes:
        name: Name of the map (``ground``, ``mound``): what sentences call it.
        heights: The grid [m], rows along +y, columns along +x (a scene file may give ``file`` instead).
        file: The ``.npy`` or ``.csv`` file the heights were read from (in a scene file, relative to it).
        cell: Spacing of the grid points along x and y [m].
        origin: World (x, y) of the grid point ``heights[0][0]`` [m].
        extent: Optional (x, y) size of the grid [m]: when given it must be ``(columns - 1, rows - 1) * cell``.
        colour: RGBA in [0, 1].
        friction: Coulomb friction coefficient of its surface [-].
        aliases: Other names of the map (``bump``, 土堆).
    """

    name: str = "ground"
    heights: Grid = ()
    file: str | None = field(default=None, metadata={"omit_none": True})
    cell: float = 0.05
    origin: tuple[float, float] = (0.0, 0.0)
    extent: tuple[float, float] | None = field(default=None, metadata={"omit_none": True})
    colour: tuple[float, float, float, float] = (0.55, 0.5, 0.4, 1.0)
    friction: float = 0.8
    aliases: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if (not isinstance(self.name, str) or not self.name.strip() or len(self.name) > MAX_NAME_LENGTH
                or self.name != self.name.strip()):
            raise field_error("name", f"must be a non-empty name of at most {MAX_NAME_LENGTH} characters")
        if self.file is not None and (not isinstance(self.file, str) or len(self.file) > MAX_TEXT_LENGTH
                                      or "\x00" in self.file):
            raise field_error("file", "must be the path of a .npy or .csv file of heights")
        if not self.heights:
            raise field_error("heights", 'a height map needs its grid: "file": a .npy or .csv of heights [m] '
                                    '(or "heights": a list of rows)')
        object.__setattr__(self, "heights", check_grid(self.heights))
        if not (_number(self.cell) and MIN_CELL <= self.cell <= MAX_CELL):
            raise field_error("cell", f"must be a spacing in [{MIN_CELL:g}, {MAX_CELL:g}] m, got {self.cell!r}")
        if (not isinstance(self.origin, tuple) or len(self.origin) != 2
                or not all(_number(v) and math.isfinite(v) and abs(v) <= MAX_DISTANCE for v in self.origin)):
            raise field_error("origin", f"must be 2 numbers (x, y) within {MAX_DISTANCE:g} m, got {self.origin!r}")
        size = self.size
        if self.extent is not None and (
                not isinstance(self.extent, tuple) or len(self.extent) != 2
                or not all(_number(v) and abs(v - s) <= 1e-6 for v, s in zip(self.extent, size, strict=True))):
            raise field_error("extent", f"is {self.extent!r} but {len(self.heights[0])} x {len(self.heights)} points "
                                   f"{self.cell:g} m apart span [{size[0]:g}, {size[1]:g}] m: fix the cell or the extent")
        if max(abs(self.origin[0]) + size[0], abs(self.origin[1]) + size[1]) > MAX_DISTANCE:
            raise field_error("extent", f"the grid reaches beyond {MAX_DISTANCE:g} m from the origin")
        if (not isinstance(self.colour, tuple) or len(self.colour) != 4
                or not all(_number(v) and 0 <= v <= 1 for v in self.colour)):
            raise field_error("colour", "must be 4 numbers (red, green, blue, opacity) in [0, 1]")
        if not (_number(self.friction) and 0 < self.friction <= MAX_FRICTION):
            raise field_error("friction", f"must be in (0, {MAX_FRICTION:g}], got {self.friction!r}")
        if not isinstance(self.aliases, tuple) or not all(isinstance(a, str) and a.strip() for a in self.aliases):
            raise field_error("aliases", "must be a list of names")

    @property
    def size(self) -> tuple[float, float]:
        """(x, y) extent of the grid [m]."""
        return ((len(self.heights[0]) - 1) * self.cell, (len(self.heights) - 1) * self.cell)


def load_heightmaps(data: dict, base: str | Path | None) -> dict:
    """A scene file's dictionary with every ``heightmaps[i].file`` read into ``heights`` (relative to
    ``base``, the scene file's folder; the working folder when None)."""
    maps = data.get("heightmaps")
    if not isinstance(maps, list):
        return data
    out = []
    for i, hm in enumerate(maps):
        if isinstance(hm, dict) and isinstance(hm.get("file"), str) and "heights" not in hm:
            path = Path(base or ".") / hm["file"]
            hm = {**hm, "heights": [list(r) for r in read_grid(path, f"heightmaps[{i}].file")]}
        out.append(hm)
    return {**data, "heightmaps": out}


__all__ = ["GRID_SUFFIXES", "MAX_CELL", "MAX_GRID", "MAX_HEIGHT", "MIN_CELL", "HeightMap", "check_grid",
           "grid_surface", "load_heightmaps", "read_grid"]
