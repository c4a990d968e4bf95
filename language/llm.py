"""LLM backend: any OpenAI-compatible chat-completions server (OpenAI, Ollama, vLLM, llama.cpp).

The request carries the registry's JSON schema (:func:`tasks.actions.actions_json_schema`),
one line per action, the unit conventions, and few-shot examples produced by the rule parser
(so the examples can never disagree with it). The model must reply with one JSON object. The
reply is checked against the same schema (:mod:`language.validate`) and by building every
:class:`tasks.actions.Action`; if either fails, the request is sent once more with the error
appended, and a second failure is a :class:`LLMReplyInvalid`. Timeouts, refused connections,
HTTP error statuses and non-JSON responses are :class:`LLMUnavailable`. Nothing is retried
silently beyond that single schema retry, and no exception but :class:`LanguageError` escapes.

Only the standard library is used (``urllib``). The API key is an argument: the library never
reads the environment (``wbmp parse`` takes it from ``WBMP_LLM_API_KEY`` or ``OPENAI_API_KEY``).
"""

from __future__ import annotations

import http.client
import json
import socket
import urllib.error
import urllib.parse
import urllib.request
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from language.exceptions import BackendError, LanguageError, LLMReplyInvalid, LLMUnavailable, UnsupportedInstruction
from language.plan import ActionPlan
from language.rules import rules_plan
from language.validate import SchemaViolation, validate
from tasks.actions import REGISTRY, actions_json_schema

#: Sentences whose rule-parser output is shown to the model as examples.
FEW_SHOT = (
    "wave your right hand twice, then squat",
    "turn right 45 degrees",
    "walk 1 meter forward",
    "wave while squatting",
    "深蹲三次",
    "向左看",
)
MAX_REPLY_BYTES = 1 << 20  # refuse absurd responses [bytes]
#: Keyword options of :func:`parse_llm` (what ``parse(..., backend="llm", **options)`` accepts).
OPTIONS = ("url", "model", "api_key", "timeout", "json_mode", "temperature")


@dataclass(frozen=True, slots=True, kw_only=True)
class LLMSettings:
    """How to reach the model.

    Attributes:
        url: Base URL of the OpenAI-compatible API (``http://127.0.0.1:11434/v1``) or the full
            ``.../chat/completions`` endpoint.
        model: Model name the server knows (``gpt-4o-mini``, ``qwen2.5:7b``...).
        api_key: Sent as ``Authorization: Bearer KEY`` when given (local servers need none).
        timeout: Limit for connecting and for each read [s].
        json_mode: Ask for ``response_format: {"type": "json_object"}`` (turn off for servers
            that refuse the field).
        temperature: Sampling temperature (0 = as deterministic as the server allows).
    """

    url: str
    model: str
    api_key: str | None = None
    timeout: float = 30.0
    json_mode: bool = True
    temperature: float = 0.0

    def __post_init__(self) -> None:
        parts = urllib.parse.urlsplit(self.url or "")
        if parts.scheme not in ("http", "https") or not parts.netloc:
            raise BackendError(f"LLM url must be http(s)://host[:port]/..., got {self.url!r}")
        if not self.model:
            raise BackendError("the LLM backend needs a model name (--llm-model NAME)")
        if not self.timeout > 0:
            raise BackendError(f"LLM timeout must be > 0 s, got {self.timeout!r}")

    @property
    def endpoint(self) -> str:
        """The chat-completions URL."""
        base = self.url.rstrip("/")
        return base if base.endswith("/chat/completions") else base + "/chat/completions"


def system_prompt() -> str:
    """Instructions, action list and JSON schema sent as the system message."""
    actions = "\n".join(f"- {name}: {schema.summary} ({schema.body} body)" for name, schema in REGISTRY.items())
    return (
        "You turn instructions for a humanoid robot (English or Chinese) into a JSON action plan.\n"
        "Reply with exactly one JSON object and nothing else: no prose, no code fences.\n"
        "The object must match this JSON schema:\n"
        f"{json.dumps(actions_json_schema(), ensure_ascii=False, separators=(',', ':'))}\n"
        f"Actions:\n{actions}\n"
        "Rules: parameters in SI units (meters, seconds, radians); turn angles are signed, "
        "left/counter-clockwise positive; sides and directions are lowercase words. "
        "Give only the parameters the instruction states; leave the others out. "
        "Actions run one after another; an action with \"overlay\": true runs at the same time as "
        "the action before it (an upper-body action on a lower-body one). "
        'If the instruction asks for something these actions cannot express, reply {"error": "<short reason>"}.'
    )


def few_shot_messages() -> list[dict[str, str]]:
    """User/assistant example pairs, produced by the rule parser."""
    out = []
    for sentence in FEW_SHOT:
        plan = rules_plan(sentence).to_dict()
        del plan["backend"]
        out.append({"role": "user", "content": sentence})
        out.append({"role": "assistant", "content": json.dumps(plan, ensure_ascii=False)})
    return out


def build_messages(text: str) -> list[dict[str, str]]:
    """The chat messages of a first request for ``text``."""
    return [{"role": "system", "content": system_prompt()}, *few_shot_messages(), {"role": "user", "content": text}]


