"""Real browser: headless Chromium (Debian's, never downloaded) driven by Playwright uses the viewer
as a person would — it drags, types and clicks on the *page* — and after each action checks the
state on the server:

1. drags a joint slider (the partner arm follows, both hands stay on the bar);
2. types a joint value beyond its limit (clamped, and a toast says so);
3. clicks Home; chooses "left hand", clicks a jog button, then moves a slider of the same arm (both applied);
4. types an unreachable object x (refused: toast, box restored), then a reachable one (accepted);
5. drags the object gizmo about 5 mm in the 3-D view (accepted);
6. runs routine 8 (it asks to switch to its own cell; switches; it is timed under the joint
   limits), scrubs the timeline, and lets a second tab close mid-animation;
7. shows the envelope overlay; saves the screenshots.

A second page, in the rising-ball cell, types a goal across a moving ball, plans, reads that the
timed motion waits for the ball, and types a time inside the wait into the timeline.

This test never skips: without /usr/bin/chromium it fails with instructions (``.ci/run`` installs it).
Screenshots go to a temporary directory, or to ``$DUALPUMA_SCREENSHOTS`` (docs/screenshots for the README).
"""

from __future__ import annotations

import contextlib
import io
import math
import os
import re
import shutil
import time
from pathlib import Path

import numpy as np
import pytest
from viewer_checks import hand as _hand
from viewer_checks import wait as _wait

from dualpuma.model import Cell
from dualpuma.viewer.app import ViewerApp

pytestmark = pytest.mark.browser

CHROMIUM = os.environ.get("DUALPUMA_CHROMIUM") or shutil.which("chromium") or "/usr/bin/chromium"
ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking", "--disable-component-update",
        "--disable-sync", "--no-first-run", "--window-size=1400,900"]


def _pixels(png: bytes) -> np.ndarray:
    import imageio.v3 as iio

    return np.asarray(iio.imread(io.BytesIO(png)), dtype=np.float64)[..., :3]


def _canvas_shot(page) -> np.ndarray:
    return _pixels(page.locator("canvas").first.screenshot())


@pytest.fixture(scope="module")
def shots(tmp_path_factory) -> Path:
    d = Path(os.environ.get("DUALPUMA_SCREENSHOTS") or tmp_path_factory.mktemp("shots"))
    d.mkdir(parents=True, exist_ok=True)
    return d


# ---------------------------------------------------------------- the page
def _control(page, label: str):
    """The element a ``<label>`` with exactly this text is for (input, slider root, select)."""
    lab = page.locator("label").filter(has_text=re.compile(f"^{re.escape(label)}$")).first
    return page.locator(f"[id='{lab.get_attribute('for')}']")


def _row(page, label: str):
    lab = page.locator("label").filter(has_text=re.compile(f"^{re.escape(label)}$")).first
    return lab.locator("xpath=ancestor::div[contains(@class, 'mantine-Flex-root')][1]")


def _type(page, label: str, text: str, number_box_of_slider: bool = False) -> None:
    box = _row(page, label).locator("input.mantine-NumberInput-input") if number_box_of_slider else _control(page, label)
    box.fill(text)
    box.press("Enter")


def _tab_to(page, button: str, max_tabs: int = 20) -> None:
    """Press Tab from the focused control until the button named ``button`` has the focus (a
    keyboard user's way there), then Enter."""
    for _ in range(max_tabs):
        page.keyboard.press("Tab")
        if page.evaluate("() => document.activeElement?.tagName === 'BUTTON' && "
                         "document.activeElement.textContent.trim()") == button:
            page.keyboard.press("Enter")
            return
    raise AssertionError(f"{button!r} not reached with {max_tabs} Tab presses")


def _choose(page, label: str, option: str) -> None:
    _control(page, label).click()
    page.get_by_role("option", name=option, exact=True).click()


def _toast(page, text: str, timeout: float = 10000) -> None:
    page.locator(".mantine-Notification-root", has_text=text).first.wait_for(state="visible", timeout=timeout)


def _close_toasts(page) -> None:
    """Close every notification (a DOM click: the 3-D view keeps the page from ever being 'stable')."""
    page.evaluate("() => document.querySelectorAll('.mantine-Notification-closeButton').forEach(b => b.click())")


def _project(cam, p) -> tuple[float, float]:
    """Pixel of world point ``p`` in a client's camera (pinhole, vertical fov)."""
    pos, look = np.asarray(cam.position), np.asarray(cam.look_at)
    f = (look - pos) / np.linalg.norm(look - pos)
    r = np.cross(f, cam.up_direction)
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    v = np.asarray(p) - pos
    z = v @ f
    w, h, t = cam.image_width, cam.image_height, math.tan(cam.fov / 2)
    return (0.5 + 0.5 * (v @ r / z) / (t * w / h)) * w, (0.5 - 0.5 * (v @ u / z) / t) * h


