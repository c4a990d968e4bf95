"""A motion library: a folder of BVH clips with a ``clips.csv`` of labels, that ``wbmp solve
--motions DIR`` (or ``$WBMP_MOTIONS``) falls back on when a sentence names no known action.

``clips.csv`` has a header row with at least ``file`` and ``label`` (``family``, and ``start`` and
``end`` in seconds for a window of the clip, optional; examples/motions/clips.csv is one). A sentence picks the clip whose label and family words hold every
content word of the sentence (articles, "do", "please" ... aside); none: the sentence is refused as
before.
"""

from __future__ import annotations

import csv
import re
from dataclasses import dataclass
from pathlib import Path

from wbmp.errors import CliError, ExitCode

STOPWORDS = frozenset("a an the do does please can you now some me us your my of to like let's lets perform "
                      "show".split())
MAX_CSV_BYTES = 1024 * 1024


@dataclass(frozen=True)
class LibraryClip:
    """One clip of a motion library."""

    path: Path
    label: str
    family: str = ""
    start: float | None = None  # [s] the window of the clip (None: its start, its end)
    end: float | None = None

    def words(self) -> set[str]:
        """The words of its label and family."""
        return set(_words(f"{self.label} {self.family.replace('_', ' ')}"))


def _words(text: str) -> list[str]:
    return re.findall(r"[a-z0-9']+", text.lower())


def load_library(folder: str | Path) -> list[LibraryClip]:
    """The clips of a library folder (CliError, exit 2, when it is not one)."""
    root = Path(folder)
    table = root / "clips.csv"
    try:
        if not root.is_dir():
            raise CliError(f"--motions {folder}: no such folder (give a folder of BVH clips with a clips.csv)",
                           ExitCode.USAGE)
        if table.stat().st_size > MAX_CSV_BYTES:
            raise CliError(f"--motions {folder}: clips.csv is larger than 1 MB", ExitCode.USAGE)
        rows = list(csv.DictReader(table.read_text(encoding="utf-8").splitlines()))
    except FileNotFoundError:
        raise CliError(f"--motions {folder}: no clips.csv in it (columns file, label[, family])",
                       ExitCode.USAGE) from None
    except (OSError, UnicodeDecodeError, csv.Error) as e:
        raise CliError(f"--motions {folder}: clips.csv cannot be read ({e})", ExitCode.USAGE) from None
    clips = []
    for row in rows:
        name, label = (row.get("file") or "").strip(), (row.get("label") or "").strip()
        if not name or not label or "/" in name or "\\" in name:
            continue
        window = [_seconds(row.get(key), folder, name, key) for key in ("start", "end")]
        clips.append(LibraryClip(path=root / name, label=label, family=(row.get("family") or "").strip(),
                                 start=window[0], end=window[1]))
    return clips


def _seconds(text: str | None, folder: str | Path, name: str, key: str) -> float | None:
    if text is None or not text.strip():
        return None
    try:
        value = float(text)
    except ValueError:
        value = -1.0
    if not value >= 0.0 or value == float("inf"):
        raise CliError(f"--motions {folder}: clips.csv row {name}: {key} must be seconds >= 0, got {text[:40]!r}",
                       ExitCode.USAGE)
    return value


def match(sentence: str, clips: list[LibraryClip]) -> LibraryClip | None:
    """The clip whose label and family hold every content word of ``sentence`` (the fewest extra words
    wins a tie); None when no clip does."""
    wanted = {w for w in _words(sentence) if w not in STOPWORDS}
    if not wanted:
        return None
    fits = [c for c in clips if wanted <= c.words()]
    if not fits:
        return None
    return min(fits, key=lambda c: (len(c.words() - wanted), str(c.path)))


def retarget_from_library(sentence: str, folder: str | Path, *, robot: str | None, simulate: bool, progress,
                          cache: bool = False):
    """The clip of the library that ``sentence`` names, retargeted (:func:`wbmp.retarget.retarget`,
    through the motion cache with ``cache``); None when no clip matches."""
    from wbmp.retarget import RetargetRequest, retarget

    clip = match(sentence, load_library(folder))
    if clip is None:
        return None
    progress(f"{sentence!r}: the clip {clip.path.name} ({clip.label}) of the motion library {folder}")
    return retarget(RetargetRequest(clip=str(clip.path), robot=robot or "talos", simulate=simulate,
                                    start=clip.start, end=clip.end), progress, cache=cache)


def clip_words(sentence: str, clip: LibraryClip) -> tuple:
    """What each word of ``sentence`` did when it picked ``clip`` (``language.plan.WordUse``, as
    ``wbmp parse`` shows for an action): runs of content words name the clip (role ``action``,
    action 1), the others are fillers."""
    from language import WordUse

    uses: list[WordUse] = []
    run: list[str] = []

    def flush() -> None:
        if run:
            uses.append(WordUse(text=" ".join(run), role="action", action=1,
                                detail=f"motion-library clip {clip.path.name} ({clip.label})"))
            run.clear()

    for word in _words(sentence):
        if word in STOPWORDS:
            flush()
            uses.append(WordUse(text=word, role="filler"))
        else:
            run.append(word)
    flush()
    return tuple(uses)


def clip_dict(clip: LibraryClip) -> dict:
    """The clip as ``wbmp parse --json`` prints it: ``file`` (name in the library folder),
    ``label``, ``family``, ``start`` and ``end`` [s] (null: the clip's own)."""
    return {"file": clip.path.name, "label": clip.label, "family": clip.family, "start": clip.start,
            "end": clip.end}


def describe_clip(clip: LibraryClip, folder: str | Path) -> str:
    """One line: the clip a sentence picked and what ``wbmp solve --motions`` does with it."""
    if clip.start is None and clip.end is None:
        window = "the whole clip"
    else:
        window = (f"{0.0 if clip.start is None else clip.start:g} s to "
                  f"{'its end' if clip.end is None else f'{clip.end:g} s'}")
    family = f", family {clip.family}" if clip.family else ""
    return (f"1. clip {clip.path.name} of the motion library {folder} ({clip.label}{family}; {window}): "
            "retargeted by wbmp solve --motions")
