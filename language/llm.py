"""LLM backend: any OpenAI-compatible chat-completions server (OpenAI, Ollama, vLLM, llama.cpp).

The request carries the registry's JSON schema (:func:`tasks.actions.actions_json_schema`),
one line per action, the unit conventions, and few-shot examples produced by the rule parser
(so the examples can never disagree with it). The model must reply with one JSON object. The
reply is checked against the same schema (:mod:`language.validate`) and by building every
:class:`tasks.actions.Action`; if either fails, the request is sent once more with the error
appended, and a second failure is a :class:`LLMReplyInvalid`. Timeouts, refused connections,
HTTP error statuses, redirects and non-JSON responses are :class:`LLMUnavailable`. Nothing is
retried silently beyond that single schema retry, and no exception but :class:`LanguageError`
escapes.

The transport is the standard library's ``http.client``, used so that the API key cannot leave
for another host and a server cannot hold the caller:

- a redirect (HTTP 3xx) is never followed: it is an error naming where it pointed;
- ``timeout`` bounds each whole request, from connecting to the last byte of the reply (every
  send and receive gets only the time left before one deadline), and the reply body is read in
  chunks up to :data:`MAX_REPLY_BYTES` (a gzip/deflate body is inflated up to the same bound);
- every piece of text that comes from the server (error messages, HTML pages, the model's
  words quoted in a validation error) has the API key redacted, control characters (ANSI
  escapes, bidi overrides) escaped, and is cut to :data:`MAX_QUOTE_CHARS` before it goes into
  a message;
- numbers in a reply must be finite (``NaN``, ``Infinity``, ``1e999`` and integers of more
  than :data:`MAX_INT_DIGITS` digits are an invalid reply).

The URL may carry a query string (``.../v1?api-version=2024-01-01``), kept when the
``/chat/completions`` path is joined; it is never printed (it may hold a token). A URL with a
user name or password is refused: the key is an argument of its own. The ``http_proxy`` /
``https_proxy`` / ``no_proxy`` variables are honoured as ``urllib`` does (http:// proxies).

The API key is an argument: the library never reads the environment for it (``wbmp parse``
takes it from ``WBMP_LLM_API_KEY`` or ``OPENAI_API_KEY``).
"""

from __future__ import annotations

import base64
import http.client
import io
import json
import math
import re
import socket
import ssl
import time
import unicodedata
import urllib.parse
import urllib.request
import zlib
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

from language.exceptions import (
    BackendError,
    LanguageError,
    LLMReplyInvalid,
    LLMUnavailable,
    SchemaViolation,
    UnsupportedInstruction,
)
from language.plan import ActionPlan
from language.rules import rules_plan
from language.validate import validate
from tasks import REGISTRY, actions_json_schema

#: Sentences whose rule-parser output is shown to the model as examples.
FEW_SHOT = (
    "wave your right hand twice, then squat",
    "turn right 45 degrees",
    "walk 1 meter forward",
    "wave while squatting",
    "深蹲三次",
    "向左看",
)
MAX_REPLY_BYTES = 1 << 20  # refuse absurd responses (also after inflating gzip) [bytes]
MAX_TIMEOUT = 3600.0  # longest accepted request timeout [s]
MAX_QUOTE_CHARS = 200  # server text quoted in an error message [characters]
MAX_INT_DIGITS = 64  # longer integers in a reply are refused (Python would refuse > 4300)
#: Keyword options of :func:`parse_llm` (what ``parse(..., backend="llm", **options)`` accepts).
OPTIONS = ("url", "model", "api_key", "timeout", "json_mode", "temperature")
REDACTED = "[redacted]"
URL_EXAMPLE = "e.g. http://127.0.0.1:11434/v1"