# ---------------------------------------------------------------- the server's state
def _on_grasp(app) -> bool:
    return all(np.allclose(_hand(app.cell, s, app.q[s]), app.T_object @ getattr(app.cell, f"grasp_{s}").T_object_hand,
                           atol=1e-9) for s in ("left", "right"))


def _deg(app, side, j) -> float:
    return math.degrees(float(app.q[side][j]))


@contextlib.contextmanager
def _viewer_page(cell, data_dir: Path):
    """A started viewer of ``cell`` and a Chromium page connected to it: ``(app, browser, page)``.
    Without /usr/bin/chromium the test fails with instructions (it never skips)."""
    if not Path(CHROMIUM).exists():
        pytest.fail(f"Chromium not found at {CHROMIUM}: install Debian's chromium (apt-get install chromium); "
                    "the browser test is mandatory and never skips")
    from playwright.sync_api import sync_playwright

    app = ViewerApp(cell, port=0, data_dir=data_dir)
    app.start()
    try:
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=ARGS)
            page = browser.new_page(viewport={"width": 1400, "height": 900})
            page.goto(app.url)
            page.locator("canvas").first.wait_for(state="visible", timeout=30000)
            _wait(lambda: len(app.server.get_clients()) >= 1, 20, "the page to connect")
            yield app, browser, page
            browser.close()
    finally:
        app.close()


