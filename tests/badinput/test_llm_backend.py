"""Bad input for the LLM backend: hostile or broken servers, bad URLs, timeouts and keys.

Every server is real and runs on 127.0.0.1 (:mod:`tests.badinput.llm_servers`). The API key is
set in the environment as the user would, and no case may print it, in any form, on either
stream; nor may a control character (an ANSI escape from the server or the model) reach the
terminal. Every refusal is exit 2 (a ``LanguageError`` or a usage error) with one line.
"""

from __future__ import annotations

import gzip
import json
import re
import ssl
import time
import unicodedata
import zlib

import pytest
from hypothesis import HealthCheck, given
from hypothesis import settings as hsettings
from hypothesis import strategies as st

from tests.badinput.conftest import Outcome, assert_refused, run_cli
from tests.badinput.llm_servers import (
    HTTPServer,
    RawServer,
    Request,
    Response,
    completion,
    drip,
    free_port,
    plan_reply,
    self_signed_certificate,
    send,
)

SECRET = "sk-test-SECRET-1234"
SQUAT = [{"action": "squat", "params": {"depth": 0.2}}]
MIB = 1 << 20


@pytest.fixture(autouse=True)
def _environment(monkeypatch: pytest.MonkeyPatch) -> None:
    """The key in the environment, no proxy, no default URL or model."""
    for var in ("http_proxy", "HTTP_PROXY", "https_proxy", "HTTPS_PROXY", "all_proxy", "ALL_PROXY",
                "no_proxy", "NO_PROXY", "WBMP_LLM_URL", "WBMP_LLM_MODEL", "OPENAI_API_KEY"):
        monkeypatch.delenv(var, raising=False)
    monkeypatch.setenv("WBMP_LLM_API_KEY", SECRET)


def llm_parse(capsys, url: str, *extra: str, timeout: float = 5, text: str = "squat") -> Outcome:
    return run_cli(["parse", text, "--parser", "llm", "--llm-url", url, "--llm-model", "m",
                    "--llm-timeout", f"{timeout:g}", *extra], capsys)


def assert_clean(outcome: Outcome, *secrets: str) -> None:
    """No secret and no control character (other than the line ends) on either stream."""
    for s in (SECRET, *secrets):
        assert s not in outcome.out and s not in outcome.err, "a secret was printed"
    for stream in (outcome.out, outcome.err):
        bad = {ch for ch in stream if ch != "\n" and unicodedata.category(ch) in ("Cc", "Cf")}
        assert not bad, f"control characters {sorted(map(hex, map(ord, bad)))} reached the terminal: {stream!r}"


def refused(outcome: Outcome, *words: str, secrets: tuple[str, ...] = ()) -> str:
    """Exit 2, one error line holding ``words``, nothing on stdout, nothing secret or raw; the line."""
    assert_refused(outcome, 2, *words, secrets=(SECRET, *secrets))
    assert_clean(outcome, *secrets)
    assert outcome.out == "", outcome.out
    return next(ln for ln in outcome.err.splitlines() if ": error:" in ln)


def echo_key(request: Request) -> str:
    """The Authorization header as the server received it (what a leaky server echoes)."""
    return request.headers.get("Authorization", "")


# --- usage errors: nothing is sent anywhere --------------------------------------------------


