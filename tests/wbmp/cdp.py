"""Headless chromium driven over the Chrome DevTools protocol on a pipe (standard library only).

``--remote-debugging-pipe``: chromium reads commands on fd 3 and writes replies and events on
fd 4, each a JSON message ended by a NUL byte. :class:`Browser` starts chromium with one page,
attaches to it (a flat session) and offers the few calls the ``wbmp serve`` tests need.
"""

from __future__ import annotations

import base64
import json
import os
import signal
import subprocess
import threading
import time
from pathlib import Path
from typing import Any

from tests.viz.browser import find_chromium

__all__ = ["Browser", "CDPError", "find_chromium"]

COMMAND_TIMEOUT = 120.0  # [s] for one command's reply (the machine may be busy)


class CDPError(RuntimeError):
    """A command failed or chromium went away."""


class Browser:
    """One headless chromium with one page.

    Args:
        chromium: The binary.
        profile: An empty folder for the profile.
        downloads: Where downloads go.
        proxy_port: Every non-loopback request goes to this port (a trap), or None.
    """

    def __init__(self, chromium: str, profile: Path, downloads: Path, *, proxy_port: int | None = None,
                 size: tuple[int, int] = (1280, 800)) -> None:
        to_chrome_r, self._to_chrome = os.pipe()
        self._from_chrome, from_chrome_w = os.pipe()
        cmd = [chromium, "--headless", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader",
               "--disable-quic", "--no-first-run", "--disable-background-networking", "--disable-component-update",
               "--disable-sync", "--disable-default-apps", "--disable-extensions", "--no-default-browser-check",
               "--disable-breakpad", "--disable-crash-reporter", "--remote-debugging-pipe",
               f"--user-data-dir={profile}", f"--window-size={size[0]},{size[1]}",
               "--hide-scrollbars"]
        if proxy_port is not None:
            cmd.append(f"--proxy-server=http://127.0.0.1:{proxy_port}")  # loopback is bypassed (our server)
        cmd.append("about:blank")

        def fds() -> None:  # the child's fd 3 and 4 (inheritable: dup2 makes them so)
            os.dup2(to_chrome_r, 3)
            os.dup2(from_chrome_w, 4)

        self._proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, close_fds=False,
                                      preexec_fn=fds, start_new_session=True)  # fds 3, 4 before exec
        os.close(to_chrome_r)
        os.close(from_chrome_w)
        self._next = 0
        self._replies: dict[int, dict[str, Any]] = {}
        self.events: list[dict[str, Any]] = []
        self._cv = threading.Condition()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()
        self.session: str | None = None
        targets = self.call("Target.getTargets")["targetInfos"]
        page = next(t for t in targets if t["type"] == "page")
        self.session = self.call("Target.attachToTarget", targetId=page["targetId"], flatten=True,
                                 _session=False)["sessionId"]
        self.call("Page.enable")
        self.call("Runtime.enable")
        self.call("Browser.setDownloadBehavior", behavior="allow", downloadPath=str(downloads),
                  eventsEnabled=True, _session=False)

    def _read(self) -> None:
        buf = b""
        while True:
            try:
                chunk = os.read(self._from_chrome, 1 << 16)
            except OSError:
                chunk = b""
            if not chunk:
                with self._cv:
                    self._replies[-1] = {"error": {"message": "chromium closed the pipe"}}
                    self._cv.notify_all()
                return
            buf += chunk
            while b"\0" in buf:
                raw, buf = buf.split(b"\0", 1)
                message = json.loads(raw)
                with self._cv:
                    if "id" in message:
                        self._replies[message["id"]] = message
                    else:
                        self.events.append(message)
                    self._cv.notify_all()

    def call(self, method: str, _session: bool = True, **params: Any) -> dict[str, Any]:
        """Send one command and wait for its result."""
        with self._cv:
            self._next += 1
            ident = self._next
        message: dict[str, Any] = {"id": ident, "method": method, "params": params}
        if _session and self.session is not None:
            message["sessionId"] = self.session
        os.write(self._to_chrome, json.dumps(message).encode() + b"\0")
        deadline = time.monotonic() + COMMAND_TIMEOUT
        with self._cv:
            while ident not in self._replies and -1 not in self._replies:
                if not self._cv.wait(timeout=max(0.0, deadline - time.monotonic())):
                    raise CDPError(f"{method}: no reply in {COMMAND_TIMEOUT} s")
            reply = self._replies.pop(ident, None) or self._replies[-1]
        if "error" in reply:
            raise CDPError(f"{method}: {reply['error'].get('message')}")
        return reply.get("result", {})

    def evaluate(self, expression: str) -> Any:
        """The value of a JavaScript expression in the page (promises awaited)."""
        result = self.call("Runtime.evaluate", expression=expression, returnByValue=True, awaitPromise=True)
        if "exceptionDetails" in result:
            raise CDPError(f"{expression[:80]}: {result['exceptionDetails'].get('text')} "
                           f"{result['exceptionDetails'].get('exception', {}).get('description', '')[:300]}")
        return result["result"].get("value")

    def wait_for(self, expression: str, timeout: float, poll: float = 0.1) -> Any:
        """Wait until ``expression`` is truthy; its value (CDPError after ``timeout`` s)."""
        deadline = time.monotonic() + timeout
        while True:
            value = self.evaluate(expression)
            if value:
                return value
            if time.monotonic() > deadline:
                raise CDPError(f"waited {timeout} s for {expression[:120]}")
            time.sleep(poll)

    def navigate(self, url: str) -> None:
        """Open ``url`` in the page."""
        self.call("Page.navigate", url=url)

    def screenshot(self):
        """The page as RGB pixels (H, W, 3) uint8."""
        import io

        import numpy as np
        from PIL import Image

        data = base64.b64decode(self.call("Page.captureScreenshot", format="png")["data"])
        return np.asarray(Image.open(io.BytesIO(data)).convert("RGB"))

    def close(self) -> None:
        """End chromium (its process group: it was started in its own session)."""
        try:
            self.call("Browser.close", _session=False)
        except CDPError:
            pass
        try:
            self._proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            os.killpg(self._proc.pid, signal.SIGKILL)
            self._proc.wait()
        for fd in (self._to_chrome, self._from_chrome):
            try:
                os.close(fd)
            except OSError:
                pass
