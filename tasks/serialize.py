"""Exact JSON round-trip of task specs: ``spec_from_dict(spec_to_dict(s)) == s``.

The dictionary form mirrors the dataclass fields one to one; tuples become lists, enums
their values, and the top level carries ``"version"``. Unknown keys are errors that name
the key and the accepted ones, so a typo in a hand-written ``task.json`` never passes.
"""

from __future__ import annotations

import dataclasses
import enum
import json
import types
import typing
from pathlib import Path
from typing import Any

from tasks import specs
from tasks.exceptions import TaskDefinitionError
from tasks.specs import SPEC_VERSION, TaskSpec


def to_plain(obj: Any) -> Any:
    """Dataclasses/tuples/enums -> JSON-compatible dicts/lists/values."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {f.name: to_plain(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, enum.Enum):
        return obj.value
    if isinstance(obj, (tuple, list)):
        return [to_plain(x) for x in obj]
    if isinstance(obj, float) and obj.is_integer() and abs(obj) < 2**53:
        return obj  # keep floats as floats (json writes 1.0)
    return obj


def spec_to_dict(spec: TaskSpec) -> dict[str, Any]:
    """The JSON-compatible dictionary form of a spec (with ``version``)."""
    return {"version": SPEC_VERSION, **to_plain(spec)}


def spec_from_dict(data: dict[str, Any]) -> TaskSpec:
    """Build a spec from its dictionary form.

    Raises:
        TaskDefinitionError: a key is unknown or missing, a value has the wrong type, or the
            spec fails validation; the message names the path (``phases[1].contacts[0]``).
    """
    if not isinstance(data, dict):
        raise TaskDefinitionError("task spec: expected a JSON object at the top level")
    data = dict(data)
    version = data.pop("version", SPEC_VERSION)
    if version != SPEC_VERSION:
        raise TaskDefinitionError(f"task spec: version {version!r} is not supported (expected {SPEC_VERSION})")
    return from_plain(TaskSpec, data, "spec")


def spec_to_json(spec: TaskSpec, *, indent: int | None = 2) -> str:
    """JSON text of a spec."""
    return json.dumps(spec_to_dict(spec), indent=indent, ensure_ascii=False)


def spec_from_json(text: str) -> TaskSpec:
    """Parse JSON text into a spec (TaskDefinitionError on bad JSON or content)."""
    try:
        data = json.loads(text)
    except json.JSONDecodeError as e:
        raise TaskDefinitionError(f"task spec: invalid JSON at line {e.lineno} column {e.colno}: {e.msg}") from None
    return spec_from_dict(data)


def load_spec(path: str | Path) -> TaskSpec:
    """Read a spec JSON file."""
    path = Path(path)
    if not path.is_file():
        raise TaskDefinitionError(f"spec file {str(path)!r} does not exist")
    try:
        return spec_from_json(path.read_text(encoding="utf-8"))
    except TaskDefinitionError as e:
        raise TaskDefinitionError(f"{path}: {e}") from None


_HINTS: dict[type, dict[str, Any]] = {}


def _hints(cls: type) -> dict[str, Any]:
    if cls not in _HINTS:
        _HINTS[cls] = typing.get_type_hints(cls, vars(specs))
    return _HINTS[cls]


def from_plain(tp: Any, value: Any, path: str) -> Any:
    """Convert a JSON value to type ``tp`` (dataclass, tuple, Optional, enum, float...)."""
    origin = typing.get_origin(tp)
    if origin in (typing.Union, types.UnionType):
        args = typing.get_args(tp)
        if value is None:
            if type(None) in args:
                return None
            raise TaskDefinitionError(f"{path}: must not be null")
        errors = []
        for a in args:
            if a is type(None):
                continue
            try:
                return from_plain(a, value, path)
            except TaskDefinitionError as e:
                errors.append(str(e))
        raise TaskDefinitionError(errors[0] if errors else f"{path}: bad value {value!r}")
    if dataclasses.is_dataclass(tp):
        if not isinstance(value, dict):
            raise TaskDefinitionError(f"{path}: expected an object for {tp.__name__}, got {value!r}")
        hints = _hints(tp)
        fields = {f.name: f for f in dataclasses.fields(tp)}
        unknown = sorted(set(value) - set(fields))
        if unknown:
            raise TaskDefinitionError(f"{path}: unknown key(s) {unknown}; accepted: {sorted(fields)}")
        kwargs = {k: from_plain(hints[k], v, f"{path}.{k}") for k, v in value.items()}
        missing = [
            n for n, f in fields.items()
            if n not in kwargs and f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
        ]
        if missing:
            raise TaskDefinitionError(f"{path}: missing key(s) {missing}")
        try:
            return tp(**kwargs)
        except TaskDefinitionError as e:
            raise TaskDefinitionError(f"{path}: {e}") from None
    if origin is tuple:
        args = typing.get_args(tp)
        if not isinstance(value, (list, tuple)):
            raise TaskDefinitionError(f"{path}: expected a list, got {value!r}")
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(from_plain(args[0], v, f"{path}[{i}]") for i, v in enumerate(value))
        if len(args) != len(value):
            raise TaskDefinitionError(f"{path}: expected {len(args)} items, got {len(value)}")
        return tuple(from_plain(a, v, f"{path}[{i}]") for i, (a, v) in enumerate(zip(args, value, strict=True)))
    if isinstance(tp, type) and issubclass(tp, enum.Enum):
        try:
            return tp(value)
        except ValueError:
            raise TaskDefinitionError(f"{path}: {value!r} is not one of {[m.value for m in tp]}") from None
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise TaskDefinitionError(f"{path}: expected a number, got {value!r}")
        return float(value)
    if tp is bool:
        if not isinstance(value, bool):
            raise TaskDefinitionError(f"{path}: expected true or false, got {value!r}")
        return value
    if tp is str:
        if not isinstance(value, str):
            raise TaskDefinitionError(f"{path}: expected a string, got {value!r}")
        return value
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise TaskDefinitionError(f"{path}: expected an integer, got {value!r}")
        return value
    if tp is type(None):
        if value is not None:
            raise TaskDefinitionError(f"{path}: expected null")
        return None
    raise TaskDefinitionError(f"{path}: unsupported type {tp!r}")
