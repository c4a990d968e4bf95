"""``wbmp parse``: output format, exit codes, the LLM options from the environment."""

from __future__ import annotations

import json

import pytest

from tests.language.llm_server import Reply, ScriptedServer
from wbmp.cli import main


def run(capsys, *argv):
    code = main(["parse", *argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_json_output_is_exact(capsys):
    code, out, err = run(capsys, "wave your right hand twice, then squat", "--json")
    assert code == 0 and err == ""
    got = json.loads(out)
    assert got.pop("words") == [
        {"text": "wave", "role": "action", "detail": "wave", "action": 1},
        {"text": "your", "role": "filler"},
        {"text": "right", "role": "parameter", "detail": "arm=right", "action": 1},
        {"text": "hand", "role": "body part", "detail": "hand", "action": 1},
        {"text": "twice", "role": "count", "detail": "repeat=2", "action": 1},
        {"text": "then", "role": "sequence"},
        {"text": "squat", "role": "action", "detail": "squat", "action": 2},
    ]
    assert got == {"actions": [{"action": "wave", "params": {"arm": "right", "repeat": 2}},
                               {"action": "squat", "params": {}}], "backend": "rules"}


def test_chinese_and_overlay_json(capsys):
    code, out, _ = run(capsys, "一边挥手一边深蹲", "--json")
    assert code == 0
    got = json.loads(out)
    assert got["actions"] == [{"action": "squat", "params": {}}, {"action": "wave", "params": {}, "overlay": True}]
    assert [(w["text"], w["role"], w.get("action")) for w in got["words"]] == [
        ("一边", "at the same time", None), ("挥手", "action", 2), ("一边", "at the same time", None), ("深蹲", "action", 1)]
    assert "挥手" in out  # UTF-8, not \u escapes


def test_text_output_and_several_words(capsys):
    code, out, _ = run(capsys, "Jump", "up", "high.")
    assert code == 0
    assert out.splitlines() == ["1. jump  height=0.06 m  (defaults: forward=0 m)", "words:",
                                "  jump up  action: jump [action 1]",
                                "  high     parameter: height=0.06 m [action 1]"]


def test_mood_words_are_listed_as_not_used(capsys):
    code, out, _ = run(capsys, "the man happily walks forward, then stops", "--json")
    assert code == 0
    got = json.loads(out)
    assert got["actions"] == [{"action": "walk", "params": {"direction": "forward"}}]
    roles = {w["text"]: (w["role"], w.get("detail")) for w in got["words"]}
    assert roles["happily"] == ("not used", "mood or style")
    assert roles["man"] == ("subject", None) and roles["stops"] == ("stop", "end of the sequence")


@pytest.mark.parametrize("argv, fragment", [
    (["fly to the moon"], 'could not understand "fly", "moon"'),
    (["don't squat"], "negations"),
    (["squat 5 meters"], "above the maximum 0.6 m"),
    (["wave", "--parser", "llm"], "--parser llm needs --llm-url"),
    (["wave", "--parser", "llm", "--llm-url", "http://127.0.0.1:9/v1"], "--llm-model"),
])
def test_bad_input_exits_2_with_one_line(capsys, monkeypatch, argv, fragment):
    monkeypatch.delenv("WBMP_LLM_URL", raising=False)
    monkeypatch.delenv("WBMP_LLM_MODEL", raising=False)
    code, out, err = run(capsys, *argv)
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and fragment in err and err.startswith("wbmp parse: error: ")


def test_llm_backend_with_key_from_environment(capsys, monkeypatch):
    for var in ("http_proxy", "HTTP_PROXY", "all_proxy", "ALL_PROXY"):
        monkeypatch.delenv(var, raising=False)
    monkeypatch.delenv("WBMP_LLM_API_KEY", raising=False)
    monkeypatch.setenv("OPENAI_API_KEY", "sk-from-env")
    srv = ScriptedServer(lifetime=600.0).start()  # a net for a forgotten stop, not a time limit
    try:
        srv.script(Reply.plan([{"action": "bow", "params": {"angle": 0.7}}]))
        code, out, _ = run(capsys, "bow deeply", "--json", "--parser", "llm", "--llm-url", srv.url, "--llm-model", "m")
        assert code == 0
        assert json.loads(out) == {"actions": [{"action": "bow", "params": {"angle": 0.7}}], "backend": "llm"}  # no "words"
        assert srv.requests[0]["headers"]["Authorization"] == "Bearer sk-from-env"
        srv.script(Reply.raw(b"{}", status=503))
        code, out, err = run(capsys, "bow", "--parser", "llm", "--llm-url", srv.url, "--llm-model", "m")
        assert code == 2 and "HTTP 503" in err
    finally:
        srv.stop()
