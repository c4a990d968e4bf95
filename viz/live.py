"""The live meshcat viewer: a loopback-only server process, the scene, the motion looping.

:func:`serve` starts meshcat's server in a child process bound to 127.0.0.1
(:mod:`viz._loopback_server`), talks to it over ZMQ with send/receive timeouts (never
``vis.wait()``, which can hang forever), loads the scene and a looping animation, prints the
URL, and waits for Ctrl-C or ``stop_event``. The server process is always stopped on the way
out, whatever the reason.
"""

from __future__ import annotations

import os
import selectors
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, TextIO

from robots import Robot
from viz import motion as vm
from viz import scene
from viz._meshcat import meshcat, umsgpack, zmq
from viz.exceptions import ViewerError

if TYPE_CHECKING:
    from sim.execution import Execution

START_TIMEOUT = 30.0  # [s] for the server process to print its URLs
ZMQ_TIMEOUT_MS = 10_000  # [ms] per command round trip
STOP_TIMEOUT = 5.0  # [s] between SIGTERM and SIGKILL
FPS = 30.0


@dataclass(frozen=True, kw_only=True)
class ServerInfo:
    """Where the live viewer runs.

    Attributes:
        web_url: Page to open in a browser (on 127.0.0.1).
        zmq_url: Command socket (on 127.0.0.1).
        pid: Server process id.
    """

    web_url: str
    zmq_url: str
    pid: int


class LiveWindow:
    """A meshcat window over a ZMQ REQ socket with timeouts (replaces meshcat's ViewerWindow)."""

    def __init__(self, zmq_url: str, *, timeout_ms: int = ZMQ_TIMEOUT_MS) -> None:
        self._context = zmq.Context()
        self.socket = self._context.socket(zmq.REQ)
        self.socket.setsockopt(zmq.LINGER, 0)
        self.socket.setsockopt(zmq.RCVTIMEO, timeout_ms)
        self.socket.setsockopt(zmq.SNDTIMEO, timeout_ms)
        self.socket.connect(zmq_url)

    def send(self, command) -> None:
        """Send a meshcat command object and wait for the server's acknowledgement."""
        self.send_lowered(command.lower())

    def send_lowered(self, message: dict) -> None:
        """Send an already lowered command dictionary.

        Raises:
            ViewerError: the server did not answer in time.
        """
        try:
            self.socket.send_multipart([message["type"].encode(), message["path"].encode(),
                                        umsgpack.packb(message)])
            self.socket.recv()
        except zmq.Again:
            raise ViewerError("the meshcat server did not answer within "
                              f"{int(self.socket.getsockopt(zmq.RCVTIMEO)) / 1000:.0f} s") from None

    def close(self) -> None:
        """Close the socket (no lingering messages)."""
        self.socket.close(linger=0)
        self._context.term()


def start_server(*, port: int | None = None, timeout: float = START_TIMEOUT) -> tuple[subprocess.Popen, ServerInfo]:
    """Start the loopback meshcat server process and read its URLs.

    Raises:
        ViewerError: the process exited or printed nothing within ``timeout`` seconds.
    """
    src = str(Path(__file__).resolve().parents[1])
    env = dict(os.environ)
    env["PYTHONPATH"] = src + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    cmd = [sys.executable, "-u", "-m", "viz._loopback_server"]
    if port is not None:
        cmd += ["--port", str(int(port))]
    proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, env=env, cwd=src, start_new_session=True)
    assert proc.stdout is not None and proc.stderr is not None  # both are pipes
    urls: dict[str, str] = {}
    deadline = time.monotonic() + timeout
    buffer = b""
    try:
        with selectors.DefaultSelector() as sel:
            sel.register(proc.stdout, selectors.EVENT_READ)
            while len(urls) < 2:
                left = deadline - time.monotonic()
                if left <= 0:
                    raise ViewerError(f"the meshcat server did not start within {timeout:.0f} s")
                if not sel.select(timeout=min(left, 0.2)):
                    if proc.poll() is not None:
                        break
                    continue
                chunk = os.read(proc.stdout.fileno(), 4096)
                if not chunk:
                    break
                buffer += chunk
                *lines, buffer = buffer.split(b"\n")
                for line in lines:
                    key, _, value = line.decode("utf-8", "replace").strip().partition("=")
                    if key in ("zmq_url", "web_url"):
                        urls[key] = value
        if len(urls) < 2:
            stop_server(proc)
            err = _drain_stderr(proc)
            raise ViewerError(f"the meshcat server exited before it was ready{': ' + err if err else ''}")
    except BaseException:
        stop_server(proc)
        if not proc.stderr.closed:
            _drain_stderr(proc)
        raise
    # stderr carries the server's websocket log: keep reading it so the pipe never fills
    threading.Thread(target=_discard, args=(proc.stderr,), daemon=True).start()
    return proc, ServerInfo(web_url=urls["web_url"], zmq_url=urls["zmq_url"], pid=proc.pid)


def _drain_stderr(proc: subprocess.Popen) -> str:
    """Last line of the (dead or dying) server's stderr; closes the pipe."""
    assert proc.stderr is not None  # start_server's pipe
    try:
        proc.wait(timeout=2.0)
        lines = proc.stderr.read().decode("utf-8", "replace").strip().splitlines()
    except (subprocess.TimeoutExpired, OSError, ValueError):
        lines = []
    finally:
        proc.stderr.close()
    return lines[-1] if lines else ""


