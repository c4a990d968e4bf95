"""Hardened JSON files of dataclasses: the reading, parsing and type conversion spec and scene files share.

:func:`read_spec_bytes` (size, kind of file), :func:`decode_spec_bytes` (UTF-8, byte-order
marks), :func:`parse_json` (no NaN, huge numbers or deep nesting) and :func:`from_plain` (exact
types, unknown keys, every error naming its path) are used by :mod:`tasks.serialize` (task specs)
and :mod:`tasks.scene` (scene files); :func:`to_plain` is the way back.
"""

from __future__ import annotations

import codecs
import dataclasses
import enum
import json
import math
import stat
import sys
import types
import typing
from pathlib import Path
from typing import Any

from tasks.exceptions import TaskDefinitionError
from tasks.limits import MAX_DIGITS, MAX_ITEMS, MAX_NESTING, MAX_SPEC_BYTES


def to_plain(obj: Any) -> Any:
    """Dataclasses/tuples/enums -> JSON-compatible dicts/lists/values (a field whose metadata has
    ``omit_none`` is left out when None: a field added later keeps older specs' JSON and cache keys)."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {f.name: to_plain(getattr(obj, f.name)) for f in dataclasses.fields(obj)
                if not (f.metadata.get("omit_none") and getattr(obj, f.name) is None)}
    if isinstance(obj, enum.Enum):
        return obj.value
    if isinstance(obj, (tuple, list)):
        return [to_plain(x) for x in obj]
    if isinstance(obj, float) and obj.is_integer() and abs(obj) < 2**53:
        return obj  # keep floats as floats (json writes 1.0)
    return obj


class _Refused(Exception):
    """Raised from inside the JSON parser's hooks (a literal JSON files must not hold)."""


def _parse_constant(name: str) -> Any:
    raise _Refused(f"{name} is not a number JSON allows (JSON has no NaN or Infinity): write a finite number")


def _parse_int(text: str) -> int:
    digits = len(text.lstrip("-"))
    if digits > MAX_DIGITS:
        raise _Refused(f"a number with {digits} digits is out of range: write a plain number in SI units")
    return int(text)


def _parse_float(text: str) -> float:
    if len(text) > MAX_DIGITS + 10:
        raise _Refused(f"a number written with {len(text)} characters is out of range: write a plain number")
    value = float(text)
    if not math.isfinite(value):
        raise _Refused(f"the number {text} is too large for a float: write a plain number in SI units")
    return value


def _nesting(data: Any) -> int:
    """The deepest nesting of lists and objects in parsed JSON (iterative: no recursion)."""
    deepest = 0
    stack = [(data, 1)]
    while stack:
        value, depth = stack.pop()
        if isinstance(value, (dict, list)):
            deepest = max(deepest, depth)
            if depth > MAX_NESTING:
                break
            children = value.values() if isinstance(value, dict) else value
            stack.extend((v, depth + 1) for v in children if isinstance(v, (dict, list)))
    return deepest


def parse_json(text: str, *, what: str = "task spec") -> Any:
    """Parse JSON text with the hardening of spec files (TaskDefinitionError, prefixed ``what: ``).

    Beyond the JSON grammar, the text may not hold NaN or Infinity, numbers of more than
    :data:`tasks.limits.MAX_DIGITS` digits, or nest deeper than :data:`tasks.limits.MAX_NESTING`
    levels; it holds at most :data:`tasks.limits.MAX_SPEC_BYTES` characters.
    """
    if not isinstance(text, str):
        raise TaskDefinitionError(f"{what}: expected JSON text, got {_kind(text)}")
    if len(text) > MAX_SPEC_BYTES:
        short = "spec" if what == "task spec" else what
        raise TaskDefinitionError(f"{what}: {len(text)} characters; a {short} holds at most {_size(MAX_SPEC_BYTES)}")
    if what == "task spec":
        too_deep = (f"task spec: JSON nested more than {MAX_NESTING} levels deep; a spec needs 7 "
                    "(spec.phases[0].contacts[0].placement.position) and may hold at most "
                    f"{MAX_NESTING}")
    else:
        too_deep = f"{what}: JSON nested more than {MAX_NESTING} levels deep; a {what} may hold at most {MAX_NESTING}"
    try:
        data = json.loads(text, parse_constant=_parse_constant, parse_int=_parse_int, parse_float=_parse_float)
    except json.JSONDecodeError as e:
        raise TaskDefinitionError(f"{what}: invalid JSON at line {e.lineno} column {e.colno}: {e.msg}") from None
    except _Refused as e:
        raise TaskDefinitionError(f"{what}: {e}") from None
    except RecursionError:  # the C parser refuses ~1,000 levels with this, cleanly
        raise TaskDefinitionError(too_deep) from None
    if _nesting(data) > MAX_NESTING:
        raise TaskDefinitionError(too_deep)
    return data


_BOMS = (
    (codecs.BOM_UTF32_LE, "utf-32-le", "UTF-32"),
    (codecs.BOM_UTF32_BE, "utf-32-be", "UTF-32"),
    (codecs.BOM_UTF8, "utf-8", "UTF-8 with a byte-order mark"),
    (codecs.BOM_UTF16_LE, "utf-16-le", "UTF-16"),
    (codecs.BOM_UTF16_BE, "utf-16-be", "UTF-16"),
)