@dataclass(frozen=True, slots=True, kw_only=True)
class LLMSettings:
    """How to reach the model.

    Attributes:
        url: Base URL of the OpenAI-compatible API (``http://127.0.0.1:11434/v1``) or the full
            ``.../chat/completions`` endpoint; a query string is kept (checked by
            :func:`check_url`).
        model: Model name the server knows (``gpt-4o-mini``, ``qwen2.5:7b``...).
        api_key: Sent as ``Authorization: Bearer KEY`` when given (local servers need none);
            visible ASCII only (checked by :func:`check_api_key`).
        timeout: Limit for each whole request, connect to last byte [s] (:func:`check_timeout`).
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
        check_url(self.url)
        if not isinstance(self.model, str) or not self.model.strip():
            raise BackendError("the LLM backend needs a model name (--llm-model NAME)")
        object.__setattr__(self, "timeout", check_timeout(self.timeout))
        if self.api_key is not None:
            check_api_key(self.api_key)
        t = self.temperature
        if isinstance(t, bool) or not isinstance(t, (int, float)) or not 0 <= t <= 2:
            raise BackendError(f"LLM temperature must be a number from 0 to 2, got {t!r}")

    @property
    def endpoint(self) -> str:
        """The chat-completions URL (the query string of ``url`` kept, no fragment)."""
        parts = urllib.parse.urlsplit(self.url.strip())
        path = parts.path.rstrip("/")
        if not path.endswith("/chat/completions"):
            path += "/chat/completions"
        return urllib.parse.urlunsplit((parts.scheme, parts.netloc, path, parts.query, ""))

    @property
    def where(self) -> str:
        """The endpoint as messages show it: without the query string (it may hold a token)."""
        parts = urllib.parse.urlsplit(self.endpoint)
        return f"{parts.scheme}://{parts.netloc}{parts.path}"

    @property
    def secrets(self) -> tuple[str, ...]:
        """Strings never to print: the key as sent, JSON-escaped and URL-quoted."""
        if not self.api_key:
            return ()
        key = self.api_key
        forms = {key, json.dumps(key)[1:-1], urllib.parse.quote(key, safe=""), urllib.parse.quote_plus(key)}
        return tuple(sorted(forms, key=len, reverse=True))


def check_url(url: Any, *, name: str = "the LLM url") -> str:
    """``url`` if it is a usable http(s) API URL, else a :class:`BackendError` saying why.

    Refused: an empty value, spaces or control characters, a scheme other than http/https, no
    host, a user name or password (``user:pass@host``: the key is passed on its own and a URL
    ends up in messages), a port outside 1-65535, non-ASCII characters in the path or query.
    The message never repeats the URL (it may hold credentials).
    """
    if not isinstance(url, str) or not url.strip():
        raise BackendError(f"{name} must be given: the API base URL, {URL_EXAMPLE}")
    url = url.strip()
    if any(ch.isspace() or unicodedata.category(ch)[0] == "C" for ch in url):
        raise BackendError(f"{name} contains spaces or control characters: give the URL alone, {URL_EXAMPLE}")
    try:
        parts = urllib.parse.urlsplit(url)
        port = parts.port
    except ValueError as e:  # a port that is no number or out of range, broken [IPv6] brackets
        raise BackendError(f"{name} is not a valid URL ({_printable(str(e), limit=80)}): {URL_EXAMPLE}") from None
    if parts.scheme not in ("http", "https"):
        got = f"scheme {_printable(parts.scheme, limit=20)!r}" if parts.scheme else "no scheme"
        raise BackendError(f"{name} must be an http:// or https:// URL (got {got}): {URL_EXAMPLE}")
    if "@" in parts.netloc:
        raise BackendError(f"{name} must not hold a user name or password (user:password@host): "
                           "pass the API key on its own (wbmp reads WBMP_LLM_API_KEY or OPENAI_API_KEY)")
    if not parts.hostname:
        raise BackendError(f"{name} has no host name: {URL_EXAMPLE}")
    if port == 0:
        raise BackendError(f"{name} has port 0: give the port the server listens on, {URL_EXAMPLE}")
    try:
        parts.hostname.encode("idna")
    except UnicodeError:
        raise BackendError(f"{name} has a host name that is not valid: {URL_EXAMPLE}") from None
    if not (parts.path + parts.query).isascii():
        raise BackendError(f"{name} has non-ASCII characters in its path or query: percent-encode them")
    return url


def check_timeout(value: Any, *, name: str = "the LLM timeout") -> float:
    """``value`` as a float if it is a usable request timeout [s], else a :class:`BackendError`."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 < value <= MAX_TIMEOUT:
        number = isinstance(value, (int, float)) and not isinstance(value, bool)
        got = (f"{value:g}" if isinstance(value, float) else f"{value}"[:24]) if number else f"a {type(value).__name__}"
        raise BackendError(f"{name} must be a number of seconds above 0 and at most {MAX_TIMEOUT:g}, got {got}")
    return float(value)