def _discard(stream) -> None:
    """Read a pipe until EOF (the server's exit), then close it."""
    try:
        while stream.read(65536):
            pass
    except (OSError, ValueError):
        pass
    finally:
        stream.close()


def stop_server(proc: subprocess.Popen, *, timeout: float = STOP_TIMEOUT) -> None:
    """Stop the server process: close its stdin, SIGTERM, then SIGKILL after ``timeout``."""
    if proc.poll() is None:
        try:
            if proc.stdin is not None:
                proc.stdin.close()
        except OSError:
            pass
        proc.terminate()
        try:
            proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=timeout)
    for stream in (proc.stdin, proc.stdout):
        try:
            if stream is not None:
                stream.close()
        except OSError:
            pass


def load_scene(vis, robot: Robot, plan, *, execution: Execution | None = None, collisions: bool = False) -> tuple[float, list[float]]:
    """Draw the plan (and the simulated robot, translucent blue; with ``collisions``, the collision
    capsules, translucent orange) and start the looping animation.

    Returns:
        The motion duration [s] and the camera's orbit target (camera frame) for the page URL.
    """
    planned = vm.plan_motion(robot, plan)
    simulated = vm.execution_motion(robot, execution)
    scene.add_ground(vis)
    scene.add_robot(vis, robot, motion="planned")
    if collisions:
        scene.add_collision_capsules(vis, robot, motion="planned")
    if simulated is not None:
        scene.add_robot(vis, robot, motion="simulated", color=scene.SIMULATED_COLOR, opacity=0.45)
    schedule = scene.add_markers(vis, robot, plan)
    scene.add_scene(vis, getattr(plan.spec, "scene", None))
    scene.set_robot_configuration(vis, robot, planned.q[0], motion="planned")
    # one node per object: it follows the simulation when there is one (where the objects went),
    # else the plan (docs/objects.md, "In the replay and the motion file")
    sim_objects = simulated is not None and bool(simulated.objects)
    clips, duration = scene.motion_animations(vis, robot, planned, robot_node="planned", fps=FPS,
                                              objects=not sim_objects)
    if simulated is not None:
        scene.set_robot_configuration(vis, robot, simulated.q[0], motion="simulated")
        sim_clips, sim_duration = scene.motion_animations(vis, robot, simulated, robot_node="simulated",
                                                          fps=FPS, markers=False, objects=sim_objects)
        clips += sim_clips
        duration = max(duration, sim_duration)
    clips += scene.visibility_animations(vis, schedule, duration)
    cam = scene.camera_view(robot, plan.com)
    vis["/Cameras/default/rotated/<object>"].set_property("position", cam["position"])
    vis.window.send_lowered(scene.animation_message(clips, play=True, loop=True))
    return duration, cam["target"]


def serve(robot: Robot, plan, *, execution: Execution | None = None, port: int | None = None, open_browser: bool = False,
          stop_event: threading.Event | None = None, stream: TextIO | None = None,
          on_ready: Callable[[ServerInfo], None] | None = None, collisions: bool = False) -> None:
    """Show ``plan`` in a live meshcat viewer on 127.0.0.1 until Ctrl-C or ``stop_event``.

    The motion loops in the browser (the animation is stored by the server, so a page opened
    later gets it too). With an execution, the simulated robot is drawn translucent blue over
    the planned one.

    Args:
        robot: The robot.
        plan: A :class:`planner.Plan`.
        execution: Optional simulated execution.
        port: Web port; default the first free port from 7000.
        open_browser: Also open the page in the default browser.
        stop_event: Set it (from another thread) to stop the viewer.
        collisions: Also draw the robot's collision capsules (translucent orange).
        stream: Where the URL line is printed; default ``sys.stdout``.
        on_ready: Called with the :class:`ServerInfo` once the scene is loaded.

    Raises:
        ViewerError: the server could not start, or died while serving.
        VizInputError: the plan does not match the robot.
    """
    out = sys.stdout if stream is None else stream
    vm.plan_motion(robot, plan)  # validate before starting a process
    proc, info = start_server(port=port)
    window = None
    try:
        window = LiveWindow(info.zmq_url)
        vis = meshcat.Visualizer(window=window)
        duration, target = load_scene(vis, robot, plan, execution=execution, collisions=collisions)
        url = info.web_url + "#target=" + ",".join(f"{x:.3f}" for x in target)
        print(f"meshcat viewer: {url}  ({duration:.2f} s motion, looping; Ctrl-C to stop)",
              file=out, flush=True)
        if on_ready is not None:
            on_ready(info)
        if open_browser:
            import webbrowser

            webbrowser.open(url, new=2)
        while stop_event is None or not stop_event.is_set():
            if proc.poll() is not None:
                raise ViewerError(f"the meshcat server exited unexpectedly (code {proc.returncode})")
            if stop_event is not None:
                stop_event.wait(0.2)
            else:
                time.sleep(0.2)
    except KeyboardInterrupt:
        print("meshcat viewer stopped", file=out, flush=True)
    finally:
        if window is not None:
            window.close()
        stop_server(proc)
