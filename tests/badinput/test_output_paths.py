"""Bad output paths: refused before any work, exit 2, one line naming the option, path and why.

Every output option is tried with every kind of bad path (``solve --out/--html/--plots``,
``show --html/--plots``, ``export --out``): the command refuses before it plans or loads
anything, and the folder is left exactly as it was (no file created, replaced or left behind,
no link replaced or written through, no device turned into a file).
"""

from __future__ import annotations

import os
import shutil
import socket
import stat
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from tests.badinput.conftest import REPO, Tree, assert_refused, run_cli
from viz import OutputWriteError
from viz.files import Staging, atomic_write

SQ = REPO / "examples" / "specs" / "squat.json"
IS_ROOT = os.geteuid() == 0


def _existing_file(tmp: Path, name: str) -> str:
    (tmp / "target").mkdir()
    return str(tmp / "target" / name)


def _make_dir(tmp: Path, name: str) -> str:
    (tmp / name).mkdir()
    return str(tmp / name)


def _symlink_to_file(tmp: Path, name: str) -> str:
    (tmp / "real.txt").write_text("keep me\n")
    (tmp / name).symlink_to(tmp / "real.txt")
    return str(tmp / name)


def _symlink_dangling(tmp: Path, name: str) -> str:
    (tmp / name).symlink_to(tmp / "nowhere" / "x")
    return str(tmp / name)


def _symlink_to_dev_null(tmp: Path, name: str) -> str:
    (tmp / name).symlink_to("/dev/null")
    return str(tmp / name)


def _fifo(tmp: Path, name: str) -> str:
    os.mkfifo(tmp / name)
    return str(tmp / name)


def _socket(tmp: Path, name: str) -> str:
    path = tmp / name
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    sock.bind(str(path))
    sock.close()  # the socket file stays
    return str(path)


def _char_device(tmp: Path, name: str) -> str:
    try:
        os.mknod(tmp / name, 0o666 | stat.S_IFCHR, os.makedev(1, 7))  # what /dev/full is
    except PermissionError:
        pytest.skip("mknod needs root (or CAP_MKNOD)")
    return str(tmp / name)


def _parent_is_file(tmp: Path, name: str) -> str:
    (tmp / "afile").write_text("x")
    return str(tmp / "afile" / name)


def _readonly_file(tmp: Path, name: str) -> str:
    if IS_ROOT:
        pytest.skip("root may write any file")
    (tmp / name).write_text("read only\n")
    (tmp / name).chmod(0o444)
    return str(tmp / name)


# kind -> (make the bad path in tmp for a file named NAME, words of the error line)
FILE_CASES: dict[str, tuple[Callable[[Path, str], str], tuple[str, ...]]] = {
    "empty": (lambda tmp, name: "", ("empty path",)),
    "blank": (lambda tmp, name: "   ", ("empty path",)),
    "directory": (_make_dir, ("is a directory",)),
    "dot": (lambda tmp, name: str(tmp) + "/.", ("directory",)),
    "dotdot": (lambda tmp, name: str(tmp / "sub" / ".."), ("directory",)),
    "trailing_slash": (lambda tmp, name: str(tmp / name) + "/", ("ends in '/'",)),
    "dev_null": (lambda tmp, name: "/dev/null", ("/dev/null", "not a regular file")),
    "char_device": (_char_device, ("not a regular file",)),
    "fifo": (_fifo, ("not a regular file",)),
    "socket": (_socket, ("not a regular file",)),
    "symlink_to_file": (_symlink_to_file, ("symbolic link",)),
    "symlink_dangling": (_symlink_dangling, ("symbolic link",)),
    "symlink_to_dev_null": (_symlink_to_dev_null, ("symbolic link",)),
    "missing_parent": (lambda tmp, name: str(tmp / "no" / "such" / name), ("does not exist",)),
    "parent_is_file": (_parent_is_file, ("not a folder",)),
    "unwritable_folder": (lambda tmp, name: f"/proc/{name}", ("cannot write in folder",)),
    "nul_character": (lambda tmp, name: str(tmp / "a\0b") + name, ("NUL",)),
    "name_too_long": (lambda tmp, name: str(tmp / ("x" * 300 + name)), ("too long",)),
    "readonly_file": (_readonly_file, ("read-only",)),
}