def check_api_key(key: Any, *, name: str = "the API key") -> str:
    """``key`` if an HTTP header can carry it (visible ASCII, no spaces), else a :class:`BackendError`.

    The message never repeats the key.
    """
    if not isinstance(key, str) or not key or not all(0x21 <= ord(ch) <= 0x7E for ch in key):
        raise BackendError(f"{name} is empty or holds characters an HTTP header cannot carry "
                           "(spaces, control or non-ASCII characters): give the key alone")
    return key


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
        url: API base URL or chat-completions endpoint (a query string is kept).
        model: Model name.
        api_key: Bearer token (None: no Authorization header).
        timeout: Limit for each whole request, connect to last byte [s] (at most
            :data:`MAX_TIMEOUT`; with the schema retry there are at most two requests).
        json_mode: Send ``response_format: json_object``.
        temperature: Sampling temperature.

    Returns:
        The validated plan (``backend="llm"``; stated parameters = those in the reply).

    Raises:
        BackendError: Missing or malformed url/model/timeout/key.
        LLMUnavailable: Connection refused, timeout, HTTP error or redirect, or a response that
            is not a chat-completions JSON document.
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
            problem = _printable(str(e), settings.secrets, limit=2 * MAX_QUOTE_CHARS)
        except UnsupportedInstruction as e:
            raise UnsupportedInstruction(_printable(str(e), settings.secrets, limit=2 * MAX_QUOTE_CHARS)) from None
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
    """Plan from the model's message content (raises _ReplyError/SchemaViolation when invalid).

    Messages quote the model's words unfiltered: :func:`parse_llm` redacts and escapes them.
    """
    body = content.strip()
    if body.startswith("```"):  # tolerate a fenced block: ```json ... ```
        body = body.strip("`").strip()
        if body[:4].lower() == "json":
            body = body[4:]
    try:
        data = loads_strict(body)
    except json.JSONDecodeError as e:
        raise _ReplyError(f"the reply is not JSON ({e.msg.removesuffix(' at')} at line {e.lineno} column {e.colno})") from None
    except _BadNumber as e:
        raise _ReplyError(f"the reply holds {e}: every number must be finite and of reasonable size") from None
    except RecursionError:
        raise _ReplyError("the reply is JSON nested too deeply") from None
    if isinstance(data, dict) and "error" in data and "actions" not in data:
        raise UnsupportedInstruction(f'the model found no actions for "{text}": {data["error"]}')
    validate(data, actions_json_schema())
    if data["actions"][0].get("overlay"):
        raise _ReplyError('actions[0]: the first action cannot have "overlay": true')
    try:
        plan = ActionPlan.from_dict({**data, "backend": "llm"}, text=text)
    except LanguageError as e:
        raise _ReplyError(str(e)) from None
    return plan


class _BadNumber(ValueError):
    """A JSON number that is not finite or absurdly long."""


def _strict_int(digits: str) -> int:
    if len(digits.lstrip("-")) > MAX_INT_DIGITS:
        raise _BadNumber(f"an integer of {len(digits.lstrip('-'))} digits")
    return int(digits)


def _strict_float(literal: str) -> float:
    value = float(literal)
    if not math.isfinite(value):
        raise _BadNumber(f"the number {literal[:24]}{'...' if len(literal) > 24 else ''} (too large for a float)")
    return value


def _no_constant(name: str) -> float:
    raise _BadNumber(f"the non-finite number {name}")


def loads_strict(text: str) -> Any:
    """``json.loads`` that refuses NaN, Infinity, numbers that overflow and huge integers.

    Raises:
        json.JSONDecodeError: Not JSON.
        ValueError: A refused number (a private subclass, :class:`_BadNumber`).
        RecursionError: Nested too deeply.
    """
    return json.loads(text, parse_int=_strict_int, parse_float=_strict_float, parse_constant=_no_constant)


