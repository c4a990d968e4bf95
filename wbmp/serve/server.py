"""The HTTP side of ``wbmp serve``: the standard library's threading server on 127.0.0.1.

Routes (every other path: 404):

=====================================  =====================================================
``GET /``                              the page (``wbmp/serve/static/index.html``)
``GET /static/meshcat.js``             meshcat's viewer bundle (the replay renderer)
``GET /api/state``                     the session: running and waiting jobs, history
``GET /api/jobs/<id>``                 one job
``GET /api/motions/<id>``              one motion: actions, words, plan, certificate
``POST /api/say``  ``{"text": ...}``   a sentence or a correction: 202 and the job's id
``POST /api/stop``                     cancel the running plan and the waiting ones
``POST /api/plots`` ``{"motion": id}``   draw the motion's plots (a job, as a plan)
``GET /plots/<id>/<name>.png``         one of them
``GET /view/<id>``                     the motion's replay for the page's viewer
``GET /download/<id>/<kind>``          ``motion.npz``, ``replay.html`` or ``motion.mcap``
=====================================  =====================================================

Safe by default:

- it listens on 127.0.0.1 only; the ``Host`` header must name it (``127.0.0.1:PORT`` or
  ``localhost:PORT``), so a page of another site whose name was re-pointed at 127.0.0.1 (DNS
  rebinding) gets 421 and nothing else;
- a POST must be JSON (``Content-Type: application/json``: a cross-site form cannot send it
  without a preflight, which is refused) and its ``Origin``, when the browser sends one, must be
  this server (403 otherwise); ``Sec-Fetch-Site`` must be ``same-origin`` or ``none`` when sent;
- a body is at most :data:`MAX_BODY` bytes (413), a sentence at most the CLI's
  ``MAX_TEXT_LENGTH`` characters (400), one plan runs at a time and :data:`session.MAX_WAITING`
  wait (429 beyond); a request line or header that takes longer than :data:`READ_TIMEOUT` to
  arrive closes the connection, and at most :data:`MAX_CONNECTIONS` are answered at once;
- ids are opaque tokens looked up in the session (no path from the page reaches the file
  system); every error is ``{"error": one line, "exit_code": n}`` with the CLI's exit code.
"""

from __future__ import annotations

import json
import re
import threading
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

from wbmp.errors import Busy, Unavailable
from wbmp.serve.session import Session

HOST = "127.0.0.1"
MAX_BODY = 64 * 1024  # bytes of a POST body
READ_TIMEOUT = 10.0  # seconds for a request to arrive
MAX_CONNECTIONS = 32  # connections answered at once; more are closed at once
DOWNLOADS = {"motion.npz": "application/octet-stream", "replay.html": "text/html; charset=utf-8",
             "motion.mcap": "application/octet-stream"}
_ID = r"([0-9a-f]{12})"
_ROUTES_GET = {
    "state": re.compile(r"^/api/state$"),
    "job": re.compile(rf"^/api/jobs/{_ID}$"),
    "motion": re.compile(rf"^/api/motions/{_ID}$"),
    "view": re.compile(rf"^/view/{_ID}$"),
    "download": re.compile(rf"^/download/{_ID}/(motion\.npz|replay\.html|motion\.mcap)$"),
    "plot": re.compile(rf"^/plots/{_ID}/([a-z_]+\.png)$"),
}


