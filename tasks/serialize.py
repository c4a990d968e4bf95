"""Exact JSON round-trip of task specs: ``spec_from_dict(spec_to_dict(s)) == s``.

The dictionary form mirrors the dataclass fields one to one; tuples become lists, enums
their values, and the top level carries ``"version"``. Unknown keys are errors that name
the key and the accepted ones, so a typo in a hand-written ``task.json`` never passes.
The file hardening (encodings, sizes, NaN, nesting) lives in :mod:`tasks.jsonio`, shared with
scene files.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from tasks.exceptions import TaskDefinitionError
from tasks.jsonio import (
    _kind,
    _show,
    decode_spec_bytes,
    from_plain,
    parse_json,
    read_spec_bytes,
    to_plain,
)
from tasks.scene import check_scene_meshes
from tasks.specs import SPEC_VERSION, TaskSpec


def spec_to_dict(spec: TaskSpec) -> dict[str, Any]:
    """The JSON-compatible dictionary form of a spec (with ``version``); ``start`` only when the
    spec has one (a spec that starts standing keeps the JSON, and the motion cache key, it had
    before start states existed)."""
    plain = to_plain(spec)
    if plain.get("start") is None:
        plain.pop("start", None)
    return {"version": SPEC_VERSION, **plain}


def spec_from_dict(data: dict[str, Any]) -> TaskSpec:
    """Build a spec from its dictionary form.

    Raises:
        TaskDefinitionError: a key is unknown or missing, a value has the wrong type, or the
            spec fails validation; the message names the path (``phases[1].contacts[0]``).
    """
    if not isinstance(data, dict):
        raise TaskDefinitionError(f"task spec: expected a JSON object ({{...}}) at the top level, got {_kind(data)}")
    data = dict(data)
    version = data.pop("version", SPEC_VERSION)
    if isinstance(version, bool) or version != SPEC_VERSION:
        raise TaskDefinitionError(f"task spec: version {_show(version)} is not supported (expected {SPEC_VERSION})")
    return from_plain(TaskSpec, data, "spec")


def spec_to_json(spec: TaskSpec, *, indent: int | None = 2) -> str:
    """JSON text of a spec."""
    return json.dumps(spec_to_dict(spec), indent=indent, ensure_ascii=False)


def spec_from_json(text: str) -> TaskSpec:
    """Parse JSON text into a spec (TaskDefinitionError on bad JSON or content).

    Beyond the JSON grammar, the text may not hold NaN or Infinity, numbers of more than
    :data:`tasks.limits.MAX_DIGITS` digits, or nest deeper than :data:`tasks.limits.MAX_NESTING`
    levels.
    """
    return spec_from_dict(parse_json(text))


def load_spec(path: str | Path) -> TaskSpec:
    """Read a spec JSON file (``-``: standard input).

    Raises:
        TaskDefinitionError: the file is missing, a directory, unreadable, empty, too large, not
            UTF-8 (or UTF-16/32 with a byte-order mark), not JSON, or not a valid spec; the
            message starts with the file name and names the field (``spec.phases[1].duration``).
    """
    raw = read_spec_bytes(path)
    where = "standard input" if str(path) == "-" else str(path)
    try:
        spec = spec_from_json(decode_spec_bytes(raw))
        check_scene_meshes(spec.scene, "scene.")
        return spec
    except TaskDefinitionError as e:
        raise TaskDefinitionError(f"{where}: {e}") from None


__all__ = [
    "decode_spec_bytes",
    "from_plain",
    "load_spec",
    "parse_json",
    "read_spec_bytes",
    "spec_from_dict",
    "spec_from_json",
    "spec_to_dict",
    "spec_to_json",
    "to_plain",
]
