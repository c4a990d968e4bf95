"""One standalone HTML file that replays a plan (and its simulation) in meshcat's viewer.

No server and no network: a :class:`RecordingWindow` stands in for meshcat's ZMQ window and
keeps every command as msgpack bytes; the file embeds meshcat's bundled ``main.min.js``, the
commands (base64, replayed synchronously and in order at load) and a small player (play/pause,
time slider, planned/simulated switch). Nothing in the page is fetched: every resource is
inline, and the only URLs in the file are XML namespace strings inside the meshcat bundle.

URL fragment (read once at load), e.g. ``motion.html#t=1.5&motion=simulated``:
``t=SECONDS`` opens paused at that time; ``motion=planned|simulated`` picks the motion;
``hide=robot,markers,grid,gui`` hides parts (used by the screenshot tests).
"""

from __future__ import annotations

import base64
import html
import importlib.util
import json
import os
import re
import zlib
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING

from viz.files import Staging, atomic_write_text

if TYPE_CHECKING:
    from robots import Robot
    from sim.execution import Execution

# meshcat's drawing modules (viz._meshcat; never its server, IPython, zmq or tornado), Pinocchio
# and numpy are imported by the functions that need them: render_page() of a cached replay needs
# none of them (wbmp solve's motion cache)

FPS = 30.0  # key frames per second of the replay


class RecordingWindow:
    """A meshcat window that records commands instead of sending them to a server."""

    def __init__(self) -> None:
        self.commands: list[bytes] = []

    def send(self, command) -> None:
        """Record a meshcat command object (``SetObject``, ``SetTransform``...)."""
        self.send_lowered(command.lower())

    def send_lowered(self, message: dict) -> None:
        """Record an already lowered command dictionary."""
        from viz._meshcat import umsgpack

        self.commands.append(umsgpack.packb(message))

    def close(self) -> None:
        """Nothing to close (meshcat's API)."""


class RecordingVisualizer:
    """The drawing half of ``meshcat.Visualizer`` (paths, objects, transforms, properties,
    animations) sending meshcat's own command objects to a :class:`RecordingWindow`: the same
    commands, without importing meshcat's server (IPython, tornado, PIL: ~0.3 s)."""

    __slots__ = ("path", "window")

    def __init__(self, window: RecordingWindow, path=None) -> None:
        from viz._meshcat import Path

        self.window = window
        self.path = Path(("meshcat",)) if path is None else path

    def __getitem__(self, path: str) -> RecordingVisualizer:
        return RecordingVisualizer(self.window, self.path.append(path))

    def set_object(self, geometry, material=None) -> None:
        """Record a ``set_object`` (a geometry and its material, or an object)."""
        from viz._meshcat import commands

        self.window.send(commands.SetObject(geometry, material, self.path))

    def set_transform(self, matrix=None) -> None:
        """Record a ``set_transform`` (4x4; default the identity)."""
        import numpy as np

        from viz._meshcat import commands

        self.window.send(commands.SetTransform(np.eye(4) if matrix is None else matrix, self.path))

    def set_property(self, key: str, value) -> None:
        """Record a ``set_property``."""
        from viz._meshcat import commands

        self.window.send(commands.SetProperty(key, value, self.path))

    def set_animation(self, animation, play: bool = True, repetitions: int = 1) -> None:
        """Record a ``set_animation`` (a ``meshcat.animation.Animation``)."""
        from viz._meshcat import commands

        self.window.send(commands.SetAnimation(animation, play=play, repetitions=repetitions))

    def delete(self) -> None:
        """Record a ``delete`` of this path."""
        from viz._meshcat import commands

        self.window.send(commands.Delete(self.path))


def meshcat_bundle() -> str:
    """Text of meshcat's bundled viewer (three.js + meshcat, ~0.85 MB)."""
    spec = importlib.util.find_spec("meshcat")  # its folder, without importing it
    if spec is None or spec.origin is None:
        from viz._meshcat import meshcat  # raises the import guard's error

        origin = meshcat.__file__
    else:
        origin = spec.origin
    path = Path(origin).parent / "viewer" / "dist" / "main.min.js"
    return path.read_text(encoding="utf-8")


def _b64(data: bytes) -> str:
    return base64.b64encode(data).decode("ascii")


def build_page(robot: Robot, plan, *, execution: Execution | None = None, title: str = "") -> str:
    """The HTML text of the replay (see the module docstring)."""
    return render_page(page_data(robot, plan, execution=execution), robot.name, plan, execution=execution,
                       title=title)


def page_data(robot: Robot, plan, *, execution: Execution | None = None) -> str:
    """The replay's data (scene, motions, camera) as the page embeds it: the part of the page
    that needs the robot model; it does not depend on the title (the motion cache keeps it)."""
    import numpy as np

    from viz import motion as vm
    from viz import scene
    from viz._meshcat import umsgpack
    from viz.meshcache import compact_meshes, replay_robot

    # on a mesh cache hit, a stand-in whose visual model holds no mesh (none is loaded)
    robot = replay_robot(robot)
    planned = vm.plan_motion(robot, plan)
    simulated = vm.execution_motion(robot, execution)

    window = RecordingWindow()
    vis = RecordingVisualizer(window)
    scene.add_ground(vis)
    scene.add_robot(vis, robot, motion="planned", compact=True, prepared=compact_meshes(robot))
    schedule = scene.add_markers(vis, robot, plan)
    scene.add_scene(vis, getattr(plan.spec, "scene", None))
    scene.set_robot_configuration(vis, robot, planned.q[0], motion="planned")

    motions: dict[str, bytes] = {}
    durations: dict[str, float] = {}
    for m in (planned, simulated):
        if m is None:
            continue
        clips, duration = scene.motion_animations(vis, robot, m, robot_node="planned", fps=FPS, packed=True)
        clips += scene.visibility_animations(vis, schedule, duration)
        motions[m.label] = umsgpack.packb(scene.animation_message(clips))
        durations[m.label] = duration

    header = {
        "scene": [len(c) for c in window.commands],
        "motions": {name: len(blob) for name, blob in motions.items()},
        "durations": durations,
        "camera": scene.camera_view(robot, np.asarray(plan.com, dtype=float)),
    }
    return pack_data(header, [*window.commands, *motions.values()])