# (command line before the bad path, option, file name with the right suffix)
FILE_OPTIONS = {
    "solve --out": (["solve", "--spec", str(SQ), "--no-sim", "--quiet"], "--out", "m.npz"),
    "solve --html": (["solve", "--spec", str(SQ), "--no-sim", "--quiet"], "--html", "m.html"),
    "show --html": (["show", "{motion}", "--quiet"], "--html", "m.html"),
    "export --out": (["export", "{motion}", "--format", "json"], "--out", "m.json"),
}


def _argv(prefix: list[str], motion: Path) -> list[str]:
    return [a.replace("{motion}", str(motion)) for a in prefix]


@pytest.fixture
def motion(tmp_path_factory, motion_file) -> Path:
    """A copy of M outside the folder under test."""
    path = tmp_path_factory.mktemp("input") / "m.npz"
    shutil.copy(motion_file, path)
    return path


@pytest.mark.parametrize("kind", sorted(FILE_CASES))
@pytest.mark.parametrize("command", sorted(FILE_OPTIONS))
def test_bad_output_file_is_refused_before_any_work(command, kind, tmp_path, motion, capsys):
    """Each bad file path of each output option: exit 2, one line naming the option and why, and
    nothing in the folder created, replaced or written through."""
    prefix, option, name = FILE_OPTIONS[command]
    make, words = FILE_CASES[kind]
    (tmp_path / "sub").mkdir()
    bad = make(tmp_path, name)
    before = Tree(tmp_path)
    outcome = run_cli([*_argv(prefix, motion), option, bad], capsys)
    assert_refused(outcome, 2, option, *words)
    before.assert_unchanged()
    if kind == "symlink_to_file":
        assert (tmp_path / "real.txt").read_text() == "keep me\n"  # not written through


def _plots_file(tmp: Path) -> str:
    (tmp / "plots").write_text("not a folder\n")
    return str(tmp / "plots")


def _plots_inner(kind: str) -> Callable[[Path], str]:
    def make(tmp: Path) -> str:
        folder = tmp / "plots"
        folder.mkdir()
        inner = folder / "joints.png"
        if kind == "dir":
            inner.mkdir()
        elif kind == "link":
            (tmp / "real.png").write_bytes(b"keep")
            inner.symlink_to(tmp / "real.png")
        else:
            os.mkfifo(inner)
        return str(folder)
    return make


def _plots_dangling(tmp: Path) -> str:
    (tmp / "plots").symlink_to(tmp / "gone")
    return str(tmp / "plots")


PLOTS_CASES: dict[str, tuple[Callable[[Path], str], tuple[str, ...]]] = {
    "empty": (lambda tmp: "", ("empty path",)),
    "regular_file": (_plots_file, ("not a folder",)),
    "dev_null": (lambda tmp: "/dev/null", ("not a folder",)),
    "missing_parent": (lambda tmp: str(tmp / "no" / "plots"), ("does not exist",)),
    "parent_is_file": (lambda tmp: _parent_is_file(tmp, "plots"), ("not a folder",)),
    "unwritable": (lambda tmp: "/proc/wbmp-plots", ("cannot write in folder",)),
    "dangling_link": (_plots_dangling, ("dangling",)),
    "inner_png_is_dir": (_plots_inner("dir"), ("joints.png", "is a directory")),
    "inner_png_is_link": (_plots_inner("link"), ("joints.png", "symbolic link")),
    "inner_png_is_fifo": (_plots_inner("fifo"), ("joints.png", "not a regular file")),
}


