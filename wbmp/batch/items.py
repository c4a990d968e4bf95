"""The items of a batch file and the jobs (item x robot) they expand to.

A batch file (``wbmp batch FILE``, docs/batch.md) is UTF-8 text in one of two forms, told apart by
its first line that is neither blank nor a ``#`` comment:

* plain lines: each line is a sentence, or the path of a TaskSpec JSON file when it ends in
  ``.json`` (a relative path is taken from the batch file's folder);
* JSONL (the first such line starts with ``{``): each line is one JSON object with
  ``instruction`` (a sentence) or ``spec`` (a path, or the spec object itself), and optionally
  ``robot``, ``scene`` (a scene file, as ``wbmp solve --scene``) and ``id``.

``FILE`` may also be a folder of motion-capture clips: each ``*.bvh`` file in it is one item,
retargeted as ``wbmp retarget CLIP`` does (the window of a ``clips.csv`` row, when the folder has
one, as ``wbmp solve --motions`` takes it).

Everything here is checked before any work, and a refused file is one :class:`CliError` line
that names the file, the line number and how to fix it (exit 2; an unknown robot is exit 3,
as in ``wbmp solve``).
"""

from __future__ import annotations

import hashlib
import json
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from robots import safeio
from wbmp.errors import CliError, ExitCode, one_line

#: Keys a JSONL line may hold.
JSONL_KEYS = ("instruction", "spec", "robot", "scene", "id")
#: An ``id`` of a JSONL line: it names the motion file, so it is a safe file-name part.
ID_PATTERN = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,79}$")
#: Longest batch file read [bytes] (a library of 100,000 sentences is ~5 MB).
MAX_FILE_BYTES = 64 * 1024 * 1024
#: Separator of the item id and the robot in a motion file name: ``<id>__<robot>.npz``.
SEPARATOR = "__"


@dataclass(frozen=True, slots=True, kw_only=True)
class Item:
    """One line of the batch file.

    Attributes:
        id: Stable identifier: the JSONL ``id``, else a slug of the text and a hash of the item.
        line: Line number in the batch file (1-based).
        instruction: The sentence, or None.
        spec_path: The spec file (resolved), or None.
        spec_text: The spec as written in the file (path as written, or the object as JSON).
        spec_object: The spec object of a JSONL line, or None.
        robot: The robot the line names, or None.
        scene_path: The scene file (resolved) the line names, or None.
        scene_text: The scene file as written in the line, or None.
        clip_path: The BVH clip (resolved) of a folder of clips, or None.
        clip_text: The clip's file name in that folder, or None.
        start, end: The clip's window [s] from the folder's ``clips.csv`` (None: its start, its end).
    """

    id: str
    line: int
    instruction: str | None = None
    spec_path: str | None = None
    spec_text: str | None = None
    spec_object: dict[str, Any] | None = None
    robot: str | None = None
    scene_path: str | None = None
    scene_text: str | None = None
    clip_path: str | None = None
    clip_text: str | None = None
    start: float | None = None
    end: float | None = None

    def source(self) -> dict[str, Any]:
        """What the index records of the input: ``instruction``, ``spec`` or ``clip`` (with its
        ``start`` and ``end`` when the folder's clips.csv gives a window), and ``scene``."""
        if self.clip_text is not None:
            window = {k: v for k, v in (("start", self.start), ("end", self.end)) if v is not None}
            return {"clip": self.clip_text, **window}
        scene = {} if self.scene_text is None else {"scene": self.scene_text}
        if self.instruction is not None:
            return {"instruction": self.instruction, **scene}
        if self.spec_object is not None:
            return {"spec": self.spec_object, **scene}
        return {"spec": self.spec_text, **scene}


@dataclass(frozen=True, slots=True, kw_only=True)
class Job:
    """One item planned on one robot: what a worker receives (plain, picklable data).

    Attributes:
        item: The item.
        robot: Robot name or profile file given to the solver.
        robot_label: The robot's name in the motion file name and the index.
        input_sha256: Hash of what decides the result (the item, the spec file's content, the
            robot, the simulation switch): a done record with another hash is planned again.
    """

    item: Item
    robot: str
    robot_label: str
    input_sha256: str

    @property
    def key(self) -> tuple[str, str]:
        """(id, robot label): one record of the index."""
        return (self.item.id, self.robot_label)

    @property
    def motion_name(self) -> str:
        """File name of the motion in the output folder."""
        return f"{self.item.id}{SEPARATOR}{self.robot_label}.npz"


