"""JSON schema of the TaskSpec file format, generated from the spec dataclasses.

``python -m tasks.spec_schema > docs/task-spec.schema.json`` regenerates the published schema
(a test checks that the file is up to date); ``python -m tasks.spec_schema --scene >
docs/scene.schema.json`` the scene file's. The schema mirrors :mod:`tasks.serialize`: one
object per dataclass with exactly its fields (``additionalProperties: false``), tuples as
fixed-length arrays, ``X | None`` as ``anyOf [X, null]``, enums as their values, and the field
descriptions taken from the dataclass docstrings. Value checks that JSON schema cannot express
(a window's order, unique names, times within the horizon) are done on loading.
"""

from __future__ import annotations

import dataclasses
import enum
import json
import re
import types
import typing
from typing import Any

from tasks.scene import SCENE_VERSION, Scene
from tasks.specs import SPEC_VERSION, TaskSpec

SCHEMA_ID = "https://wbmp.invalid/task-spec.schema.json"  # a name, not a location
SCENE_SCHEMA_ID = "https://wbmp.invalid/scene.schema.json"


def _attribute_docs(cls: type) -> dict[str, str]:
    """Field descriptions from the ``Attributes:`` section of a Google-style docstring."""
    doc = cls.__doc__ or ""
    out: dict[str, str] = {}
    if "Attributes:" not in doc:
        return out
    section = doc.split("Attributes:", 1)[1]
    current: list[str] = []
    for line in section.splitlines():
        m = re.match(r"^\s{8}([a-z_, ]+):\s*(.*)$", line)
        if m:
            current = [n.strip() for n in m.group(1).split(",")]
            for n in current:
                out[n] = m.group(2).strip()
        elif line.strip() and current and line.startswith(" " * 12):
            for n in current:
                out[n] += " " + line.strip()
    return out


def type_schema(tp: Any, defs: dict[str, Any]) -> dict[str, Any]:
    """JSON schema of a type hint of the spec dataclasses (dataclasses go to ``defs``)."""
    origin = typing.get_origin(tp)
    if origin in (typing.Union, types.UnionType):
        return {"anyOf": [type_schema(a, defs) for a in typing.get_args(tp)]}
    if tp is type(None):
        return {"type": "null"}
    if isinstance(tp, type) and dataclasses.is_dataclass(tp):
        name = tp.__name__
        if name not in defs:
            defs[name] = {}  # placeholder against recursion
            hints = typing.get_type_hints(tp)  # in the class's own module (specs, scene)
            docs = _attribute_docs(tp)
            props, required = {}, []
            for f in dataclasses.fields(tp):
                prop = type_schema(hints[f.name], defs)
                if f.name in docs:
                    prop = {**prop, "description": docs[f.name]}
                if f.default is not dataclasses.MISSING:
                    prop = {**prop, "default": _plain(f.default)}
                elif f.default_factory is dataclasses.MISSING:
                    required.append(f.name)
                props[f.name] = prop
            summary = (tp.__doc__ or "").strip().splitlines()[0] if tp.__doc__ else name
            defs[name] = {"type": "object", "description": summary, "properties": props,
                          "required": required, "additionalProperties": False}
        return {"$ref": f"#/$defs/{name}"}
    if origin is tuple:
        args = typing.get_args(tp)
        if len(args) == 2 and args[1] is Ellipsis:
            return {"type": "array", "items": type_schema(args[0], defs)}
        return {"type": "array", "prefixItems": [type_schema(a, defs) for a in args],
                "items": False, "minItems": len(args), "maxItems": len(args)}
    if isinstance(tp, type) and issubclass(tp, enum.Enum):
        return {"enum": [m.value for m in tp]}
    simple = {float: "number", int: "integer", bool: "boolean", str: "string"}
    if tp in simple:
        return {"type": simple[tp]}
    raise TypeError(f"no JSON schema for type {tp!r}")


def _plain(value: Any) -> Any:
    from tasks.jsonio import to_plain

    return to_plain(value)


def task_spec_schema() -> dict[str, Any]:
    """The JSON schema (draft 2020-12) of a TaskSpec file."""
    defs: dict[str, Any] = {}
    type_schema(TaskSpec, defs)
    root = dict(defs.pop("TaskSpec"))
    root["properties"] = {
        "version": {"const": SPEC_VERSION, "description": "File format version."}, **root["properties"]
    }
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "$id": SCHEMA_ID,
        "title": "wbmp TaskSpec",
        **root,
        "$defs": dict(sorted(defs.items())),
    }


def scene_schema() -> dict[str, Any]:
    """The JSON schema (draft 2020-12) of a scene file (docs/scenes.md)."""
    defs: dict[str, Any] = {}
    type_schema(Scene, defs)
    root = dict(defs.pop("Scene"))
    root["properties"] = {
        "version": {"const": SCENE_VERSION, "description": "File format version."}, **root["properties"]
    }
    obj = defs["SceneObject"]
    obj["properties"]["shape"] = {**obj["properties"]["shape"], "enum": ["box", "cylinder", "sphere", "mesh"]}
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "$id": SCENE_SCHEMA_ID,
        "title": "wbmp scene",
        **root,
        "$defs": dict(sorted(defs.items())),
    }


def schema_json(*, scene: bool = False) -> str:
    """The schema as the text of ``docs/task-spec.schema.json`` (``scene``: ``docs/scene.schema.json``)."""
    return json.dumps(scene_schema() if scene else task_spec_schema(), indent=2, ensure_ascii=False) + "\n"


if __name__ == "__main__":
    import sys

    print(schema_json(scene="--scene" in sys.argv[1:]), end="")