def pack_data(header: dict, blobs: list[bytes]) -> str:
    """The page's data: raw DEFLATE of (4-byte little-endian header length, header JSON, the
    blobs one after the other), base64-encoded. The page inflates it synchronously with its own
    small decoder (``player.html``), so the scene is drawn before the load event ends (headless
    screenshots, the browser test); ``DecompressionStream`` would make that asynchronous."""
    head = json.dumps(header, separators=(",", ":")).encode("utf-8")
    raw = b"".join([len(head).to_bytes(4, "little"), head, *blobs])
    # level 1: a third to half of level 9's time, and ~1 % larger (talos four steps: 2.89 MB, not 2.86)
    packer = zlib.compressobj(1, zlib.DEFLATED, -15)
    return _b64(packer.compress(raw) + packer.flush())


def unpack_data(text: str) -> dict:
    """The data of a page written by :func:`write_html` (for tests and tools): ``scene`` (the
    recorded meshcat commands, msgpack bytes), ``motions`` (name -> msgpack bytes of the
    animation command), ``durations`` and ``camera``."""
    m = re.search(r'<script type="application/octet-stream" id="wbmp-data">(.*?)</script>', text, re.S)
    if m is None:
        raise ValueError("not a wbmp HTML replay (no wbmp-data element)")
    raw = zlib.decompress(base64.b64decode(m.group(1)), -15)
    n = int.from_bytes(raw[:4], "little")
    header = json.loads(raw[4:4 + n])
    at = 4 + n
    scene_cmds = []
    for size in header["scene"]:
        scene_cmds.append(raw[at:at + size])
        at += size
    motions = {}
    for name, size in header["motions"].items():
        motions[name] = raw[at:at + size]
        at += size
    return {"scene": scene_cmds, "motions": motions, "durations": header["durations"], "camera": header["camera"]}


def render_page(data: str, robot_name: str, plan, *, execution: Execution | None = None, title: str = "",
                meshcat_src: str | None = None) -> str:
    """The page around :func:`page_data`'s data: title, subtitle, meshcat's viewer, the player.

    ``meshcat_src``: load meshcat's bundle from this same-origin URL instead of embedding it
    (``wbmp serve``'s viewer: the browser fetches the 0.85 MB once for every motion)."""
    page_title = title or plan.spec.description or plan.spec.name or f"wbmp: {robot_name}"
    template = resources.files("viz").joinpath("player.html").read_text(encoding="utf-8")
    bundle = meshcat_bundle() if meshcat_src is None else \
        f'</script><script src="{html.escape(meshcat_src)}">'  # an empty inline script, then the file
    return (template
            .replace("{{TITLE}}", html.escape(page_title))
            .replace("{{SUBTITLE}}", html.escape(_subtitle(robot_name, plan, execution)))
            .replace("{{MESHCAT}}", bundle)
            .replace("{{DATA}}", data))


def _subtitle(robot_name: str, plan, execution: Execution | None = None) -> str:
    parts = [robot_name, f"{float(plan.t[-1]):.2f} s", f"{len(plan.t)} knots"]
    stats = getattr(plan, "stats", None)
    if stats is not None:
        parts.append(f"solver: {stats.status.name.lower()}")
    scene = getattr(getattr(plan, "spec", None), "scene", None)
    if scene is not None and scene.objects:
        names = [o.name for o in scene.objects]
        shown = ", ".join(names[:4]) + (f" and {len(names) - 4} more" if len(names) > 4 else "")
        parts.append(f"scene: {shown}")
    if execution is not None:
        certificate = execution.certificate
        parts.append("simulation included" if certificate is None else
                     f"simulation: {'certified' if certificate.ok else 'FAILED the check'}")
        for stop in () if certificate is None else certificate.stops:  # the E-stops (sim.estop, docs/safety.md)
            if isinstance(stop, dict) and stop.get("message"):
                parts.append(str(stop["message"]))
    return " · ".join(parts)


def write_html(path: str | os.PathLike, robot: Robot, plan, *, execution: Execution | None = None, title: str = "",
               staging: Staging | None = None) -> Path:
    """Write a standalone HTML replay of ``plan`` (and of ``execution`` when given).

    The page shows the robot's meshes, the contact soles (while active), the support polygon of
    each phase, the frame targets, the CoM path and a CoM marker, with play/pause, a time
    slider and, when an execution is given, a planned/simulated switch. Open
    ``file.html#t=1.5`` to start paused at 1.5 s. Nothing is fetched from the network.

    Args:
        path: Output file; written atomically (temporary file, then ``os.replace``; see
            :mod:`viz.files` for the mode of the file).
        robot: The robot the plan is for.
        plan: A :class:`planner.Plan`.
        execution: Optional simulated execution (a :class:`sim.Execution`).
        title: Page title; default the spec's description or name.
        staging: Stage the file there (renamed into place by ``staging.commit()``, together with
            the command's other outputs) instead of writing it now (:mod:`viz.files`).

    Returns:
        The path written.

    Raises:
        VizInputError: the plan or execution arrays do not match the robot.
    """
    text = build_page(robot, plan, execution=execution, title=title)
    if staging is None:
        return atomic_write_text(path, text)
    data = text.encode("utf-8")
    return staging.add(path, lambda fh: fh.write(data))
