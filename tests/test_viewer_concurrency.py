"""Concurrency: two clients fire interleaved slider events while the loop runs. Every value the
server ends with is one a client sent last, the sliders show the state, and nothing is logged as
an error (the old viewer dropped genuine events behind a global 'syncing' flag and read values on a
pool thread after the loop had written others)."""

from __future__ import annotations

import logging
import math
import sys
import threading
import time

import numpy as np
import pytest
from viewer_checks import hand as _hand
from viser_client import Client, control

from dualpuma.model import Cell
from dualpuma.viewer import ViewerApp

#: (arm, joint) -> range [deg] the partner arm can follow through from home (every combination)
RANGES = {("left", 0): (59.0, 62.0), ("left", 3): (-4.0, 4.0), ("left", 4): (35.0, 41.0), ("left", 5): (-31.0, -27.0)}


@pytest.fixture()
def app():
    a = ViewerApp(Cell.default(), port=0)
    a.start()
    yield a
    a.close()


def _settled(app, timeout: float = 20.0) -> None:
    """Wait until the shown joints stop changing for half a second."""
    t0, last, since = time.time(), None, time.time()
    while time.time() - t0 < timeout:
        q = np.concatenate([app.q["left"], app.q["right"]])
        if last is None or not np.array_equal(q, last):
            last, since = q, time.time()
        elif time.time() - since > 0.5:
            return
        time.sleep(0.02)


def test_interleaved_slider_events_from_two_clients(app, caplog, capfd):
    caplog.set_level(logging.WARNING)
    url = f"ws://127.0.0.1:{app.server.get_port()}"
    clients = [Client(url), Client(url)]
    t0 = time.time()
    while len(app.server.get_clients()) < 2 and time.time() - t0 < 10:
        time.sleep(0.02)
    handles = {k: control(app.server, f"{k[0]} q{k[1] + 1}") for k in RANGES}
    last: list[dict] = [{}, {}]

    def fire(i: int) -> None:
        rng = np.random.default_rng(100 + i)
        keys = list(RANGES)
        for n in range(200):
            k = keys[rng.integers(len(keys))]
            v = round(float(rng.uniform(*RANGES[k])), 1)
            clients[i].set(handles[k], v)
            last[i][k] = v
            if n % 10 == 0:
                time.sleep(0.005)

    threads = [threading.Thread(target=fire, args=(i,)) for i in (0, 1)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    _settled(app)
    t0 = time.time()  # a few more loop ticks: write-backs done (slower on a busy machine)
    while time.time() - t0 < 15 and not all(
            abs(h.value - round(math.degrees(app.q[side][j]), 1)) < 1e-9 for (side, j), h in handles.items()):
        time.sleep(0.05)
    try:
        for (side, j), h in handles.items():
            final = math.degrees(app.q[side][j])
            candidates = {last[0].get((side, j)), last[1].get((side, j))} - {None}
            assert any(abs(final - c) < 1e-9 for c in candidates), (side, j, final, candidates)
            assert h.value == pytest.approx(round(final, 1), abs=1e-9)
        for side in ("left", "right"):  # both hands still on their grasps
            G = app.T_object @ getattr(app.cell, f"grasp_{side}").T_object_hand
            np.testing.assert_allclose(_hand(app.cell, side, app.q[side]), G, atol=1e-9)
    finally:
        for c in clients:
            c.close()
    err = capfd.readouterr().err
    assert "Traceback" not in err
    assert not [r for r in caplog.records if r.levelno >= logging.ERROR]


@pytest.mark.parametrize("window", [0.0, 0.02])
def test_events_arriving_while_the_loop_writes_are_applied(window, monkeypatch):
    """The old loop raised a global 'syncing' flag while it wrote GUI values and dropped every user
    event arriving meanwhile (a user set 75.6 deg; slider and q ended at 60.6 deg). Here the loop
    runs flat out (this test's thread is the loop: step() without pause), so it is nearly always
    writing, and every value a client sends must land. A short GIL switch interval makes the
    server's event thread run often, and nearly always in the middle of a write (the loop never
    yields by itself); with the default 5 ms each event took seconds to be read.

    ``window``: viser stores a client's new value on the control, then runs the callback that reads
    it; a write-back made from the loop's thread could land in between, and the callback then
    recorded the loop's stale value as the user's (a CI run ended with 1.2 deg where 3.8 was sent).
    With ``window`` > 0 that gap is held open for so long after every store [s]."""
    interval = sys.getswitchinterval()
    sys.setswitchinterval(2e-4)
    a = ViewerApp(Cell.default(), port=0)
    if window:
        for k in RANGES:  # viser calls sync_cb after storing the value, before the callbacks
            impl = control(a.server, f"{k[0]} q{k[1] + 1}")._impl
            sync = impl.sync_cb

            def slow(client_id, updates, sync=sync):
                sync(client_id, updates)
                time.sleep(window)  # the loop's thread runs meanwhile

            monkeypatch.setattr(impl, "sync_cb", slow)
    stop = threading.Event()

    def loop() -> None:
        while not stop.is_set():
            a.step()

    t = threading.Thread(target=loop, daemon=True)
    t.start()
    c = Client(f"ws://127.0.0.1:{a.server.get_port()}")
    try:
        t0 = time.time()
        while len(a.server.get_clients()) < 1 and time.time() - t0 < 10:
            time.sleep(0.02)
        handles = {k: control(a.server, f"{k[0]} q{k[1] + 1}") for k in RANGES}
        rng = np.random.default_rng(3)
        for _ in range(6):
            sent = {k: round(float(rng.uniform(*r)), 1) for k, r in RANGES.items()}
            for k, v in sent.items():
                c.set(handles[k], v)
                time.sleep(0.01)

            def landed(sent=sent):
                return all(abs(math.degrees(a.q[side][j]) - v) < 1e-9 and abs(handles[(side, j)].value - v) < 1e-9
                           for (side, j), v in sent.items())

            t0 = time.time()  # a dropped event never lands; a busy machine only delays it
            while not landed() and time.time() - t0 < 15:
                time.sleep(0.05)
            for (side, j), v in sent.items():
                assert math.degrees(a.q[side][j]) == pytest.approx(v, abs=1e-9), (side, j)
                assert handles[(side, j)].value == pytest.approx(v, abs=1e-9)
    finally:
        stop.set()
        t.join(timeout=5)
        c.close()
        a.close()
        sys.setswitchinterval(interval)

