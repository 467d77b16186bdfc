"""web_demo: routines recorded to .viser files play back from a static page in headless Chromium."""

from __future__ import annotations

import functools
import http.server
import importlib.util
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from test_browser import ARGS, CHROMIUM, _canvas_shot

from dualpuma.errors import FileError

pytestmark = pytest.mark.browser
ROOT = Path(__file__).resolve().parents[1]


def _load_recorder():
    spec = importlib.util.spec_from_file_location("record_routines", ROOT / "web_demo" / "record_routines.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_recorded_routine_plays_back_statically(tmp_path):
    if not Path(CHROMIUM).exists():
        pytest.fail(f"Chromium not found at {CHROMIUM}: apt-get install chromium (this test never skips)")
    recorder = _load_recorder()
    site = recorder.build_site(tmp_path / "site", [2], fps=10.0)
    rec = site / "recordings" / "routine2.viser"
    assert rec.stat().st_size > 2000 and (site / "viewer.html").stat().st_size > 100_000
    assert "routine2.viser" in (site / "index.html").read_text()
    before = {p: p.read_bytes() for p in site.rglob("*") if p.is_file()}
    with pytest.raises(FileError, match="--force"):  # recorded before: nothing replaced without asking
        recorder.build_site(site, [2], fps=10.0)
    assert {p: p.read_bytes() for p in site.rglob("*") if p.is_file()} == before
    handler = functools.partial(http.server.SimpleHTTPRequestHandler, directory=str(site))
    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=httpd.serve_forever, daemon=True).start()
    from playwright.sync_api import sync_playwright

    try:
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=ARGS)
            page = browser.new_page(viewport={"width": 1200, "height": 800})
            page.goto(f"http://127.0.0.1:{httpd.server_address[1]}/viewer.html?playbackPath=recordings/routine2.viser")
            page.locator("canvas").first.wait_for(state="visible", timeout=30000)
            time.sleep(4.0)
            shot = _canvas_shot(page)
            assert shot.std() > 5.0, "the played-back scene is blank"
            browser.close()
    finally:
        httpd.shutdown()


def test_the_recorder_refuses_a_users_page_before_recording(tmp_path):
    site = tmp_path / "site"
    site.mkdir()
    (site / "index.html").write_text("mine")
    r = subprocess.run([sys.executable, str(ROOT / "web_demo" / "record_routines.py"), "--out", str(site),
                        "--routines", "2"], capture_output=True, text=True, timeout=120, check=False)
    assert r.returncode != 0 and "index.html" in r.stderr and "--force" in r.stderr and "Traceback" not in r.stderr
    assert (site / "index.html").read_text() == "mine"
    assert sorted(p.name for p in site.iterdir()) == ["index.html"]  # refused before anything was written