@pytest.mark.parametrize("url, words, secret", [
    ("ftp://127.0.0.1/v1", ("--llm-url", "scheme 'ftp'"), ""),
    ("file:///etc/passwd", ("--llm-url", "scheme 'file'"), ""),
    ("localhost:8080/v1", ("--llm-url", "http://"), ""),
    ("127.0.0.1:8080/v1", ("--llm-url", "http://"), ""),
    ("http://user:PASSWORD-42@127.0.0.1:9/v1", ("--llm-url", "password"), "PASSWORD-42"),
    ("https://:TOKEN-42@api.example.com/v1", ("--llm-url", "password"), "TOKEN-42"),
    ("http:///v1", ("--llm-url", "no host"), ""),
    ("http://127.0.0.1:99999/v1", ("--llm-url", "port"), ""),
    ("http://127.0.0.1:abc/v1", ("--llm-url", "port"), ""),
    ("http://127.0.0.1:0/v1", ("--llm-url", "port 0"), ""),
    ("http://[::1/v1", ("--llm-url", "not a valid url"), ""),
    ("http://127.0.0.1:9/v1 extra", ("--llm-url", "spaces"), ""),
    ("http://127.0.0.1:9/v\x1b[31m1", ("--llm-url", "control"), ""),
    ("http://127.0.0.1:9/modèle", ("--llm-url", "non-ascii"), ""),
    ("   ", ("--llm-url", "must be given"), ""),
])
def test_bad_url_is_a_usage_error(capsys, url, words, secret):
    """A URL that is not http(s)://host[:port]/... is refused before any request, never echoed."""
    outcome = llm_parse(capsys, url)
    refused(outcome, *words, secrets=(secret,) if secret else ())


@pytest.mark.parametrize("value", ["inf", "-inf", "nan", "0", "-1", "1e9", "3601", "abc", "", "1e400"])
def test_bad_timeout_is_a_usage_error(capsys, value):
    """--llm-timeout must be finite, above 0 and at most 3600 s: argparse says so in one line."""
    outcome = run_cli(["parse", "squat", "--parser", "llm", "--llm-url", "http://127.0.0.1:9/v1",
                       "--llm-model", "m", "--llm-timeout", value], capsys)
    refused(outcome, "--llm-timeout")


@pytest.mark.parametrize("value", ["inf", "nan", "0", "-5"])
def test_solve_checks_the_timeout_before_any_work(capsys, tmp_path, tree, value):
    """``solve`` refuses the same timeouts (its own --llm-timeout is a plain float) and writes nothing."""
    outcome = run_cli(["solve", "squat", "--parser", "llm", "--llm-url", "http://127.0.0.1:9/v1",
                       "--llm-model", "m", "--llm-timeout", value, "--no-sim", "--quiet",
                       "--out", tmp_path / "m.npz"], capsys)
    refused(outcome, "--llm-timeout")
    tree.assert_unchanged()


@pytest.mark.parametrize("key", ["sk test key", "sk-\x1b[31mred", "sk-ключ-1", "sk-a\nsk-b", "sk-\x7fdel"])
def test_key_a_header_cannot_carry(capsys, monkeypatch, key):
    """A key with spaces, control or non-ASCII characters names its variable, never itself."""
    monkeypatch.setenv("WBMP_LLM_API_KEY", key)
    outcome = llm_parse(capsys, f"http://127.0.0.1:{free_port()}/v1")
    line = refused(outcome, "WBMP_LLM_API_KEY", "http header")
    assert key.strip() not in line


def test_openai_key_variable_is_named(capsys, monkeypatch):
    monkeypatch.delenv("WBMP_LLM_API_KEY")
    monkeypatch.setenv("OPENAI_API_KEY", "sk bad")
    refused(llm_parse(capsys, "http://127.0.0.1:9/v1"), "OPENAI_API_KEY")


def test_key_with_a_trailing_newline_is_stripped(capsys, monkeypatch):
    """The usual copy-paste mistake: the key is sent without the newline and the plan printed."""
    monkeypatch.setenv("WBMP_LLM_API_KEY", SECRET + "\n")
    with HTTPServer(lambda r: Response(body=plan_reply(SQUAT))) as srv:
        outcome = llm_parse(capsys, srv.url)
    assert outcome.code == 0, outcome.err
    assert [r.headers["Authorization"] for r in srv.requests] == [f"Bearer {SECRET}"]
    assert "squat" in outcome.out
    assert_clean(outcome)


# --- the URL's query string ---------------------------------------------------------------


