"""``wbmp show`` and ``wbmp export`` on a real motion file."""

from __future__ import annotations

import json
import os
import queue
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

motionfile = pytest.importorskip("wbmp.motionfile")

from wbmp.cli import main  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def motion_path(tmp_path_factory, talos, synth_plan, synth_execution):
    ex = synth_execution
    execution = ex
    path = tmp_path_factory.mktemp("motion") / "squat.npz"
    return motionfile.save_motion(path, synth_plan, talos, execution=execution,
                                  report={"certificate": {"ok": True}})


def test_export_json_has_the_same_numbers(tmp_path, motion_path, synth_plan, synth_execution, capsys):
    out = tmp_path / "m.json"
    assert main(["export", str(motion_path), "--format", "json", "--out", str(out)]) == 0
    assert f"json: {out}" in capsys.readouterr().out
    doc = json.loads(out.read_text())
    for key in ("t", "q", "v", "com"):
        np.testing.assert_array_equal(np.asarray(doc[key]), getattr(synth_plan, key), err_msg=key)
    np.testing.assert_array_equal(np.asarray(doc["exec_q"]), synth_execution.q)
    np.testing.assert_array_equal(np.asarray(doc["exec_tau"]), synth_execution.tau)
    assert doc["robot"] == "talos" and doc["spec"]["name"] == "synthetic squat"
    assert doc["report"]["certificate"] == {"ok": True}


def test_export_csv_has_the_same_numbers(tmp_path, motion_path, synth_plan, synth_execution, talos):
    out = tmp_path / "m.csv"
    assert main(["export", str(motion_path), "--out", str(out)]) == 0  # format from the suffix
    lines = out.read_text().splitlines()
    meta = {ln[2:].split(":", 1)[0]: json.loads(ln[2:].split(":", 1)[1]) for ln in lines if ln.startswith("# ")}
    assert meta["robot"] == "talos" and meta["spec"]["name"] == "synthetic squat"
    header = next(ln for ln in lines if not ln.startswith("#")).split(",")
    assert header[:4] == ["t", "q_base_x", "q_base_y", "q_base_z"]
    assert f"q_{talos.joint_names[0]}" in header and header[-3:] == ["com_x", "com_y", "com_z"]
    rows = np.loadtxt(out, delimiter=",", comments="#", skiprows=len(meta) + 1)
    np.testing.assert_array_equal(rows[:, 0], synth_plan.t)
    np.testing.assert_array_equal(rows[:, 1:1 + talos.nq], synth_plan.q)
    np.testing.assert_array_equal(rows[:, -3:], synth_plan.com)
    exec_rows = np.loadtxt(tmp_path / "m.exec.csv", delimiter=",", skiprows=1)
    np.testing.assert_array_equal(exec_rows[:, 0], synth_execution.t)
    np.testing.assert_array_equal(exec_rows[:, -(talos.nv - 6):], synth_execution.tau)


def test_export_refuses_contradictions(tmp_path, motion_path, capsys):
    assert main(["export", str(motion_path), "--format", "csv", "--out", str(tmp_path / "x.json")]) == 2
    assert "ends in .json but --format is csv" in capsys.readouterr().err
    assert main(["export", str(tmp_path / "missing.npz")]) == 2


def test_show_writes_html_and_plots_without_a_server(tmp_path, motion_path, talos, capsys):
    html, plots = tmp_path / "m.html", tmp_path / "plots"
    assert main(["show", str(motion_path), "--html", str(html), "--plots", str(plots), "--quiet"]) == 0
    out = capsys.readouterr().out
    assert f"html: {html}" in out and "plot: " in out
    text = html.read_text()
    from viz.html import unpack_data

    assert "simulated" in unpack_data(text)["motions"] and "synthetic squat" in text  # the execution came along
    assert sorted(p.name for p in plots.iterdir()) == ["com_support.png", "joints.png", "keyframes.png",
                                                        "torques.png"]
    assert main(["show", str(tmp_path / "missing.npz")]) == 2


# Bounds on hangs, not on speed (each wait ends at its event): generous for a loaded 2-core
# machine. Idle, the URL appears in ~2 s and the process exits within ~1 s of SIGINT.
READY_TIMEOUT = 120.0  # [s] until `wbmp show` prints its URL
EXIT_TIMEOUT = 120.0  # [s] from SIGINT to the process's exit
HTTP_TIMEOUT = 60.0  # [s] one request to the viewer


def _first_line_with(stream, text: str, timeout: float) -> str | None:
    """The first line of ``stream`` containing ``text``, read in a thread so a silent process
    cannot block the test past ``timeout``; None at timeout or end of stream."""
    lines: queue.Queue[str | None] = queue.Queue()

    def pump() -> None:
        try:
            for line in stream:
                lines.put(line)
        except (OSError, ValueError):  # the test closed the stream: it no longer listens
            pass
        lines.put(None)

    threading.Thread(target=pump, daemon=True).start()
    deadline = time.monotonic() + timeout
    while (left := deadline - time.monotonic()) > 0:
        try:
            line = lines.get(timeout=left)
        except queue.Empty:
            return None
        if line is None or text in line:
            return line
    return None


@pytest.mark.slow
def test_show_live_stops_on_ctrl_c(motion_path):
    """`wbmp show motion.npz` prints a loopback URL, serves, and on SIGINT exits 0 with the
    server's port closed."""
    import urllib.request

    env = dict(os.environ, PYTHONPATH=str(ROOT), PYTHONUNBUFFERED="1")
    proc = subprocess.Popen([sys.executable, "-m", "wbmp.cli", "show", str(motion_path), "--quiet"],
                            cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = _first_line_with(proc.stdout, "http://", READY_TIMEOUT)
        assert line and "http://127.0.0.1:" in line, (
            f"no URL within {READY_TIMEOUT:.0f} s: {line!r} {proc.stderr.read() if proc.poll() is not None else ''}")
        port = int(line.split("http://127.0.0.1:")[1].split("/")[0])
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/static/", timeout=HTTP_TIMEOUT) as r:
            assert r.status == 200
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=EXIT_TIMEOUT) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        proc.stdout.close()
        proc.stderr.close()
    with pytest.raises(OSError):
        urllib.request.urlopen(f"http://127.0.0.1:{port}/static/", timeout=HTTP_TIMEOUT)