def test_viewer_in_chromium(shots, tmp_path):
    with _viewer_page(Cell.default(), tmp_path / "dualpuma-data") as (app, browser, page):
        page.get_by_text("left q1", exact=True).first.wait_for(timeout=20000)
        # Chromium without a GPU announces software WebGL: close it before the screenshot
        notice = page.locator(".mantine-Notification-root", has_text="WebGL")
        t_notice = time.time()
        while notice.count() == 0 and time.time() - t_notice < 5:
            time.sleep(0.1)
        time.sleep(0.5)
        _close_toasts(page)
        first = _canvas_shot(page)
        assert first.std() > 5.0, "3-D canvas looks blank"
        page.screenshot(path=str(shots / "teach_mode.png"))

        # 1. drag a joint slider: left q1 down by about 12 deg; the right arm follows
        q1 = _deg(app, "left", 0)
        thumb = _row(page, "left q1").get_by_role("slider")
        box = thumb.bounding_box()
        x, y = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
        page.mouse.move(x, y)
        page.mouse.down()
        for k in range(1, 11):
            page.mouse.move(x - k, y)
            time.sleep(0.02)
        page.mouse.up()
        _wait(lambda: _deg(app, "left", 0) < q1 - 3.0, 10, "the dragged slider to reach the server")
        time.sleep(0.5)
        assert _on_grasp(app)
        slider = app.controls.handles["joint.left.0"]
        assert slider.value == pytest.approx(round(_deg(app, "left", 0), 1), abs=0.051)
        assert np.abs(_canvas_shot(page) - first).mean() > 0.3, "the picture did not change after the drag"

        # 2. type a value beyond the limit into a joint's number box: clamped, and told
        _type(page, "right q5", "-150", number_box_of_slider=True)
        _wait(lambda: abs(_deg(app, "right", 4) + 100.0) < 1e-9, 10, "right q5 clamped to -100 deg")
        _toast(page, "clamped to -100.0 deg")
        assert _on_grasp(app)
        _close_toasts(page)
        page.get_by_role("button", name="Home", exact=True).click()  # q5 at its limit constrains the rest
        home = np.array(app.cell.right.q_home, float)
        _wait(lambda: np.allclose(app.q["right"], home, atol=1e-12), 10, "Home")

        # 3. jog the left hand +z, then move a slider of the same arm: both applied
        _choose(page, "jog", "left hand")
        _wait(lambda: app.settings["jog_frame"] == "left hand", 5, "the jog frame")
        H0 = _hand(app.cell, "left", app.q["left"])
        page.get_by_role("button", name="+z", exact=True).click()
        _wait(lambda: _hand(app.cell, "left", app.q["left"])[2, 3] > H0[2, 3] + 0.009, 10, "the jog")
        H1 = _hand(app.cell, "left", app.q["left"])
        np.testing.assert_allclose(H1[:3, 3] - H0[:3, 3], (0.0, 0.0, 0.01), atol=1e-9)
        shown = float(_row(page, "left q6").get_by_role("slider").get_attribute("aria-valuenow"))
        assert shown == pytest.approx(round(_deg(app, "left", 5), 1), abs=0.051)
        _row(page, "left q6").get_by_role("slider").focus()
        for _ in range(10):
            page.keyboard.press("ArrowRight")  # +0.1 deg per press, from the value shown
        _wait(lambda: abs(_deg(app, "left", 5) - (shown + 1.0)) < 1e-6, 10,
              f"the slider after the jog ({shown} + 1.0 deg; server at {_deg(app, 'left', 5):.3f})")
        assert "read-only" not in app.message and _on_grasp(app)

        # 4. an unreachable object move is refused, the next reachable one accepted
        T0 = app.T_object.copy()
        _type(page, "object x", "4000")
        _toast(page, "refused")
        np.testing.assert_array_equal(app.T_object, T0)
        box = _control(page, "object x")
        _wait(lambda: abs(float(box.input_value()) - round(T0[0, 3] * 1000, 1)) < 0.051, 10, "the box restored")
        _type(page, "object x", f"{T0[0, 3] * 1000 - 30.0:.1f}")
        _wait(lambda: abs(app.T_object[0, 3] - (round(T0[0, 3] * 1000 - 30.0, 1) / 1000)) < 1e-9, 10, "the move")
        assert _on_grasp(app)
        _close_toasts(page)

        # 5. drag the object gizmo ~5 mm along its y arrow (seen from close by)
        client = next(iter(app.server.get_clients().values()))
        T = app.T_object.copy()
        c = T[:3, 3]
        client.camera.position = tuple(c + (0.25, -0.6, 0.35))
        client.camera.look_at = tuple(c)
        time.sleep(1.5)
        cam = client.camera
        ay = T[:3, 1]
        p0, p1 = _project(cam, c + 0.22 * ay), _project(cam, c + 0.225 * ay)
        page.mouse.move(*p0)
        page.mouse.down()
        for k in (1, 2, 3):  # few events: software WebGL redraws the close-up slowly
            page.mouse.move(p0[0] + (p1[0] - p0[0]) * k / 3, p0[1] + (p1[1] - p0[1]) * k / 3)
        page.mouse.up()
        _wait(lambda: np.linalg.norm(app.T_object[:3, 3] - c) > 0.002, 10, "the gizmo drag")
        time.sleep(0.5)
        d = app.T_object[:3, 3] - c
        assert 0.002 < float(d @ ay) < 0.009 and np.linalg.norm(d - (d @ ay) * ay) < 1e-6
        assert _on_grasp(app)
        np.testing.assert_allclose(app.teach.gizmo.position, app.T_object[:3, 3], atol=1e-9)
        page.get_by_role("tab", name="view").click()
        page.get_by_role("button", name="fit view").click()
        time.sleep(1.0)

        # 6. routine 8: asks to switch cells, switches, plays; scrub the timeline
        page.get_by_role("tab", name="routines & planning").click()
        _choose(page, "routine", next(o for o in app.controls.handles["routine"].options if o.startswith("8:")))
        page.get_by_role("button", name="run routine").click()
        page.get_by_role("button", name="switch and run").click()
        _wait(lambda: app.plan is not None and app.cell.name == "routine8-overhang", 60, "routine 8 in its own cell")
        pb = app.playback
        page2 = browser.new_page()
        page2.goto(app.url)
        _wait(lambda: len(app.server.get_clients()) >= 2, 20, "the second tab")
        page2.close()
        _wait(lambda: not app.state.playing, 30, "routine 8 to play to its end")
        np.testing.assert_allclose(app.T_object, pb.plan.T_world_object[-1], atol=1e-12)
        assert pb.timed and pb.plan.trajectory.certified  # the default: timed under the joint limits
        track = _row(page, "timeline [s]").locator(".mantine-Slider-track")
        tb = track.bounding_box()
        page.mouse.move(tb["x"] + tb["width"] - 2, tb["y"] + tb["height"] / 2)
        page.mouse.down()
        page.mouse.move(tb["x"] + 0.45 * tb["width"], tb["y"] + tb["height"] / 2, steps=8)
        page.mouse.up()
        _wait(lambda: app.state.view == "plan" and app.controls.handles["timeline"].value < 0.6 * pb.x_end, 10,
              "the scrubbed timeline")
        # the server has acted on the last position the drag sent when its playback time is that one's
        _wait(lambda: abs(app.state.play_time - pb.time_at_x(float(app.controls.handles["timeline"].value))) < 1e-9,
              10, "the server at the scrubbed time")
        x = float(app.controls.handles["timeline"].value)
        assert not app.state.playing and 0.2 * pb.x_end < x < 0.6 * pb.x_end
        np.testing.assert_allclose(app.T_object, pb.sample(pb.time_at_x(x)).T_object, atol=1e-9)
        page.get_by_text(re.compile(rf"step \d+/{pb.plan.n_steps}\b")).first.wait_for(timeout=10000)
        _close_toasts(page)
        client.camera.position, client.camera.look_at = (1.05, -2.3, 1.35), (1.75, -0.35, 0.35)
        time.sleep(1.5)
        page.screenshot(path=str(shots / "routine8_mid.png"))

        # 7. the envelope overlay (off by default), for the docs
        assert not app.scene.envelope.visible
        page.get_by_role("tab", name="view").click()
        _control(page, "envelope, ideal").check()
        _wait(lambda: app.scene.envelope.visible, 10, "the envelope toggle")
        page.get_by_role("button", name="fit view").click()
        time.sleep(1.5)
        page.screenshot(path=str(shots / "envelope_arcs.png"))
        page.get_by_role("tab", name="cell & files").click()
        time.sleep(0.5)
        page.screenshot(path=str(shots / "cell_files.png"))
    for name in ("teach_mode", "routine8_mid", "envelope_arcs", "cell_files"):
        assert (shots / f"{name}.png").stat().st_size > 10_000


