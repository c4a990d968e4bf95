"""Headless Debian chromium for the HTML tests: screenshots with every network request trapped.

Every run goes through a local "proxy" that accepts connections on 127.0.0.1, records the
first line of each request and answers 403, so a page that tried to load anything from the
network would both fail to and leave a trace. ``file://`` pages do not use the proxy.
"""

from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import threading
import time
from pathlib import Path

import numpy as np

SHOT_TIMEOUT = 90.0  # [s] per screenshot (3-6 s normally; the machine may be busy)
WINDOW = (1280, 720)


def find_chromium() -> str | None:
    """Path of a chromium binary, or None."""
    for name in ("chromium", "chromium-browser"):
        path = shutil.which(name)
        if path:
            return path
    return None


class RequestTrap:
    """A loopback TCP server that records request lines and refuses them.

    Each connection is answered in its own thread, so an idle one (chromium's speculative
    preconnect) cannot hold up the next; :meth:`settle` waits until every connection made so
    far has been recorded.
    """

    REQUEST_TIMEOUT = 60.0  # [s] for a connected client to send its request line (loaded machine)

    def __init__(self) -> None:
        self.requests: list[str] = []
        self._lock = threading.Lock()
        self._handlers: list[threading.Thread] = []
        self._last_accept = time.monotonic()
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self._sock.bind(("127.0.0.1", 0))
        self._sock.listen(16)
        self._sock.settimeout(0.2)
        self.port = self._sock.getsockname()[1]
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        while not self._stop.is_set():
            try:
                conn, _ = self._sock.accept()
            except (TimeoutError, OSError):
                continue
            handler = threading.Thread(target=self._answer, args=(conn,), daemon=True)
            with self._lock:
                self._last_accept = time.monotonic()
                self._handlers.append(handler)
            handler.start()

    def _answer(self, conn: socket.socket) -> None:
        with conn:
            conn.settimeout(self.REQUEST_TIMEOUT)
            try:
                head = conn.recv(4096).split(b"\r\n", 1)[0].decode("latin-1")
            except OSError:
                head = "<no request line>"
            with self._lock:
                self.requests.append(head)
            try:
                conn.sendall(b"HTTP/1.1 403 Forbidden\r\nContent-Length: 0\r\nConnection: close\r\n\r\n")
            except OSError:
                pass

    def settle(self, quiet: float = 1.0, limit: float = REQUEST_TIMEOUT) -> None:
        """Wait (at most ``limit`` s) until every accepted connection is recorded and none was
        accepted for ``quiet`` s. Call it after the browser has exited: its sockets are closed."""
        deadline = time.monotonic() + limit
        while time.monotonic() < deadline:
            with self._lock:
                busy = any(h.is_alive() for h in self._handlers)
                idle = time.monotonic() - self._last_accept
            if not busy and idle >= quiet:
                return
            time.sleep(0.05)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=10.0)
        self._sock.close()


def screenshot(chromium: str, url: str, out: Path, profile_dir: Path, proxy_port: int) -> np.ndarray:
    """Render ``url`` headless into ``out`` and return its RGB pixels (H, W, 3) uint8."""
    from PIL import Image

    cmd = [
        chromium, "--headless", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader",
        "--disable-quic", "--no-first-run", "--disable-background-networking",
        "--disable-component-update", "--disable-sync", "--disable-default-apps",
        "--disable-extensions", "--metrics-recording-only", "--no-default-browser-check",
        f"--proxy-server=http://127.0.0.1:{proxy_port}", "--proxy-bypass-list=<-loopback>",
        f"--user-data-dir={profile_dir}", f"--window-size={WINDOW[0]},{WINDOW[1]}",
        "--hide-scrollbars", f"--screenshot={out}", url,
    ]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True)
    try:
        _, err = proc.communicate(timeout=SHOT_TIMEOUT)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        raise
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    if not out.is_file():
        raise RuntimeError(f"chromium wrote no screenshot (exit {proc.returncode}): {err.decode()[-500:]}")
    return np.asarray(Image.open(out).convert("RGB"))


def changed_fraction(a: np.ndarray, b: np.ndarray, threshold: int = 24) -> float:
    """Fraction of pixels whose largest channel difference exceeds ``threshold``."""
    diff = np.abs(a.astype(int) - b.astype(int)).max(axis=2)
    return float(np.mean(diff > threshold))