# --- transport ---------------------------------------------------------------------------------


def request_completion(settings: LLMSettings, messages: Sequence[dict[str, str]]) -> str:
    """POST one chat-completions request and return the first choice's message content.

    Raises:
        LLMUnavailable: No usable reply within ``settings.timeout`` (the message is safe to
            print: no key, no control characters, one line).
    """
    payload: dict[str, Any] = {"model": settings.model, "messages": list(messages), "temperature": settings.temperature}
    if settings.json_mode:
        payload["response_format"] = {"type": "json_object"}
    headers = {"Content-Type": "application/json", "Accept": "application/json"}
    if settings.api_key:
        headers["Authorization"] = f"Bearer {settings.api_key}"
    raw = _post(settings, json.dumps(payload, allow_nan=False).encode(), headers)
    where = settings.where
    try:
        data = loads_strict(raw.decode("utf-8-sig"))
    except UnicodeDecodeError:
        raise LLMUnavailable(f"LLM server {where} sent a response that is not UTF-8 text: "
                             f"{_excerpt(raw, settings)}") from None
    except (ValueError, RecursionError):  # JSONDecodeError, a refused number, deep nesting
        raise LLMUnavailable(f"LLM server {where} sent a response that is not JSON: {_excerpt(raw, settings)}") from None
    try:
        content = data["choices"][0]["message"]["content"]
    except (KeyError, IndexError, TypeError):
        raise LLMUnavailable(f"LLM server {where} sent JSON that is not a chat-completions reply: "
                             f"{_excerpt(raw, settings)}") from None
    if not isinstance(content, str):
        raise LLMUnavailable(f"LLM server {where} sent a reply without text content")
    return content


class _Deadline(TimeoutError):
    """The request's deadline passed."""


class _TooLarge(Exception):
    def __init__(self, size: int | None) -> None:
        self.size = size


class _BadEncoding(Exception):
    """A Content-Encoding that cannot be decoded (the message says why)."""


def _post(settings: LLMSettings, body: bytes, headers: dict[str, str]) -> bytes:
    """Body of a 2xx answer to one POST, all within ``settings.timeout``; LLMUnavailable otherwise."""
    deadline = time.monotonic() + settings.timeout
    where = settings.where
    target = urllib.parse.urlsplit(settings.endpoint)
    conn, request_target, proxy_headers = _connection(target, settings.timeout, deadline)
    stage = "answer"  # "answer" until the status line and headers arrived, then "finish its reply"
    try:
        conn.request("POST", request_target, body=body, headers={**headers, **proxy_headers})
        resp = conn.getresponse()
        stage = "finish its reply"
        status, reason = resp.status, _printable(resp.reason or "", settings.secrets, limit=60)
        if 300 <= status < 400:
            raise _redirect_error(settings, status, resp.getheader("Location"))
        if not 200 <= status < 300:
            try:
                detail = _error_detail(_read_body(resp, deadline), settings)
            except (OSError, http.client.HTTPException, _TooLarge, _BadEncoding):
                detail = ""
            hint = ""
            if status in (401, 403):
                hint = " (check the API key)"
            elif status == 404:
                hint = " (check the URL: the API base, e.g. .../v1, or the full .../chat/completions)"
            raise LLMUnavailable(f"LLM server {where} answered HTTP {status} {reason}{detail}{hint}")
        return _read_body(resp, deadline)
    except TimeoutError:  # socket.timeout and _Deadline included
        raise LLMUnavailable(f"LLM server {where} did not {stage} within {settings.timeout:g} s") from None
    except _TooLarge as e:
        size = f" ({e.size} bytes)" if e.size else ""
        raise LLMUnavailable(f"LLM server {where} sent a reply larger than {MAX_REPLY_BYTES} bytes{size}") from None
    except _BadEncoding as e:
        raise LLMUnavailable(f"LLM server {where} sent a reply that cannot be decoded: {e}") from None
    except ConnectionRefusedError:
        raise LLMUnavailable(f"cannot reach LLM server {where}: connection refused (is the server running "
                             "and the port right?)") from None
    except socket.gaierror as e:
        raise LLMUnavailable(f"cannot reach LLM server {where}: the host name does not resolve "
                             f"({_printable(str(e.strerror or e), settings.secrets, limit=80)})") from None
    except ssl.SSLError as e:
        raise LLMUnavailable(f"cannot reach LLM server {where}: TLS failed "
                             f"({_printable(str(e.reason or e), settings.secrets, limit=120)})") from None
    except http.client.IncompleteRead as e:
        got = len(e.partial or b"")
        raise LLMUnavailable(f"LLM server {where} closed the connection in the middle of its reply "
                             f"({got} bytes received)") from None
    except http.client.RemoteDisconnected:
        raise LLMUnavailable(f"LLM server {where} closed the connection without answering") from None
    except http.client.HTTPException as e:
        raise LLMUnavailable(f"LLM server {where} sent a malformed HTTP response ({type(e).__name__}: "
                             f"{_printable(str(e), settings.secrets, limit=80)})") from None
    except OSError as e:
        text = e.strerror or str(e) or type(e).__name__
        verb = "cannot reach" if stage == "answer" else "lost the connection to"
        raise LLMUnavailable(f"{verb} LLM server {where}: {_printable(text, settings.secrets, limit=120)}") from None
    finally:
        conn.release()


