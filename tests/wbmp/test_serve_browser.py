"""``wbmp serve`` in a real browser: headless chromium driven over the DevTools protocol (a pipe).

The server is the real one on 127.0.0.1 with its planning process; every request that does not go
to 127.0.0.1 goes to a trap (tests/viz/browser.py), so the page is shown to fetch nothing from the
network. Skips with a one-line reason when chromium is not installed (CI installs it: .ci/run).
"""

from __future__ import annotations

import json
import threading
import time

import numpy as np
import pytest

from tests.viz import browser as trap_mod
from tests.wbmp.cdp import Browser, find_chromium

CHROMIUM = find_chromium()
if CHROMIUM is None:
    pytest.skip("chromium not installed (apt-get install chromium): browser test skipped", allow_module_level=True)

SENTENCE = "raise your arms"  # ~15 s to plan and simulate on talos (WBMP_COMPILE=0), certified
PLAN_TIMEOUT = 900.0  # [s] for a plan in the test (the machine may be busy): a bound, not a target
FIRST_PAINT = 1.0  # [s] the target for the page's first paint
CACHED_CORRECTION = 2.0  # [s] the target for a correction answered from the motion cache


@pytest.fixture(scope="module")
def served(tmp_path_factory):
    from wbmp.serve.server import ServeServer
    from wbmp.serve.session import Session

    session = Session(folder=tmp_path_factory.mktemp("serve-motions"), start_worker=False)
    server = ServeServer(session, 0)
    session.start()
    thread = threading.Thread(target=server.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True)
    thread.start()
    yield server
    server.shutdown()
    server.server_close()
    session.close()
    thread.join(10)


@pytest.fixture(scope="module")
def trap():
    t = trap_mod.RequestTrap()
    yield t
    t.close()


@pytest.fixture(scope="module")
def downloads(tmp_path_factory):
    return tmp_path_factory.mktemp("downloads")


@pytest.fixture(scope="module")
def page(served, trap, tmp_path_factory, downloads):
    b = Browser(CHROMIUM, tmp_path_factory.mktemp("profile"), downloads, proxy_port=trap.port)
    b.navigate(served.url)
    b.wait_for("document.body && document.body.getAttribute('data-ready') === '1'", 60)
    yield b
    b.close()


def type_and_submit(page: Browser, text: str) -> None:
    """Focus the sentence box, type ``text`` as keyboard input, press Enter."""
    page.evaluate("document.getElementById('text').focus(), true")
    page.call("Input.insertText", text=text)
    for kind in ("keyDown", "keyUp"):
        page.call("Input.dispatchKeyEvent", type=kind, key="Enter", code="Enter", windowsVirtualKeyCode=13,
                  **({"text": "\r"} if kind == "keyDown" else {}))


def wait_done(page: Browser, previous: str | None, timeout: float = PLAN_TIMEOUT) -> str:
    """Wait until the page shows a motion other than ``previous``; its id."""
    return page.wait_for(f"(function () {{ var m = document.body.getAttribute('data-motion'); "
                         f"return m && m !== {json.dumps(previous)} && document.getElementById('verdict') "
                         f"&& document.querySelector('#history li.current') ? m : null; }})()", timeout, poll=0.25)


def viewer_pixels(page: Browser) -> np.ndarray:
    """The 3D view's part of a screenshot (the iframe's box)."""
    box = page.evaluate("(function () { var r = document.getElementById('viewer').getBoundingClientRect(); "
                        "return [r.left, r.top, r.width, r.height].map(Math.round); })()")
    shot = page.screenshot()
    x, y, w, h = box
    return shot[y:y + h - 60, x:x + w]  # without the player's bar at the bottom


def seek(page: Browser, t: float) -> None:
    """Move the replay's time slider to ``t`` seconds, as a user drags it."""
    page.evaluate(f"(function () {{ var d = document.getElementById('viewer').contentDocument; "
                  f"var s = d.getElementById('wbmp-slider'); s.value = {t}; "
                  f"s.dispatchEvent(new Event('input')); return true; }})()")
    time.sleep(0.5)  # a few animation frames


