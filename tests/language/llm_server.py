"""A real OpenAI-compatible chat-completions server on 127.0.0.1 with scripted replies.

Each request pops the next scripted reply: ``(status, body, delay)``. ``body`` is a chat
completion whose message content is the given string (``Reply.content``), or raw bytes
(``Reply.raw``). The server records every request (path, headers, JSON body), runs in a daemon
thread, and stops itself after ``lifetime`` seconds if a test forgets to stop it.
"""

from __future__ import annotations

import json
import threading
import time
from collections import deque
from dataclasses import dataclass
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer


@dataclass(frozen=True)
class Reply:
    """One scripted answer."""

    status: int = 200
    body: bytes = b""
    delay: float = 0.0  # [s] before answering

    @classmethod
    def content(cls, text: str, *, delay: float = 0.0) -> Reply:
        doc = {"id": "x", "object": "chat.completion", "choices": [{"index": 0, "message": {"role": "assistant", "content": text}, "finish_reason": "stop"}]}
        return cls(200, json.dumps(doc).encode(), delay)

    @classmethod
    def plan(cls, actions: list, *, delay: float = 0.0) -> Reply:
        return cls.content(json.dumps({"actions": actions}), delay=delay)

    @classmethod
    def raw(cls, body: bytes, status: int = 200) -> Reply:
        return cls(status, body)


class ScriptedServer:
    """ThreadingHTTPServer on an ephemeral loopback port with a queue of replies."""

    def __init__(self, lifetime: float = 600.0) -> None:
        self.replies: deque[Reply] = deque()
        self.requests: list[dict] = []
        self._lock = threading.Lock()
        owner = self

        class Handler(BaseHTTPRequestHandler):
            def do_POST(self):  # noqa: N802 - http.server API
                length = int(self.headers.get("Content-Length", "0"))
                raw = self.rfile.read(length)
                with owner._lock:
                    owner.requests.append({"path": self.path, "headers": dict(self.headers), "json": json.loads(raw or b"null")})
                    reply = owner.replies.popleft() if owner.replies else Reply.raw(b'{"error": "no scripted reply"}', 500)
                if reply.delay:
                    time.sleep(reply.delay)
                try:
                    self.send_response(reply.status)
                    self.send_header("Content-Type", "application/json")
                    self.send_header("Content-Length", str(len(reply.body)))
                    self.end_headers()
                    self.wfile.write(reply.body)
                except (BrokenPipeError, ConnectionResetError):
                    pass  # the client gave up (timeout test)

            def log_message(self, *args):  # keep test output clean
                pass

        self.httpd = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.httpd.daemon_threads = True
        self.url = f"http://127.0.0.1:{self.httpd.server_address[1]}/v1"
        self._thread = threading.Thread(target=self.httpd.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True)
        self._watchdog = threading.Timer(lifetime, self.stop)
        self._watchdog.daemon = True

    def start(self) -> ScriptedServer:
        self._thread.start()
        self._watchdog.start()
        return self

    def script(self, *replies: Reply) -> None:
        """Replace the queue of replies and forget earlier requests."""
        with self._lock:
            self.replies = deque(replies)
            self.requests.clear()

    def stop(self) -> None:
        self._watchdog.cancel()
        self.httpd.shutdown()
        self.httpd.server_close()
        self._thread.join(timeout=5)