def parse_llm(text: str, *, url: str | None = None, model: str | None = None, api_key: str | None = None,
              timeout: float = 30.0, json_mode: bool = True, temperature: float = 0.0) -> ActionPlan:
    """Actions of an instruction, from an OpenAI-compatible chat-completions server.

    Args:
        text: The instruction.
        url: API base URL or chat-completions endpoint.
        model: Model name.
        api_key: Bearer token (None: no Authorization header).
        timeout: Connect/read limit per request [s].
        json_mode: Send ``response_format: json_object``.
        temperature: Sampling temperature.

    Returns:
        The validated plan (``backend="llm"``; stated parameters = those in the reply).

    Raises:
        BackendError: Missing or malformed url/model.
        LLMUnavailable: Connection refused, timeout, HTTP error, or a response that is not a
            chat-completions JSON document.
        LLMReplyInvalid: The model's content was not a valid plan, also after one retry.
        UnsupportedInstruction: The model replied that the instruction cannot be expressed.
    """
    if not text or not text.strip():
        from language.exceptions import EmptyInstruction

        raise EmptyInstruction('empty instruction: say what the robot should do, e.g. "wave your right hand twice"')
    settings = LLMSettings(url=url or "", model=model or "", api_key=api_key, timeout=timeout,
                           json_mode=json_mode, temperature=temperature)
    messages = build_messages(text)
    problem = ""
    for attempt in (1, 2):
        content = request_completion(settings, messages)
        try:
            return plan_from_reply(content, text)
        except (SchemaViolation, _ReplyError) as e:
            problem = str(e)
        if attempt == 1:
            messages = [
                *messages,
                {"role": "assistant", "content": content},
                {"role": "user", "content": f"That reply is invalid: {problem}. Reply again with only the corrected JSON object."},
            ]
    raise LLMReplyInvalid(f"the model's reply is not a valid action plan, also after one retry: {problem}")


class _ReplyError(LanguageError):
    """The model's content is not a usable plan (triggers the retry)."""


def plan_from_reply(content: str, text: str) -> ActionPlan:
    """Plan from the model's message content (raises _ReplyError/SchemaViolation when invalid)."""
    body = content.strip()
    if body.startswith("```"):  # tolerate a fenced block: ```json ... ```
        body = body.strip("`").strip()
        if body[:4].lower() == "json":
            body = body[4:]
    try:
        data = json.loads(body)
    except json.JSONDecodeError as e:
        raise _ReplyError(f"the reply is not JSON ({e.msg} at line {e.lineno} column {e.colno})") from None
    if isinstance(data, dict) and "error" in data and "actions" not in data:
        raise UnsupportedInstruction(f'the model found no actions for "{text}": {str(data["error"])[:200]}')
    validate(data, actions_json_schema())
    if data["actions"][0].get("overlay"):
        raise _ReplyError('actions[0]: the first action cannot have "overlay": true')
    try:
        plan = ActionPlan.from_dict({**data, "backend": "llm"}, text=text)
    except LanguageError as e:
        raise _ReplyError(str(e)) from None
    return plan


def request_completion(settings: LLMSettings, messages: Sequence[dict[str, str]]) -> str:
    """POST one chat-completions request and return the first choice's message content."""
    payload: dict[str, Any] = {"model": settings.model, "messages": list(messages), "temperature": settings.temperature}
    if settings.json_mode:
        payload["response_format"] = {"type": "json_object"}
    headers = {"Content-Type": "application/json", "Accept": "application/json"}
    if settings.api_key:
        headers["Authorization"] = f"Bearer {settings.api_key}"
    req = urllib.request.Request(settings.endpoint, data=json.dumps(payload).encode(), headers=headers, method="POST")
    where = settings.endpoint
    try:
        with urllib.request.urlopen(req, timeout=settings.timeout) as resp:  # noqa: S310 - http(s) checked above
            raw = resp.read(MAX_REPLY_BYTES + 1)
    except urllib.error.HTTPError as e:
        detail = _error_detail(e)
        raise LLMUnavailable(f"LLM server {where} answered HTTP {e.code} {e.reason}{detail}") from None
    except urllib.error.URLError as e:
        reason = e.reason
        if isinstance(reason, (TimeoutError, socket.timeout)):
            raise LLMUnavailable(f"LLM server {where} did not answer within {settings.timeout:g} s") from None
        raise LLMUnavailable(f"cannot reach LLM server {where}: {reason}") from None
    except (TimeoutError, socket.timeout):
        raise LLMUnavailable(f"LLM server {where} did not answer within {settings.timeout:g} s") from None
    except (http.client.HTTPException, OSError) as e:
        raise LLMUnavailable(f"LLM server {where} broke the connection: {type(e).__name__}: {e}") from None
    if len(raw) > MAX_REPLY_BYTES:
        raise LLMUnavailable(f"LLM server {where} sent more than {MAX_REPLY_BYTES} bytes")
    try:
        data = json.loads(raw.decode("utf-8"))
        content = data["choices"][0]["message"]["content"]
    except (UnicodeDecodeError, json.JSONDecodeError):
        raise LLMUnavailable(f"LLM server {where} sent a response that is not JSON: {raw[:80]!r}") from None
    except (KeyError, IndexError, TypeError):
        raise LLMUnavailable(f"LLM server {where} sent JSON that is not a chat-completions reply: {raw[:120]!r}") from None
    if not isinstance(content, str):
        raise LLMUnavailable(f"LLM server {where} sent a reply without text content")
    return content


def _error_detail(e: urllib.error.HTTPError) -> str:
    try:
        body = e.read(300).decode("utf-8", "replace").strip()
    except Exception:  # noqa: BLE001 - the detail is a courtesy
        return ""
    try:
        message = json.loads(body)["error"]["message"]
        return f": {message}"
    except Exception:  # noqa: BLE001
        return f": {body[:120]}" if body else ""
