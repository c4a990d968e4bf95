"""A small JSON-schema validator for the subset the action registry's schema uses.

:func:`tasks.actions.actions_json_schema` is what the LLM backend sends to the model and checks
the reply against. It uses ``type``, ``properties``, ``required``, ``additionalProperties``,
``items``, ``minItems``/``maxItems``, ``enum``, ``const``, ``minimum``/``maximum`` and
``oneOf`` (plus annotations). This module checks exactly those and refuses any other keyword,
so a schema that grows a new keyword fails loudly instead of being half-checked.

Error messages name the place in the reply (``actions[1].params.depth``) and what was wrong;
for a ``oneOf`` over actions the branch whose ``const`` matches (the action name) reports.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from language.exceptions import SchemaViolation, UnsupportedSchema

ANNOTATIONS = frozenset({"$schema", "title", "description", "default", "examples", "$comment"})
SUPPORTED = frozenset({
    "type", "properties", "required", "additionalProperties", "items", "minItems", "maxItems",
    "enum", "const", "minimum", "maximum", "oneOf",
}) | ANNOTATIONS


def validate(instance: Any, schema: Mapping[str, Any]) -> None:
    """Raise :class:`SchemaViolation` if ``instance`` does not match ``schema``."""
    errs = errors(instance, schema)
    if errs:
        raise SchemaViolation(errs)


def errors(instance: Any, schema: Mapping[str, Any], path: str = "") -> list[str]:
    """Every violation of ``schema`` by ``instance``, as ``"path: problem"`` strings."""
    unknown = set(schema) - SUPPORTED
    if unknown:
        raise UnsupportedSchema(f"schema keyword(s) {sorted(unknown)} are not supported by language.validate")
    where = path or "reply"
    out: list[str] = []
    if "type" in schema and not _is_type(instance, schema["type"]):
        return [f"{where}: expected {_a(schema['type'])}, got {_describe(instance)}"]
    if "const" in schema and not _equal(instance, schema["const"]):
        out.append(f"{where}: must be {schema['const']!r}, got {_short(instance)}")
    if "enum" in schema and not any(_equal(instance, e) for e in schema["enum"]):
        out.append(f"{where}: must be one of {', '.join(map(repr, schema['enum']))}, got {_short(instance)}")
    if _is_type(instance, "number"):
        if "minimum" in schema and instance < schema["minimum"]:
            out.append(f"{where}: {_short(instance)} is below the minimum {schema['minimum']!r}")
        if "maximum" in schema and instance > schema["maximum"]:
            out.append(f"{where}: {_short(instance)} is above the maximum {schema['maximum']!r}")
    if isinstance(instance, Mapping):
        props = schema.get("properties", {})
        for key in schema.get("required", ()):
            if key not in instance:
                out.append(f"{where}: missing required key {_short(key)}")
        for key, value in instance.items():
            if key in props:
                out.extend(errors(value, props[key], f"{path}.{key}" if path else key))
            else:
                extra = schema.get("additionalProperties", True)
                if extra is False:
                    allowed = ", ".join(props) or "none"
                    out.append(f"{where}: unknown key {_short(key)} (allowed: {allowed})")
                elif isinstance(extra, Mapping):
                    out.extend(errors(value, extra, f"{path}.{key}" if path else key))
    if isinstance(instance, list):
        if "minItems" in schema and len(instance) < schema["minItems"]:
            out.append(f"{where}: needs at least {schema['minItems']} item(s), got {len(instance)}")
        if "maxItems" in schema and len(instance) > schema["maxItems"]:
            # Refused for its length: the items are not checked (10,000 of them would take seconds).
            return [*out, f"{where}: takes at most {schema['maxItems']} item(s), got {len(instance)}"]
        if "items" in schema:
            for i, item in enumerate(instance):
                out.extend(errors(item, schema["items"], f"{path}[{i}]"))
    if "oneOf" in schema:
        out.extend(_one_of(instance, schema["oneOf"], path))
    return out


def _one_of(instance: Any, branches: list[Mapping[str, Any]], path: str) -> list[str]:
    where = path or "reply"
    results = [errors(instance, b, path) for b in branches]
    valid = sum(not r for r in results)
    if valid == 1:
        return []
    if valid > 1:
        return [f"{where}: matches {valid} alternatives, expected exactly one"]
    # Report the branch whose discriminating constants match (e.g. the one whose "action" const
    # equals the reply's action name); otherwise say which constants were allowed.
    consts: dict[str, list[Any]] = {}
    for branch, errs in zip(branches, results, strict=True):
        branch_consts = {k: p["const"] for k, p in branch.get("properties", {}).items() if "const" in p}
        for k, v in branch_consts.items():
            consts.setdefault(k, []).append(v)
        if branch_consts and isinstance(instance, Mapping) and all(
            k in instance and _equal(instance[k], v) for k, v in branch_consts.items()
        ):
            return errs
    if isinstance(instance, Mapping):
        for key, values in consts.items():
            if len(values) == len(branches):
                got = instance.get(key, "<missing>")
                return [f"{path + '.' if path else ''}{key}: {_short(got)} is not one of {', '.join(map(repr, values))}"]
    return [f"{where}: matches none of the {len(branches)} alternatives"]


_TYPES = {
    "object": lambda v: isinstance(v, Mapping),
    "array": lambda v: isinstance(v, list),
    "string": lambda v: isinstance(v, str),
    "boolean": lambda v: isinstance(v, bool),
    "null": lambda v: v is None,
    # JSON has no NaN or Infinity (Python's parser accepts them): a number is finite.
    "number": lambda v: isinstance(v, (int, float)) and not isinstance(v, bool) and _finite(v),
    "integer": lambda v: (isinstance(v, int) and not isinstance(v, bool)) or (isinstance(v, float) and v.is_integer()),
}


def _finite(v: int | float) -> bool:
    return isinstance(v, int) or math.isfinite(v)


def _short(value: Any) -> str:
    """A repr for messages, cut short (a reply may hold a huge number, string or list)."""
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) > 10**40:
        return f"a number with {len(str(abs(value))) if abs(value) < 10**4000 else 'thousands of'} digits"
    text = repr(value)
    return text if len(text) <= 60 else f"{text[:40]}... ({len(text)} characters)"


def _is_type(value: Any, kind: str | list[str]) -> bool:
    kinds = [kind] if isinstance(kind, str) else kind
    for k in kinds:
        if k not in _TYPES:
            raise UnsupportedSchema(f"schema type {k!r} is not supported by language.validate")
    return any(_TYPES[k](value) for k in kinds)


def _equal(a: Any, b: Any) -> bool:
    if isinstance(a, bool) or isinstance(b, bool):
        return a is b
    return a == b


def _a(kind: str | list[str]) -> str:
    kinds = [kind] if isinstance(kind, str) else kind
    return " or ".join(("an " if k[0] in "aeiou" else "a ") + k for k in kinds)


def _describe(value: Any) -> str:
    if isinstance(value, float) and not math.isfinite(value):
        return f"{value!r}, which JSON does not allow (a number must be finite)"
    for name in ("boolean", "null", "integer", "number", "string", "array", "object"):
        if _TYPES[name](value):
            return f"{_a(name)} ({_short(value)})" if name not in ("array", "object") else _a(name)
    return type(value).__name__
