"""The HTML replay in a real browser (headless Debian chromium), with the network trapped.

Skips with a one-line reason when chromium is not installed (CI installs it: .ci/run).
"""

from __future__ import annotations

import numpy as np
import pytest

from tests.viz import browser

CHROMIUM = browser.find_chromium()
if CHROMIUM is None:
    pytest.skip("chromium not installed (apt-get install chromium): browser test skipped",
                allow_module_level=True)

# chromium's own service traffic (clock, component updates, sign-in), not the page's
BROWSER_SERVICE_DOMAINS = ("google.com", "googleapis.com", "gstatic.com", "gvt1.com", "googleusercontent.com")


def _host(request_line: str) -> str:
    parts = request_line.split()
    target = parts[1] if len(parts) > 1 else ""
    target = target.split("://", 1)[-1]
    return target.split("/", 1)[0].rsplit(":", 1)[0].lower()


def page_requests(trap: browser.RequestTrap) -> list[str]:
    """Requests that did not come from chromium's own background services.

    A connection that sends no request line (chromium's speculative preconnect to its proxy,
    closed unused) fetched nothing and is not counted; the positive control below shows that
    real fetches always leave a request line in the trap.
    """
    trap.settle()
    return [r for r in trap.requests
            if r.strip()
            and not any(_host(r) == d or _host(r).endswith("." + d) for d in BROWSER_SERVICE_DOMAINS)]


@pytest.fixture(scope="module")
def trap():
    t = browser.RequestTrap()
    yield t
    t.close()


@pytest.fixture(scope="module")
def squat_page(tmp_path_factory, talos, squat_plan):
    from viz import write_html

    return write_html(tmp_path_factory.mktemp("browser") / "squat.html", talos, squat_plan, title="squat")


def test_trap_sees_a_page_that_fetches(tmp_path, trap):
    """Positive control: a page with an external image and a fetch() leaves both in the trap."""
    page = tmp_path / "leaky.html"
    page.write_text('<html><body><img src="http://example.com/x.png">'
                    '<script>fetch("https://example.org/a")</script></body></html>')
    browser.screenshot(CHROMIUM, page.as_uri(), tmp_path / "leaky.png", tmp_path / "profile", trap.port)
    hosts = {_host(r) for r in page_requests(trap)}
    assert {"example.com", "example.org"} <= hosts
    trap.requests.clear()


@pytest.mark.slow
def test_squat_replay_shows_the_robot_moving_without_network(tmp_path, trap, squat_page, squat_plan):
    """The robot covers >= 1 % of the frame, the squat bottom differs from the start, and the
    page asks the network for nothing."""
    trap.requests.clear()
    t_bottom = float(squat_plan.t[int(np.argmin(squat_plan.com[:, 2]))])
    assert t_bottom > 0.3
    url = squat_page.as_uri()
    profile = tmp_path / "profile"
    start = browser.screenshot(CHROMIUM, f"{url}#t=0&hide=markers,gui", tmp_path / "start.png", profile, trap.port)
    empty = browser.screenshot(CHROMIUM, f"{url}#t=0&hide=robot,markers,gui", tmp_path / "empty.png", profile,
                               trap.port)
    bottom = browser.screenshot(CHROMIUM, f"{url}#t={t_bottom:.3f}&hide=markers,gui", tmp_path / "bottom.png",
                                profile, trap.port)
    assert start.shape == (browser.WINDOW[1], browser.WINDOW[0], 3)
    robot = browser.changed_fraction(start, empty)
    moved = browser.changed_fraction(start, bottom)
    assert robot >= 0.01, f"robot covers only {100 * robot:.2f} % of the frame"
    assert moved >= 0.005, f"t=0 and t={t_bottom:.2f} s differ on only {100 * moved:.3f} % of the pixels"
    assert page_requests(trap) == []


def test_held_object_moves_in_the_replay(tmp_path, trap, talos, pick_plan):
    """With the robot, markers and controls hidden, nothing but the held cup moves (its planned
    track): the replay at its start and at its end differ (they would be identical if the cup stood
    still), and the page fetches nothing."""
    from viz import write_html

    trap.requests.clear()
    url = write_html(tmp_path / "held.html", talos, pick_plan).as_uri()
    profile = tmp_path / "profile"
    end = float(pick_plan.t[-1])
    start, last = (browser.screenshot(CHROMIUM, f"{url}#t={t:.3f}&hide=robot,markers,gui", tmp_path / f"{k}.png",
                                      profile, trap.port) for k, t in enumerate((0.0, end)))
    moved = browser.changed_fraction(start, last)
    assert moved >= 5e-4, f"the cup changed only {100 * moved:.3f} % of the pixels"
    assert page_requests(trap) == []