@pytest.mark.parametrize("suffix, path", [
    ("/v1?api-version=2024-01-01", "/v1/chat/completions?api-version=2024-01-01"),
    ("/v1/?api-version=2024-01-01", "/v1/chat/completions?api-version=2024-01-01"),
    ("/v1/chat/completions?api-version=2024-01-01&x=1", "/v1/chat/completions?api-version=2024-01-01&x=1"),
    ("?api-version=1", "/chat/completions?api-version=1"),
    ("/openai/deployments/gpt/", "/openai/deployments/gpt/chat/completions"),
])
def test_query_string_is_kept(capsys, suffix, path):
    """The /chat/completions path is joined before the query, which reaches the server intact."""
    with HTTPServer(lambda r: Response(body=plan_reply(SQUAT))) as srv:
        outcome = llm_parse(capsys, f"http://127.0.0.1:{srv.port}{suffix}", "--json")
    assert outcome.code == 0, outcome.err
    assert [r.path for r in srv.requests] == [path]
    assert json.loads(outcome.out)["actions"] == SQUAT


def test_query_string_is_never_printed(capsys):
    """A token in the query (some providers take one) stays out of the error message."""
    with HTTPServer(lambda r: Response(500, b'{"error": {"message": "down"}}')) as srv:
        outcome = llm_parse(capsys, srv.url + "?token=QUERY-TOKEN-9")
    line = refused(outcome, "HTTP 500", "down", secrets=("QUERY-TOKEN-9",))
    assert f"127.0.0.1:{srv.port}/v1/chat/completions" in line


# --- redirects: never followed, the key never goes along -------------------------------------


@pytest.mark.parametrize("status", [301, 302, 303, 307, 308])
def test_redirect_is_refused_and_not_followed(capsys, status):
    """A redirect to another host is an error naming that host; the other host gets nothing."""
    with HTTPServer(lambda r: Response(body=plan_reply(SQUAT))) as other:
        location = f"http://localhost:{other.port}/v1/chat/completions"
        with HTTPServer(lambda r: Response(status, b"", {"Location": location})) as srv:
            outcome = llm_parse(capsys, srv.url)
    refused(outcome, f"HTTP {status}", "redirect", "localhost", "--llm-url")
    assert other.requests == []
    assert len(srv.requests) == 1


@pytest.mark.parametrize("location, words", [
    ("/elsewhere/chat/completions", ("redirect", "127.0.0.1", "/elsewhere/chat/completions")),
    ("", ("redirect", "without a location")),
    ("http://[broken/v1", ("redirect", "invalid location")),
    ("http://evil.example/steal/{key}?k={key}", ("redirect", "evil.example", "[redacted]")),
    ("http://evil.example/\x1b[2J\x1b[31m", ("redirect", "evil.example")),
])
def test_redirect_odd_locations(capsys, location, words):
    """Relative, missing, broken, key-echoing or escape-laden Locations: one clean line each."""
    def respond(request: Request) -> Response:
        key = echo_key(request).removeprefix("Bearer ")
        return Response(302, b"moved", {"Location": location.format(key=key)} if location else {})

    with HTTPServer(respond) as srv:
        outcome = llm_parse(capsys, srv.url)
    refused(outcome, *words)


# --- HTTP error statuses ------------------------------------------------------------------


def _html(title: str, body: str) -> bytes:
    return f"<!DOCTYPE html><html><head><title>{title}</title></head><body>{body}</body></html>".encode()


