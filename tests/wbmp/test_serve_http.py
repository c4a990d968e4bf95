"""``wbmp serve``'s HTTP side: real requests on 127.0.0.1 against the real server and session.

The session here never starts its planning process (``start_worker=False``): a job stays queued,
which is what the bounds need (the queue fills); planning is the browser test's business
(tests/wbmp/test_serve_browser.py).
"""

from __future__ import annotations

import http.client
import json
import socket
import threading

import pytest

from tasks.limits import MAX_TEXT_LENGTH
from wbmp.serve import server as srv
from wbmp.serve.session import MAX_WAITING, Session


@pytest.fixture
def served(tmp_path):
    session = Session(folder=tmp_path, start_worker=False)
    server = srv.ServeServer(session, 0)
    thread = threading.Thread(target=server.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True)
    thread.start()
    yield server
    server.shutdown()
    server.server_close()
    session.close()
    thread.join(10)


def request(server, method, path, body=None, headers=None, *, host=None):
    """(status, JSON or bytes, headers) of one request with exactly the headers given."""
    conn = http.client.HTTPConnection("127.0.0.1", server.port, timeout=30)
    conn.putrequest(method, path, skip_host=True, skip_accept_encoding=True)
    all_headers = {"Host": host if host is not None else f"127.0.0.1:{server.port}", **(headers or {})}
    if body is not None:
        all_headers.setdefault("Content-Length", str(len(body)))
    for k, v in all_headers.items():
        if v is not None:
            conn.putheader(k, v)
    conn.endheaders()
    if body is not None:
        conn.send(body)
    r = conn.getresponse()
    data = r.read()
    conn.close()
    if r.getheader("Content-Type", "").startswith("application/json"):
        return r.status, json.loads(data), r
    return r.status, data, r


def say(server, text, **headers):
    body = json.dumps({"text": text}).encode()
    return request(server, "POST", "/api/say", body, {"Content-Type": "application/json", **headers})


def test_binds_loopback_only(served):
    assert served.server_address[0] == "127.0.0.1"
    with pytest.raises(OSError):  # nothing listens on the machine's other addresses for it
        socket.create_connection(("127.0.0.2", served.port), timeout=2).close()


def test_page_and_assets_within_budget(served):
    """The page and everything it loads before the first motion: <= 3 MB (the target)."""
    status, page, r = request(served, "GET", "/")
    assert status == 200 and b'id="text"' in page
    assert "frame-ancestors 'none'" in r.getheader("Content-Security-Policy")
    status, bundle, _ = request(served, "GET", "/static/meshcat.js")
    assert status == 200 and b"MeshCat" in bundle
    total = len(page) + len(bundle)
    assert total <= 3_000_000, total
    assert b"http://" not in page.replace(b"http://www.w3.org", b"") and b"https://" not in page  # nothing fetched


@pytest.mark.parametrize("host", ["evil.example", f"evil.example:{0}", "127.0.0.1:1", "", "localhost"])
def test_host_header_checked(served, host):
    """DNS rebinding: a name other than this server's address gets 421 and nothing else."""
    host = host.replace(":0", f":{served.port}")
    for method, path in (("GET", "/"), ("GET", "/api/state"), ("GET", "/static/meshcat.js")):
        status, data, _ = request(served, method, path, host=host)
        assert status == 421, (host, path)
        assert "not this server" in data["error"] and "\n" not in data["error"]
    status, data, _ = request(served, "POST", "/api/say", b'{"text": "squat"}', {"Content-Type": "application/json"},
                              host=host)
    assert status == 421
    assert served.session.state()["waiting"] == []


def test_localhost_name_allowed(served):
    status, data, _ = request(served, "GET", "/api/state", host=f"localhost:{served.port}")
    assert status == 200 and data["history"] == []


@pytest.mark.parametrize("headers, status", [
    ({"Origin": "http://evil.example"}, 403),
    ({"Origin": "null"}, 403),
    ({"Origin": "http://127.0.0.1:1"}, 403),
    ({"Sec-Fetch-Site": "cross-site"}, 403),
    ({"Sec-Fetch-Site": "same-site"}, 403),
    ({"Content-Type": "text/plain"}, 415),  # what a cross-site <form> or a simple fetch can send
    ({"Content-Type": "application/x-www-form-urlencoded"}, 415),
])
def test_cross_site_posts_refused(served, headers, status):
    body = b'{"text": "squat"}'
    got, data, _ = request(served, "POST", "/api/say", body, {"Content-Type": "application/json", **headers})
    assert got == status and data["exit_code"] == 2 and data["error"]
    got, _, _ = request(served, "POST", "/api/stop", b"{}", {"Content-Type": "application/json", **headers})
    assert got == status
    assert served.session.state()["waiting"] == []  # nothing was queued


