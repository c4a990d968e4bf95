"""A small strict reader of BVH (Biovision Hierarchy) motion-capture files, and their forward kinematics.

BVH: a ``HIERARCHY`` of joints (``ROOT``/``JOINT`` name, ``OFFSET x y z`` from the parent,
``CHANNELS n ...``, ``End Site`` leaves) followed by ``MOTION``, ``Frames: F``, ``Frame Time: dt``
and F lines of numbers, one per channel. A joint's placement in its parent is the offset plus its
position channels, rotated by its rotation channels composed in the order they are listed
(``Zrotation Yrotation Xrotation``: ``R = Rz(a) Ry(b) Rx(c)``, degrees), the usual reading of the
format (CMU's and Daz's conversions both write it so).

Strict: anything that is not such a file (empty, binary, truncated, a channel count that does not
match the numbers, a frame count that does not match the lines, NaN or infinite values, more than
:data:`MAX_FRAMES` frames) is refused with :class:`~tasks.exceptions.ClipError`, one line
naming the file and the problem. Why not an installed parser: the maintained ones (``pybvh``,
``bvhio``) are full toolkits (writers, editing, their own transform classes) for the few hundred
lines needed here, and none refuses a damaged file with a message a user can act on.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tasks.exceptions import ClipError

MAX_FILE_BYTES = 256 * 1024 * 1024  # a 10-minute 120 Hz clip of 43 joints is ~60 MB of text
MAX_FRAMES = 120 * 600  # 10 minutes at 120 frames/s; a window of at most 60 s is planned
MAX_JOINTS = 512
MIN_FRAME_TIME, MAX_FRAME_TIME = 1e-4, 1.0  # [s]
_ROTATIONS = {"Xrotation": 0, "Yrotation": 1, "Zrotation": 2}
_POSITIONS = {"Xposition": 0, "Yposition": 1, "Zposition": 2}


@dataclass(frozen=True, slots=True)
class BvhJoint:
    """One joint (or end site) of a BVH hierarchy.

    Attributes:
        name: Its name (an end site is ``<parent>_end``).
        parent: Index of the parent joint, -1 for the root.
        offset: Offset from the parent, in the file's length unit.
        channels: Channel names, in the file's order (empty for an end site).
        first_channel: Column of its first channel in the motion table.
    """

    name: str
    parent: int
    offset: tuple[float, float, float]
    channels: tuple[str, ...]
    first_channel: int

    @property
    def end_site(self) -> bool:
        """True for an ``End Site`` leaf (no channels)."""
        return not self.channels


@dataclass(frozen=True, eq=False)
class BvhClip:
    """A BVH file's skeleton and motion.

    Attributes:
        joints: The joints, parents before children (end sites included).
        frame_time: Time between frames [s].
        motion: (F, C) channel values of every frame (positions in the file's unit, angles in degrees).
        source: The file it was read from (for messages).
    """

    joints: tuple[BvhJoint, ...]
    frame_time: float
    motion: np.ndarray
    source: str = ""

    @property
    def n_frames(self) -> int:
        """Number of frames."""
        return int(self.motion.shape[0])

    @property
    def duration(self) -> float:
        """Time from the first to the last frame [s]."""
        return (self.n_frames - 1) * self.frame_time

    @property
    def names(self) -> tuple[str, ...]:
        """Joint names, in order."""
        return tuple(j.name for j in self.joints)

    def index(self, name: str) -> int:
        """Index of a joint by name (ClipError naming the joints otherwise)."""
        for i, j in enumerate(self.joints):
            if j.name == name:
                return i
        raise ClipError(f"{self.source or 'clip'}: no joint {name!r}; its joints: {', '.join(self.names[:60])}")

    def window(self, start: float | None, end: float | None) -> BvhClip:
        """The frames from ``start`` to ``end`` [s] (None: the clip's start or end)."""
        where = self.source or "clip"
        s = 0.0 if start is None else start
        e = self.duration if end is None else end
        for label, v in (("--start", start), ("--end", end)):
            if v is not None and not (math.isfinite(v) and v >= 0.0):
                raise ClipError(f"{where}: {label} must be a time >= 0 s, got {v!r}")
        if s >= self.duration:
            raise ClipError(f"{where}: --start {s:g} s is at or after the end of the clip ({self.duration:.3f} s)")
        if e <= s:
            raise ClipError(f"{where}: --end {e:g} s must be after --start {s:g} s")
        i0 = int(round(s / self.frame_time))
        i1 = min(self.n_frames - 1, int(round(e / self.frame_time)))
        if i1 - i0 < 2:
            raise ClipError(f"{where}: the window {s:g}-{e:g} s holds fewer than 3 frames")
        return BvhClip(joints=self.joints, frame_time=self.frame_time, motion=self.motion[i0:i1 + 1],
                       source=self.source)

    def global_transforms(self) -> tuple[np.ndarray, np.ndarray]:
        """World rotations (F, J, 3, 3) and positions (F, J, 3) of every joint, in the file's frame and unit."""
        F, J = self.n_frames, len(self.joints)
        R = np.empty((F, J, 3, 3))
        p = np.empty((F, J, 3))
        for i, j in enumerate(self.joints):
            Rl, pl = local_transform(j, self.motion)
            if j.parent < 0:
                R[:, i], p[:, i] = Rl, pl
            else:
                Rp = R[:, j.parent]
                R[:, i] = Rp @ Rl
                p[:, i] = p[:, j.parent] + np.einsum("fab,fb->fa", Rp, pl)
        return R, p

    def positions(self) -> np.ndarray:
        """World positions (F, J, 3) of every joint, in the file's frame and unit."""
        return self.global_transforms()[1]


def axis_rotations(axis: int, degrees: np.ndarray) -> np.ndarray:
    """Rotation matrices (F, 3, 3) about x (0), y (1) or z (2) by ``degrees`` (F,)."""
    a = np.radians(degrees)
    c, s = np.cos(a), np.sin(a)
    out = np.zeros((len(a), 3, 3))
    i, k = [(1, 2), (2, 0), (0, 1)][axis]
    out[:, axis, axis] = 1.0
    out[:, i, i] = c
    out[:, k, k] = c
    out[:, i, k] = -s
    out[:, k, i] = s
    return out


def local_transform(joint: BvhJoint, motion: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(rotations (F, 3, 3), translations (F, 3)) of a joint in its parent, every frame."""
    F = motion.shape[0]
    R = np.broadcast_to(np.eye(3), (F, 3, 3)).copy()
    p = np.broadcast_to(np.array(joint.offset, dtype=float), (F, 3)).copy()
    for c, name in enumerate(joint.channels):
        col = motion[:, joint.first_channel + c]
        if name in _POSITIONS:
            p[:, _POSITIONS[name]] += col
        else:
            R = R @ axis_rotations(_ROTATIONS[name], col)
    return R, p


class _Tokens:
    """The hierarchy's whitespace-separated words, with the line each came from."""

    def __init__(self, lines: list[str], where: str) -> None:
        self.words: list[tuple[str, int]] = [(w, n + 1) for n, line in enumerate(lines) for w in line.split()]
        self.i = 0
        self.where = where

    def next(self, what: str) -> str:
        if self.i >= len(self.words):
            raise ClipError(f"{self.where}: the file ends inside the hierarchy (expected {what}): truncated?")
        w = self.words[self.i][0]
        self.i += 1
        return w

    def expect(self, word: str) -> None:
        got = self.next(repr(word))
        if got != word:
            raise ClipError(f"{self.where}: line {self.words[self.i - 1][1]}: expected {word!r}, found {_short(got)}")

    def number(self, what: str) -> float:
        w = self.next(what)
        try:
            v = float(w)
        except ValueError:
            raise ClipError(f"{self.where}: line {self.words[self.i - 1][1]}: {what} must be a number, "
                            f"found {_short(w)}") from None
        if not math.isfinite(v):
            raise ClipError(f"{self.where}: line {self.words[self.i - 1][1]}: {what} is {w}; give finite numbers")
        return v


def _short(text: str) -> str:
    return repr(text if len(text) <= 40 else text[:40] + "...")


def read_bvh(path: str | os.PathLike[str]) -> BvhClip:
    """Read a BVH file (ClipError naming the file and the problem when it is not a usable one)."""
    where = str(path)
    p = Path(path)
    try:
        if not p.is_file():
            raise ClipError(f"{where}: no such clip file (give a .bvh file)")
        size = p.stat().st_size
        if size > MAX_FILE_BYTES:
            raise ClipError(f"{where}: {size / 1e6:.0f} MB; wbmp reads clips of at most {MAX_FILE_BYTES / 1e6:.0f} MB")
        raw = p.read_bytes()
    except OSError as e:
        raise ClipError(f"{where}: cannot be read ({e.strerror or e})") from None
    return parse_bvh(raw, where)


def parse_bvh(raw: bytes, where: str = "clip") -> BvhClip:
    """Parse the bytes of a BVH file (see :func:`read_bvh`)."""
    if not raw.strip():
        raise ClipError(f"{where}: the file is empty (give a BVH motion-capture file)")
    if b"\x00" in raw[:65536]:
        raise ClipError(f"{where}: a binary file, not a BVH text file")
    try:
        text = raw.decode("ascii")
    except UnicodeDecodeError:
        try:
            text = raw.decode("utf-8")
        except UnicodeDecodeError:
            raise ClipError(f"{where}: not a text file (a BVH file is plain text)") from None
    lines = text.splitlines()
    try:
        cut = next(n for n, line in enumerate(lines) if line.strip() == "MOTION")
    except StopIteration:
        if not text.lstrip().startswith("HIERARCHY"):
            raise ClipError(f"{where}: not a BVH file (it must start with HIERARCHY)") from None
        raise ClipError(f"{where}: no MOTION section: the file is truncated") from None
    joints = _hierarchy(_Tokens(lines[:cut], where))
    n_channels = sum(len(j.channels) for j in joints)
    frames, frame_time, body = _motion_header(lines, cut, where)
    rows = [line for line in body if line.strip()]
    if len(rows) != frames:
        raise ClipError(f"{where}: the header says {frames} frames but the file holds {len(rows)} lines of numbers"
                        + (" (truncated?)" if len(rows) < frames else ""))
    try:
        table = np.loadtxt(rows, dtype=float, ndmin=2) if rows else np.zeros((0, n_channels))
    except ValueError:
        bad = next((n for n, r in enumerate(rows) if len(r.split()) != n_channels), None)
        if bad is not None:
            raise ClipError(f"{where}: frame {bad} has {len(rows[bad].split())} values; the hierarchy has "
                            f"{n_channels} channels") from None
        raise ClipError(f"{where}: a frame holds something that is not a number") from None
    if table.shape[1] != n_channels:
        raise ClipError(f"{where}: frames have {table.shape[1]} values; the hierarchy has {n_channels} channels")
    if not np.isfinite(table).all():
        f, c = np.argwhere(~np.isfinite(table))[0]
        raise ClipError(f"{where}: frame {f} channel {c} is {table[f, c]}; a clip must hold finite numbers")
    if np.abs(table).max(initial=0.0) > 1e7:
        raise ClipError(f"{where}: values above 1e7 in the motion; not a motion-capture clip")
    return BvhClip(joints=tuple(joints), frame_time=frame_time, motion=table, source=where)


def _motion_header(lines: list[str], cut: int, where: str) -> tuple[int, float, list[str]]:
    rest = lines[cut + 1:]
    if len(rest) < 2:
        raise ClipError(f"{where}: the MOTION section lacks 'Frames:' and 'Frame Time:': truncated?")
    f_line, t_line = rest[0].split(), rest[1].split()
    if len(f_line) != 2 or f_line[0] != "Frames:":
        raise ClipError(f"{where}: expected 'Frames: N' after MOTION, found {_short(rest[0].strip())}")
    if len(t_line) != 3 or t_line[:2] != ["Frame", "Time:"]:
        raise ClipError(f"{where}: expected 'Frame Time: seconds', found {_short(rest[1].strip())}")
    try:
        frames = int(f_line[1])
        frame_time = float(t_line[2])
    except ValueError:
        raise ClipError(f"{where}: the frame count or frame time is not a number") from None
    if frames < 3:
        raise ClipError(f"{where}: {frames} frames; a clip needs at least 3")
    if frames > MAX_FRAMES:
        raise ClipError(f"{where}: {frames:,} frames; wbmp reads clips of at most {MAX_FRAMES:,} frames "
                        "(10 min at 120 frames/s): cut the clip")
    if not (math.isfinite(frame_time) and MIN_FRAME_TIME <= frame_time <= MAX_FRAME_TIME):
        raise ClipError(f"{where}: frame time {t_line[2]} s; it must be in [{MIN_FRAME_TIME:g}, {MAX_FRAME_TIME:g}] s")
    return frames, frame_time, rest[2:]


def _hierarchy(tok: _Tokens) -> list[BvhJoint]:
    tok.expect("HIERARCHY")
    tok.expect("ROOT")
    joints: list[BvhJoint] = []
    _joint(tok, joints, -1, root=True)
    if tok.i != len(tok.words):
        raise ClipError(f"{tok.where}: line {tok.words[tok.i][1]}: unexpected {_short(tok.words[tok.i][0])} "
                        "after the root joint")
    return joints


def _joint(tok: _Tokens, joints: list[BvhJoint], parent: int, *, root: bool = False) -> None:
    name = tok.next("a joint name")
    if len(joints) >= MAX_JOINTS:
        raise ClipError(f"{tok.where}: more than {MAX_JOINTS} joints; not a body skeleton")
    tok.expect("{")
    tok.expect("OFFSET")
    offset = (tok.number("OFFSET x"), tok.number("OFFSET y"), tok.number("OFFSET z"))
    tok.expect("CHANNELS")
    count_word = tok.next("the channel count")
    if count_word not in ("3", "6"):
        raise ClipError(f"{tok.where}: joint {name!r} has {_short(count_word)} channels; wbmp reads 3 (rotations) "
                        "or 6 (positions and rotations)")
    channels = tuple(tok.next("a channel name") for _ in range(int(count_word)))
    for c in channels:
        if c not in _ROTATIONS and c not in _POSITIONS:
            raise ClipError(f"{tok.where}: joint {name!r}: unknown channel {_short(c)} (Xposition ... Zrotation)")
    if sorted(c for c in channels if c in _ROTATIONS) != ["Xrotation", "Yrotation", "Zrotation"]:
        raise ClipError(f"{tok.where}: joint {name!r} must rotate about X, Y and Z once each, has {channels}")
    if root and len(channels) != 6:
        raise ClipError(f"{tok.where}: the root joint {name!r} needs 6 channels (position and rotation)")
    first = sum(len(j.channels) for j in joints)
    index = len(joints)
    joints.append(BvhJoint(name=name, parent=parent, offset=offset, channels=channels, first_channel=first))
    while True:
        word = tok.next("JOINT, End Site or '}'")
        if word == "}":
            return
        if word == "JOINT":
            _joint(tok, joints, index)
        elif word == "End":
            tok.expect("Site")
            tok.expect("{")
            tok.expect("OFFSET")
            end = (tok.number("OFFSET x"), tok.number("OFFSET y"), tok.number("OFFSET z"))
            tok.expect("}")
            joints.append(BvhJoint(name=f"{name}_end", parent=index, offset=end, channels=(), first_channel=first))
        else:
            raise ClipError(f"{tok.where}: line {tok.words[tok.i - 1][1]}: expected JOINT, End Site or '}}', "
                            f"found {_short(word)}")