def test_first_paint_and_offline(page, trap):
    """The page paints within the target, shows the planner's state, and fetches nothing outside."""
    paint = page.wait_for("(function () { var e = performance.getEntriesByType('paint')"
                          ".filter(function (p) { return p.name === 'first-contentful-paint'; }); "
                          "return e.length ? e[0].startTime : null; })()", 30)  # recorded after the frame
    print(f"\nfirst contentful paint: {paint:.0f} ms")
    assert paint is not None and paint / 1000.0 <= FIRST_PAINT, paint
    page.wait_for("document.getElementById('robot').textContent.indexOf('talos') >= 0", 30)


def test_correction_before_any_motion_is_one_line(page):
    type_and_submit(page, "slower")
    error = page.wait_for("document.getElementById('error').textContent", 120)
    assert "there is none yet" in error and "(exit code 2)" in error and "\n" not in error
    page.evaluate("document.getElementById('error').textContent = '', true")
    type_and_submit(page, "   ")
    assert "type an instruction" in page.wait_for("document.getElementById('error').textContent", 10)


@pytest.mark.long
def test_sentence_correction_download_stop(page, trap, downloads):
    """Type, submit, wait for the certificate; the canvas is drawn and changes with time; "slower"
    changes the duration by x1.5 (page, and the downloaded motion file); the same correction again
    comes back from the motion cache within the target; stop cancels a plan."""
    from wbmp.motionfile import load_motion

    type_and_submit(page, SENTENCE)
    first = wait_done(page, None)
    actions = page.evaluate("document.getElementById('actions').textContent")
    assert "raise_arms" in actions
    assert "raise" in page.evaluate("document.getElementById('words').textContent")  # every word's use
    assert page.evaluate("document.getElementById('verdict').textContent").startswith(("PASS", "FAIL"))

    # the 3D view: drawn (not one colour), and different at two times of the motion
    page.wait_for("(function () { var d = document.getElementById('viewer').contentDocument; "
                  "return d && d.body && d.body.getAttribute('data-wbmp-ready') === '1'; })()", 120)
    assert page.evaluate("document.getElementById('viewer').contentDocument.body"
                         ".getAttribute('data-wbmp-failures')") == "0"
    seek(page, 0.0)
    start = viewer_pixels(page)
    seek(page, 1.5)  # the arms are up
    raised = viewer_pixels(page)
    assert start.std() > 10.0  # a scene, not a blank canvas
    changed = trap_mod.changed_fraction(start, raised)
    print(f"\nview: std {start.std():.1f}, changed fraction between 0 s and 1.5 s {changed:.4f}")
    assert changed > 0.002, changed  # the robot moved
    assert trap_mod.changed_fraction(raised, viewer_pixels(page)) < changed / 4  # still when paused

    # the plots, drawn on demand by the planning process
    page.evaluate("document.getElementById('draw-plots').click(), true")
    sizes = page.wait_for("(function () { var i = document.querySelectorAll('#plots img'); "
                          "return i.length && Array.prototype.every.call(i, function (x) { return x.complete; }) "
                          "? Array.prototype.map.call(i, function (x) { return x.naturalWidth; }) : null; })()",
                          PLAN_TIMEOUT, poll=0.25)
    assert len(sizes) >= 3 and min(sizes) > 100, sizes  # PNGs the browser decoded

    old = page.evaluate("parseFloat(document.querySelector('#actions [data-param=duration]').textContent"
                        ".split('=')[1])")
    type_and_submit(page, "slower")
    second = wait_done(page, first)
    change = page.evaluate("(function () { var c = document.querySelector('#changes .change'); "
                           "return [c.getAttribute('data-param'), Number(c.getAttribute('data-old')), "
                           "Number(c.getAttribute('data-new')), c.textContent]; })()")
    assert change[0] == "duration" and change[1] == pytest.approx(old) and change[2] == pytest.approx(1.5 * old)
    assert "x1.5" in change[3]
    shown = page.evaluate("parseFloat(document.querySelector('#actions [data-param=duration]').textContent"
                          ".split('=')[1])")
    assert shown == pytest.approx(1.5 * old, rel=0.01)

    # download the corrected motion's file with a click, and read what was planned from it
    page.evaluate(f"document.querySelector('#history li[data-id=\"{second}\"] a[href$=\"motion.npz\"]').click(), true")
    target = downloads / f"wbmp-{second}.npz"
    deadline = time.monotonic() + 120
    while not target.is_file() and time.monotonic() < deadline:
        time.sleep(0.2)
    motion = load_motion(target)
    assert motion.actions[0]["action"] == "raise_arms"
    assert motion.actions[0]["params"]["duration"] == pytest.approx(1.5 * old)
    assert float(motion.plan.t[-1]) > 0

    # undo, then the same correction: from the motion cache, within the target
    type_and_submit(page, "undo")
    page.wait_for(f"document.body.getAttribute('data-motion') === {json.dumps(first)}", 60)
    type_and_submit(page, "slower")
    wait_done(page, first)
    seconds = float(page.evaluate("document.body.getAttribute('data-last-seconds')"))
    print(f"\nthe same correction from the motion cache: {seconds:.2f} s")
    assert seconds <= CACHED_CORRECTION, seconds
    assert "from the cache" in page.evaluate("document.querySelector('#history li').textContent")

    # stop: a new plan is cancelled, the page says so, and the session goes on
    type_and_submit(page, "bow twice")
    page.wait_for("document.getElementById('status').textContent.indexOf('running') === 0", 120)
    page.evaluate("document.getElementById('stop').click(), true")
    page.wait_for("document.body.getAttribute('data-stopped')", 300)
    assert "stopped" in page.evaluate("document.getElementById('status').textContent")

    assert not [r for r in trap.requests if r.strip() and "google" not in r and "gvt1" not in r]