@pytest.mark.parametrize("kind", sorted(PLOTS_CASES))
@pytest.mark.parametrize("command", ["solve", "show"])
def test_bad_plots_folder_is_refused_before_any_work(command, kind, tmp_path, motion, capsys):
    """--plots DIR that is not a usable folder (or holds a link/folder/FIFO where a PNG goes): exit 2."""
    make, words = PLOTS_CASES[kind]
    bad = make(tmp_path)
    before = Tree(tmp_path)
    prefix = (["solve", "--spec", str(SQ), "--no-sim", "--quiet"] if command == "solve"
              else ["show", str(motion), "--quiet"])
    outcome = run_cli([*prefix, "--plots", bad], capsys)
    assert_refused(outcome, 2, "--plots", *words)
    before.assert_unchanged()


def test_later_bad_output_refused_before_the_first_is_written(tmp_path, capsys):
    """A good --out beside a bad --html: neither is written (the solve never starts)."""
    (tmp_path / "h").mkdir()
    before = Tree(tmp_path)
    outcome = run_cli(["solve", "--spec", SQ, "--no-sim", "--quiet", "--out", tmp_path / "m.npz",
                       "--html", tmp_path / "h", "--plots", tmp_path / "p"], capsys)
    assert_refused(outcome, 2, "--html", "is a directory")
    before.assert_unchanged()


@pytest.mark.parametrize(("args", "words"), [
    (["--out", "{t}/m.json"], ("--out", "ends in .npz")),
    (["--out", "{t}/m"], ("--out", "ends in .npz")),
    (["--out", "{t}/m.html"], ("--out", "ends in .npz")),
    (["--out", "{t}/same.npz", "--html", "{t}/same.npz"], ("--html", "same file as --out")),
    (["--plots", "{spec}"], ("--plots", "not a folder")),
    (["--html", "{t}/p/joints.png", "--plots", "{t}/p"], ("--plots", "same file as --html")),
    (["--out", "{spec}"], ("--out", "ends in .npz")),
    (["--html", "{spec}"], ("--html", "same file as --spec")),
])
def test_solve_output_contradictions(args, words, tmp_path, capsys):
    """A motion file not named .npz, two outputs on one file, an output on the input spec: exit 2."""
    spec = tmp_path / "squat.json"
    shutil.copy(SQ, spec)
    (tmp_path / "p").mkdir()
    before = Tree(tmp_path)
    argv = [a.replace("{t}", str(tmp_path)).replace("{spec}", str(spec)) for a in args]
    outcome = run_cli(["solve", "--spec", spec, "--no-sim", "--quiet", *argv], capsys)
    assert_refused(outcome, 2, *words)
    before.assert_unchanged()


@pytest.mark.parametrize(("args", "words"), [
    (["--out", "{t}/x.npz"], ("--out", "not .npz")),
    (["--out", "{t}/x.NPZ", "--format", "json"], ("--out", "not .npz")),
    (["--out", "{t}/x"], ("--out", "no suffix", "--format")),
    (["--out", "{t}/x.txt"], ("--out", ".txt", "--format")),
    (["--out", "{t}/x.json", "--format", "csv"], ("--out", "ends in .json but --format is csv")),
    (["--out", "{t}/x.csv", "--format", "json"], ("--out", "ends in .csv but --format is json")),
    (["--out", ""], ("--out", "empty path")),
])
def test_export_suffix_and_format_contradictions(args, words, tmp_path, motion, capsys):
    """export never writes JSON into a .npz, guesses no format, never overwrites its input: exit 2."""
    before = Tree(tmp_path)
    before_motion = motion.read_bytes()
    argv = [a.replace("{t}", str(tmp_path)).replace("{motion}", str(motion)) for a in args]
    outcome = run_cli(["export", motion, *argv], capsys)
    assert_refused(outcome, 2, *words)
    before.assert_unchanged()
    assert motion.read_bytes() == before_motion