class ServeServer(ThreadingHTTPServer):
    """The threading HTTP server with its session."""

    daemon_threads = True
    allow_reuse_address = True
    request_queue_size = 64  # the listen backlog (the standard library's 5 drops a burst's SYNs)

    def __init__(self, session: Session, port: int = 0) -> None:
        super().__init__((HOST, port), Handler)
        self.session = session
        self.port = int(self.server_address[1])
        self.allowed_hosts = {f"127.0.0.1:{self.port}", f"localhost:{self.port}"}
        self.allowed_origins = {f"http://{h}" for h in self.allowed_hosts}
        self.read_timeout = READ_TIMEOUT
        self._slots_lock = threading.Lock()
        self._answering: set[int] = set()  # id() of the connections being answered
        self._mcap_lock = threading.Lock()
        self._meshcat: bytes | None = None
        self._index: bytes | None = None

    @property
    def free_slots(self) -> int:
        """How many more connections would be answered now."""
        with self._slots_lock:
            return MAX_CONNECTIONS - len(self._answering)

    def process_request(self, request: Any, client_address: Any) -> None:
        """Answer in a thread, at most MAX_CONNECTIONS at once (more: closed unanswered).

        A connection's slot is freed once, by whoever holds it last: Ctrl-C can arrive while the
        thread starts (``Thread.start`` waits for it), and the started thread still frees its slot."""
        with self._slots_lock:
            if len(self._answering) >= MAX_CONNECTIONS:
                full = True
            else:
                full = False
                self._answering.add(id(request))
        if full:
            self.shutdown_request(request)
            return
        thread = threading.Thread(target=self.process_request_thread, args=(request, client_address), daemon=True)
        try:
            thread.start()
        except RuntimeError:  # no thread could start: the connection is closed unanswered
            self._free(request)
            self.shutdown_request(request)

    def process_request_thread(self, request: Any, client_address: Any) -> None:
        """One connection's thread; frees its slot at the end."""
        try:
            super().process_request_thread(request, client_address)
        finally:
            self._free(request)

    def _free(self, request: Any) -> None:
        with self._slots_lock:
            self._answering.discard(id(request))

    @property
    def url(self) -> str:
        """The page's address."""
        return f"http://127.0.0.1:{self.port}/"

    def index(self) -> bytes:
        """The page."""
        if self._index is None:
            self._index = resources.files("wbmp.serve").joinpath("static/index.html").read_bytes()
        return self._index

    def meshcat(self) -> bytes:
        """The bundle of meshcat's viewer."""
        if self._meshcat is None:
            from viz import meshcat_bundle

            self._meshcat = meshcat_bundle().encode("utf-8")
        return self._meshcat

    def mcap(self, folder: Path) -> Path:
        """The motion's MCAP bag, made on first request (one at a time)."""
        path = folder / "motion.mcap"
        with self._mcap_lock:
            if not path.exists():
                from wbmp.export.files import export_motion

                export_motion(folder / "motion.npz", path, "mcap")
        return path


