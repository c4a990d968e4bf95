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
import json
import os
from importlib import resources
from pathlib import Path

import numpy as np

from robots import Robot
from viz import motion as vm
from viz import scene
from viz._meshcat import meshcat, umsgpack
from viz.files import Staging, atomic_write_text

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
        self.commands.append(umsgpack.packb(message))

    def close(self) -> None:
        """Nothing to close (meshcat's API)."""


def meshcat_bundle() -> str:
    """Text of meshcat's bundled viewer (three.js + meshcat, ~0.85 MB)."""
    path = Path(meshcat.__file__).parent / "viewer" / "dist" / "main.min.js"
    return path.read_text(encoding="utf-8")


def _b64(data: bytes) -> str:
    return base64.b64encode(data).decode("ascii")


def build_page(robot: Robot, plan, *, execution=None, title: str = "") -> str:
    """The HTML text of the replay (see the module docstring)."""
    planned = vm.plan_motion(robot, plan)
    simulated = vm.execution_motion(robot, execution)

    window = RecordingWindow()
    vis = meshcat.Visualizer(window=window)
    scene.add_ground(vis)
    scene.add_robot(vis, robot, motion="planned")
    schedule = scene.add_markers(vis, robot, plan)
    scene.set_robot_configuration(vis, robot, planned.q[0], motion="planned")

    motions: dict[str, str] = {}
    durations: dict[str, float] = {}
    for m in (planned, simulated):
        if m is None:
            continue
        clips, duration = scene.motion_animations(vis, robot, m, robot_node="planned", fps=FPS)
        clips += scene.visibility_animations(vis, schedule, duration)
        motions[m.label] = _b64(umsgpack.packb(scene.animation_message(clips)))
        durations[m.label] = duration

    data = {
        "scene": [_b64(c) for c in window.commands],
        "motions": motions,
        "durations": durations,
        "camera": scene.camera_view(robot, np.asarray(plan.com, dtype=float)),
    }
    page_title = title or plan.spec.description or plan.spec.name or f"wbmp: {robot.name}"
    template = resources.files("viz").joinpath("player.html").read_text(encoding="utf-8")
    payload = json.dumps(data, separators=(",", ":"))
    return (template
            .replace("{{TITLE}}", html.escape(page_title))
            .replace("{{SUBTITLE}}", html.escape(_subtitle(robot, plan, simulated, execution)))
            .replace("{{MESHCAT}}", meshcat_bundle())
            .replace("{{DATA}}", payload.replace("</", "<\\/")))


def _subtitle(robot: Robot, plan, simulated: vm.Motion | None, execution=None) -> str:
    parts = [robot.name, f"{float(plan.t[-1]):.2f} s", f"{len(plan.t)} knots"]
    stats = getattr(plan, "stats", None)
    if stats is not None:
        parts.append(f"solver: {stats.status.name.lower()}")
    if simulated is not None:
        certificate = getattr(execution, "certificate", None)
        ok = getattr(certificate, "ok", None)
        parts.append("simulation included" if ok is None else
                     f"simulation: {'certified' if ok else 'FAILED the check'}")
    return " · ".join(parts)


def write_html(path: str | os.PathLike, robot: Robot, plan, *, execution=None, title: str = "",
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
        execution: Optional simulated execution (a ``sim`` Execution or a mapping with
            ``exec_t``/``exec_q``).
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
