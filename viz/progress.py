"""A small progress display for long steps: a spinner/bar on a terminal, JSON lines, or nothing.

Usage::

    progress = Progress(mode="bar")          # or "quiet", or "json"
    with progress.stage("planning"):
        for i in range(n):
            progress.update((i + 1) / n, f"iteration {i + 1}")
    progress("writing motion.html")          # a one-off message (callable, like a print)

Modes:

- ``bar``: on a terminal, one self-erasing line redrawn 10 times a second (spinner, stage,
  elapsed time, a bar when a fraction is known, the last message), replaced at the end of the
  stage by ``done <stage> (1.23 s)``. On a non-terminal stream (a log file, CI) the live line is
  skipped and only the final line of each stage (and one-off messages) are written. Stages
  shorter than ``min_duration`` (1 s) show nothing at all: the display is for long steps.
- ``json``: one JSON object per line: ``{"event": "start"|"progress"|"end"|"message", "stage",
  "elapsed", "fraction", "message", "ok"}``, for machines.
- ``quiet``: nothing at all.

Output goes to ``stream`` (default ``sys.stderr``), so it never mixes with a command's results
on stdout. The display is thread-safe: the solver's callback may report from another thread.
"""

from __future__ import annotations

import contextlib
import json
import sys
import threading
import time
from collections.abc import Iterator
from typing import Any, TextIO

MODES = ("bar", "quiet", "json")
SPINNER = "|/-\\"
BAR_WIDTH = 20
REFRESH = 0.1  # [s]


