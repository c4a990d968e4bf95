"""Build a meshcat scene for a plan: robot meshes, contacts, targets, CoM path, support polygon.

Every function takes the meshcat ``Visualizer`` it draws into; nothing here keeps a viewer. The
same functions feed the live viewer (:mod:`viz.live`) and the offline HTML (:mod:`viz.html`,
where the visualizer's window only records the commands).

Scene tree (under meshcat's ``/meshcat`` root)::

    wbmp/robot/<motion>/<geometry>        rigid placement of one visual geometry (animated)
    wbmp/robot/<motion>/<geometry>/mesh   the mesh, with its static scale (may be negative)
    wbmp/contacts/<foot>/<i>              a sole at its i-th distinct placement (shown when active);
                                          <foot> is left_foot/right_foot, else the frame name
    wbmp/support/<phase index>            support polygon of a phase, on the ground
    wbmp/targets/<target name>            frame target (sphere of radius = tolerance, min 2 cm)
    wbmp/com/path                         planned CoM path (line)
    wbmp/com/point, wbmp/com/ground       CoM and its ground projection (animated)
    wbmp/paths/<frame>                    planned path of each frame that has a target
    wbmp/scene/<object>                   a scene object at its pose (the spec's scene); a movable
                                          one animated along the motion's object poses
    wbmp/scene/<object>/shape             its shape (a cylinder turned upright; a mesh scaled)

Why ``<geometry>`` and ``<geometry>/mesh`` are separate nodes: animation tracks carry a
position and a quaternion, and a mirrored mesh (negative scale) has no rotation quaternion, so
the scale lives on a child node that never moves.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np
import pinocchio as pin

from robots import Robot, read_bytes
from viz import motion as vm
from viz._meshcat import mg, umsgpack

ROOT = "wbmp"
PLANNED_COLOR = None  # keep the URDF colours
SIMULATED_COLOR = (0.25, 0.45, 0.95)
CONTACT_COLOR = 0x2E9E4F
SUPPORT_COLOR = 0x1B7A3A
TARGET_COLOR = 0xF08C00
COM_COLOR = 0xD62828
COM_PATH_COLOR = 0xB01020
HAND_PATH_COLOR = 0x6A4C93


def node_name(text: str) -> str:
    """A meshcat path component: no slashes, no spaces."""
    return "".join(c if (c.isalnum() or c in "-_.") else "_" for c in text) or "_"


def _rgb_int(rgb: Sequence[float]) -> int:
    r, g, b = (int(round(255 * float(np.clip(x, 0.0, 1.0)))) for x in rgb[:3])
    return (r << 16) + (g << 8) + b


def _mesh_material(rgba: Sequence[float], override: tuple[float, float, float] | None,
                   opacity: float) -> mg.MeshPhongMaterial:
    rgb = override if override is not None else tuple(rgba[:3])
    if max(rgb) < 0.08:  # pitch-black meshes (iCub) vanish against the floor: lift them
        rgb = (0.22, 0.22, 0.24)
    alpha = float(rgba[3]) * opacity if override is None else opacity
    return mg.MeshPhongMaterial(color=_rgb_int(rgb), opacity=alpha, transparent=alpha < 1.0,
                                shininess=30)


class _MeshFile(mg.MeshGeometry):
    """A mesh file sent as is (``_meshfile_geometry``, the non-deprecated name in meshcat.js)."""

    def lower(self, object_data):
        return {"type": "_meshfile_geometry", "uuid": self.uuid, "format": self.mesh_format,
                "data": self.contents}


def _stl_file(path: str) -> _MeshFile:
    data = read_bytes(path, "mesh")
    return _MeshFile(umsgpack.Ext(0x12, data), "stl")  # 0x12: meshcat's Uint8Array extension


def _triangles(geom: pin.GeometryObject) -> mg.TriangularMeshGeometry | None:
    """The mesh as loaded by Pinocchio/coal (already scaled), or None if it is not a mesh."""
    shape = geom.geometry
    if hasattr(shape, "tri_indices") and hasattr(shape, "num_tris") and shape.num_tris > 0:
        vertices = np.asarray(shape.vertices(), dtype=np.float32)
        tris = (shape.tri_indices(k) for k in range(shape.num_tris))
        faces = np.array([(t[0], t[1], t[2]) for t in tris], dtype=np.uint32)
    else:
        return None
    if np.prod(np.sign(np.asarray(geom.meshScale, dtype=float))) < 0:
        faces = faces[:, [0, 2, 1]]  # a mirror turns the triangles inside out: restore the winding
    return mg.TriangularMeshGeometry(vertices, faces)


# -- compact meshes (the HTML replay): decimated by vertex clustering, quantized to 16 bits --

COMPACT_CELLS = 96  # clustering grid cells along a mesh's longest side
COMPACT_MAX_CELL = 0.004  # [m] largest clustering cell (a 4 mm grid on the robot's big parts)


class _PackedMesh(mg.Geometry):
    """An indexed triangle mesh whose positions are 16-bit integers over the mesh's bounding box
    (0..65535; the node above scales them back); three.js computes its normals.

    The integers are not marked ``normalized``: meshcat's three.js computes bounding spheres
    from the raw values, so normalized ones were culled by mistake (Talos' torso and head).
    """

    def __init__(self, positions: np.ndarray, faces: np.ndarray) -> None:
        super().__init__()
        self.positions = np.ascontiguousarray(positions, dtype=np.uint16)
        wide = int(faces.max(initial=0)) >= 1 << 16
        self.faces = np.ascontiguousarray(faces, dtype=np.uint32 if wide else np.uint16)

    def lower(self, object_data):
        index_type, index_code = ("Uint32Array", 0x16) if self.faces.dtype == np.uint32 else ("Uint16Array", 0x14)
        return {
            "uuid": self.uuid, "type": "BufferGeometry",
            "data": {
                "attributes": {"position": {"itemSize": 3, "type": "Uint16Array", "normalized": False,
                                            "array": umsgpack.Ext(0x14, self.positions.tobytes())}},
                "index": {"itemSize": 1, "type": index_type, "normalized": False,
                          "array": umsgpack.Ext(index_code, self.faces.tobytes())},
            },
        }


def stl_triangles(path: str) -> np.ndarray | None:
    """The triangles (n, 3, 3) of a binary STL file [file units], or None (ASCII or malformed)."""
    try:
        data = read_bytes(path, "mesh")
    except OSError:
        return None
    if len(data) < 84:
        return None
    n = int.from_bytes(data[80:84], "little")
    if n == 0 or 84 + 50 * n != len(data):
        return None
    record = np.dtype([("normal", "<f4", (3,)), ("v", "<f4", (3, 3)), ("attr", "<u2")])
    return np.frombuffer(data, dtype=record, count=n, offset=84)["v"].astype(float)


def decimate(triangles: np.ndarray, cell: float) -> tuple[np.ndarray, np.ndarray]:
    """Vertex clustering: weld the vertices of each ``cell``-sized grid cube into their mean.

    Args:
        triangles: (n, 3, 3) triangle corners [m].
        cell: Grid size [m].

    Returns:
        ``(vertices (m, 3), faces (k, 3))``: triangles that collapsed (two corners in one cell)
        and duplicates are dropped; the winding of every kept triangle is unchanged.
    """
    v = triangles.reshape(-1, 3)
    lo = v.min(axis=0)
    cells = np.floor((v - lo) / cell).astype(np.int64)
    size = cells.max(axis=0) + 1
    code = (cells[:, 0] * size[1] + cells[:, 1]) * size[2] + cells[:, 2]
    _, inverse = np.unique(code, return_inverse=True)
    inverse = inverse.reshape(-1)
    counts = np.bincount(inverse)
    vertices = np.zeros((len(counts), 3))
    np.add.at(vertices, inverse, v)
    vertices /= counts[:, None]
    faces = inverse.reshape(-1, 3)
    faces = faces[(faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2])]
    if len(faces):  # drop repeats of a triangle with the same winding (a thin shell's two sides stay)
        turn = np.argmin(faces, axis=1)
        rolled = np.stack([faces[np.arange(len(faces)), (turn + k) % 3] for k in range(3)], axis=1)
        _, first = np.unique(rolled, axis=0, return_index=True)
        faces = faces[np.sort(first)]
    used = np.unique(faces)
    remap = np.full(len(vertices), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    return vertices[used], remap[faces]


def _compact_geometry(geom: pin.GeometryObject) -> tuple[mg.Geometry, np.ndarray] | None:
    """(packed mesh, static transform) of a mesh geometry, or None when it is not a mesh."""
    scale = np.asarray(geom.meshScale, dtype=float)
    path = geom.meshPath or ""
    tris = stl_triangles(path) if path.lower().endswith(".stl") else None
    if tris is not None:
        tris = tris * scale
        mirrored = np.prod(np.sign(scale)) < 0
    else:
        loaded = _triangles(geom)
        if loaded is None:
            return None
        tris = np.asarray(loaded.vertices, dtype=float)[np.asarray(loaded.faces, dtype=np.int64)]
        mirrored = False  # _triangles already restored the winding
    if mirrored:
        tris = tris[:, [0, 2, 1]]
    if not len(tris) or not np.all(np.isfinite(tris)):
        return None
    extent = float(np.ptp(tris.reshape(-1, 3), axis=0).max())
    vertices, faces = decimate(tris, max(min(COMPACT_MAX_CELL, extent / COMPACT_CELLS), 1e-6))
    if not len(faces):
        return None
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    span = np.where(hi - lo > 1e-9, hi - lo, 1e-9)
    positions = np.round((vertices - lo) / span * 65535.0)
    static = np.eye(4)
    static[:3, :3] = np.diag(span / 65535.0)
    static[:3, 3] = lo
    return _PackedMesh(positions, faces), static


def _geometry_object(geom: pin.GeometryObject) -> tuple[mg.Geometry | None, np.ndarray]:
    """(meshcat geometry, static 4x4 transform of the mesh node) for a visual geometry.

    STL files are sent as they are (three.js' STL loader gives crisp per-face normals) with
    the mesh scale, possibly negative, on the static node. Other meshes (Collada, OBJ) are sent
    as the triangles Pinocchio loaded, which already include the scale: three.js' Collada
    loader fails on some multi-part files (iCub).
    """
    static = np.eye(4)
    path = geom.meshPath or ""
    ext = path.rsplit(".", 1)[-1].lower() if "." in path else ""
    if ext == "stl":
        static[:3, :3] = np.diag(np.asarray(geom.meshScale, dtype=float))
        return _stl_file(path), static
    tris = _triangles(geom)
    if tris is not None:
        return tris, static
    shape = geom.geometry
    kind = type(shape).__name__
    if kind == "Box":
        return mg.Box([float(2.0 * h) for h in shape.halfSide]), static
    if kind == "Sphere":
        return mg.Sphere(float(shape.radius)), static
    if kind in ("Cylinder", "Capsule"):
        # three.js cylinders run along y; URDF/coal cylinders along z.
        static[:3, :3] = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])
        return mg.Cylinder(float(2.0 * shape.halfLength), float(shape.radius)), static
    return None, static


def add_robot(vis, robot: Robot, *, motion: str = "planned",
              color: tuple[float, float, float] | None = PLANNED_COLOR, opacity: float = 1.0,
              compact: bool = False, prepared: Sequence[tuple[mg.Geometry, np.ndarray] | None] | None = None) -> list[str]:
    """Load the robot's visual meshes under ``wbmp/robot/<motion>``.

    Args:
        vis: A ``meshcat.Visualizer`` (live or recording).
        robot: The robot.
        motion: Sub-tree name (``planned``, ``simulated``).
        color: RGB in [0, 1] overriding the URDF colours, or None to keep them.
        opacity: Opacity in [0, 1].
        compact: Send meshes decimated (vertex clustering, :data:`COMPACT_MAX_CELL`) and
            quantized to 16 bits over their bounding box (the HTML replay; a Talos mesh set
            shrinks from ~8 MB to well under 1 MB), instead of the files as they are.
        prepared: With ``compact``, the packed meshes already made (one per geometry, None
            where it is not packed: :func:`viz.meshcache.compact_meshes`, cached on disk);
            default: made here.

    Returns:
        The node name of each visual geometry (in ``robot.visual_model`` order; None-free:
        geometries meshcat cannot show get an empty node).
    """
    base = vis[ROOT]["robot"][motion]
    names = []
    for i, geom in enumerate(robot.visual_model.geometryObjects):
        name = node_name(geom.name)
        names.append(name)
        if not compact:
            packed = None
        elif prepared is not None:
            packed = prepared[i]
        else:
            packed = _compact_geometry(geom)
        obj, static = packed if packed is not None else _geometry_object(geom)
        if obj is None:
            continue
        node = base[name]["mesh"]
        node.set_object(obj, _mesh_material(geom.meshColor, color, opacity))
        node.set_transform(static)
    return names


COLLISION_COLOR = 0xFF8C1A  # the collision capsules, translucent orange


def add_collision_capsules(vis, robot: Robot, *, motion: str = "planned", opacity: float = 0.35) -> int:
    """Draw the robot's collision capsules (robots/collision.py) under the visual geometry of their
    joint, so they follow the animation; returns how many were drawn."""
    from robots import collision_model

    base = vis[ROOT]["robot"][motion]
    by_joint: dict[int, pin.GeometryObject] = {}
    for geom in robot.visual_model.geometryObjects:
        by_joint.setdefault(int(geom.parentJoint), geom)
    material = mg.MeshLambertMaterial(color=COLLISION_COLOR, opacity=opacity, transparent=True)
    z_to_y = pin.SE3(pin.utils.rotate("x", np.pi / 2), np.zeros(3))  # meshcat's cylinder axis is y
    n = 0
    for i, capsule in enumerate(collision_model(robot).capsules):
        geom = by_joint.get(capsule.joint)
        if geom is None:
            continue
        node = base[node_name(geom.name)][f"capsule_{i}"]
        in_geom = geom.placement.inverse() * capsule.placement
        if capsule.length > 0:
            node["body"].set_object(mg.Cylinder(capsule.length, capsule.radius), material)
            node["body"].set_transform((in_geom * z_to_y).homogeneous)
        for end, sign in (("top", 0.5), ("bottom", -0.5)):
            M = in_geom * pin.SE3(np.eye(3), np.array([0.0, 0.0, sign * capsule.length]))
            node[end].set_object(mg.Sphere(capsule.radius), material)
            node[end].set_transform(M.homogeneous)
        n += 1
    return n


def set_robot_configuration(vis, robot: Robot, q: np.ndarray, *, motion: str = "planned") -> None:
    """Place the robot's geometries at configuration ``q`` (no animation)."""
    base = vis[ROOT]["robot"][motion]
    placements = vm.geometry_placements(robot, np.asarray(q, dtype=float)[None, :])
    for g, geom in enumerate(robot.visual_model.geometryObjects):
        base[node_name(geom.name)].set_transform(placements[g, 0])


def add_ground(vis, *, half_size: float = 2.0, spacing: float = 0.25) -> None:
    """A light floor with a grid at z = 0 (replaces meshcat's grid and axes, which are hidden).

    Args:
        vis: A ``meshcat.Visualizer``.
        half_size: Half the side of the square floor [m].
        spacing: Grid spacing [m].
    """
    vis["/Grid"].set_property("visible", False)
    vis["/Axes"].set_property("visible", False)
    floor = vis[ROOT]["ground"]
    floor["plane"].set_object(mg.Box([2 * half_size, 2 * half_size, 0.002]),
                              mg.MeshLambertMaterial(color=0xD9DCE1))
    floor["plane"].set_transform(_translation([0.0, 0.0, -0.0012]))
    ticks = np.arange(-half_size, half_size + 1e-9, spacing)
    segs = []
    for x in ticks:
        segs += [[x, -half_size, 0.0005], [x, half_size, 0.0005], [-half_size, x, 0.0005], [half_size, x, 0.0005]]
    pts = np.asarray(segs, dtype=np.float32).T
    floor["grid"].set_object(mg.LineSegments(mg.PointsGeometry(pts), mg.LineBasicMaterial(color=0xA4A9B2)))


def object_transform(obj) -> np.ndarray:
    """The 4x4 world placement of a scene object (``tasks.scene.SceneObject``): rpy + position."""
    T = np.eye(4)
    T[:3, :3] = pin.rpy.rpyToMatrix(*(float(a) for a in obj.rpy))
    T[:3, 3] = [float(c) for c in obj.position]
    return T


_UPRIGHT = np.array([[1.0, 0, 0, 0], [0, 0, -1.0, 0], [0, 1.0, 0, 0], [0, 0, 0, 1.0]])  # meshcat y axis -> z


def _ground_mesh(obj) -> mg.Geometry:
    """A height map's ground (``heightfield`` object) as two triangles per cell, in its box's frame."""
    h = np.asarray(obj.heights, dtype=float)
    nrow, ncol = h.shape
    xs = np.linspace(-obj.size[0] / 2, obj.size[0] / 2, ncol)
    ys = np.linspace(-obj.size[1] / 2, obj.size[1] / 2, nrow)
    X, Y = np.meshgrid(xs, ys)
    vertices = np.column_stack([X.ravel(), Y.ravel(), h.ravel() - obj.size[2] / 2]).astype(np.float32)
    i, j = np.meshgrid(np.arange(nrow - 1), np.arange(ncol - 1), indexing="ij")
    a = (i * ncol + j).ravel()
    faces = np.vstack([np.column_stack([a, a + 1, a + ncol + 1]), np.column_stack([a, a + ncol + 1, a + ncol])])
    return mg.TriangularMeshGeometry(vertices, faces.astype(np.uint32))


def _object_geometry(obj) -> tuple[mg.Geometry | None, np.ndarray]:
    """(meshcat geometry, static transform of the shape node) of a scene object."""
    size = [float(v) for v in obj.size]
    if obj.shape == "box":
        return mg.Box(size), np.eye(4)
    if obj.shape == "sphere":
        return mg.Sphere(size[0]), np.eye(4)
    if obj.shape == "cylinder":
        return mg.Cylinder(size[1], radius=size[0]), _UPRIGHT  # meshcat's cylinders run along y
    if obj.shape == "heightfield":
        return _ground_mesh(obj), np.eye(4)
    path = str(obj.mesh or "")
    suffix = path.rsplit(".", 1)[-1].lower()
    geometry: mg.Geometry | None = None
    if suffix in ("stl", "obj", "dae"):
        try:  # a regular file of bounded size only: a FIFO or a device is left out, never waited on
            raw = read_bytes(path, "mesh")
            if suffix == "stl":
                geometry = mg.MeshGeometry(umsgpack.Ext(0x12, raw), "stl")  # 0x12: Uint8Array
            else:
                geometry = mg.MeshGeometry(raw.decode("utf-8"), suffix)
        except (OSError, UnicodeDecodeError):
            geometry = None
    return geometry, np.diag([*size, 1.0])


def add_scene(vis, scene) -> list[str]:
    """Draw every object of a scene (``tasks.scene.Scene``; None draws nothing) in its colour.

    Returns:
        The node paths drawn (``wbmp/scene/<name>``); a mesh whose file cannot be read is left out.
    """
    drawn: list[str] = []
    if scene is None:
        return drawn
    for obj in scene.objects:
        geometry, shape_T = _object_geometry(obj)
        if geometry is None:
            continue
        r, g, b, a = (float(c) for c in obj.colour)
        material = mg.MeshLambertMaterial(color=_rgb_int((r, g, b)), opacity=a, transparent=a < 1.0)
        node = vis[ROOT]["scene"][node_name(obj.name)]
        node.set_transform(object_transform(obj))
        node["shape"].set_object(geometry, material)
        node["shape"].set_transform(shape_T)
        drawn.append(f"{ROOT}/scene/{node_name(obj.name)}")
    return drawn


def footprint(obj, *, segments: int = 48) -> np.ndarray | None:
    """The outline (k, 2) of a scene object seen from above (convex hull of its ground projection)
    [m]; None for a mesh (its extent is not read)."""
    size = [float(v) for v in obj.size]
    if obj.shape == "mesh":
        return None
    T = object_transform(obj)
    if obj.shape in ("box", "heightfield"):
        hx, hy, hz = (v / 2 for v in size)
        local = np.array([[sx * hx, sy * hy, sz * hz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    else:
        a = np.linspace(0.0, 2 * np.pi, segments, endpoint=False)
        r = size[0]
        if obj.shape == "sphere":
            centre = T[:2, 3]
            return np.column_stack([centre[0] + r * np.cos(a), centre[1] + r * np.sin(a)])
        ring = np.column_stack([r * np.cos(a), r * np.sin(a)])
        half = size[1] / 2
        local = np.vstack([np.column_stack([ring, np.full(segments, -half)]),
                           np.column_stack([ring, np.full(segments, half)])])
    world = local @ T[:3, :3].T + T[:3, 3]
    return _hull(world[:, :2])


def _hull(points: np.ndarray) -> np.ndarray:
    """Convex hull of 2-D points, counter-clockwise (monotone chain)."""
    pts = sorted({(round(float(x), 12), round(float(y), 12)) for x, y in points})
    if len(pts) <= 2:
        return np.array(pts)

    def cross(o, a, b) -> float:
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower: list[tuple[float, float]] = []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    upper: list[tuple[float, float]] = []
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    return np.array(lower[:-1] + upper[:-1])


def _translation(p: Sequence[float]) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = p
    return T


def _line(points: np.ndarray, color: int, *, loop: bool = False, width: float = 2.0) -> mg.Object:
    pts = np.asarray(points, dtype=np.float32).T
    cls = mg.LineLoop if loop else mg.Line
    return cls(mg.PointsGeometry(pts), mg.LineBasicMaterial(color=color, linewidth=width))


def _sole_box(corners: np.ndarray) -> tuple[mg.Box, np.ndarray]:
    """A thin box covering a sole rectangle given by its 4 world corners."""
    c = np.asarray(corners, dtype=float)
    ex, ey = c[1] - c[0], c[3] - c[0]
    lx, ly = float(np.linalg.norm(ex)), float(np.linalg.norm(ey))
    R = np.eye(3)
    R[:, 0] = ex / lx
    R[:, 2] = np.cross(ex, ey) / np.linalg.norm(np.cross(ex, ey))
    R[:, 1] = np.cross(R[:, 2], R[:, 0])
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = c.mean(axis=0) + R[:, 2] * 0.002
    return mg.Box([lx, ly, 0.004]), T


def add_markers(vis, robot: Robot, plan, *, com: np.ndarray | None = None) -> dict[str, list[tuple[float, bool]]]:
    """Draw contacts, support polygons, frame targets and the planned CoM path.

    Args:
        vis: A ``meshcat.Visualizer``.
        robot: The robot.
        plan: A :class:`planner.Plan`.
        com: Planned CoM path (T, 3) [m]; default ``plan.com``.

    Returns:
        Visibility schedule of the phase-dependent nodes: node path (relative to the
        visualizer) -> [(time [s], visible), ...], for :func:`visibility_animations`. What is
        active in the last phase stays visible at the very end.
    """
    root = vis[ROOT]
    schedule: dict[str, list[tuple[float, bool]]] = {}
    phases = vm.support_phases(robot, plan)
    horizon = plan.spec.horizon

    def interval(start: float, end: float) -> list[tuple[float, bool]]:
        return [(start, True)] if end >= horizon - 1e-9 else [(start, True), (end, False)]

    # contacts: one node per distinct sole placement of each frame (feet named by role)
    seen: dict[str, list[np.ndarray]] = {}
    for p_index, ph in enumerate(phases):
        for frame, corners in ph.soles.items():
            side = robot.foot_side(robot.profile.frame(frame) or frame)
            name = f"{side}_foot" if side else node_name(frame)
            places = seen.setdefault(name, [])
            match = next((i for i, c in enumerate(places) if np.abs(c - corners).max() < 5e-3), None)
            if match is None:
                places.append(corners)
                match = len(places) - 1
                box, T = _sole_box(corners)
                node = root["contacts"][name][str(match)]
                node["sole"].set_object(box, mg.MeshLambertMaterial(color=CONTACT_COLOR, opacity=0.8))
                node["sole"].set_transform(T)
            key = f"{ROOT}/contacts/{name}/{match}"
            schedule.setdefault(key, []).extend(interval(ph.start, ph.end))
        if len(ph.polygon) >= 3:
            ring = np.column_stack([ph.polygon, np.full(len(ph.polygon), 0.003)])
            root["support"][str(p_index)].set_object(_line(ring, SUPPORT_COLOR, loop=True, width=3.0))
            key = f"{ROOT}/support/{p_index}"
            schedule[key] = interval(ph.start, ph.end)

    # frame targets, and the planned path of each targeted frame
    drawn: set[str] = set()
    for target in plan.spec.targets:
        if target.frame not in drawn and len(plan.q) >= 2:
            drawn.add(target.frame)
            path = vm.frame_trajectory(robot, np.asarray(plan.q, dtype=float), target.frame)
            root["paths"][node_name(target.frame)].set_object(_line(path, HAND_PATH_COLOR, width=2.0))
        if target.position is None:
            continue
        radius = max(float(target.tolerance), 0.02)
        node = root["targets"][node_name(target.name)]
        node.set_object(mg.Sphere(radius), mg.MeshLambertMaterial(color=TARGET_COLOR, opacity=0.6))
        node.set_transform(_translation(target.position))

    com_path = np.asarray(plan.com if com is None else com, dtype=float)
    if len(com_path) >= 2:
        root["com"]["path"].set_object(_line(com_path, COM_PATH_COLOR, width=3.0))
        ground = com_path.copy()
        ground[:, 2] = 0.002
        root["com"]["ground_path"].set_object(_line(ground, COM_PATH_COLOR, width=1.0))
    root["com"]["point"].set_object(mg.Sphere(0.03), mg.MeshLambertMaterial(color=COM_COLOR))
    # a flat disk: meshcat cylinders run along y, so the (static) child node turns it upright
    disk = root["com"]["ground"]["disk"]
    disk.set_object(mg.Cylinder(0.004, 0.025), mg.MeshLambertMaterial(color=COM_COLOR))
    disk.set_transform(np.array([[1.0, 0, 0, 0], [0, 0, -1.0, 0], [0, 1.0, 0, 0], [0, 0, 0, 1.0]]))
    return _finish_schedule(schedule)


def _finish_schedule(schedule: dict[str, list[tuple[float, bool]]]) -> dict[str, list[tuple[float, bool]]]:
    """Merge touching intervals: [(0,T),(1,F),(1,T),(2,F)] -> [(0,T),(2,F)]."""
    out = {}
    for key, events in schedule.items():
        events = sorted(events, key=lambda e: (e[0], e[1]))  # at a tie, False first then True
        merged: list[tuple[float, bool]] = []
        for t, vis_ in events:
            if merged and abs(merged[-1][0] - t) < 1e-9:
                merged[-1] = (t, vis_ or merged[-1][1])
            else:
                merged.append((t, vis_))
        if merged and merged[0][0] > 1e-9:
            merged.insert(0, (0.0, False))
        out[key] = [e for i, e in enumerate(merged) if i == 0 or e[1] != merged[i - 1][1]]
    return out


def _track(name: str, kind: str, times: Iterable[float], values: np.ndarray, *, packed: bool = False) -> dict:
    if packed:  # float32 typed arrays (msgpack extension 0x17): 4 bytes a number instead of 9
        return {
            "name": "." + name,
            "type": kind,
            "times": umsgpack.Ext(0x17, np.asarray(list(times), dtype="<f4").tobytes()),
            "values": umsgpack.Ext(0x17, np.asarray(values, dtype="<f4").reshape(-1).tobytes()),
        }
    return {
        "name": "." + name,
        "type": kind,
        "times": [float(t) for t in times],
        "values": [float(x) for x in np.asarray(values, dtype=float).reshape(-1)],
    }


def _bool_track(times: Iterable[float], values: Iterable[bool]) -> dict:
    return {"name": ".visible", "type": "boolean", "times": [float(t) for t in times],
            "values": [bool(v) for v in values]}


def _clip(tracks: list[dict]) -> dict:
    return {"fps": 1.0, "name": "default", "tracks": tracks}


def motion_animations(vis, robot: Robot, motion: vm.Motion, *, robot_node: str = "planned",
                      fps: float = 30.0, markers: bool = True, packed: bool = False,
                      objects: bool = True) -> tuple[list[dict], float]:
    """Animation clips (meshcat's lowered form) that replay ``motion`` on the robot.

    Args:
        vis: The visualizer (only its path is used).
        robot: The robot.
        motion: Planned or simulated motion.
        robot_node: Which ``wbmp/robot/<node>`` sub-tree to animate.
        fps: Key frames per second [1/s].
        markers: Also animate the CoM point and its ground projection.
        packed: Times and values as float32 typed arrays (the HTML replay) instead of lists.
        objects: Also move the movable scene objects (``wbmp/scene/<object>``) along the motion's
            object poses (``motion.objects``: planned or simulated, see :func:`object_animations`).

    Returns:
        ``(clips, duration)``: a list of ``{"path", "clip"}`` dicts and the duration [s].
    """
    times, qs = vm.resample(robot, motion, fps)
    placements = vm.geometry_placements(robot, qs)
    base = vis[ROOT]["robot"][robot_node]
    clips = []
    for g, geom in enumerate(robot.visual_model.geometryObjects):
        Ts = placements[g]
        pos = Ts[:, :3, 3]
        quat = np.array([pin.Quaternion(T[:3, :3]).coeffs() for T in Ts])  # x, y, z, w
        # keep consecutive quaternions in the same hemisphere (cheaper interpolation)
        for i in range(1, len(quat)):
            if quat[i] @ quat[i - 1] < 0:
                quat[i] = -quat[i]
        clips.append({
            "path": base[node_name(geom.name)].path.lower(),
            "clip": _clip([_track("position", "vector3", times, pos, packed=packed),
                           _track("quaternion", "quaternion", times, quat, packed=packed)]),
        })
    if markers:
        com = vm.com_trajectory(robot, qs)
        ground = com.copy()
        ground[:, 2] = 0.0
        clips.append({"path": vis[ROOT]["com"]["point"].path.lower(),
                      "clip": _clip([_track("position", "vector3", times, com, packed=packed)])})
        clips.append({"path": vis[ROOT]["com"]["ground"].path.lower(),
                      "clip": _clip([_track("position", "vector3", times, ground, packed=packed)])})
    if objects:
        clips += object_animations(vis, motion, times, packed=packed)
    return clips, float(times[-1])


def object_animations(vis, motion: vm.Motion, times: np.ndarray, *, packed: bool = False) -> list[dict]:
    """Clips that move each object of ``motion.objects`` (its node ``wbmp/scene/<object>``, drawn by
    :func:`add_scene`) through its poses, sampled at ``times`` [s] from the motion's start."""
    clips = []
    t = np.asarray(motion.t, dtype=float) - float(motion.t[0])
    for name, poses in motion.objects.items():
        sampled = vm.resample_poses(t, poses, np.asarray(times, dtype=float))
        quat = sampled[:, 3:].copy()
        for i in range(1, len(quat)):  # consecutive quaternions in one hemisphere
            if quat[i] @ quat[i - 1] < 0:
                quat[i] = -quat[i]
        clips.append({"path": vis[ROOT]["scene"][node_name(name)].path.lower(),
                      "clip": _clip([_track("position", "vector3", times, sampled[:, :3], packed=packed),
                                     _track("quaternion", "quaternion", times, quat, packed=packed)])})
    return clips


def visibility_animations(vis, schedule: dict[str, list[tuple[float, bool]]], duration: float) -> list[dict]:
    """Clips that switch phase-dependent nodes on and off (see :func:`add_markers`)."""
    clips = []
    for key, events in schedule.items():
        node = vis
        for part in key.split("/"):
            node = node[part]
        times = [min(t, duration) for t, _ in events]
        values = [v for _, v in events]
        if times[-1] < duration:
            times.append(duration)
            values.append(values[-1])
        clips.append({"path": node.path.lower(), "clip": _clip([_bool_track(times, values)])})
    return clips


def animation_message(clips: list[dict], *, play: bool = True, loop: bool = True) -> dict:
    """The lowered ``set_animation`` command meshcat's viewer understands."""
    return {
        "type": "set_animation",
        "path": "",
        "animations": clips,
        "options": {"play": bool(play), "repetitions": 1_000_000 if loop else 1,
                    "clampWhenFinished": True},
    }


def camera_view(robot: Robot, plan_com: np.ndarray | None = None) -> dict[str, list[float]]:
    """A three-quarter front view framing the robot: camera position and orbit target.

    Returns:
        ``{"position": [...], "target": [...]}`` in meshcat's camera frame (three.js y-up:
        world (x, y, z) -> (x, z, -y)).
    """
    h = max(robot.height(), 0.5)
    centre = np.zeros(3) if plan_com is None or len(plan_com) == 0 else np.mean(plan_com, axis=0)
    target_w = np.array([centre[0], centre[1], 0.5 * h])
    eye_w = target_w + h * np.array([1.35, 0.95, 0.35])

    def to_cam(p: np.ndarray) -> list[float]:
        return [float(p[0]), float(p[2]), float(-p[1])]

    return {"position": to_cam(eye_w), "target": to_cam(target_w)}