HTTP_ERRORS = [
    (400, lambda k: json.dumps({"error": {"message": f"Incorrect API key provided: {k}"}}).encode(),
     ("HTTP 400", "Incorrect API key provided", "[redacted]")),
    (401, lambda k: f"unauthorized: {k}".encode(), ("HTTP 401", "check the API key", "[redacted]")),
    (403, lambda k: _html("Forbidden", f"<p>{k}</p>"), ("HTTP 403", "Forbidden")),
    (404, lambda k: b"<html><body><h1>Not Found</h1><p>nothing here</p></body></html>", ("HTTP 404", "Not Found", "check the URL")),
    (429, lambda k: b'{"error": "rate limited, retry later"}', ("HTTP 429", "rate limited")),
    (500, lambda k: _html("Oops", "x" * 50_000), ("HTTP 500", "Oops")),
    (500, lambda k: b"<html><body>" + b"<p>line</p>\n" * 5000 + b"</body></html>", ("HTTP 500", "line")),
    (502, lambda k: b"\x1b[2J\x1b[31mBad gateway\x1b[0m \xe2\x80\xae reversed", ("HTTP 502", "Bad gateway", "\\x1b", "\\u202e")),
    (503, lambda k: b"", ("HTTP 503",)),
    (500, lambda k: b"\xff\xfe\x00 not utf-8 \x9b31m", ("HTTP 500",)),
    (500, lambda k: b'{"detail": "model not loaded"}', ("HTTP 500", "model not loaded")),
    (500, lambda k: b'{"error": {"message": NaN}}', ("HTTP 500",)),
    (500, lambda k: b"[" * 100_000, ("HTTP 500",)),
    (500, lambda k: b"x" * (2 * MIB), ("HTTP 500",)),
    (418, lambda k: json.dumps({"error": {"message": k * 40}}).encode(), ("HTTP 418", "[redacted]")),
]


@pytest.mark.parametrize("status, body, words", HTTP_ERRORS)
def test_http_error_status(capsys, status, body, words):
    """4xx/5xx with JSON, HTML, binary, huge or key-echoing bodies: one short, clean line."""
    with HTTPServer(lambda r: Response(status, body(echo_key(r)), {"Content-Type": "text/html"})) as srv:
        outcome = llm_parse(capsys, srv.url)
    line = refused(outcome, *words)
    assert len(line) < 600, len(line)
    assert len(srv.requests) == 1  # no retry on transport errors


def test_reason_phrase_with_escapes_and_key(capsys):
    """The status line's reason phrase comes from the server too: escaped and redacted."""
    def script(conn):
        conn.sendall(b"HTTP/1.1 500 \x1b[31mbroken " + SECRET.encode() + b"\r\nContent-Length: 0\r\n\r\n")

    with RawServer(script) as srv:
        outcome = llm_parse(capsys, srv.url)
    refused(outcome, "HTTP 500", "broken", "[redacted]")


# --- 200 answers that are not chat completions --------------------------------------------


BAD_BODIES = [
    (b"<html><body>hello</body></html>", ("not JSON",)),
    (b"", ("not JSON", "empty body")),
    (b"\xff\xfe{\x00}\x00", ("not UTF-8",)),
    (b"[" * 200_000, ("not JSON",)),
    (b'{"choices": NaN}', ("not JSON",)),
    (b'{"created": 1' + b"0" * 5000 + b', "choices": []}', ("not JSON",)),
    (b"[]", ("not a chat-completions reply",)),
    (b'"just a string"', ("not a chat-completions reply",)),
    (b'{"choices": "x"}', ("not a chat-completions reply",)),
    (b'{"choices": [{"message": {}}]}', ("not a chat-completions reply",)),
    (b'{"choices": [{"message": {"content": null}}]}', ("without text content",)),
    (b'{"choices": [{"message": {"content": 5}}]}', ("without text content",)),
    (b'{"choices": [{"message": {"content": ["a"]}}]}', ("without text content",)),
    (b"\x1b]0;pwned\x07\x1b[31mnot json", ("not JSON", "\\x1b")),
]


@pytest.mark.parametrize("body, words", BAD_BODIES)
def test_body_that_is_not_a_completion(capsys, body, words):
    """Non-JSON, non-UTF-8, too deep, NaN, 5,000 digits or the wrong structure: one line, exit 2."""
    with HTTPServer(lambda r: Response(200, body)) as srv:
        outcome = llm_parse(capsys, srv.url)
    refused(outcome, *words)