def _redirect_error(settings: LLMSettings, status: int, location: str | None) -> LLMUnavailable:
    where = settings.where
    if not location or not location.strip():
        return LLMUnavailable(f"LLM server {where} answered HTTP {status} (a redirect) without a location; "
                              "give the final chat-completions URL with --llm-url")
    try:
        parts = urllib.parse.urlsplit(urllib.parse.urljoin(settings.endpoint, location.strip()))
        host = parts.hostname
        port = f":{parts.port}" if parts.port else ""
    except ValueError:
        host, port = None, ""
    if not host:
        target = "an invalid location"
    else:
        target = _printable(f"{parts.scheme}://{host}{port}{parts.path}", settings.secrets, limit=120)
    return LLMUnavailable(f"LLM server {where} redirects (HTTP {status}) to {target} (host "
                          f"{_printable(host or '?', settings.secrets, limit=80)}); redirects are not followed, "
                          "so the API key cannot go to another host: give the final URL with --llm-url")


def _read_body(resp: http.client.HTTPResponse, deadline: float) -> bytes:
    """The whole body, in chunks, before the deadline and within :data:`MAX_REPLY_BYTES`, decoded."""
    expected = resp.length  # Content-Length (None when chunked or absent)
    if expected is not None and expected > MAX_REPLY_BYTES:
        raise _TooLarge(expected)
    chunks: list[bytes] = []
    total = 0
    while True:
        if time.monotonic() >= deadline:
            raise _Deadline("the deadline passed")
        chunk = resp.read1(64 * 1024)
        if not chunk:
            break
        total += len(chunk)
        if total > MAX_REPLY_BYTES:
            raise _TooLarge(None)
        chunks.append(chunk)
    raw = b"".join(chunks)
    if expected is not None and total < expected:
        raise http.client.IncompleteRead(raw, expected - total)
    return _decode_content(raw, resp.getheader("Content-Encoding"))


def _decode_content(raw: bytes, encoding: str | None) -> bytes:
    """``raw`` inflated as its Content-Encoding says (gzip, deflate), within MAX_REPLY_BYTES."""
    names = [e.strip().lower() for e in (encoding or "").split(",") if e.strip() and e.strip().lower() != "identity"]
    for name in reversed(names):  # the last encoding applied is undone first
        if name in ("gzip", "x-gzip"):
            raw = _inflate(raw, 16 + zlib.MAX_WBITS, name)
        elif name == "deflate":
            try:
                raw = _inflate(raw, zlib.MAX_WBITS, name)
            except _BadEncoding:  # some servers send raw deflate without the zlib header
                raw = _inflate(raw, -zlib.MAX_WBITS, name)
        else:
            raise _BadEncoding(f"content encoding {_printable(name, limit=40)!r} is not supported (only gzip and deflate)")
    return raw