class Progress:
    """Progress display; see the module docstring.

    Args:
        mode: ``"bar"``, ``"quiet"`` or ``"json"``.
        stream: Where to write; default ``sys.stderr``.
        live: Redraw a live line; default: only when ``stream`` is a terminal.
        clock: Time source [s] (tests pass a fake one).
        min_duration: In ``bar`` mode, stages shorter than this show nothing [s].

    Raises:
        ValueError: unknown mode.
    """

    def __init__(self, mode: str = "bar", *, stream: TextIO | None = None, live: bool | None = None,
                 clock=time.monotonic, min_duration: float = 1.0) -> None:
        if mode not in MODES:
            raise ValueError(f"progress mode must be one of {MODES}, got {mode!r}")
        self.mode = mode
        self.stream = sys.stderr if stream is None else stream
        isatty = getattr(self.stream, "isatty", lambda: False)
        self.live = (mode == "bar" and bool(isatty())) if live is None else (live and mode == "bar")
        self._clock = clock
        self.min_duration = float(min_duration)
        self._lock = threading.RLock()
        self._stages: list[dict] = []
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._tick = 0
        self._width = 0

    # ---- public API -------------------------------------------------------------------------

    @contextlib.contextmanager
    def stage(self, name: str) -> Iterator[Progress]:
        """Context manager around a long step; reports its start, progress and duration."""
        with self._lock:
            self._stages.append({"name": name, "start": self._clock(), "fraction": None, "message": ""})
            self._emit_json("start", name)
            self._start_thread()
        ok = False
        try:
            yield self
            ok = True
        finally:
            with self._lock:
                st = self._stages.pop()
                elapsed = self._clock() - st["start"]
                if not self._stages:
                    self._stop_thread()
                self._clear_line()
                if self.mode == "bar" and elapsed >= self.min_duration:
                    mark = "done" if ok else "FAILED"
                    self._write(f"{mark} {name} ({elapsed:.2f} s)\n")
                self._emit_json("end", name, elapsed=elapsed, ok=ok)
                self._draw()

    def update(self, fraction: float | None = None, message: str = "") -> None:
        """Report progress of the current stage: a fraction in [0, 1] (or None) and a message."""
        with self._lock:
            if not self._stages:
                if message:
                    self(message)
                return
            st = self._stages[-1]
            if fraction is not None:
                st["fraction"] = min(max(float(fraction), 0.0), 1.0)
            if message:
                st["message"] = message
            self._emit_json("progress", st["name"], elapsed=self._clock() - st["start"],
                            fraction=st["fraction"], message=message)
            self._draw()

    def __call__(self, message: str | float) -> None:
        """A one-off message; a number is taken as the current stage's fraction done.

        So the display is usable both as a ``Callable[[str], None]`` (planner, pipeline) and as
        a ``Callable[[float], None]`` (the simulator's progress) callback.
        """
        if isinstance(message, (int, float)) and not isinstance(message, bool):
            self.update(float(message))
            return
        with self._lock:
            if self._stages:
                self._stages[-1]["message"] = message
                self._emit_json("progress", self._stages[-1]["name"],
                                elapsed=self._clock() - self._stages[-1]["start"], message=message)
                if not self.live and self.mode == "bar" and \
                        self._clock() - self._stages[0]["start"] >= self.min_duration:
                    self._write(f"  {message}\n")
                self._draw()
                return
            if self.mode == "bar":
                self._clear_line()
                self._write(f"{message}\n")
            self._emit_json("message", None, message=message)

    def close(self) -> None:
        """Stop the refresh thread and erase the live line."""
        with self._lock:
            self._stop_thread()
            self._clear_line()

    # ---- internals --------------------------------------------------------------------------

    def _write(self, text: str) -> None:
        try:
            self.stream.write(text)
            self.stream.flush()
        except (OSError, ValueError):  # closed pipe: progress is best effort
            pass

    def _emit_json(self, event: str, stage: str | None, **fields) -> None:
        if self.mode != "json":
            return
        record: dict[str, Any] = {"event": event, "stage": stage}
        for k, v in fields.items():
            if v is None or v == "":
                continue
            record[k] = round(v, 4) if isinstance(v, float) else v
        self._write(json.dumps(record, ensure_ascii=False) + "\n")

    def line(self) -> str:
        """The live line for the current stage ('' when idle)."""
        with self._lock:
            if not self._stages:
                return ""
            st = self._stages[-1]
            names = " > ".join(s["name"] for s in self._stages)
            elapsed = self._clock() - st["start"]
            parts = [SPINNER[self._tick % len(SPINNER)], names, f"{elapsed:5.1f} s"]
            if st["fraction"] is not None:
                filled = int(round(st["fraction"] * BAR_WIDTH))
                parts.append("[" + "#" * filled + "." * (BAR_WIDTH - filled) + f"] {100 * st['fraction']:3.0f}%")
            if st["message"]:
                parts.append(st["message"])
            return "  ".join(parts)

    def _draw(self) -> None:
        if not self.live or not self._stages:
            return
        if self._clock() - self._stages[0]["start"] < self.min_duration:
            return
        text = self.line()[:119]
        pad = max(0, self._width - len(text))
        self._write("\r" + text + " " * pad)
        self._width = len(text)

    def _clear_line(self) -> None:
        if self.live and self._width:
            self._write("\r" + " " * self._width + "\r")
            self._width = 0

    def _start_thread(self) -> None:
        if not self.live or self._thread is not None:
            return
        stop = threading.Event()  # one event per thread: a stopped thread never wakes up again
        self._stop = stop
        self._thread = threading.Thread(target=self._run, args=(stop,), name="wbmp-progress", daemon=True)
        self._thread.start()

    def _stop_thread(self) -> None:
        # no join: the thread exits at its next tick (<= REFRESH) and draws nothing after stop
        self._stop.set()
        self._thread = None

    def _run(self, stop: threading.Event) -> None:
        while not stop.wait(REFRESH):
            with self._lock:
                if stop.is_set():
                    break
                self._tick += 1
                self._draw()


def make_progress(*, quiet: bool = False, json_lines: bool = False, stream: TextIO | None = None) -> Progress:
    """The display a CLI wants for ``--quiet`` / ``--json``: quiet wins, then JSON, else a bar."""
    mode = "quiet" if quiet else "json" if json_lines else "bar"
    return Progress(mode=mode, stream=stream)
