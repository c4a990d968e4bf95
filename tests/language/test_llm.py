"""LLM backend against a real HTTP server on 127.0.0.1 (scripted replies, no mocks)."""

from __future__ import annotations

import json
import math
import socket
import time

import pytest

from language import (
    BackendError,
    LanguageError,
    LLMReplyInvalid,
    LLMUnavailable,
    UnsupportedInstruction,
    parse,
)
from language.llm import FEW_SHOT, LLMSettings
from tasks.actions import actions_json_schema
from tests.language.llm_server import Reply, ScriptedServer

WAVE_SQUAT = [{"action": "wave", "params": {"arm": "right", "repeat": 2}}, {"action": "squat", "params": {}}]


@pytest.fixture(scope="module")
def server():
    srv = ScriptedServer(lifetime=600.0).start()  # a net for a forgotten stop, not a time limit
    yield srv
    srv.stop()


@pytest.fixture(autouse=True)
def _no_proxy(monkeypatch):
    for var in ("http_proxy", "HTTP_PROXY", "https_proxy", "HTTPS_PROXY", "all_proxy", "ALL_PROXY"):
        monkeypatch.delenv(var, raising=False)


def llm(server, text, **kw):
    kw.setdefault("timeout", 30.0)  # replies are immediate: a bound for a loaded machine, never waited out
    return parse(text, backend="llm", url=server.url, model="test-model", **kw)


def test_valid_reply_becomes_a_plan(server):
    """A canned valid reply gives the same plan as the rule parser, with backend "llm"."""
    server.script(Reply.plan(WAVE_SQUAT))
    plan = llm(server, "wave your right hand twice, then squat")
    rules = parse("wave your right hand twice, then squat").to_dict()
    assert plan.to_dict() == {**rules, "backend": "llm"}
    assert plan.actions[1].params["depth"] == 0.15  # registry default filled, not stated
    assert len(server.requests) == 1


def test_request_carries_schema_examples_and_json_mode(server):
    """The request: chat-completions path, model, system prompt with the schema, few-shot pairs, JSON mode, key."""
    server.script(Reply.plan([{"action": "jump", "params": {"height": 0.2}}]))
    llm(server, "Jump up high.", api_key="sk-test")
    req = server.requests[0]
    assert req["path"] == "/v1/chat/completions"
    assert req["headers"]["Authorization"] == "Bearer sk-test"
    body = req["json"]
    assert body["model"] == "test-model"
    assert body["temperature"] == 0.0
    assert body["response_format"] == {"type": "json_object"}
    messages = body["messages"]
    assert messages[0]["role"] == "system"
    assert json.dumps(actions_json_schema(), ensure_ascii=False, separators=(",", ":")) in messages[0]["content"]
    assert len(messages) == 2 + 2 * len(FEW_SHOT)
    assert messages[-1] == {"role": "user", "content": "Jump up high."}
    for user, assistant in zip(messages[1:-1:2], messages[2:-1:2], strict=True):
        assert json.loads(assistant["content"]) == {k: v for k, v in parse(user["content"]).to_dict().items() if k != "backend"}


def test_no_key_no_authorization_header_and_full_endpoint_accepted(server):
    server.script(Reply.plan([{"action": "bow", "params": {}}]))
    plan = parse("bow", backend="llm", url=server.url + "/chat/completions", model="m", json_mode=False, timeout=30)
    assert plan.actions[0].name == "bow"
    req = server.requests[0]
    assert "Authorization" not in req["headers"]
    assert req["path"] == "/v1/chat/completions"
    assert "response_format" not in req["json"]


def test_reply_fixed_on_retry(server):
    """An invalid first reply is sent back with the validation error; the corrected one is used."""
    server.script(
        Reply.plan([{"action": "squat", "params": {"depth": 5.0}}]),
        Reply.plan([{"action": "squat", "params": {"depth": 0.3}}]),
    )
    plan = llm(server, "do a deep squat")
    assert plan.to_dict()["actions"] == [{"action": "squat", "params": {"depth": 0.3}}]
    assert len(server.requests) == 2
    retry = server.requests[1]["json"]["messages"]
    assert retry[-2]["role"] == "assistant" and '"depth": 5.0' in retry[-2]["content"]
    assert retry[-1]["role"] == "user"
    assert "actions[0].params.depth: 5.0 is above the maximum 0.6" in retry[-1]["content"]