def test_non_json_body_echoing_the_key(capsys):
    with HTTPServer(lambda r: Response(200, b"oops, your header was " + echo_key(r).encode())) as srv:
        refused(llm_parse(capsys, srv.url), "not JSON", "[redacted]")


# --- the model's content ---------------------------------------------------------------------


MODEL_REPLIES = [
    ('{"actions": [{"action": "squat", "params": {"depth": NaN}}]}', ("not a valid action plan", "NaN")),
    ('{"actions": [{"action": "squat", "params": {"depth": Infinity}}]}', ("not a valid action plan", "Infinity")),
    ('{"actions": [{"action": "squat", "params": {"depth": -Infinity}}]}', ("not a valid action plan", "finite")),
    ('{"actions": [{"action": "squat", "params": {"depth": 1e999}}]}', ("not a valid action plan", "finite")),
    ('{"actions": [{"action": "squat", "params": {"repeat": 1' + "0" * 5000 + "}}]}", ("not a valid action plan", "digits")),
    ('{"actions": [{"action": "\\u001b[31mfly\\u001b[0m", "params": {}}]}', ("not a valid action plan", "fly")),
    ('{"actions": [{"action": "\\u202efly", "params": {}}]}', ("not a valid action plan", "fly")),
    ("[" * 5000, ("not a valid action plan",)),
    ('{"actions": [{"action": "' + "x" * 900_000 + '", "params": {}}]}', ("not a valid action plan",)),
    ("\x1b[2J\x1b[Hsure! \x1b[31mhere\x1b[0m", ("not a valid action plan", "not JSON")),
]


@pytest.mark.parametrize("content, words", MODEL_REPLIES)
def test_invalid_model_reply_twice(capsys, content, words):
    """Non-finite numbers, huge integers, escapes in names, deep or huge replies: exit 2, clean line."""
    with HTTPServer(lambda r: Response(body=completion(content))) as srv:
        outcome = llm_parse(capsys, srv.url, "--json")
    line = refused(outcome, *words)
    assert len(line) < 800
    assert len(srv.requests) == 2  # the one schema retry, then the error


def test_model_echoing_the_key_in_an_action_name(capsys):
    def respond(request: Request) -> Response:
        return Response(body=plan_reply([{"action": echo_key(request), "params": {}}]))

    with HTTPServer(respond) as srv:
        refused(llm_parse(capsys, srv.url), "not a valid action plan", "[redacted]")


def test_model_refusal_with_escapes_and_key(capsys):
    """``{"error": ...}`` from the model is quoted escaped and redacted."""
    def respond(request: Request) -> Response:
        return Response(body=completion(json.dumps({"error": f"\x1b[2J\x1b[31mno way {echo_key(request)}"})))

    with HTTPServer(respond) as srv:
        refused(llm_parse(capsys, srv.url), "found no actions", "no way", "[redacted]", "\\x1b")


def test_nan_then_valid_prints_strict_json(capsys):
    """A NaN reply is retried like any invalid one; ``--json`` prints only strict JSON."""
    replies = iter([completion('{"actions": [{"action": "squat", "params": {"depth": NaN}}]}'), plan_reply(SQUAT)])
    with HTTPServer(lambda r: Response(body=next(replies))) as srv:
        outcome = llm_parse(capsys, srv.url, "--json")
    assert outcome.code == 0, outcome.err
    doc = json.loads(outcome.out, parse_constant=lambda c: pytest.fail(f"{c} in --json output"))
    assert doc == {"actions": SQUAT, "backend": "llm"}
    assert "NaN" in srv.requests[1].json()["messages"][-1]["content"]  # the retry names the problem
    assert_clean(outcome)


