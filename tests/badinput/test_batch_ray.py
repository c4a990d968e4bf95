"""``wbmp batch --ray ADDRESS``: a bad or dead address is one line before any work, exit 2, soon.

The servers are real sockets on 127.0.0.1 (a closed port, a port that accepts and never
answers, a real HTTP server); nothing here reaches beyond 127.0.0.1. Each case must finish
within :data:`BOUND` and leave the test's folder unchanged (no library folder created).
"""

from __future__ import annotations

import http.server
import socket
import threading
import time
from collections.abc import Iterator

import pytest

from tests.badinput.conftest import assert_refused, run_cli
from wbmp.batch import raynet

BOUND = 30.0  # [s] a refused address, the probe's timeout included (1 s here)


@pytest.fixture(autouse=True)
def _short_probe(monkeypatch):
    """The probe's timeout 1 s (5 s by default): a silent port is reported sooner."""
    monkeypatch.setattr(raynet, "CONNECT_TIMEOUT", 1.0)
    monkeypatch.delenv("RAY_ADDRESS", raising=False)


def _closed_port() -> int:
    """A loopback port nothing listens on (bound, then released)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def silent_port() -> Iterator[int]:
    """A loopback port that accepts connections (the kernel's backlog) and never answers."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen(8)
        yield s.getsockname()[1]


@pytest.fixture
def http_port() -> Iterator[int]:
    """A real HTTP server on 127.0.0.1 (a web server where a Ray cluster was expected)."""
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), http.server.SimpleHTTPRequestHandler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield server.server_address[1]
    finally:
        server.shutdown()
        server.server_close()
        thread.join(10)


def _refused(tmp_path, capsys, tree, address: str, *words: str) -> None:
    items = tmp_path / "items.txt"
    items.write_text("squat\n")
    tree.before = tree.snapshot()
    t0 = time.monotonic()
    outcome = run_cli(["batch", items, "--out-dir", tmp_path / "lib", "--no-sim", "--ray", address], capsys)
    assert time.monotonic() - t0 < BOUND
    assert_refused(outcome, 2, "--ray", *words)
    tree.assert_unchanged()


@pytest.mark.parametrize(("address", "words"), [
    ("not an address", ["'not an address'", "no port", "host:port"]),
    ("a b:12", ["'a b'", "not a host name"]),
    ("http://127.0.0.1:6379", ["unknown scheme 'http'"]),
    ("ray://", ["no port"]),
    ("127.0.0.1:0", ["port '0'", "1 to 65535"]),
    ("127.0.0.1:65536", ["port '65536'"]),
    ("127.0.0.1:http", ["port 'http'"]),
    ("127.0.0.1:１２", ["port"]),  # fullwidth digits are not a port
    ("[::1:80", ["not an address"]),
    ("\x1b[31m:1", ["\\x1b", "not a host name"]),
])
def test_an_address_of_the_wrong_form_is_refused_without_network_use(tmp_path, capsys, tree, address, words):
    """The form is checked first (no connection tried, Ray not needed): one line, exit 2."""
    _refused(tmp_path, capsys, tree, address, *words)


def test_nothing_listening_is_one_line_naming_the_address(tmp_path, capsys, tree):
    """A closed port, as host:port and as ray://host:port: refused at once (was: minutes of
    Ray's retries, then a traceback)."""
    pytest.importorskip("ray", reason="ray is not installed (pip install 'wbmp[ray]')")
    port = _closed_port()
    _refused(tmp_path, capsys, tree, f"127.0.0.1:{port}", f"127.0.0.1:{port}", "cannot connect")
    _refused(tmp_path, capsys, tree, f"ray://127.0.0.1:{port}", f"ray://127.0.0.1:{port}", "cannot connect")


def test_a_port_that_never_answers_is_bounded(tmp_path, capsys, tree, silent_port):
    """A port that accepts and stays silent: refused after the probe's timeout (1 s here)."""
    pytest.importorskip("ray", reason="ray is not installed (pip install 'wbmp[ray]')")
    _refused(tmp_path, capsys, tree, f"127.0.0.1:{silent_port}", f"127.0.0.1:{silent_port}", "no answer within 1 s")


def test_a_web_server_is_not_a_ray_cluster(tmp_path, capsys, tree, http_port):
    """A real HTTP server answers the connection but not the gRPC handshake: refused."""
    pytest.importorskip("ray", reason="ray is not installed (pip install 'wbmp[ray]')")
    _refused(tmp_path, capsys, tree, f"127.0.0.1:{http_port}", "not a Ray server")
    _refused(tmp_path, capsys, tree, f"ray://localhost:{http_port}", "not a Ray server")


def test_auto_is_resolved_then_checked(tmp_path, capsys, tree, monkeypatch):
    """``auto`` takes RAY_ADDRESS as Ray does: a dead one is named with what auto resolved to;
    a RAY_ADDRESS that is not an address is refused as such (was: a traceback)."""
    pytest.importorskip("ray", reason="ray is not installed (pip install 'wbmp[ray]')")
    port = _closed_port()
    monkeypatch.setenv("RAY_ADDRESS", f"127.0.0.1:{port}")
    _refused(tmp_path, capsys, tree, "auto", f"auto (127.0.0.1:{port})", "cannot connect")
    monkeypatch.setenv("RAY_ADDRESS", "somewhere over the rainbow")
    _refused(tmp_path, capsys, tree, "AUTO", "RAY_ADDRESS", "is not an address")


def test_a_temp_folder_too_long_for_rays_sockets_is_refused_before_any_work(tmp_path, capsys, tree, monkeypatch):
    """A local instance whose temp folder is too long for a Unix socket: one line naming it and
    RAY_TMPDIR, exit 2 (was: Ray's OSError traceback once the batch had started)."""
    pytest.importorskip("ray", reason="ray is not installed (pip install 'wbmp[ray]')")
    monkeypatch.setenv("RAY_TMPDIR", str(tmp_path / ("x" * 60)))
    items = tmp_path / "items.txt"
    items.write_text("squat\n")
    tree.before = tree.snapshot()
    outcome = run_cli(["batch", items, "--out-dir", tmp_path / "lib", "--no-sim", "--ray"], capsys)
    assert_refused(outcome, 2, "--ray", "x" * 60, "too long for its sockets", "RAY_TMPDIR")
    tree.assert_unchanged()