def test_same_origin_post_accepted(served):
    status, data, _ = say(served, "squat", Origin=f"http://127.0.0.1:{served.port}", **{"Sec-Fetch-Site": "same-origin"})
    assert status == 202 and len(data["job"]) == 12
    assert [j["text"] for j in served.session.state()["waiting"]] == ["squat"]


def test_preflight_refused(served):
    status, data, r = request(served, "OPTIONS", "/api/say", headers={
        "Origin": "http://evil.example", "Access-Control-Request-Method": "POST"})
    assert status == 403 and r.getheader("Access-Control-Allow-Origin") is None


def test_body_bounds(served):
    json_type = {"Content-Type": "application/json"}
    status, data, _ = request(served, "POST", "/api/say", b"", {**json_type, "Content-Length": str(srv.MAX_BODY + 1)})
    assert status == 413 and f"{srv.MAX_BODY:,}" in data["error"]  # refused before a byte is read
    status, data, _ = request(served, "POST", "/api/say", b"", {**json_type, "Content-Length": "-5"})
    assert status == 413
    status, data, _ = request(served, "POST", "/api/say", None, json_type)
    assert status == 411
    status, data, _ = request(served, "POST", "/api/say", b"{not json", json_type)
    assert status == 400 and "not JSON" in data["error"]
    status, data, _ = request(served, "POST", "/api/say", b'["squat"]', json_type)
    assert status == 400
    status, data, _ = say(served, "   ")
    assert status == 400 and "type an instruction" in data["error"]
    long_text = "squat " * (MAX_TEXT_LENGTH // 6 + 1)
    status, data, _ = say(served, long_text)
    assert status == 400 and f"{MAX_TEXT_LENGTH:,}" in data["error"] and f"{len(long_text):,}" in data["error"]
    status, data, _ = say(served, "\x1b[31mred\nline")  # queued as text: a sentence, never a terminal write
    assert status == 202
    assert served.session.state()["waiting"][0]["text"] == "\x1b[31mred\nline"


def test_one_plan_at_a_time_queue_bounded(served):
    """Nothing runs here (no planning process): the running slot and MAX_WAITING jobs queue, the
    next is told to wait (429); stop cancels them, and the queue takes jobs again."""
    accepted = [say(served, f"squat {i + 1} times") for i in range(MAX_WAITING + 1)]
    assert [s for s, _, _ in accepted] == [202] * (MAX_WAITING + 1)
    status, data, _ = say(served, "wave")
    assert status == 429 and "wait" in data["error"] and data["exit_code"] == 2
    status, data, _ = request(served, "POST", "/api/stop", b"{}", {"Content-Type": "application/json"})
    assert status == 200 and data["cancelled"] == MAX_WAITING + 1
    for _, job, _ in accepted:
        assert request(served, "GET", f"/api/jobs/{job['job']}")[1]["state"] == "cancelled"
    assert say(served, "wave")[0] == 202


def test_ids_are_opaque(served, tmp_path):
    """Only ids of the session's motions name files; nothing from the path reaches the disk."""
    (tmp_path / "secret.txt").write_text("the-content-of-the-file")
    for path in ("/download/0123456789ab/motion.npz", "/download/../secret.txt", "/download/..%2fsecret.txt",
                 "/view/0123456789ab", "/view/../../etc/passwd", "/download/0123456789ab/secret.txt",
                 "/api/motions/0123456789ab", "/api/jobs/0123456789ab", "/static/../session.py",
                 "/download/0123456789AB/motion.npz", "//etc/passwd", "/plots/0123456789ab/joints.png",
                 "/plots/0123456789ab/../../secret.txt"):
        status, data, _ = request(served, "GET", path)
        assert status == 404, path
        assert b"the-content-of-the-file" not in json.dumps(data).encode()


def test_closed_session_unavailable(served):
    served.session.close()
    status, data, _ = say(served, "squat")
    assert status == 503 and data["exit_code"] == 1 and "restart wbmp serve" in data["error"]


def test_other_methods_refused(served):
    for method in ("PUT", "DELETE", "PATCH"):
        status, data, _ = request(served, method, "/api/say", b"{}", {"Content-Type": "application/json"})
        assert status == 405 and data["error"]


def test_slow_client_dropped(served):
    """A request that never finishes its headers is closed after READ_TIMEOUT, not kept forever."""
    assert srv.READ_TIMEOUT <= 30
    served.read_timeout = 0.5
    sock = socket.create_connection(("127.0.0.1", served.port), timeout=30)
    sock.sendall(b"GET / HTTP/1.1\r\nHost: 127.0.0.1\r\n")  # no blank line: the headers never end
    assert sock.recv(100) == b""  # the server closed the connection
    sock.close()


def test_bad_options_refused_before_the_server_starts(tmp_path, capsys):
    """One line and the CLI's exit code; nothing listens afterwards."""
    from wbmp.cli import main

    with pytest.raises(SystemExit) as e:
        main(["serve", "--port", "70000"])
    assert e.value.code == 2 and "65535" in capsys.readouterr().err
    assert main(["serve", "--robot", "no_such_robot"]) == 3
    assert main(["serve", "--out-dir", str(tmp_path / "missing")]) == 2
    assert "not an existing folder" in capsys.readouterr().err
    assert main(["serve", "--motions", str(tmp_path / "no-clips")]) == 2
    assert "--motions" in capsys.readouterr().err
    (tmp_path / "clips.csv").write_text("file,label\n")
    assert main(["serve", "--motions", str(tmp_path)]) == 2
    assert "lists no clip" in capsys.readouterr().err
    bad_scene = tmp_path / "scene.json"
    bad_scene.write_text("{not json")
    assert main(["serve", "--scene", str(bad_scene)]) == 3
    busy = socket.socket()
    busy.bind(("127.0.0.1", 0))
    busy.listen(1)
    try:
        assert main(["serve", "--port", str(busy.getsockname()[1])]) == 2
        err = capsys.readouterr().err
        assert "cannot listen" in err and "--port 0" in err and err.count("\n") == 2  # one line per refusal
    finally:
        busy.close()


def test_plots_of_an_unknown_motion(served):
    status, data, _ = request(served, "POST", "/api/plots", b'{"motion": "0123456789ab"}',
                              {"Content-Type": "application/json"})
    assert status == 404 and "no such motion" in data["error"]
    status, data, _ = request(served, "POST", "/api/plots", b'{"motion": ["../x"]}', {"Content-Type": "application/json"})
    assert status == 404
    assert served.session.state()["waiting"] == []


def test_connections_bounded(served):
    """MAX_CONNECTIONS idle connections hold every slot: the next is closed unanswered; once they
    time out, the server answers again."""
    import time

    served.read_timeout = 5.0
    idle = [socket.create_connection(("127.0.0.1", served.port), timeout=30) for _ in range(srv.MAX_CONNECTIONS)]
    try:
        deadline = time.monotonic() + 4
        while served.free_slots and time.monotonic() < deadline:  # every idle one accepted, holding a slot
            time.sleep(0.05)
        assert served.free_slots == 0
        extra = socket.create_connection(("127.0.0.1", served.port), timeout=30)
        extra.sendall(f"GET /api/state HTTP/1.1\r\nHost: 127.0.0.1:{served.port}\r\n\r\n".encode())
        try:
            assert extra.recv(100) == b""
        except ConnectionResetError:
            pass
        extra.close()
    finally:
        for s in idle:
            s.close()
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        try:
            if request(served, "GET", "/api/state")[0] == 200:
                break
        except (ConnectionError, http.client.HTTPException):
            time.sleep(0.2)
    else:
        pytest.fail("the server did not answer again")


def test_ctrl_c_stops_the_server_and_removes_its_folder(tmp_path):
    """A real ``python -m wbmp serve`` process: it answers on the port it prints and its planning
    process starts; Ctrl-C ends both (130), and its temporary folder is gone."""
    import os
    import re
    import signal
    import subprocess
    import sys
    import urllib.request

    env = {**os.environ, "TMPDIR": str(tmp_path), "PYTHONPATH": os.getcwd()}
    proc = subprocess.Popen([sys.executable, "-m", "wbmp", "serve", "--port", "0"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env, start_new_session=True)
    try:
        line = proc.stdout.readline()
        url = re.search(r"http://127\.0\.0\.1:\d+/", line).group(0)
        import time

        deadline = time.monotonic() + 120
        while True:  # the planning process started (under python -m: not a second server)
            with urllib.request.urlopen(url + "api/state", timeout=30) as r:
                state = json.loads(r.read())
            assert state["robot"] == "talos" and state["worker"] != "failed"
            if state["worker"] == "ready" or time.monotonic() > deadline:
                break
            time.sleep(0.1)
        assert state["worker"] == "ready"
        assert [p.name.startswith("wbmp-serve-") for p in tmp_path.iterdir()] == [True]
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert proc.returncode == 130 and err.strip().endswith("wbmp: interrupted")
    assert not [p for p in tmp_path.iterdir() if p.name.startswith("wbmp-serve-")]
