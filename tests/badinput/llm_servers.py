"""Real servers on 127.0.0.1 for the LLM backend's bad-input cases (no mocks).

- :class:`HTTPServer`: an ``http.server`` on an ephemeral port; a function turns each request
  into a :class:`Response` (status, headers, body), and every request is recorded. Its loop
  handles one request at a time and stops by itself after ``lifetime`` seconds.
- :class:`RawServer`: a plain TCP socket for what ``http.server`` cannot do (a body sent one
  byte a second, a connection closed mid-body, a broken status line): a function gets the
  connected socket after the request was read and writes what it likes. It accepts at most
  ``connections`` clients and stops by itself after ``lifetime`` seconds.

Both are context managers; leaving the block stops them.
"""

from __future__ import annotations

import json
import select
import socket
import ssl
import subprocess
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from http.server import BaseHTTPRequestHandler
from http.server import HTTPServer as _StdHTTPServer
from pathlib import Path


def completion(content: str) -> bytes:
    """A chat-completions reply whose first choice says ``content``."""
    doc = {"id": "x", "object": "chat.completion",
           "choices": [{"index": 0, "message": {"role": "assistant", "content": content}, "finish_reason": "stop"}]}
    return json.dumps(doc).encode()


def plan_reply(actions: list) -> bytes:
    """A chat-completions reply whose content is ``{"actions": actions}``."""
    return completion(json.dumps({"actions": actions}))


@dataclass(frozen=True)
class Request:
    """What the server received."""

    path: str
    headers: dict[str, str]
    body: bytes

    def json(self):
        return json.loads(self.body or b"null")


@dataclass(frozen=True)
class Response:
    """What the server answers (Content-Length is added unless ``headers`` sets it)."""

    status: int = 200
    body: bytes = b""
    headers: dict[str, str] = field(default_factory=lambda: {"Content-Type": "application/json"})
    reason: str | None = None


class HTTPServer:
    """``http.server`` on 127.0.0.1:<ephemeral> answering every request with ``respond(request)``."""

    def __init__(self, respond: Callable[[Request], Response], *, lifetime: float = 30.0,
                 tls: ssl.SSLContext | None = None) -> None:
        self.requests: list[Request] = []
        owner = self

        class Handler(BaseHTTPRequestHandler):
            protocol_version = "HTTP/1.1"

            def do_POST(self) -> None:  # noqa: N802 - http.server API
                length = int(self.headers.get("Content-Length", "0"))
                request = Request(self.path, dict(self.headers), self.rfile.read(length))
                owner.requests.append(request)
                reply = respond(request)
                try:
                    self.send_response(reply.status, reply.reason)
                    headers = dict(reply.headers)
                    headers.setdefault("Content-Length", str(len(reply.body)))
                    headers.setdefault("Connection", "close")
                    for k, v in headers.items():
                        self.send_header(k, v)
                    self.end_headers()
                    self.wfile.write(reply.body)
                except (BrokenPipeError, ConnectionResetError):
                    pass  # the client gave up first
                self.close_connection = True

            do_GET = do_POST  # noqa: N815 - a followed redirect would arrive as GET

            def log_message(self, *args: object) -> None:
                pass

        self._httpd = _StdHTTPServer(("127.0.0.1", 0), Handler)
        self._httpd.timeout = 0.05
        if tls is not None:  # the TLS handshake happens in accept(), in the server's thread
            self._httpd.socket = tls.wrap_socket(self._httpd.socket, server_side=True)
        self.port = self._httpd.server_address[1]
        self.url = f"{'https' if tls else 'http'}://127.0.0.1:{self.port}/v1"
        self._end = time.monotonic() + lifetime
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, daemon=True)

    def _loop(self) -> None:
        while not self._stop.is_set() and time.monotonic() < self._end:
            try:
                self._httpd.handle_request()  # returns after one request or 0.05 s
            except (OSError, ssl.SSLError):
                pass  # a client that refused our certificate

    def __enter__(self) -> HTTPServer:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(timeout=10)
        self._httpd.server_close()