def test_export_never_overwrites_its_input(tmp_path, motion, capsys):
    """A motion file named .json exported to itself (directly or through ./): exit 2, unchanged."""
    source = tmp_path / "m.json"
    shutil.copy(motion, source)
    before = Tree(tmp_path)
    for out in (source, tmp_path / "." / "m.json"):
        outcome = run_cli(["export", source, "--out", out], capsys)
        assert_refused(outcome, 2, "--out", "same file as the motion file")
    outcome = run_cli(["export", source, "--format", "json"], capsys)  # default name: m.json itself
    assert_refused(outcome, 2, "same file as the motion file")
    before.assert_unchanged()


def _with_execution(motion_file: Path, folder: Path, samples: int) -> Path:
    """M plus a synthetic simulated execution (exec_*) of ``samples`` samples."""
    with np.load(motion_file) as data:
        arrays = {k: data[k] for k in data.files}
    q, v = arrays["q"], arrays["v"]
    rows = np.arange(samples) % len(q)
    arrays.update(exec_t=np.arange(samples) * 1e-3, exec_q=q[rows], exec_v=v[rows],
                  exec_tau=np.zeros((samples, v.shape[1] - 6)))
    path = folder / "sim.npz"
    np.savez_compressed(path, **arrays)
    return path


def test_csv_export_refuses_a_bad_exec_csv_before_writing_the_csv(tmp_path_factory, tmp_path, motion_file, capsys):
    """The execution's .exec.csv is checked too: if it is a folder, neither CSV is written."""
    sim = _with_execution(motion_file, tmp_path_factory.mktemp("sim"), 50)
    (tmp_path / "x.exec.csv").mkdir()
    before = Tree(tmp_path)
    outcome = run_cli(["export", sim, "--out", tmp_path / "x.csv"], capsys)
    assert_refused(outcome, 2, "x.exec.csv", "is a directory")
    before.assert_unchanged()


def test_failing_csv_export_leaves_neither_csv(tmp_path_factory, tmp_path, motion_file):
    """When writing the .exec.csv fails (here: the file-size limit), the plan CSV is not left
    behind either: exit 2, one line, folder unchanged."""
    import resource
    import signal
    import subprocess
    import sys

    sim = _with_execution(motion_file, tmp_path_factory.mktemp("sim"), 3000)
    limit = 1 << 20  # the plan CSV (~70 kB) fits, the execution CSV (~7 MB) does not

    def small_files() -> None:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    before = Tree(tmp_path)
    proc = subprocess.run([sys.executable, "-c", "from wbmp.cli import run; run()", "export", str(sim),
                           "--out", str(tmp_path / "x.csv")],
                          capture_output=True, text=True, preexec_fn=small_files, timeout=300)
    from tests.badinput.conftest import Outcome

    assert_refused(Outcome(proc.returncode, proc.stdout, proc.stderr), 2, "x.exec.csv", "cannot write")
    before.assert_unchanged()


def test_staging_removes_everything_on_ctrl_c_and_on_errors(tmp_path):
    """Ctrl-C or an error while one output is made removes the temporary files of all of them."""
    (tmp_path / "old.txt").write_text("old\n")
    before = Tree(tmp_path)

    def interrupted(fh) -> None:
        fh.write(b"half")
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt), Staging() as staging:
        staging.add(tmp_path / "a.txt", lambda fh: fh.write(b"a"))
        staging.add(tmp_path / "old.txt", interrupted)
    before.assert_unchanged()

    def failing(fh) -> None:
        fh.write(b"half")
        raise OSError(28, "No space left on device")

    with pytest.raises(OutputWriteError, match="No space left"), Staging() as staging:
        staging.add(tmp_path / "sub" / "a.txt", lambda fh: fh.write(b"a"))
        staging.add(tmp_path / "old.txt", failing)
    before.assert_unchanged()