def test_ten_thousand_actions_do_not_crash(capsys):
    """A 10,000-action plan: refused by the shared cap on actions (or, without it, printed) — never a crash."""
    actions = [{"action": "bow", "params": {}}] * 10_000
    with HTTPServer(lambda r: Response(body=plan_reply(actions))) as srv:
        outcome = llm_parse(capsys, srv.url, "--json")
    assert "Traceback" not in outcome.err
    assert_clean(outcome)
    if outcome.code == 0:
        assert len(json.loads(outcome.out)["actions"]) == 10_000
    else:
        refused(outcome, "10000")


# --- size and encodings ----------------------------------------------------------------------


def test_huge_body_with_length_is_refused(capsys):
    with HTTPServer(lambda r: Response(body=b" " * (2 * MIB) + plan_reply(SQUAT))) as srv:
        refused(llm_parse(capsys, srv.url), "larger than 1048576 bytes")


def test_huge_chunked_body_is_refused(capsys):
    """No Content-Length: the chunks are counted and the reading stops past 1 MiB."""
    chunk = b"%x\r\n%s\r\n" % (64 * 1024, b" " * (64 * 1024))
    head = b"HTTP/1.1 200 OK\r\nTransfer-Encoding: chunked\r\nContent-Type: application/json\r\n\r\n"
    with RawServer(send(head + chunk * 40 + b"0\r\n\r\n", hold=5)) as srv:
        refused(llm_parse(capsys, srv.url), "larger than 1048576 bytes")


def _raw_deflate(data: bytes) -> bytes:
    c = zlib.compressobj(wbits=-zlib.MAX_WBITS)
    return c.compress(data) + c.flush()


@pytest.mark.parametrize("encoding, pack", [
    ("gzip", gzip.compress),
    ("x-gzip", gzip.compress),
    ("deflate", zlib.compress),
    ("deflate", _raw_deflate),
])
def test_compressed_reply_is_inflated(capsys, encoding, pack):
    """A server that compresses anyway (a proxy may): gzip and deflate are read, within the bound."""
    with HTTPServer(lambda r: Response(body=pack(plan_reply(SQUAT)), headers={"Content-Encoding": encoding})) as srv:
        outcome = llm_parse(capsys, srv.url, "--json")
    assert outcome.code == 0, outcome.err
    assert json.loads(outcome.out)["actions"] == SQUAT


@pytest.mark.parametrize("encoding, body, words", [
    ("gzip", gzip.compress(b" " * (20 * MIB)), ("larger than 1048576 bytes",)),  # a gzip bomb
    ("gzip", b"\x1f\x8b\x08\x00 damaged gzip data", ("cannot be decoded", "damaged")),
    ("gzip", gzip.compress(plan_reply(SQUAT))[:-12], ("cannot be decoded", "cut short")),
    ("br", b"\x0b\x02\x80{}\x03", ("cannot be decoded", "'br'")),
    ("\x1b[31mweird", b"{}", ("cannot be decoded", "not supported")),
])
def test_bad_compressed_reply(capsys, encoding, body, words):
    with HTTPServer(lambda r: Response(body=body, headers={"Content-Encoding": encoding})) as srv:
        refused(llm_parse(capsys, srv.url), *words)


# --- connections that fail -------------------------------------------------------------------


def test_connection_refused(capsys):
    refused(llm_parse(capsys, f"http://127.0.0.1:{free_port()}/v1"), "cannot reach", "connection refused")