def _refuse(path: str, line: int | None, message: str, code: ExitCode = ExitCode.USAGE) -> CliError:
    where = f"{path}:{line}" if line is not None else path
    return CliError(f"{where}: {message}", code)


def _slug(text: str) -> str:
    words = re.findall(r"[a-z0-9]+", text.lower())
    return "-".join(words)[:40].strip("-") or "item"


def _digest(*parts: str) -> str:
    h = hashlib.sha256()
    for p in parts:
        h.update(p.encode("utf-8", "surrogatepass"))
        h.update(b"\0")
    return h.hexdigest()


def read_lines(path: str) -> list[tuple[int, str]]:
    """(line number, text) of every line that is not blank or a ``#`` comment."""
    p = Path(path)
    shown = repr(path)
    try:
        if not p.is_file():
            if not p.exists():
                raise CliError(f"FILE {shown} does not exist (give a text or JSONL file with one item per line)",
                               ExitCode.USAGE)
            raise CliError(f"FILE {shown} is not a regular file", ExitCode.USAGE)
        if p.stat().st_size > MAX_FILE_BYTES:
            raise CliError(f"FILE {shown} is larger than {MAX_FILE_BYTES // 2**20} MiB; split the batch",
                           ExitCode.USAGE)
        raw = safeio.read_bytes(p, MAX_FILE_BYTES)  # (a FIFO or device in the file's place never blocks)
    except OSError as e:
        raise CliError(f"FILE {shown}: cannot read it: {e.strerror or e}", ExitCode.USAGE) from None
    if raw.startswith(b"\xef\xbb\xbf"):
        raw = raw[3:]
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as e:
        raise CliError(f"FILE {shown}: not UTF-8 text (byte {e.start}); save it as UTF-8", ExitCode.USAGE) from None
    out = []
    for n, line in enumerate(text.splitlines(), 1):
        stripped = line.strip()
        if stripped and not stripped.startswith("#"):
            out.append((n, stripped))
    if not out:
        raise CliError(f"FILE {shown} holds no item (only blank lines or # comments): write one sentence, "
                       "spec file or JSON object per line", ExitCode.USAGE)
    return out


def read_items(path: str) -> list[Item]:
    """The items of a batch file, in file order, duplicates (same id and content) kept once; or
    the clips of a folder of ``*.bvh`` files (:func:`clip_items`)."""
    if Path(path).is_dir():
        return clip_items(path)
    lines = read_lines(path)
    jsonl = lines[0][1].startswith("{")
    base = Path(path).parent
    items: list[Item] = []
    seen: dict[str, tuple[int, Item]] = {}
    for n, text in lines:
        item = _json_item(path, n, text, base) if jsonl else _plain_item(path, n, text, base)
        if item.id in seen:
            first_line, first = seen[item.id]
            if first.source() == item.source() and first.robot == item.robot:  # source() holds the scene
                continue  # the same item twice: planned once
            raise _refuse(path, n, f"id {item.id!r} is used by line {first_line} too; give each item its own id")
        seen[item.id] = (n, item)
        items.append(item)
    return items


def _plain_item(path: str, n: int, text: str, base: Path) -> Item:
    if text.lower().endswith(".json"):
        spec_path = _spec_file(path, n, text, base)
        return Item(id=_auto_id(Path(text).stem, "spec", text), line=n, spec_path=spec_path, spec_text=text)
    if text.startswith("{"):
        raise _refuse(path, n, "a JSON object in a file of sentences: a JSONL batch file starts with "
                               "an object on its first line, and every line is one")
    return Item(id=_auto_id(text, "instruction", text), line=n, instruction=text)


def _auto_id(label: str, kind: str, text: str, robot: str | None = None, scene: str | None = None) -> str:
    parts = (kind, text, robot or "") if scene is None else (kind, text, robot or "", "scene", scene)
    return f"{_slug(label)}-{_digest(*parts)[:10]}"


