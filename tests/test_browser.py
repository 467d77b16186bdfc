"""Real browser: headless Chromium (Debian's, never downloaded) driven by Playwright opens the viewer,
sees a non-blank 3-D canvas, moves a joint slider and sees the picture change, runs routine 2 to the
end, survives a second tab closing mid-animation, and saves screenshots.

This test never skips: without /usr/bin/chromium it fails with instructions (``.ci/run`` installs it).
Screenshots go to a temporary directory, or to ``$DUALPUMA_SCREENSHOTS`` (docs/screenshots for the README).
"""

from __future__ import annotations

import io
import os
import shutil
import socket
import time
from pathlib import Path

import numpy as np
import pytest

from dualpuma.model import Cell
from dualpuma.viewer.app import ViewerApp

pytestmark = pytest.mark.browser

CHROMIUM = os.environ.get("DUALPUMA_CHROMIUM") or shutil.which("chromium") or "/usr/bin/chromium"
ARGS = ["--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist",
        "--window-size=1400,900"]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _pixels(png: bytes) -> np.ndarray:
    import imageio.v3 as iio

    return np.asarray(iio.imread(io.BytesIO(png)), dtype=np.float64)[..., :3]


def _canvas_shot(page) -> np.ndarray:
    return _pixels(page.locator("canvas").first.screenshot())


def _wait(cond, timeout: float, what: str) -> None:
    t0 = time.time()
    while time.time() - t0 < timeout:
        if cond():
            return
        time.sleep(0.1)
    raise AssertionError(f"timed out waiting for {what}")


@pytest.fixture(scope="module")
def shots(tmp_path_factory) -> Path:
    d = Path(os.environ.get("DUALPUMA_SCREENSHOTS") or tmp_path_factory.mktemp("shots"))
    d.mkdir(parents=True, exist_ok=True)
    return d


def _aim(app, position, look_at) -> None:
    for client in app.server.get_clients().values():
        client.camera.position = position
        client.camera.look_at = look_at


def test_viewer_in_chromium(shots):
    if not Path(CHROMIUM).exists():
        pytest.fail(f"Chromium not found at {CHROMIUM}: install Debian's chromium (apt-get install chromium); "
                    "the browser test is mandatory and never skips")
    from playwright.sync_api import sync_playwright

    app = ViewerApp(Cell.default(), port=_free_port())
    app.start()
    try:
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=ARGS)
            page = browser.new_page(viewport={"width": 1400, "height": 900})
            page.goto(app.url)
            page.locator("canvas").first.wait_for(state="visible", timeout=30000)
            _wait(lambda: len(app.server.get_clients()) >= 1, 20, "the page to connect")
            _aim(app, (1.5, -2.6, 1.6), (1.5, -0.2, 0.35))
            time.sleep(3.0)
            toast = page.locator(".mantine-Notification-closeButton")  # "software WebGL" notice, cosmetic
            for i in range(toast.count()):
                toast.nth(i).click()
            first = _canvas_shot(page)
            assert first.std() > 5.0, "3-D canvas looks blank"
            page.screenshot(path=str(shots / "teach_mode.png"))

            # move the first joint slider (left q1) with the keyboard, as a user would
            q_before = float(app.sliders[("left", 0)].value)
            slider = page.get_by_role("slider").first
            slider.focus()
            for _ in range(60):
                slider.press("ArrowRight")
            _wait(lambda: abs(float(app.sliders[("left", 0)].value) - q_before) > 1.0, 10, "the slider to reach the server")
            time.sleep(1.5)
            moved = _canvas_shot(page)
            assert np.abs(moved - first).mean() > 0.5, "the picture did not change after moving a joint"

            # a second tab joins, then closes mid-animation; the first keeps going
            page2 = browser.new_page()
            page2.goto(app.url)
            _wait(lambda: len(app.server.get_clients()) >= 2, 20, "the second tab")
            page.get_by_role("button", name="run routine").click()
            _wait(lambda: app.plan is not None, 30, "routine 2's plan")
            page2.close()
            _wait(lambda: app.plan is not None and not app.playing and app.routines.timeline.value == app.plan.n_steps,
                  30, "routine 2 to play to the end")
            assert app.plan.reached and app.plan.n_steps == 5
            page.get_by_text("step 5/5").first.wait_for(timeout=10000)
            time.sleep(1.0)
            page.screenshot(path=str(shots / "routine2_end.png"))

            # routine 8 mid-motion and the envelope arcs, for the docs
            app.routines.choice.value = app.routines.choice.options[7]
            app.routines.speed.value = 2.0
            app.run_routine(8)
            _wait(lambda: app.plan is not None and app.plan_title == "routine 8" and app.idx >= 7, 60, "routine 8 mid-motion")
            app.set_playing(False)
            _aim(app, (1.2, -2.4, 1.4), (1.7, -0.3, 0.3))
            time.sleep(2.0)
            page.screenshot(path=str(shots / "routine8_mid.png"))
            _aim(app, (1.5, -3.2, 0.7), (1.5, 0.0, 0.5))
            time.sleep(2.0)
            page.screenshot(path=str(shots / "envelope_arcs.png"))
            browser.close()
    finally:
        app.close()
    for name in ("teach_mode", "routine2_end", "routine8_mid", "envelope_arcs"):
        assert (shots / f"{name}.png").stat().st_size > 10_000