def test_a_timed_plan_waits_for_a_moving_ball_in_chromium(tmp_path):
    """The page plans across a rising ball (``rising_ball_cell``): it types the goal, clicks "plan to
    goal", sees the message that the timed motion waits at the start, and types a time inside the
    wait into the timeline; the server's plan is certified and waits, and the arms shown are at the
    start's joints."""
    from dualpuma.scenarios import rising_ball_cell

    cell, _, B = rising_ball_cell(0.5, 1.0)
    with _viewer_page(cell, tmp_path / "dualpuma-data") as (app, _browser, page):
        page.get_by_role("tab", name="routines & planning").click()
        # the goal's folder is open (viser opens a folder by mouse only: closed, it kept the goal
        # and "plan to goal" from a keyboard user)
        for k, v in zip("xyz", B[:3, 3]):
            _type(page, f"goal {k}", f"{v * 1000:.1f}")
        _wait(lambda: np.allclose(app.settings["goal"][:3, 3], np.round(B[:3, 3] * 1000, 1) / 1000, atol=1e-9), 10,
              "the typed goal")
        # first untimed: the clearance plot's x axis is the plan's steps, 0 .. its last, as the page draws it
        scales = "() => Object.values(window.__viserTestpoints?.uplots ?? {}).map(u => [u.chart.scales.x.min, u.chart.scales.x.max])"
        _row(page, "timed trajectory (joint limits)").locator("input[type=checkbox]").click()
        _wait(lambda: app.settings["timed"] is False, 10, "timed unticked")
        _control(page, "goal z").focus()
        _tab_to(page, "plan to goal")  # by keyboard
        _wait(lambda: app.plan is not None and not app.busy and app.state.playback is not None, 60, "the untimed plan")
        n = app.state.playback.x_end
        _wait(lambda: any(abs(lo) < 1e-6 and abs(hi - n) < 1e-6 for lo, hi in page.evaluate(scales)), 10,
              "the plot's step range")
        page.get_by_role("button", name="start", exact=True).click()  # the next plan starts where this one did
        _wait(lambda: not app.state.playing and app.state.play_time == app.state.playback.t[0], 10, "back at the start")
        _row(page, "timed trajectory (joint limits)").locator("input[type=checkbox]").click()
        _wait(lambda: app.settings["timed"] is True, 10, "timed ticked")
        page.get_by_role("button", name="plan to goal", exact=True).click()
        _toast(page, "to let a moving obstacle pass", timeout=60000)
        tr = app.plan.trajectory
        assert app.plan.reached and tr is not None and tr.certified and tr.start_delay > 0
        _type(page, "timeline [s]", f"{0.5 * tr.start_delay:.2f}", number_box_of_slider=True)
        # the server took the typed time when playback stops there (the control's value alone can
        # arrive before the server acts on it, while the plan still plays on: a race under load)
        t_typed = app.state.playback.time_at_x(round(0.5 * tr.start_delay, 2))
        _wait(lambda: app.state.view == "plan" and not app.state.playing and abs(app.state.play_time - t_typed) < 1e-9
              and abs(app.controls.handles["timeline"].value - round(0.5 * tr.start_delay, 2)) < 1e-9, 10,
              "the typed time")
        np.testing.assert_allclose(app.q["left"], app.plan.q_left[0], atol=1e-12)
        np.testing.assert_allclose(app.q["right"], app.plan.q_right[0], atol=1e-12)
        # then the trajectory's time, 0 .. its duration (the page kept the steps' range when the axis
        # changed from steps to seconds, and squashed the curve or cut it off)
        x_end = float(tr.t[-1] - tr.t[0])
        assert abs(x_end - n) > 0.5
        _wait(lambda: any(abs(lo) < 1e-6 and abs(hi - x_end) < 1e-6 for lo, hi in page.evaluate(scales)), 10,
              "the plot's x range")