def test_commit_undoes_created_files_when_a_target_changes_meanwhile(tmp_path):
    """If a target turns into a folder between the check and the rename, the files this commit
    created are removed again and no temporary file remains."""
    before = Tree(tmp_path)
    with Staging() as staging:
        staging.add(tmp_path / "new" / "a.txt", lambda fh: fh.write(b"a"))
        staging.add(tmp_path / "b.txt", lambda fh: fh.write(b"b"))
        (tmp_path / "b.txt").mkdir()  # someone else, meanwhile
        with pytest.raises(OutputWriteError, match="no longer a regular file"):
            staging.commit()
    (tmp_path / "b.txt").rmdir()
    before.assert_unchanged()


def test_existing_regular_file_is_replaced_whole(tmp_path):
    """An existing regular file is replaced (what users expect), by a new inode: a reader holding
    the old file still sees the old content, never a mix."""
    target = tmp_path / "out.txt"
    target.write_text("old content\n")
    with open(target, encoding="utf-8") as old_reader:
        atomic_write(target, lambda fh: fh.write(b"new content\n"))
        assert old_reader.read() == "old content\n"
    assert target.read_text() == "new content\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.txt"]


def test_background_write_is_waited_for_and_its_failure_undoes_everything(tmp_path):
    """A background write (``wbmp solve``'s motion file, compressed while the page is built) is
    complete when commit renames it; one that fails raises its own error at commit and leaves the
    folder as it was; Ctrl-C meanwhile waits for the write to end and removes its temporary file."""
    import threading

    started, release = threading.Event(), threading.Event()

    def slow(fh) -> None:
        started.set()
        release.wait(10)
        fh.write(b"x" * 1_000_000)

    with Staging() as staging:
        staging.add(tmp_path / "m.npz", slow, background=True)
        assert started.wait(10)
        staging.add(tmp_path / "m.html", lambda fh: fh.write(b"<html>"))  # meanwhile, in this thread
        release.set()
        staging.commit()
    assert (tmp_path / "m.npz").stat().st_size == 1_000_000
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.html", "m.npz"]

    before = Tree(tmp_path)

    def failing(fh) -> None:
        fh.write(b"half")
        raise OSError(28, "No space left on device")

    with pytest.raises(OutputWriteError, match="cannot write .*a.npz.*No space left"), Staging() as staging:
        staging.add(tmp_path / "a.npz", failing, background=True)
        staging.add(tmp_path / "m.html", lambda fh: fh.write(b"new"))
        staging.commit()
    before.assert_unchanged()

    started.clear()
    release.clear()
    with pytest.raises(KeyboardInterrupt), Staging() as staging:
        staging.add(tmp_path / "b.npz", slow, background=True)
        assert started.wait(10)
        threading.Timer(0.05, release.set).start()
        raise KeyboardInterrupt
    assert not any(t.name.startswith("wbmp-write") for t in threading.enumerate())  # waited for
    before.assert_unchanged()


def test_ctrl_c_while_writing_leaves_nothing(tmp_path, motion_file):
    """SIGINT once a temporary output file exists: exit 130 and the folder as it was (no
    temporary file, no plot folder); if the signal comes too late, every output is complete."""
    import signal
    import subprocess
    import sys
    import time

    out = tmp_path / "out"
    out.mkdir()
    proc = subprocess.Popen([sys.executable, "-c", "from wbmp.cli import run; run()", "show", str(motion_file),
                             "--html", str(out / "m.html"), "--plots", str(out / "plots"), "--quiet"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        while proc.poll() is None:
            if any(p.name.endswith(".tmp") for p in out.iterdir()):
                proc.send_signal(signal.SIGINT)
                break
            time.sleep(0.002)
        _, err = proc.communicate(timeout=300)
    finally:
        proc.kill()
    assert "Traceback" not in err
    if proc.returncode == 130:
        assert list(out.iterdir()) == []
    else:
        assert proc.returncode == 0, err
        assert sorted(p.name for p in out.iterdir()) == ["m.html", "plots"]
        assert not any(p.name.endswith(".tmp") for p in (out / "plots").iterdir())
