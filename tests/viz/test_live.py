"""The live meshcat viewer: loopback only, URL printed, scene + looping animation, always stopped."""

from __future__ import annotations

import asyncio
import contextlib
import io
import os
import socket
import threading
import time
import urllib.request
from pathlib import Path

import pytest

from viz import ViewerError
from viz._meshcat import umsgpack
from viz.live import ServerInfo, serve

# Bounds on hangs, not on speed: each wait ends as soon as its event happens, so they can be
# generous for a loaded 2-core machine (a fraction of a second to a few seconds when idle).
READY_TIMEOUT = 120.0  # [s] the viewer's server is up
STOP_TIMEOUT = 60.0  # [s] the viewer stops after stop_event
SCENE_TIMEOUT = 120.0  # [s] the whole scene reaches a websocket client


def listening_addresses(port: int) -> set[str]:
    """Local addresses (hex, as in /proc/net/tcp*) of sockets listening on ``port``."""
    out = set()
    for name in ("/proc/net/tcp", "/proc/net/tcp6"):
        path = Path(name)
        if not path.exists():
            continue
        for line in path.read_text().splitlines()[1:]:
            fields = line.split()
            addr, hex_port = fields[1].rsplit(":", 1)
            if fields[3] == "0A" and int(hex_port, 16) == port:
                out.add(addr)
    return out


LOOPBACK = {"0100007F", "00000000000000000000000001000000"}  # 127.0.0.1, ::1


def _receive_scene(web_url: str, n_objects: int, linger: float = 1.0) -> list[dict]:
    """Messages a new websocket client gets: read until ``n_objects`` set_object messages and
    the animation have arrived (the server sends its whole scene on connection), then for
    ``linger`` more quiet seconds to catch anything extra; at most SCENE_TIMEOUT in all."""
    from tornado.websocket import websocket_connect

    async def run() -> list[dict]:
        loop = asyncio.get_running_loop()
        deadline = loop.time() + SCENE_TIMEOUT
        conn = await asyncio.wait_for(
            websocket_connect(web_url.replace("http://", "ws://").replace("/static/", "/")), SCENE_TIMEOUT)
        messages: list[dict] = []

        def complete() -> bool:
            kinds = [m["type"] for m in messages]
            return kinds.count("set_object") >= n_objects and "set_animation" in kinds

        while loop.time() < deadline:
            wait = min(linger, deadline - loop.time()) if complete() else deadline - loop.time()
            try:
                msg = await asyncio.wait_for(conn.read_message(), max(wait, 0.0))
            except TimeoutError:
                break
            if msg is None:
                break
            messages.append(umsgpack.unpackb(msg))
        conn.close()
        # close() only sends the close frame: wait for the server's reply, which closes the socket
        # (left open, it is collected later as an unclosed socket during whatever test runs then)
        with contextlib.suppress(TimeoutError):
            while await asyncio.wait_for(conn.read_message(), SCENE_TIMEOUT) is not None:
                pass
        return messages

    return asyncio.run(run())


@contextlib.contextmanager
def _serving(robot, plan, execution, stream):
    """A live viewer served in a thread: yields its ServerInfo once ready; on leaving, stops it and
    checks that serve() returned within STOP_TIMEOUT and raised nothing."""
    stop = threading.Event()
    ready: list[ServerInfo] = []
    errors: list[BaseException] = []

    def target() -> None:
        try:
            serve(robot, plan, execution=execution, stop_event=stop, stream=stream, on_ready=ready.append)
        except BaseException as e:  # noqa: BLE001 - reported below
            errors.append(e)

    thread = threading.Thread(target=target, daemon=True)
    thread.start()
    deadline = time.monotonic() + READY_TIMEOUT
    while not ready and thread.is_alive() and time.monotonic() < deadline:
        time.sleep(0.05)
    try:
        assert ready, f"viewer not ready: {errors}"
        yield ready[0]
    finally:
        stop.set()
        thread.join(STOP_TIMEOUT)
    assert not thread.is_alive(), f"serve() did not return within {STOP_TIMEOUT} s of stop_event"
    assert errors == []


def test_live_viewer_serves_on_loopback_and_stops(talos, synth_plan, synth_execution):
    out = io.StringIO()
    with _serving(talos, synth_plan, synth_execution, out) as info:
        assert info.web_url.startswith("http://127.0.0.1:") and info.web_url in out.getvalue()
        web_port = int(info.web_url.split(":")[2].split("/")[0])
        zmq_port = int(info.zmq_url.rsplit(":", 1)[1])
        for port in (web_port, zmq_port):
            addrs = listening_addresses(port)
            assert addrs and addrs <= LOOPBACK, f"port {port} listens on {addrs}"
        with urllib.request.urlopen(info.web_url, timeout=60) as r:
            assert r.status == 200 and b"MeshCat" in r.read()
        n_geoms = len(talos.visual_model.geometryObjects)
        messages = _receive_scene(info.web_url, 2 * n_geoms)
        kinds = [m["type"] for m in messages]
        assert kinds.count("set_object") >= 2 * n_geoms  # planned + simulated robots
        (anim,) = [m for m in messages if m["type"] == "set_animation"]
        assert anim["options"]["repetitions"] > 1000  # loops
        paths = {a["path"] for a in anim["animations"]}
        assert sum(p.startswith("/meshcat/wbmp/robot/planned/") for p in paths) == n_geoms
        assert sum(p.startswith("/meshcat/wbmp/robot/simulated/") for p in paths) == n_geoms
    with pytest.raises(ProcessLookupError):
        os.kill(info.pid, 0)  # the server process is gone (and reaped)


def test_busy_port_is_a_clear_error(talos, synth_plan):
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen(1)
        port = s.getsockname()[1]
        t0 = time.monotonic()
        with pytest.raises(ViewerError, match="exited before it was ready"):
            serve(talos, synth_plan, port=port, stream=io.StringIO())
        assert time.monotonic() - t0 < READY_TIMEOUT


def test_live_viewer_moves_the_held_object_as_simulated(talos, pick_plan, pick_execution):
    """With a simulation, meshcat's server (real, on loopback) gives a new client one animation clip
    for the cup's node, following the simulated poses (3 cm below the planned ones here): its key
    frame at 2.5 s holds the execution's cup pose at that time; the box no hand holds has its clip at
    its place."""
    import numpy as np

    from tests.viz.test_scene_objects import object_clip_at

    with _serving(talos, pick_plan, pick_execution, io.StringIO()) as info:
        n_geoms = len(talos.visual_model.geometryObjects)
        messages = _receive_scene(info.web_url, 2 * n_geoms)
        (anim,) = [m for m in messages if m["type"] == "set_animation"]
        paths = [a["path"] for a in anim["animations"]]
        assert paths.count("/meshcat/wbmp/scene/cup") == 1  # one node: the simulated poses, not the planned too
        pose, at = object_clip_at(anim, "cup", 2.5)
        t, cup = pick_execution.t, pick_execution.objects["cup"]
        assert np.abs(pose[:3] - [np.interp(at, t, cup[:, i]) for i in range(3)]).max() < 1e-9
        box, _ = object_clip_at(anim, "box", 2.5)
        assert np.allclose(box[:3], pick_plan.spec.scene.get("box").position)
        shapes = {m["path"] for m in messages if m["type"] == "set_object"}
        assert "/meshcat/wbmp/scene/cup/shape" in shapes