class Handler(BaseHTTPRequestHandler):
    """One request."""

    server: ServeServer
    protocol_version = "HTTP/1.1"
    timeout = READ_TIMEOUT
    server_version = "wbmp-serve"
    sys_version = ""

    def setup(self) -> None:
        """The connection, with the server's read timeout."""
        super().setup()
        self.connection.settimeout(self.server.read_timeout)

    def log_message(self, format: str, *args: Any) -> None:
        """Quiet: the terminal shows the page's address and nothing else."""

    # ---- checks --------------------------------------------------------------------------
    def _host_ok(self) -> bool:
        host = (self.headers.get("Host") or "").strip().lower()
        if host in self.server.allowed_hosts:
            return True
        self._error(HTTPStatus.MISDIRECTED_REQUEST, f"host {host[:80]!r} is not this server: open "
                    f"{self.server.url} (other host names are refused: DNS rebinding)", 2)
        return False

    def _post_ok(self) -> bool:
        origin = self.headers.get("Origin")
        if origin is not None and origin.strip().lower() not in self.server.allowed_origins:
            self._error(HTTPStatus.FORBIDDEN, f"requests from {origin[:80]!r} are refused: only this server's own "
                        "page may send them", 2)
            return False
        site = self.headers.get("Sec-Fetch-Site")
        if site is not None and site.strip().lower() not in ("same-origin", "none"):
            self._error(HTTPStatus.FORBIDDEN, f"a {site[:40]} request is refused: only this server's own page may "
                        "send it", 2)
            return False
        kind = (self.headers.get("Content-Type") or "").split(";")[0].strip().lower()
        if kind != "application/json":
            self._error(HTTPStatus.UNSUPPORTED_MEDIA_TYPE, "send JSON (Content-Type: application/json)", 2)
            return False
        return True

    def _body(self) -> dict[str, Any] | None:
        length_text = self.headers.get("Content-Length")
        if self.headers.get("Transfer-Encoding") or length_text is None:
            self._error(HTTPStatus.LENGTH_REQUIRED, "give the body's Content-Length (no chunked bodies)", 2)
            return None
        try:
            length = int(length_text)
        except ValueError:
            length = -1
        if not 0 <= length <= MAX_BODY:
            self._error(HTTPStatus.REQUEST_ENTITY_TOO_LARGE,
                        f"the request's body is {length_text[:20]} bytes; at most {MAX_BODY:,}", 2)
            return None
        raw = self.rfile.read(length)
        try:
            data = json.loads(raw.decode("utf-8")) if raw else {}
        except (UnicodeDecodeError, ValueError):
            self._error(HTTPStatus.BAD_REQUEST, "the body is not JSON in UTF-8", 2)
            return None
        if not isinstance(data, dict):
            self._error(HTTPStatus.BAD_REQUEST, 'the body must be a JSON object, e.g. {"text": "squat"}', 2)
            return None
        return data

    # ---- answers -------------------------------------------------------------------------
    def _send(self, status: int, body: bytes, kind: str, *, headers: dict[str, str] | None = None) -> None:
        self.send_response(status)
        self.send_header("Content-Type", kind)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("X-Content-Type-Options", "nosniff")
        self.send_header("X-Frame-Options", "SAMEORIGIN")
        self.send_header("Referrer-Policy", "no-referrer")
        self.send_header("Cross-Origin-Resource-Policy", "same-origin")
        for k, v in (headers or {}).items():
            self.send_header(k, v)
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(body)

    def _json(self, status: int, data: Any) -> None:
        self._send(status, json.dumps(_finite(data), ensure_ascii=False, default=_plain).encode("utf-8"),
                   "application/json; charset=utf-8", headers={"Cache-Control": "no-store"})

    def _error(self, status: int, message: str, exit_code: int) -> None:
        from wbmp.errors import one_line

        self.close_connection = True
        self._json(status, {"error": one_line(message), "exit_code": exit_code})

    def _file(self, path: Path, kind: str, *, download: str | None = None) -> None:
        try:
            body = path.read_bytes()
        except OSError:
            self._error(HTTPStatus.NOT_FOUND, "that file is gone (the session's folder was changed)", 2)
            return
        headers = {"Cache-Control": "no-store"}
        if download is not None:
            headers["Content-Disposition"] = f'attachment; filename="{download}"'
        self._send(HTTPStatus.OK, body, kind, headers=headers)

    # ---- methods -------------------------------------------------------------------------
    def do_HEAD(self) -> None:  # noqa: N802 - http.server's name
        """As GET, without the body."""
        self.do_GET()

    def do_GET(self) -> None:  # noqa: N802
        """The page, its script, the session's state, a view or a download."""
        if not self._host_ok():
            return
        path = urlsplit(self.path).path
        session = self.server.session
        if path in ("/", "/index.html"):
            self._send(HTTPStatus.OK, self.server.index(), "text/html; charset=utf-8",
                       headers={"Cache-Control": "no-store", "Content-Security-Policy": _CSP})
            return
        if path == "/static/meshcat.js":
            self._send(HTTPStatus.OK, self.server.meshcat(), "text/javascript; charset=utf-8",
                       headers={"Cache-Control": "max-age=3600"})
            return
        if path == "/favicon.ico":
            self._send(HTTPStatus.NO_CONTENT, b"", "image/x-icon")
            return
        for name, pattern in _ROUTES_GET.items():
            m = pattern.match(path)
            if m is None:
                continue
            if name == "state":
                self._json(HTTPStatus.OK, session.state())
                return
            if name == "job":
                job = session.job(m.group(1))
                if job is None:
                    self._error(HTTPStatus.NOT_FOUND, "no such job in this session", 2)
                else:
                    self._json(HTTPStatus.OK, job)
                return
            motion = session.motion(m.group(1))
            if motion is None:
                self._error(HTTPStatus.NOT_FOUND, "no such motion in this session", 2)
                return
            if name == "motion":
                self._json(HTTPStatus.OK, motion.full())
            elif name == "view":
                self._file(motion.folder / "view.html", "text/html; charset=utf-8")
            elif name == "plot":
                if m.group(2) not in motion.summary.get("plots", ()):
                    self._error(HTTPStatus.NOT_FOUND, "no such plot of this motion (draw them first)", 2)
                else:
                    self._file(motion.folder / "plots" / m.group(2), "image/png")
            else:
                self._download(motion.id, motion.folder, m.group(2))
            return
        self._error(HTTPStatus.NOT_FOUND, f"no page {path[:80]!r} here: open {self.server.url}", 2)

    def _download(self, motion_id: str, folder: Path, kind: str) -> None:
        stem, suffix = kind.split(".")
        name = f"wbmp-{motion_id}.{suffix}" if stem != "replay" else f"wbmp-{motion_id}.html"
        if kind == "motion.mcap":
            try:
                path = self.server.mcap(folder)
            except Exception as exc:  # noqa: BLE001 - shown as the CLI's line
                from wbmp.errors import classify

                self._error(HTTPStatus.INTERNAL_SERVER_ERROR, f"mcap export: {exc}", int(classify(exc) or 1))
                return
        else:
            path = folder / kind
        self._file(path, DOWNLOADS[kind], download=name)

    def do_POST(self) -> None:  # noqa: N802
        """A sentence, a correction or stop."""
        if not self._host_ok() or not self._post_ok():
            return
        path = urlsplit(self.path).path
        if path not in ("/api/say", "/api/stop", "/api/plots"):
            self._error(HTTPStatus.NOT_FOUND, f"no action {path[:80]!r} here", 2)
            return
        data = self._body()
        if data is None:
            return
        session = self.server.session
        if path == "/api/stop":
            self._json(HTTPStatus.OK, {"cancelled": session.stop()})
            return
        if path == "/api/plots":
            motion = data.get("motion")
            try:
                job = session.submit_plots(motion if isinstance(motion, str) else "")
            except KeyError:
                self._error(HTTPStatus.NOT_FOUND, "no such motion in this session", 2)
                return
            except Busy as e:
                self._error(HTTPStatus.TOO_MANY_REQUESTS, str(e), 2)
                return
            except Unavailable as e:
                self._error(HTTPStatus.SERVICE_UNAVAILABLE, str(e), 1)
                return
            self._json(HTTPStatus.ACCEPTED, {"job": job.id})
            return
        text = data.get("text")
        if not isinstance(text, str) or not text.strip():
            self._error(HTTPStatus.BAD_REQUEST, 'type an instruction, e.g. "squat twice" or 深蹲两次', 2)
            return
        from tasks import MAX_TEXT_LENGTH

        if len(text) > MAX_TEXT_LENGTH:
            self._error(HTTPStatus.BAD_REQUEST, f"the instruction is {len(text):,} characters long; wbmp reads at most "
                        f"{MAX_TEXT_LENGTH:,} (one to a few sentences)", 2)
            return
        try:
            job = session.submit(text.strip())
        except Busy as e:
            self._error(HTTPStatus.TOO_MANY_REQUESTS, str(e), 2)
            return
        except Unavailable as e:
            self._error(HTTPStatus.SERVICE_UNAVAILABLE, str(e), 1)
            return
        self._json(HTTPStatus.ACCEPTED, {"job": job.id})

    def do_OPTIONS(self) -> None:  # noqa: N802
        """A CORS preflight: refused."""
        if not self._host_ok():
            return
        self._error(HTTPStatus.FORBIDDEN, "cross-origin requests are refused", 2)

    def do_PUT(self) -> None:  # noqa: N802
        """Refused (also DELETE, PATCH)."""
        self._error(HTTPStatus.METHOD_NOT_ALLOWED, "only GET and POST", 2)

    do_DELETE = do_PATCH = do_PUT  # noqa: N815


_CSP = ("default-src 'self'; script-src 'self' 'unsafe-inline'; style-src 'self' 'unsafe-inline'; "
        "img-src 'self' data: blob:; connect-src 'self'; frame-src 'self'; frame-ancestors 'none'; "
        "base-uri 'none'; form-action 'none'")


def _plain(obj: Any) -> Any:
    import numpy as np

    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    return str(obj)


def _finite(obj: Any) -> Any:
    """``obj`` with NaN and infinities as None (JSON has neither; the page's JSON.parse refuses them)."""
    import math

    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    if hasattr(obj, "item") and not isinstance(obj, (str, bytes)):
        try:
            return _finite(obj.item())
        except (TypeError, ValueError):
            return obj
    return obj