def decode_spec_bytes(raw: bytes) -> str:
    """The text of a spec file: UTF-8, or UTF-8/UTF-16/UTF-32 with a byte-order mark.

    Editors on Windows often save UTF-16 with a byte-order mark, and some add one to UTF-8:
    both are read. Anything else must be UTF-8; other bytes (Latin-1, UTF-16 without a mark)
    are refused with the offending byte and how to fix the file.
    """
    for bom, codec, label in _BOMS:
        if raw.startswith(bom):
            try:
                return raw[len(bom):].decode(codec)
            except UnicodeDecodeError as e:
                raise TaskDefinitionError(
                    f"the file starts with a {label} byte-order mark but is not valid {label.split()[0]} "
                    f"(at byte {e.start + len(bom)}): save it as UTF-8"
                ) from None
    if b"\x00" in raw[:4]:
        raise TaskDefinitionError("the file looks like UTF-16 or UTF-32 without a byte-order mark: save it as UTF-8")
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as e:
        line = raw[: e.start].count(b"\n") + 1
        raise TaskDefinitionError(
            f"the file is not UTF-8 text (byte 0x{raw[e.start]:02x} on line {line}; Latin-1 or another "
            "8-bit encoding?): save it as UTF-8"
        ) from None


def _open_input(path: Path):
    """``path`` opened for reading without waiting for a writer (``O_NONBLOCK``), then switched
    back to blocking reads: a named pipe that nobody writes to reads as empty (refused as an
    empty file) instead of hanging the command; a pipe with a writer (``/dev/stdin``, ``<(...)``)
    is read to its end, a regular file as always."""
    import os

    fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    try:
        os.set_blocking(fd, True)
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def read_spec_bytes(path: str | Path, *, what: str = "spec") -> bytes:
    """The bytes of a spec file (``-`` reads standard input), at most :data:`MAX_SPEC_BYTES`.

    ``what`` names the kind of file in messages (``spec``, ``scene``).

    A directory, a missing or unreadable file, an empty one and one larger than the limit are
    refused with a message that says which. Character devices and pipes (``/dev/stdin``, a
    named pipe) are read like files, at most the limit plus one byte (``/dev/zero`` is too large);
    a named pipe without a writer is empty, never waited on.
    """
    if str(path) == "-":
        stream = sys.stdin.buffer if sys.stdin is not None else None
        if stream is None:
            raise TaskDefinitionError(f"{what} from standard input ('-'): there is no standard input")
        data = stream.read(MAX_SPEC_BYTES + 1)
        where = "standard input"
    else:
        path = Path(path)
        where = f"{what} file {str(path)!r}"
        try:
            st = path.stat()
        except FileNotFoundError:
            raise TaskDefinitionError(f"{where} does not exist") from None
        except NotADirectoryError:
            raise TaskDefinitionError(f"{where} does not exist (a part of the path is a file, not a folder)") from None
        except PermissionError:
            raise TaskDefinitionError(f"{where} cannot be read: permission denied") from None
        except OSError as e:
            raise TaskDefinitionError(f"{where} cannot be read: {e.strerror or e}") from None
        if stat.S_ISDIR(st.st_mode):
            raise TaskDefinitionError(f"{where} is a directory, not a JSON file")
        if stat.S_ISREG(st.st_mode) and st.st_size > MAX_SPEC_BYTES:
            raise TaskDefinitionError(
                f"{where} is {_size(st.st_size)}; a {what} file holds at most {_size(MAX_SPEC_BYTES)}"
            )
        try:
            with _open_input(path) as f:
                data = f.read(MAX_SPEC_BYTES + 1)
        except PermissionError:
            raise TaskDefinitionError(f"{where} cannot be read: permission denied") from None
        except IsADirectoryError:
            raise TaskDefinitionError(f"{where} is a directory, not a JSON file") from None
        except OSError as e:
            raise TaskDefinitionError(f"{where} cannot be read: {e.strerror or e}") from None
    if len(data) > MAX_SPEC_BYTES:
        raise TaskDefinitionError(f"{where} is larger than {_size(MAX_SPEC_BYTES)}, the most a {what} file may hold")
    if not data.strip():
        doc = "docs/spec-format.md" if what == "spec" else f"docs/{what}s.md"
        raise TaskDefinitionError(f"{where} is empty; a {what} is a JSON object ({doc})")
    return data


def _size(n: int) -> str:
    return f"{n / 2**20:.0f} MiB" if n >= 2**20 else f"{n} bytes"


def _kind(value: Any) -> str:
    names = {dict: "an object", list: "a list", str: "a string", bool: "a boolean", type(None): "null",
             int: "a number", float: "a number"}
    kind = names.get(type(value), type(value).__name__)
    if isinstance(value, (str, int, float)) and not isinstance(value, bool):
        return f"{kind} ({_show(value)})"
    return kind