def download(page: Browser, downloads, motion: str):
    """Click the history's motion-file link of ``motion``; the file read back."""
    from wbmp.motionfile import load_motion

    page.evaluate(f"document.querySelector('#history li[data-id=\"{motion}\"] a[href$=\"motion.npz\"]').click(), true")
    target = downloads / f"wbmp-{motion}.npz"
    deadline = time.monotonic() + 120
    while not target.is_file() and time.monotonic() < deadline:
        time.sleep(0.2)
    time.sleep(0.5)  # the browser renames the finished download into place
    return load_motion(target)


@pytest.mark.long
def test_then_continues_from_where_the_robot_stands(page, downloads):
    """A turn, then "then squat": the page says where the continuation starts, lists only the
    squat, and the downloaded squat starts at the downloaded turn's last knot."""
    type_and_submit(page, "turn left 45 degrees")
    turn = wait_done(page, page.evaluate("document.body.getAttribute('data-motion')"))
    assert page.evaluate("document.getElementById('ends-at').getAttribute('data-kind')") == "start"
    type_and_submit(page, "then squat")
    squat = wait_done(page, turn)
    note = page.evaluate("document.getElementById('starts-at').textContent")
    assert "starts where the motion before ended" in note and "heading 4" in note, note  # 45 deg or so
    assert "squat" in page.evaluate("document.getElementById('actions').textContent")
    assert "turn" not in page.evaluate("document.getElementById('actions').textContent")
    assert "continuation" in page.evaluate(f"document.querySelector('#history li[data-id=\"{squat}\"]').textContent")
    before, after = download(page, downloads, turn), download(page, downloads, squat)
    np.testing.assert_allclose(after.plan.q[0], before.plan.q[-1], atol=1e-9)
