"""The bad-input suite: every case runs the real CLI and states what a user must see.

A case is refused correctly when:
- the CLI returns (no exception escapes ``wbmp.cli.main``: that would be a traceback),
- with the documented exit code (``wbmp.errors.ExitCode``),
- and one line on stderr that starts ``wbmp <command>: error:`` and names the problem,
- no file was created, replaced or left half-written (``Tree`` snapshots a folder),
- and no secret appears in stdout or stderr.

Cheap cases run the CLI in-process (:func:`run_cli`); cases about signals, the umask or a
crash of the process itself run it as a subprocess (:func:`run_cli_process`).
"""

from __future__ import annotations

import hashlib
import os
import stat
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


@contextmanager
def umask(mask: int) -> Iterator[None]:
    """The process umask set to ``mask`` inside the block, restored after."""
    old = os.umask(mask)
    try:
        yield
    finally:
        os.umask(old)


@dataclass(frozen=True)
class Outcome:
    """What a user saw: the exit code and both streams."""

    code: int
    out: str
    err: str

    def error_lines(self) -> list[str]:
        """The non-empty stderr lines that are not progress output."""
        return [ln for ln in self.err.splitlines() if ": error:" in ln or ln.startswith("wbmp:")]


def run_cli(argv: list[str], capsys: pytest.CaptureFixture[str]) -> Outcome:
    """Run ``wbmp ARGV`` in this process; an exception escaping main() fails the test."""
    from wbmp.cli import main

    capsys.readouterr()
    try:
        code = main([str(a) for a in argv])
    except SystemExit as e:  # argparse usage errors
        code = e.code if isinstance(e.code, int) else 2
    except BaseException as e:  # noqa: BLE001 - this is exactly what the suite looks for
        captured = capsys.readouterr()
        pytest.fail(f"wbmp {' '.join(map(str, argv))!r} raised {type(e).__name__}: {e}\n"
                    f"stderr: {captured.err}")
    captured = capsys.readouterr()
    return Outcome(int(code), captured.out, captured.err)


def run_cli_process(argv: list[str], *, cwd: Path | None = None, env: dict[str, str] | None = None,
                    timeout: float = 300.0, input_text: str | None = None) -> Outcome:
    """Run ``wbmp ARGV`` as a child process (the console script's own wrapper included)."""
    full_env = dict(os.environ)
    full_env.update(env or {})
    proc = subprocess.run(
        [sys.executable, "-c", "from wbmp.cli import run; run()", *map(str, argv)],
        cwd=cwd, env=full_env, capture_output=True, text=True, timeout=timeout, input=input_text,
    )
    return Outcome(proc.returncode, proc.stdout, proc.stderr)


def assert_refused(outcome: Outcome, code: int, *words: str, secrets: tuple[str, ...] = ()) -> None:
    """Exit ``code``, no traceback, one error line that contains every one of ``words``."""
    assert "Traceback" not in outcome.err, outcome.err
    assert outcome.code == code, f"exit {outcome.code}, expected {code}; stderr: {outcome.err!r}"
    errors = [ln for ln in outcome.err.splitlines() if ": error:" in ln]
    assert len(errors) == 1, f"expected one error line, got {outcome.err!r}"
    line = errors[0]
    for w in words:
        assert w.lower() in line.lower(), f"{w!r} not in the error line {line!r}"
    for s in secrets:
        assert s not in outcome.out and s not in outcome.err, "a secret was printed"


class Tree:
    """A snapshot of every entry below a folder: path -> (kind, mode, size, content hash)."""

    def __init__(self, root: Path) -> None:
        self.root = Path(root)
        self.before = self.snapshot()

    def snapshot(self) -> dict[str, tuple]:
        out: dict[str, tuple] = {}
        for dirpath, dirnames, filenames in os.walk(self.root):
            for name in dirnames + filenames:
                p = Path(dirpath) / name
                st = p.lstat()
                digest = ""
                if stat.S_ISREG(st.st_mode):
                    digest = hashlib.sha256(p.read_bytes()).hexdigest()
                elif stat.S_ISLNK(st.st_mode):
                    digest = os.readlink(p)
                out[str(p.relative_to(self.root))] = (stat.S_IFMT(st.st_mode), stat.S_IMODE(st.st_mode),
                                                     st.st_size, digest)
        return out

    def assert_unchanged(self) -> None:
        """Nothing created, removed or changed below the root since the snapshot."""
        after = self.snapshot()
        added = sorted(set(after) - set(self.before))
        removed = sorted(set(self.before) - set(after))
        changed = sorted(k for k in set(after) & set(self.before) if after[k] != self.before[k])
        assert not (added or removed or changed), f"added {added}, removed {removed}, changed {changed}"


@pytest.fixture
def tree(tmp_path: Path) -> Tree:
    """A snapshot of the test's tmp_path, taken when the test starts using it."""
    return Tree(tmp_path)


@pytest.fixture(scope="session")
def motion_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """M: a valid motion file (the example squat spec, planned without simulation), made once.

    Tests must copy it before damaging it: ``shutil.copy(motion_file, tmp_path / "m.npz")``.
    """
    from wbmp.cli import main

    out = tmp_path_factory.mktemp("motion") / "squat.npz"
    code = main(["solve", "--spec", str(REPO / "examples" / "specs" / "squat.json"), "--no-sim",
                 "--quiet", "--out", str(out)])
    assert code == 0 and out.is_file()
    return out