def _show(value: Any) -> str:
    """A short description of a JSON value for messages (no 5,000-character reprs)."""
    if isinstance(value, dict):
        return "an object"
    if isinstance(value, (list, tuple)):
        if len(value) <= 4 and all(v is None or isinstance(v, (int, float, str, bool)) for v in value):
            return "[" + ", ".join(_show(v) if v is not None else "null" for v in value) + "]"
        return f"a list of {len(value)} items"
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    text = repr(value)
    return text if len(text) <= 40 else f"{text[:30]}... ({len(text)} characters)"


_UNITS = {
    "duration": " in seconds", "time": " in seconds", "dt": " in seconds", "window": " in seconds",
    "position": " in metres", "lower": " in metres", "upper": " in metres", "tolerance": " in metres",
    "margin": " in metres", "swing_height": " in metres", "rpy": " in radians",
    "orientation_tolerance": " in radians", "value": " (radians or metres)", "size": " (metres)",
    "mass": " in kilograms", "colour": " in [0, 1]", "floor_friction": "", "friction": "",
}


def _unit(path: str) -> str:
    key = path.rsplit(".", 1)[-1].split("[", 1)[0]
    return _UNITS.get(key, "")


_HINTS: dict[type, dict[str, Any]] = {}


def _hints(cls: type) -> dict[str, Any]:
    if cls not in _HINTS:
        _HINTS[cls] = typing.get_type_hints(cls)  # in the class's own module (specs, scene)
    return _HINTS[cls]


def from_plain(tp: Any, value: Any, path: str) -> Any:
    """Convert a JSON value to type ``tp`` (dataclass, tuple, Optional, enum, float...).

    Every error names the path of the value (``spec.phases[1].duration``) and what was expected.
    """
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
        raise TaskDefinitionError(errors[0] if errors else f"{path}: bad value {_show(value)}")
    if isinstance(tp, type) and dataclasses.is_dataclass(tp):
        if not isinstance(value, dict):
            raise TaskDefinitionError(f"{path}: expected an object for {tp.__name__}, got {_kind(value)}")
        hints = _hints(tp)
        fields = {f.name: f for f in dataclasses.fields(tp)}
        unknown = sorted(set(value) - set(fields))
        if unknown:
            shown = [k if len(k) <= 40 else k[:30] + "..." for k in unknown[:5]]
            raise TaskDefinitionError(f"{path}: unknown key(s) {shown}; accepted: {sorted(fields)}")
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
            message = str(e)
            if tp.__name__ == "TaskSpec" and message.startswith("task spec: "):
                message = message[len("task spec: "):]  # "spec: the motion would last...", not "spec: task spec: ..."
            field = getattr(e, "field", None)
            if field is not None:  # the scene's classes name the field: "spec.scene.objects[2].size: ..."
                raise TaskDefinitionError(f"{path}.{field}: {getattr(e, 'reason', message)}") from None
            raise TaskDefinitionError(f"{path}: {message}") from None
    if origin is tuple:
        args = typing.get_args(tp)
        if not isinstance(value, (list, tuple)):
            raise TaskDefinitionError(f"{path}: expected a list, got {_kind(value)}")
        if len(args) == 2 and args[1] is Ellipsis:
            if len(value) > MAX_ITEMS:
                raise TaskDefinitionError(f"{path}: {len(value)} items; a spec holds at most {MAX_ITEMS} in a list")
            return tuple(from_plain(args[0], v, f"{path}[{i}]") for i, v in enumerate(value))
        if len(args) != len(value):
            raise TaskDefinitionError(f"{path}: expected {len(args)} items{_unit(path)}, got {_show(value)}")
        return tuple(from_plain(a, v, f"{path}[{i}]") for i, (a, v) in enumerate(zip(args, value, strict=True)))
    if isinstance(tp, type) and issubclass(tp, enum.Enum):
        try:
            return tp(value)
        except (ValueError, TypeError):
            raise TaskDefinitionError(f"{path}: expected one of {[m.value for m in tp]}, got {_show(value)}") from None
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise TaskDefinitionError(f"{path}: expected a number{_unit(path)}, got {_kind(value)}")
        try:
            number = float(value)
        except OverflowError:
            number = math.inf
        if not math.isfinite(number):
            raise TaskDefinitionError(f"{path}: expected a finite number{_unit(path)}, got {_show(value)}")
        return number
    if tp is bool:
        if not isinstance(value, bool):
            raise TaskDefinitionError(f"{path}: expected true or false, got {_kind(value)}")
        return value
    if tp is str:
        if not isinstance(value, str):
            raise TaskDefinitionError(f"{path}: expected a string, got {_kind(value)}")
        try:
            value.encode("utf-8")
        except UnicodeEncodeError:
            raise TaskDefinitionError(f"{path}: the string holds an invalid character (a lone surrogate)") from None
        return value
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise TaskDefinitionError(f"{path}: expected an integer, got {_kind(value)}")
        return value
    if tp is type(None):
        if value is not None:
            raise TaskDefinitionError(f"{path}: expected null, got {_kind(value)}")
        return None
    raise TaskDefinitionError(f"{path}: unsupported type {tp!r}")