def _spec_file(path: str, n: int, text: str, base: Path, what: str = "spec") -> str:
    p = Path(text)
    if not p.is_absolute():
        p = base / p
    if not p.is_file():
        if p.exists():  # a FIFO, device or folder: read, it would block or never end
            raise _refuse(path, n, f"{what} file {text!r} is not a regular file; give a JSON file")
        raise _refuse(path, n, f"{what} file {text!r} not found (relative paths are taken from the batch "
                               f"file's folder, {str(base)!r})")
    return str(p)


class _NonFinite(ValueError):
    """A number JSON has no finite value for: NaN, Infinity, or a float too large (1e999)."""


def _no_constant(name: str) -> float:
    raise _NonFinite(name)


def _finite_float(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise _NonFinite(text)
    return value


def _json_item(path: str, n: int, text: str, base: Path) -> Item:
    try:
        doc = json.loads(text, parse_constant=_no_constant, parse_float=_finite_float)
    except _NonFinite as e:
        raise _refuse(path, n, f"the number {one_line(str(e), 40)} is not finite; write finite numbers "
                               "(JSON has no NaN or Infinity)") from None
    except (ValueError, RecursionError) as e:  # JSONDecodeError, or an integer of too many digits
        why = (e.msg if isinstance(e, json.JSONDecodeError) else "nested too deeply" if isinstance(e, RecursionError)
               else "a number with too many digits")
        raise _refuse(path, n, f"not a JSON object ({why}); a JSONL batch file holds one object per line, "
                               'e.g. {"instruction": "squat twice", "robot": "talos"}') from None
    if not isinstance(doc, dict):
        raise _refuse(path, n, f"a JSON {type(doc).__name__}, not an object; write "
                               '{"instruction": ...} or {"spec": ...}')
    try:
        json.dumps(doc, ensure_ascii=False).encode("utf-8")
    except UnicodeEncodeError:
        raise _refuse(path, n, "a string holds a lone surrogate escape (such as \\ud800), which is not "
                               "text; write the character itself or a valid pair") from None
    unknown = sorted(set(doc) - set(JSONL_KEYS))
    if unknown:
        raise _refuse(path, n, f"unknown key {one_line(unknown[0])!r}; a line may hold {', '.join(JSONL_KEYS)}")
    has_text, has_spec = "instruction" in doc, "spec" in doc
    if has_text == has_spec:
        raise _refuse(path, n, 'give exactly one of "instruction" and "spec"')
    robot = doc.get("robot")
    if robot is not None and (not isinstance(robot, str) or not robot.strip()):
        raise _refuse(path, n, '"robot" must be a non-empty robot name')
    scene = doc.get("scene")
    if scene is not None and (not isinstance(scene, str) or not scene.strip()):
        raise _refuse(path, n, '"scene" must be a scene JSON file path (docs/scenes.md)')
    scene_path = _spec_file(path, n, scene, base, "scene") if scene is not None else None
    given_id = doc.get("id")
    if given_id is not None:
        if not isinstance(given_id, str) or not ID_PATTERN.match(given_id) or SEPARATOR in given_id:
            raise _refuse(path, n, f'"id" {one_line(str(given_id))!r}: use 1 to 80 letters, digits, ".", "_" or "-" '
                                   f'(starting with a letter or digit, no "{SEPARATOR}"): it names the motion file')
    if has_text:
        sentence = doc["instruction"]
        if not isinstance(sentence, str) or not sentence.strip():
            raise _refuse(path, n, '"instruction" must be a non-empty sentence')
        return Item(id=given_id or _auto_id(sentence, "instruction", sentence, robot, scene), line=n,
                    instruction=sentence.strip(), robot=robot, scene_path=scene_path, scene_text=scene)
    spec = doc["spec"]
    if isinstance(spec, str) and spec.strip():
        spec_path = _spec_file(path, n, spec, base)
        return Item(id=given_id or _auto_id(Path(spec).stem, "spec", spec, robot, scene), line=n,
                    spec_path=spec_path, spec_text=spec, robot=robot, scene_path=scene_path, scene_text=scene)
    if isinstance(spec, dict):
        canonical = json.dumps(spec, sort_keys=True, ensure_ascii=False)
        label = str(spec.get("name") or "spec")
        return Item(id=given_id or _auto_id(label, "spec-object", canonical, robot, scene), line=n,
                    spec_object=spec, spec_text=canonical, robot=robot, scene_path=scene_path, scene_text=scene)
    raise _refuse(path, n, '"spec" must be a spec file path or a spec object')


def clip_items(folder: str) -> list[Item]:
    """One item per ``*.bvh`` file of ``folder`` (name order; ``line`` is the position in it),
    with the window of its ``clips.csv`` row when the folder has that table."""
    from wbmp.motions import load_library

    root = Path(folder)
    try:
        clips = sorted(p for p in root.iterdir() if p.suffix.lower() == ".bvh" and p.is_file())
    except OSError as e:
        raise CliError(f"FILE {folder!r}: cannot list the folder: {e.strerror or e}", ExitCode.USAGE) from None
    if not clips:
        raise CliError(f"FILE {folder!r} is a folder without .bvh clips: give a folder of BVH clips, or a "
                       "file with one sentence, spec file or JSON object per line", ExitCode.USAGE)
    windows = {}
    if (root / "clips.csv").is_file():
        windows = {c.path.name: (c.start, c.end) for c in load_library(root)}
    items = []
    for n, clip in enumerate(clips, 1):
        start, end = windows.get(clip.name, (None, None))
        text = f"{clip.name} [{start}, {end}]"
        items.append(Item(id=_auto_id(clip.stem, "clip", text), line=n, clip_path=str(clip), clip_text=clip.name,
                          start=start, end=end))
    return items


def robot_label(robot: str) -> str:
    """The robot's part of a motion file name: the name, or a profile file's stem."""
    return _slug(Path(robot).stem) if robot.lower().endswith((".toml", ".json")) else robot


def check_robot(robot: str, known: list[str], where: str) -> None:
    """An unknown robot (neither built in nor a file) is refused like ``wbmp solve`` does (exit 3)."""
    if robot in known or (robot.lower().endswith((".toml", ".json")) and Path(robot).is_file()):
        return
    raise CliError(f"{where}: unknown robot {one_line(robot)!r}; known: {', '.join(known)} (or a profile file)",
                   ExitCode.INVALID_SPEC)


def spec_robot(item: Item) -> str:
    """The robot a spec names (its ``robot`` field), else talos; checked again by the solver."""
    doc: Any = item.spec_object
    if doc is None and item.spec_path is not None:
        try:
            doc = json.loads(safeio.read_text(item.spec_path, "spec", encoding="utf-8-sig"))
        except (OSError, ValueError):
            doc = None  # the solver reports the bad file for this item
    robot = doc.get("robot") if isinstance(doc, dict) else None
    return robot if isinstance(robot, str) and robot.strip() else "talos"


def expand(items: list[Item], robots: list[str] | None, *, simulate: bool, file: str) -> list[Job]:
    """Item x robot jobs: a line's own robot wins; else each of ``robots``; else the spec's robot
    (or talos for a sentence). Unknown robots are refused here, before any work (exit 3)."""
    from robots import available_robots

    known = available_robots()
    jobs = []
    for item in items:
        if item.robot is not None:
            check_robot(item.robot, known, f"{file}:{item.line}")
            chosen = [item.robot]
        elif robots:
            chosen = robots
        else:
            chosen = [spec_robot(item) if item.instruction is None else "talos"]
        for robot in chosen:
            content = _file_hash(item.spec_path or item.clip_path)
            parts = [json.dumps(item.source(), sort_keys=True, ensure_ascii=False), content, robot,
                     "sim" if simulate else "no-sim"]
            if item.scene_path is not None:  # (no scene: the hash of earlier versions, their records stay done)
                parts.append(_file_hash(item.scene_path))
            digest = _digest(*parts)
            jobs.append(Job(item=item, robot=robot, robot_label=robot_label(robot), input_sha256=digest))
    return jobs


def _file_hash(path: str | None) -> str:
    """sha256 of a spec or scene file's bytes ("" without a file, "unreadable" when it cannot be read)."""
    if path is None:
        return ""
    try:
        return safeio.sha256_file(path, "spec")
    except OSError:
        return "unreadable"