@pytest.mark.parametrize("data, words", [
    (b"HTTP/1.1 200 OK\r\nContent-Length: 1000\r\n\r\n" + b'{"choices": ' + b" " * 88, ("in the middle", "100 bytes")),
    (b"HTTP/1.1 200 OK\r\nTransfer-Encoding: chunked\r\n\r\n10\r\nabc", ("in the middle",)),
    (b"", ("closed the connection without answering",)),
    (b"HELLO WORLD\r\n\r\n", ("malformed HTTP response",)),
    (b"HTTP/1.1 200 OK\r\nX-Long: " + b"a" * 70_000 + b"\r\n\r\n", ("malformed HTTP response",)),
    (b"HTTP/1.1 200 OK\r\n" + b"X-A: b\r\n" * 150 + b"\r\n", ("malformed HTTP response",)),
])
def test_server_breaks_the_connection(capsys, data, words):
    """Closed mid-body, closed before answering, not HTTP at all, absurd headers: one line."""
    with RawServer(send(data)) as srv:
        refused(llm_parse(capsys, srv.url), *words)


def test_slow_body_is_cut_at_the_deadline(capsys):
    """A 1 byte/s body (slowloris) cannot hold a 2 s timeout: the whole request is bounded."""
    body = completion(json.dumps({"actions": SQUAT}))
    head = b"HTTP/1.1 200 OK\r\nContent-Type: application/json\r\nContent-Length: %d\r\n\r\n" % len(body)
    with RawServer(drip(body, interval=1.0, prefix=head)) as srv:  # the body would take minutes
        t0 = time.monotonic()
        outcome = llm_parse(capsys, srv.url, timeout=2)
        elapsed = time.monotonic() - t0
    refused(outcome, "did not finish its reply within 2 s")
    assert elapsed < 20, f"the 2 s timeout held for {elapsed:.1f} s"


def test_slow_headers_are_cut_at_the_deadline(capsys):
    """The status line and headers a byte a second: also bounded by the one deadline."""
    with RawServer(drip(b"HTTP/1.1 200 OK\r\nContent-Length: 2\r\n\r\n{}", interval=0.5)) as srv:
        t0 = time.monotonic()
        outcome = llm_parse(capsys, srv.url, timeout=1)
        elapsed = time.monotonic() - t0
    refused(outcome, "did not answer within 1 s")
    assert elapsed < 15, f"the 1 s timeout held for {elapsed:.1f} s"


def test_silent_server(capsys):
    """A server that accepts and never answers."""
    with RawServer(send(b"", hold=20)) as srv:
        refused(llm_parse(capsys, srv.url, timeout=1), "did not answer within 1 s")


# --- https ---------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def certificate(tmp_path_factory):
    files = self_signed_certificate(tmp_path_factory.mktemp("tls"))
    if files is None:
        pytest.skip("the openssl command is needed to make a test certificate")
    server_side = ssl.SSLContext(ssl.PROTOCOL_TLS_SERVER)
    server_side.load_cert_chain(*files)
    return files[0], server_side


def test_https_reply_is_read_through_the_deadline_socket(capsys, monkeypatch, certificate):
    """A trusted https server (its certificate in SSL_CERT_FILE): the plan comes back."""
    cert, server_side = certificate
    monkeypatch.setenv("SSL_CERT_FILE", str(cert))
    with HTTPServer(lambda r: Response(body=plan_reply(SQUAT)), tls=server_side) as srv:
        outcome = llm_parse(capsys, srv.url + "?api-version=3", "--json")
    assert outcome.code == 0, outcome.err
    assert json.loads(outcome.out)["actions"] == SQUAT
    assert [(r.path, r.headers["Authorization"]) for r in srv.requests] == [
        ("/v1/chat/completions?api-version=3", f"Bearer {SECRET}")]


def test_https_untrusted_certificate(capsys, certificate):
    """A self-signed certificate the system does not trust: refused, nothing sent."""
    _, server_side = certificate
    with HTTPServer(lambda r: Response(body=plan_reply(SQUAT)), tls=server_side) as srv:
        outcome = llm_parse(capsys, srv.url)
    refused(outcome, "TLS failed", "certificate")
    assert srv.requests == []


def test_https_to_a_plain_http_server(capsys):
    """https:// typed for a local server that speaks plain HTTP: one line, not a traceback."""
    with HTTPServer(lambda r: Response(body=plan_reply(SQUAT))) as srv:
        refused(llm_parse(capsys, srv.url.replace("http://", "https://")), "TLS failed")