@pytest.mark.parametrize("bad, fragment", [
    ("sure! here you go", "not JSON"),
    ('{"actions": [{"action": "fly", "params": {}}]}', "actions[0].action: 'fly' is not one of"),
    ('{"actions": []}', "needs at least 1 item"),
    ('{"actions": [{"action": "wave", "params": {"arm": "middle"}}]}', "actions[0].params.arm: must be one of"),
    ('{"actions": [{"action": "wave", "params": {"speed": 2}}]}', "unknown key 'speed'"),
    ('{"actions": [{"action": "wave", "overlay": true}]}', 'first action cannot have "overlay"'),
    ('[1, 2]', "expected an object"),
])
def test_invalid_twice_is_a_clear_error(server, bad, fragment):
    """Two invalid replies: LLMReplyInvalid naming the problem (one line), never a crash."""
    server.script(Reply.content(bad), Reply.content(bad))
    with pytest.raises(LLMReplyInvalid) as info:
        llm(server, "something")
    assert fragment in str(info.value)
    assert "\n" not in str(info.value)
    assert len(server.requests) == 2


def test_fenced_json_is_accepted(server):
    server.script(Reply.content('```json\n{"actions": [{"action": "turn", "params": {"angle": -0.5}}]}\n```'))
    plan = llm(server, "turn right a bit")
    assert math.isclose(plan.actions[0].params["angle"], -0.5)


def test_model_refusal(server):
    server.script(Reply.content('{"error": "flying is not an action"}'))
    with pytest.raises(UnsupportedInstruction, match="flying is not an action"):
        llm(server, "fly")
    assert len(server.requests) == 1


def test_http_500(server):
    server.script(Reply.raw(b'{"error": {"message": "model overloaded"}}', status=500))
    with pytest.raises(LLMUnavailable, match="HTTP 500.*model overloaded"):
        llm(server, "wave")
    assert len(server.requests) == 1  # no retry on transport errors


def test_http_404_plain_text(server):
    server.script(Reply.raw(b"no such route", status=404))
    with pytest.raises(LLMUnavailable, match="HTTP 404.*no such route"):
        llm(server, "wave")


@pytest.mark.parametrize("body, fragment", [
    (b"<html>oops</html>", "not JSON"),
    (b'{"choices": []}', "not a chat-completions reply"),
    (b'{"object": "chat.completion"}', "not a chat-completions reply"),
])
def test_malformed_http_body(server, body, fragment):
    server.script(Reply.raw(body))
    with pytest.raises(LLMUnavailable, match=fragment):
        llm(server, "wave")


def test_slow_reply_times_out(server):
    """A reply 20 s late with a 1 s timeout: LLMUnavailable long before the reply would come
    (the 10 s bound leaves a loaded machine room and still proves the client gave up)."""
    server.script(Reply.plan(WAVE_SQUAT, delay=20.0))
    t0 = time.monotonic()
    with pytest.raises(LLMUnavailable, match="did not answer within 1 s"):
        llm(server, "wave", timeout=1.0)
    assert time.monotonic() - t0 < 10.0


def test_connection_refused():
    """Nothing listening: a clear LLMUnavailable, not an exception from urllib."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with pytest.raises(LLMUnavailable, match="cannot reach LLM server"):
        parse("wave", backend="llm", url=f"http://127.0.0.1:{port}/v1", model="m", timeout=30)


@pytest.mark.parametrize("kwargs, fragment", [
    ({"model": "m"}, "url must be"),
    ({"url": "ftp://x/v1", "model": "m"}, "url must be"),
    ({"url": "http://127.0.0.1:9/v1"}, "model name"),
    ({"url": "http://127.0.0.1:9/v1", "model": "m", "timeout": 0}, "timeout"),
])
def test_bad_settings(kwargs, fragment):
    with pytest.raises(BackendError, match=fragment):
        parse("wave", backend="llm", **kwargs)


def test_unknown_backend_and_options():
    with pytest.raises(BackendError, match="unknown parser backend 'gpt'"):
        parse("wave", backend="gpt")
    with pytest.raises(BackendError, match="takes no options"):
        parse("wave", url="http://x")
    with pytest.raises(BackendError, match="unknown LLM option.*max_tokens"):
        parse("wave", backend="llm", url="http://127.0.0.1:9/v1", model="m", max_tokens=5)


def test_every_failure_is_a_language_error():
    """The CLI maps LanguageError to exit 2; the LLM errors are LanguageErrors."""
    for cls in (LLMUnavailable, LLMReplyInvalid, BackendError, UnsupportedInstruction):
        assert issubclass(cls, LanguageError)
    assert LLMSettings(url="http://h:1/v1/", model="m").endpoint == "http://h:1/v1/chat/completions"