def _inflate(raw: bytes, wbits: int, name: str) -> bytes:
    inflater = zlib.decompressobj(wbits)
    try:
        out = inflater.decompress(raw, MAX_REPLY_BYTES + 1)
    except zlib.error:
        raise _BadEncoding(f"the {name} data is damaged") from None
    if len(out) > MAX_REPLY_BYTES or inflater.unconsumed_tail:
        raise _TooLarge(None)
    if not inflater.eof:
        raise _BadEncoding(f"the {name} data is cut short")
    return out


def _error_detail(raw: bytes, settings: LLMSettings) -> str:
    """``": <the server's message>"`` from an error body (JSON, HTML or text), safe to print."""
    text = raw.decode("utf-8", "replace").strip()
    message: Any = None
    try:
        doc = loads_strict(text)
    except (ValueError, RecursionError):
        doc = None
    if isinstance(doc, dict):
        error = doc.get("error")
        if isinstance(error, dict):
            message = error.get("message")
        elif isinstance(error, str):
            message = error
        if message is None:
            message = doc.get("message") if doc.get("message") is not None else doc.get("detail")
    if message is None:
        message = text
        if re.search(r"<\s*(!doctype|html|head|body|title|h1)\b", text, re.IGNORECASE):
            title = re.search(r"<title[^>]*>(.*?)</title\s*>", text, re.IGNORECASE | re.DOTALL)
            message = title.group(1) if title else re.sub(r"<[^>]*>", " ", text)
    message = _printable(str(message), settings.secrets)
    return f": {message}" if message else ""


def _excerpt(raw: bytes, settings: LLMSettings) -> str:
    """The start of a body, redacted and escaped (for 'not JSON' messages)."""
    text = _printable(raw.decode("utf-8", "replace"), settings.secrets, limit=120)
    return repr(text) if text else "an empty body"


_ESCAPED_CATEGORIES = frozenset({"Cc", "Cf", "Cs", "Co", "Zl", "Zp"})


def _printable(text: str, secrets: Iterable[str] = (), *, limit: int = MAX_QUOTE_CHARS) -> str:
    """``text`` safe for a one-line terminal message.

    Every secret is replaced by ``[redacted]`` (before anything is cut, so no part of a secret
    can survive), runs of whitespace become one space, control and format characters (ESC of an
    ANSI sequence, bidi overrides, lone surrogates) are written as ``\\xNN``/``\\uNNNN``, and
    the result is cut to ``limit`` characters.
    """
    for secret in secrets:
        if secret:
            text = text.replace(secret, REDACTED)
    text = text[: 8 * limit]  # enough to fill ``limit`` after whitespace runs collapse
    out = []
    for ch in text:
        if ch.isspace():
            out.append(" ")
        elif unicodedata.category(ch) in _ESCAPED_CATEGORIES:
            code = ord(ch)
            out.append(f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}" if code < 0x10000 else f"\\U{code:08x}")
        else:
            out.append(ch)
    line = " ".join("".join(out).split())
    return line if len(line) <= limit else line[: limit - 3].rstrip() + "..."


# --- connections with one deadline ----------------------------------------------------------------


class _DeadlineSocket:
    """A connected socket whose every send and receive may take only the time left before the deadline."""

    def __init__(self, sock: socket.socket, deadline: float) -> None:
        self._sock = sock
        self._deadline = deadline

    def _arm(self) -> None:
        left = self._deadline - time.monotonic()
        if left <= 0:
            raise _Deadline("the deadline passed")
        self._sock.settimeout(left)

    def sendall(self, data: bytes, *flags: int) -> None:
        self._arm()
        self._sock.sendall(data, *flags)

    def send(self, data: bytes, *flags: int) -> int:
        self._arm()
        return self._sock.send(data, *flags)

    def recv_into(self, buffer: Any, *args: int) -> int:
        self._arm()
        return self._sock.recv_into(buffer, *args)

    def recv(self, size: int, *flags: int) -> bytes:
        self._arm()
        return self._sock.recv(size, *flags)

    def makefile(self, mode: str = "rb", *args: Any, **kwargs: Any) -> io.BufferedReader:
        if mode != "rb":
            raise ValueError(f"_DeadlineSocket.makefile supports mode 'rb' only, got {mode!r}")
        return io.BufferedReader(_DeadlineReader(self))

    def close(self) -> None:
        """Nothing: http.client closes the connection while the response still reads from it;
        :meth:`_DeadlineConnection.release` closes the real socket."""

    def __getattr__(self, name: str) -> Any:
        return getattr(self._sock, name)