def test_https_handshake_that_never_comes(capsys):
    """A server that accepts the connection and never answers the TLS hello: the deadline holds."""
    with RawServer(send(b"", hold=20)) as srv:
        refused(llm_parse(capsys, srv.url.replace("http://", "https://"), timeout=1), "did not answer within 1 s")


# --- proxies and solve -----------------------------------------------------------------------


def test_http_proxy_from_the_environment(capsys, monkeypatch):
    """http_proxy is honoured: the proxy gets the absolute URL (query kept), the plan comes back."""
    with HTTPServer(lambda r: Response(body=plan_reply(SQUAT))) as proxy:
        monkeypatch.setenv("http_proxy", f"http://127.0.0.1:{proxy.port}")
        outcome = llm_parse(capsys, "http://llm.invalid/v1?api-version=2", "--json")
    assert outcome.code == 0, outcome.err
    assert [r.path for r in proxy.requests] == ["http://llm.invalid/v1/chat/completions?api-version=2"]
    assert json.loads(outcome.out)["actions"] == SQUAT


def test_solve_with_a_redirecting_server_writes_nothing(capsys, tmp_path, tree):
    """``solve --parser llm``: the redirect stops it before planning; no output file appears."""
    with HTTPServer(lambda r: Response(307, b"", {"Location": "http://localhost:1/v1"})) as srv:
        outcome = run_cli(["solve", "squat", "--parser", "llm", "--llm-url", srv.url, "--llm-model", "m",
                           "--no-sim", "--quiet", "--out", tmp_path / "m.npz", "--html", tmp_path / "m.html"], capsys)
    assert_refused(outcome, 2, "redirect", "localhost", secrets=(SECRET,))
    assert_clean(outcome)
    tree.assert_unchanged()


# --- properties ------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def switchboard():
    """One server for the property cases; ``switchboard.respond[0]`` answers the next request."""
    respond = [lambda r: Response(500)]
    with HTTPServer(lambda r: respond[0](r), lifetime=120) as srv:
        srv.respond = respond
        yield srv


@hsettings(suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(status=st.sampled_from([400, 401, 404, 429, 500, 502, 503]), body=st.binary(max_size=400),
       with_key=st.booleans())
def test_any_error_body_is_one_clean_line(capsys, switchboard, status, body, with_key):
    """Whatever bytes an error status carries (the key spliced in or not): one clean line, exit 2."""
    def respond(request: Request) -> Response:
        middle = echo_key(request).encode() if with_key else b""
        return Response(status, body[:200] + middle + body[200:])

    switchboard.respond[0] = respond
    outcome = llm_parse(capsys, switchboard.url)
    refused(outcome, f"HTTP {status}")


@hsettings(suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(content=st.text(max_size=300))
def test_any_model_text_is_a_plan_or_one_clean_line(capsys, switchboard, content):
    """Whatever text the model says (control characters included): a plan or one clean line."""
    switchboard.respond[0] = lambda r: Response(body=completion(content))
    outcome = llm_parse(capsys, switchboard.url, "--json")
    assert "Traceback" not in outcome.err
    assert_clean(outcome)
    if outcome.code == 0:
        json.loads(outcome.out, parse_constant=lambda c: pytest.fail(f"{c} in --json output"))
    else:
        refused(outcome, "model")


def test_every_message_is_within_a_terminal_line_budget():
    """The escaping helper: ANSI, bidi, NUL and lone surrogates become visible escapes."""
    from language.llm import _printable

    text = "a\x1b[31mb\u202ec\x00d\udcff e\n\tf " + SECRET
    out = _printable(text, (SECRET,))
    assert out == "a\\x1b[31mb\\u202ec\\x00d\\udcff e f [redacted]"
    assert re.fullmatch(r"[ -~]*", out)
