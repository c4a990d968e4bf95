"""The published TaskSpec JSON schema: up to date, accepts the examples, rejects typos."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tasks.serialize import load_spec
from tasks.spec_schema import schema_json, task_spec_schema

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = sorted((ROOT / "examples" / "specs").glob("*.json"))


def validate(instance, schema, root=None, path="$") -> list[str]:
    """A small JSON-schema subset validator (the keywords the generated schema uses)."""
    root = root or schema
    if "$ref" in schema:
        return validate(instance, root["$defs"][schema["$ref"].split("/")[-1]], root, path)
    if "anyOf" in schema:
        return [] if any(not validate(instance, s, root, path) for s in schema["anyOf"]) else [f"{path}: no match"]
    if "const" in schema and instance != schema["const"]:
        return [f"{path}: expected {schema['const']!r}"]
    if "enum" in schema and instance not in schema["enum"]:
        return [f"{path}: {instance!r} not in {schema['enum']}"]
    kind = schema.get("type")
    checks = {"object": dict, "array": list, "string": str, "boolean": bool, "null": type(None)}
    if kind == "number" and (isinstance(instance, bool) or not isinstance(instance, (int, float))):
        return [f"{path}: expected a number"]
    if kind == "integer" and (isinstance(instance, bool) or not isinstance(instance, int)):
        return [f"{path}: expected an integer"]
    if kind in checks and not isinstance(instance, checks[kind]):
        return [f"{path}: expected {kind}"]
    errors = []
    if kind == "object":
        props = schema.get("properties", {})
        errors += [f"{path}: missing {k}" for k in schema.get("required", []) if k not in instance]
        if schema.get("additionalProperties") is False:
            errors += [f"{path}: unknown key {k}" for k in instance if k not in props]
        for k, v in instance.items():
            if k in props:
                errors += validate(v, props[k], root, f"{path}.{k}")
    if kind == "array":
        n = len(instance)
        if n < schema.get("minItems", 0) or n > schema.get("maxItems", n):
            errors.append(f"{path}: {n} items")
        prefix = schema.get("prefixItems", [])
        for i, v in enumerate(instance):
            sub = prefix[i] if i < len(prefix) else schema.get("items", {})
            if sub is not False:
                errors += validate(v, sub, root, f"{path}[{i}]")
    return errors


def test_published_schema_is_up_to_date():
    """docs/task-spec.schema.json equals what tasks.spec_schema generates from the dataclasses."""
    assert (ROOT / "docs" / "task-spec.schema.json").read_text() == schema_json(), (
        "regenerate it: .venv/bin/python -m tasks.spec_schema > docs/task-spec.schema.json"
    )


@pytest.mark.parametrize("path", EXAMPLES, ids=[p.stem for p in EXAMPLES])
def test_examples_validate_and_load(path):
    """Every example spec passes the schema and loads as a TaskSpec."""
    assert validate(json.loads(path.read_text()), task_spec_schema()) == []
    assert load_spec(path).phases


def test_schema_rejects_a_typo_and_a_wrong_type():
    """An unknown key and a string where a number belongs are both reported with their path."""
    doc = json.loads(EXAMPLES[0].read_text())
    doc["phases"][0]["duraton"] = 3.0
    doc["dt"] = "fast"
    errors = validate(doc, task_spec_schema())
    assert "$.phases[0]: unknown key duraton" in errors and "$.dt: expected a number" in errors