class RawServer:
    """A TCP server on 127.0.0.1 that reads one HTTP request per client, then runs ``script(sock)``."""

    def __init__(self, script: Callable[[socket.socket], None], *, lifetime: float = 30.0,
                 connections: int = 4) -> None:
        self.requests: list[bytes] = []
        self._script = script
        self._listener = socket.socket()
        self._listener.bind(("127.0.0.1", 0))
        self._listener.listen(connections)
        self._listener.settimeout(0.05)
        self.port = self._listener.getsockname()[1]
        self.url = f"http://127.0.0.1:{self.port}/v1"
        self._end = time.monotonic() + lifetime
        self._left = connections
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, daemon=True)

    def _loop(self) -> None:
        while self._left and not self._stop.is_set() and time.monotonic() < self._end:
            try:
                conn, _ = self._listener.accept()
            except TimeoutError:
                continue
            self._left -= 1
            with conn:
                conn.settimeout(5.0)
                try:
                    self.requests.append(_read_request(conn))
                    self._script(conn)
                except OSError:
                    pass  # the client went away (it gave up: that is what the slow cases test)

    def __enter__(self) -> RawServer:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(timeout=15)
        self._listener.close()


def _read_request(conn: socket.socket) -> bytes:
    data = b""
    while b"\r\n\r\n" not in data:
        chunk = conn.recv(65536)
        if not chunk:
            return data
        data += chunk
    head, _, body = data.partition(b"\r\n\r\n")
    length = 0
    for line in head.split(b"\r\n")[1:]:
        name, _, value = line.partition(b":")
        if name.strip().lower() == b"content-length":
            length = int(value)
    while len(body) < length:
        chunk = conn.recv(65536)
        if not chunk:
            break
        body += chunk
    return head + b"\r\n\r\n" + body


def drip(data: bytes, *, interval: float = 1.0, prefix: bytes = b"",
         stop_after: float = 40.0) -> Callable[[socket.socket], None]:
    """A script that sends ``prefix`` at once, then ``data`` one byte every ``interval`` seconds
    (the slowloris server); it stops when the client closes the connection."""

    def script(conn: socket.socket) -> None:
        end = time.monotonic() + stop_after
        if prefix:
            conn.sendall(prefix)
        for i in range(len(data)):
            if time.monotonic() > end:
                return
            conn.sendall(data[i:i + 1])
            if _closed_within(conn, interval):
                return

    return script


def send(data: bytes, *, hold: float = 0.0) -> Callable[[socket.socket], None]:
    """A script that sends ``data`` at once, then keeps the connection open for up to ``hold``
    seconds (or until the client closes it), then closes it."""

    def script(conn: socket.socket) -> None:
        if data:
            conn.sendall(data)
        if hold:
            _closed_within(conn, hold)

    return script


def _closed_within(conn: socket.socket, seconds: float) -> bool:
    """Wait up to ``seconds``; True as soon as the client has closed the connection."""
    readable, _, _ = select.select([conn], [], [], seconds)
    if not readable:
        return False
    try:
        return conn.recv(1) == b""
    except OSError:
        return True


def free_port() -> int:
    """A loopback port nothing listens on (bound, then released)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def self_signed_certificate(folder: Path) -> tuple[Path, Path] | None:
    """(cert, key) PEM files for 127.0.0.1 made by the openssl command, None without it."""
    cert, key = folder / "cert.pem", folder / "key.pem"
    try:
        subprocess.run(
            ["openssl", "req", "-x509", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes",
             "-keyout", str(key), "-out", str(cert), "-days", "2", "-subj", "/CN=127.0.0.1",
             "-addext", "subjectAltName=IP:127.0.0.1"],
            check=True, capture_output=True, timeout=60,
        )
    except (OSError, subprocess.SubprocessError):
        return None
    return cert, key
