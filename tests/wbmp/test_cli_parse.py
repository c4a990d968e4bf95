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
    assert json.loads(out) == {"actions": [{"action": "wave", "params": {"arm": "right", "repeat": 2}},
                                           {"action": "squat", "params": {}}], "backend": "rules"}


def test_chinese_and_overlay_json(capsys):
    code, out, _ = run(capsys, "一边挥手一边深蹲", "--json")
    assert code == 0
    assert json.loads(out)["actions"] == [{"action": "squat", "params": {}}, {"action": "wave", "params": {}, "overlay": True}]
    assert "挥" not in out


def test_text_output_and_several_words(capsys):
    code, out, _ = run(capsys, "Jump", "up", "high.")
    assert code == 0
    assert out.strip() == "1. jump  height=0.06 m  (defaults: forward=0 m)"


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
        assert json.loads(out) == {"actions": [{"action": "bow", "params": {"angle": 0.7}}], "backend": "llm"}
        assert srv.requests[0]["headers"]["Authorization"] == "Bearer sk-from-env"
        srv.script(Reply.raw(b"{}", status=503))
        code, out, err = run(capsys, "bow", "--parser", "llm", "--llm-url", srv.url, "--llm-model", "m")
        assert code == 2 and "HTTP 503" in err
    finally:
        srv.stop()