class _DeadlineReader(io.RawIOBase):
    def __init__(self, sock: _DeadlineSocket) -> None:
        self._sock = sock

    def readable(self) -> bool:
        return True

    def readinto(self, buffer: Any) -> int:
        return self._sock.recv_into(buffer)


class _DeadlineConnection:
    """Mixin for http.client connections: the socket gets a deadline once connected."""

    _deadline: float
    _real_sock: socket.socket | None = None
    sock: Any  # declared by http.client.HTTPConnection: the socket, then its deadline wrapper
    timeout: float | None

    def connect(self) -> None:
        left = self._deadline - time.monotonic()
        if left <= 0:
            raise _Deadline("the deadline passed")
        self.timeout = left  # bounds the TCP connect (and the TLS handshake)
        super().connect()  # type: ignore[misc]
        self._real_sock = self.sock
        self.sock = _DeadlineSocket(self.sock, self._deadline)

    def release(self) -> None:
        """Close the connection and its socket."""
        self.close()  # type: ignore[attr-defined]
        if self._real_sock is not None:
            self._real_sock.close()
            self._real_sock = None


class _HTTPConnection(_DeadlineConnection, http.client.HTTPConnection):
    def __init__(self, host: str, port: int | None, *, timeout: float, deadline: float) -> None:
        super().__init__(host, port, timeout=timeout)
        self._deadline = deadline


class _HTTPSConnection(_DeadlineConnection, http.client.HTTPSConnection):
    def __init__(self, host: str, port: int | None, *, timeout: float, deadline: float) -> None:
        super().__init__(host, port, timeout=timeout, context=ssl.create_default_context())
        self._deadline = deadline


def _connection(target: urllib.parse.SplitResult, timeout: float,
                deadline: float) -> tuple[_HTTPConnection | _HTTPSConnection, str, dict[str, str]]:
    """Connection, request target and extra headers for ``target``, through the environment's proxy if any.

    An http endpoint through a proxy is requested by its absolute URL; an https one through a
    CONNECT tunnel. A proxy's own user:password becomes a Proxy-Authorization header.
    """
    host, port = target.hostname or "", target.port
    path = urllib.parse.urlunsplit(("", "", target.path or "/", target.query, ""))
    proxy = _proxy_for(target)
    cls = _HTTPSConnection if target.scheme == "https" else _HTTPConnection
    if proxy is None:
        return cls(host, port, timeout=timeout, deadline=deadline), path, {}
    proxy_host, proxy_port, auth = proxy
    auth_headers = {"Proxy-Authorization": auth} if auth else {}
    if target.scheme == "https":
        conn = cls(proxy_host, proxy_port, timeout=timeout, deadline=deadline)
        conn.set_tunnel(host, port or 443, headers=auth_headers)
        return conn, path, {}
    absolute = urllib.parse.urlunsplit((target.scheme, target.netloc, target.path or "/", target.query, ""))
    return cls(proxy_host, proxy_port, timeout=timeout, deadline=deadline), absolute, auth_headers


def _proxy_for(target: urllib.parse.SplitResult) -> tuple[str, int, str | None] | None:
    """(host, port, Proxy-Authorization value) of the proxy for ``target``, None for a direct connection."""
    proxy_url = urllib.request.getproxies().get(target.scheme)
    if not proxy_url or urllib.request.proxy_bypass(target.netloc):
        return None
    if "://" not in proxy_url:
        proxy_url = "http://" + proxy_url
    try:
        parts = urllib.parse.urlsplit(proxy_url)
        port = parts.port or 80
    except ValueError:
        parts, port = None, 0
    if parts is None or parts.scheme != "http" or not parts.hostname:
        raise LLMUnavailable(f"the {target.scheme}_proxy setting is not an http://host:port URL: fix or unset it")
    auth = None
    if parts.username is not None:
        user = urllib.parse.unquote(parts.username)
        password = urllib.parse.unquote(parts.password or "")
        auth = "Basic " + base64.b64encode(f"{user}:{password}".encode()).decode("ascii")
    return parts.hostname, port, auth
