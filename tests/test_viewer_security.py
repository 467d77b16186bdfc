"""Security of ``dualpuma serve`` (issue 14): who may connect, what a client may send, where files
go, and how the command treats hosts and ports. Clients here speak viser's own protocol."""

from __future__ import annotations

import http.client
import math
import re
import socket
import subprocess
import sys
import time

import msgspec
import numpy as np
import pytest
import viser
from viewer_checks import serve_process
from viewer_checks import wait as wait_until
from viser import _messages
from viser_client import Client, uuid_of
from websockets.exceptions import InvalidStatus
from websockets.sync.client import connect

from dualpuma.errors import FileError, ParameterError
from dualpuma.model import Cell
from dualpuma.viewer import DataDir, ViewerApp, check_listen, is_loopback
from dualpuma.viewer.datadir import MAX_NAME, file_name
from dualpuma.viewer.security import CLIENT_MESSAGES, MAX_TEXT, AccessPolicy, screen_message


@pytest.fixture()
def app(tmp_path):
    a = ViewerApp(Cell.default(), port=0, data_dir=tmp_path / "data")
    a.start()
    yield a
    a.close()


def url(app) -> str:
    return f"ws://127.0.0.1:{app.server.get_port()}"


def wait(cond, timeout=15.0, what="condition"):
    wait_until(cond, timeout, what)


def handshake(app, **kw) -> int:
    """HTTP status of a WebSocket handshake (101 = accepted)."""
    try:
        with connect(url(app), subprotocols=[f"viser-v{viser.__version__}"], proxy=None, open_timeout=5, **kw):
            return 101
    except InvalidStatus as exc:
        return exc.response.status_code


def raw_request(port: int, host: str, origin: str | None, upgrade: bool) -> int:
    """Status of a request with a spoofed Host header (a DNS-rebinding page's request)."""
    lines = ["GET / HTTP/1.1", f"Host: {host}"] + ([f"Origin: {origin}"] if origin else [])
    if upgrade:
        lines += ["Upgrade: websocket", "Connection: Upgrade", "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==",
                  "Sec-WebSocket-Version: 13", f"Sec-WebSocket-Protocol: viser-v{viser.__version__}"]
    with socket.create_connection(("127.0.0.1", port), timeout=5) as s:
        s.sendall(("\r\n".join(lines) + "\r\n\r\n").encode())
        return int(s.recv(200).split(b" ")[1])


# ---------------------------------------------------------------- who may connect
def test_a_foreign_origin_is_refused_the_own_origin_is_served(app):
    port = app.server.get_port()
    assert handshake(app, origin="http://evil.example") == 403
    assert handshake(app, origin=f"http://evil.example:{port}") == 403
    assert handshake(app, origin="null") == 403
    assert handshake(app, origin=f"http://localhost:{port}") == 403  # another origin than the page's
    assert handshake(app, origin=f"http://127.0.0.1:{port}") == 101
    assert handshake(app) == 101  # no Origin: not a browser page
    # DNS rebinding: the attacker's name resolves to us, Origin == Host == attacker's name
    assert raw_request(port, f"evil.example:{port}", f"http://evil.example:{port}", upgrade=True) == 403
    assert raw_request(port, f"evil.example:{port}", None, upgrade=False) == 403
    assert raw_request(port, f"127.0.0.1:{port}", None, upgrade=False) == 200
    c = http.client.HTTPConnection("127.0.0.1", port, timeout=5)
    c.request("GET", "/")
    assert c.getresponse().status == 200


def test_no_other_site_may_show_the_viewer_in_a_frame(app):
    """Without these headers a page on any site could lay the viewer in a transparent frame over its
    own and have the user click "record" or "save" (found by a reviewer in Chromium); the frame's
    WebSocket is same-origin, so the Origin check does not stop it."""
    port = app.server.get_port()
    for path in ("/", "/index.html", "/no-such-file"):
        c = http.client.HTTPConnection("127.0.0.1", port, timeout=5)
        c.request("GET", path)
        r = c.getresponse()
        assert r.getheader("X-Frame-Options") == "DENY", path
        assert r.getheader("Content-Security-Policy") == "frame-ancestors 'none'", path
    assert raw_request(port, f"evil.example:{port}", None, upgrade=False) == 403  # the refusal carries them too


def test_access_policy_names():
    p = AccessPolicy.for_host("127.0.0.1", ["robots.lab.example"])
    assert p.host_ok("127.0.0.1:8080") and p.host_ok("localhost:1") and p.host_ok("[::1]:8080")
    assert p.host_ok("ROBOTS.lab.example:8080") and not p.host_ok("evil.example:8080") and not p.host_ok(None)
    assert p.origin_ok(None, "x") and p.origin_ok("https://a:1", "a:1") and not p.origin_ok("ftp://a:1", "a:1")
    assert is_loopback("127.0.0.2") and is_loopback("::1") and not is_loopback("0.0.0.0")
    # what the host resolves to counts: 127.1 is loopback (it printed the network warning), and 0
    # listens everywhere like 0.0.0.0 (this machine's names were then refused: 403 to other machines)
    assert is_loopback("127.1") and not is_loopback("0") and not is_loopback("no-such-host.invalid")
    assert AccessPolicy.for_host("0").hosts == AccessPolicy.for_host("0.0.0.0").hosts - {"0.0.0.0"} | {"0"}


# ---------------------------------------------------------------- what a client may send
def test_saving_outside_the_data_directory_is_refused_and_the_server_keeps_serving(app, tmp_path):
    """'../x', '/tmp/x' and a 10 MB name: refused, nothing written, the server serves the others."""
    a, b = Client(url(app)), Client(url(app))
    try:
        wait(lambda: len(app.server.get_clients()) == 2, what="two clients")
        name, save = app.controls.handles["file_name"], app.controls.handles["file_action"]
        before = set(tmp_path.rglob("*"))
        outside = tmp_path / "x.json"
        for bad in ("../x", str(outside.with_suffix("")), "/tmp/x", "a/b", "..", "x" * (MAX_NAME + 1)):
            n = len(a.notifications)
            a.set(name, bad)
            a.set(save, "save")
            wait(lambda n=n: len(a.notifications) > n, what=f"the refusal of {bad!r}")
            assert "not saved" in a.notifications[-1][1] or "file name" in a.notifications[-1][1]
        assert not outside.exists() and not (tmp_path / "x").exists()
        assert set(tmp_path.rglob("*")) == before  # nothing written anywhere (not even the data dir)
        # a 10 MB name: the connection that sends it is closed; nothing is kept or written
        big = msgspec.msgpack.encode(_messages.GuiUpdateMessage(uuid_of(name), {"value": "y" * 10_000_000})
                                     .as_serializable_dict())
        a.send_raw(big)
        wait(lambda: a.closed is not None, what="the oversized message's connection to close")
        assert len(name.value) <= MAX_TEXT + 1 and set(tmp_path.rglob("*")) == before
        # the server keeps serving the other client
        b.set(app.controls.handles["joint.left.0"], 61.5)
        wait(lambda: abs(math.degrees(app.q["left"][0]) - 61.5) < 1e-9, what="the other client's slider")
        b.set(app.controls.handles["waypoints"], "record")  # (nothing empty is saved)
        b.set(name, "good")
        b.set(save, "save")
        wait(lambda: (app.data.root / "good.json").exists(), what="a good save")
    finally:
        a.close()
        b.close()


def test_an_oversized_string_is_refused_and_not_kept(app):
    c = Client(url(app))
    try:
        wait(lambda: len(app.server.get_clients()) == 1, what="client")
        h = app.controls.handles["file_name"]
        c.set(h, "z" * 100_000)  # under the 1 MB message limit: cut by the screen, refused by the viewer
        c.wait_notification("too long")
        wait(lambda: h.value == "waypoints", what="the text box to be restored")
        assert app.settings["file_name"] == "waypoints"
    finally:
        c.close()


def test_a_client_cannot_overwrite_a_handles_internals(app):
    c = Client(url(app))
    try:
        wait(lambda: len(app.server.get_clients()) == 1, what="client")
        h = app.controls.handles["joint.left.0"]
        c.send(_messages.GuiUpdateMessage(uuid_of(h), {"update_cb": []}))
        c.send(_messages.GuiUpdateMessage(uuid_of(h), {"value": 62.5, "min": -1000.0}))
        time.sleep(0.3)
        assert h.min == -160.0
        c.set(h, 62.0)  # the callbacks are still there
        wait(lambda: abs(math.degrees(app.q["left"][0]) - 62.0) < 1e-9, what="the slider")
    finally:
        c.close()


def test_screen_message_rules():
    enc = msgspec.msgpack.encode
    ok = enc({"type": "GuiUpdateMessage", "uuid": "u", "updates": {"value": 1.0}})
    assert screen_message(ok) == ok
    assert screen_message(enc({"type": "GuiUpdateMessage", "uuid": "u", "updates": {"value": 1, "x": 2}})) is None
    for bad in ({"a": 1}, [1.0, 2.0], None):
        assert screen_message(enc({"type": "GuiUpdateMessage", "uuid": "u", "updates": {"value": bad}})) is None
    assert screen_message(enc({"type": "ShareUrlRequest"})) is None
    assert screen_message(b"\xc1garbage") is None and screen_message("text") is None
    cut = msgspec.msgpack.decode(screen_message(enc({"type": "GuiUpdateMessage", "uuid": "u",
                                                     "updates": {"value": "a" * 50_000}})))
    assert len(cut["updates"]["value"]) == MAX_TEXT + 1

CAMERA = {"type": "ViewerCameraMessage", "wxyz": [1.0, 0.0, 0.0, 0.0], "position": [3.0, 3.0, 3.0], "fov": 1.0,
          "near": 0.01, "far": 100.0, "image_height": 600, "image_width": 900, "look_at": [0.0, 0.0, 0.0],
          "up_direction": [0.0, 0.0, 1.0]}


def test_only_the_kinds_of_message_the_viewer_uses_pass():
    """Every kind viser's web client can send (read from its sources) but the camera, GUI updates and
    the gizmo is dropped; a camera no browser has, a gizmo pose with NaN and a message nested too
    deeply to decode are dropped too (the last raised RecursionError in the handler)."""
    enc = msgspec.msgpack.encode
    assert screen_message(enc(CAMERA)) == enc(CAMERA)
    for kind in ("GuiFormDirtyMessage", "GuiFormSubmitMessage", "GuiButtonHoldMessage", "ScenePointerMessage",
                 "SceneNodeClickMessage", "SceneNodeDragMessage", "CommandTriggerMessage", "ShareUrlDisconnect",
                 "LocalStorageGetItemResponseMessage", "GetRenderResponseMessage", "FileTransferPart", "NoSuchMessage"):
        assert screen_message(enc({"type": kind, "uuid": "x"})) is None, kind
    for bad in ({"fov": 0.0}, {"fov": 3.2}, {"image_height": 0}, {"image_width": -5}, {"near": math.nan},
                {"position": [1.0, math.inf, 0.0]}, {"wxyz": [0.0, 0.0, 0.0, 0.0]}, {"look_at": [0.0, 0.0]},
                {"image_height": 10**9}, {"fov": True}):
        assert screen_message(enc({**CAMERA, **bad})) is None, bad
    gizmo = {"type": "TransformControlsUpdateMessage", "name": "/g", "wxyz": [1.0, 0.0, 0.0, 0.0],
             "position": [0.1, 0.2, 0.3], "owner": ""}
    assert screen_message(enc(gizmo)) == enc(gizmo)
    assert screen_message(enc({**gizmo, "position": [math.nan, 0.0, 0.0]})) is None
    assert screen_message(enc({**gizmo, "name": 3})) is None
    assert screen_message(b"\x91" * 200_000 + b"\x00") is None
    for kind in ([1], {"a": 1}, None, 3):  # not a name at all (an unhashable one raised TypeError)
        assert screen_message(enc({"type": kind})) is None


def test_screen_message_never_raises_on_any_message():
    """Whatever a client sends decodes to, the screen answers bytes or None (a list as the message
    type raised TypeError in it: an unhandled error in the connection's handler)."""
    from hypothesis import given, settings
    from hypothesis import strategies as st

    scalars = st.none() | st.booleans() | st.integers(-2**63, 2**64 - 1) | st.floats() | st.text(max_size=20)
    values = st.recursive(scalars, lambda c: st.lists(c, max_size=4) | st.dictionaries(st.text(max_size=8), c, max_size=4),
                          max_leaves=12)
    kinds = st.sampled_from(sorted(CLIENT_MESSAGES)) | values
    fields = st.dictionaries(st.sampled_from(["uuid", "updates", "wxyz", "position", "fov", "near", "far", "name",
                                              "image_height", "image_width", "look_at", "up_direction", "value"]),
                             values, max_size=8)

    @settings(max_examples=400, deadline=None, derandomize=True)
    @given(kind=kinds, rest=fields)
    def check(kind, rest):
        out = screen_message(msgspec.msgpack.encode({**rest, "type": kind}))
        assert out is None or isinstance(out, bytes)

    check()


def test_a_clients_form_messages_are_not_kept_for_later_clients(app):
    """viser re-broadcast a form's 'dirty' message to every client and kept each one for every
    client that connects later: 300 of them with a 1 MB id took the server from 244 to 835 MB and
    were all sent to the next browser (found by a reviewer)."""
    a = Client(url(app))
    try:
        wait(lambda: len(app.server.get_clients()) == 1, what="client")
        for k in range(5):
            a.send_raw(msgspec.msgpack.encode({"type": "GuiFormDirtyMessage", "uuid": f"{k}" + "x" * 100_000}))
        a.set(app.controls.handles["speed"], 1.5)  # after them on the same connection
        wait(lambda: app.settings["speed"] == 1.5, what="the speed")
        b = Client(url(app))
        try:
            wait(lambda: b.received["ReplayDoneMessage"] >= 1, what="the new client's replay")
            assert b.received["GuiFormDirtyMessage"] == 0 and a.received["GuiFormDirtyMessage"] == 0
        finally:
            b.close()
    finally:
        a.close()


def test_a_camera_no_browser_has_is_not_taken_and_framing_survives_one(app):
    """A client reporting a field of view of 0 or a window 0 px high: viser's aspect divided by zero
    in the framing after every cell load, and the loop's step failed for every client."""
    from types import SimpleNamespace

    from dualpuma.viewer.camera import FOV, fit_client

    c = Client(url(app))
    try:
        wait(lambda: len(app.server.get_clients()) == 1, what="client")
        c.send_raw(msgspec.msgpack.encode({**CAMERA, "fov": 0.0, "image_height": 0}))
        c.set(app.controls.handles["speed"], 1.5)
        wait(lambda: app.settings["speed"] == 1.5, what="the speed")
        cam = next(iter(app.server.get_clients().values())).camera
        assert cam.fov == 1.0 and cam.image_height == 600  # the registered camera, not the bad one
    finally:
        c.close()

    class Broken:  # a camera whose aspect divides by zero, as viser's does for a 0 px high window
        fov, position, look_at = 0.0, (3.0, 0.0, 0.0), (0.0, 0.0, 0.0)

        @property
        def aspect(self):
            return 1 / 0

    client = SimpleNamespace(camera=Broken(), atomic=lambda: __import__("contextlib").nullcontext())
    fit_client(client, [[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]])
    d = np.linalg.norm(np.subtract(client.camera.position, client.camera.look_at))
    assert math.isfinite(d) and d > 0.5 / math.tan(FOV / 2)  # framed with the initial camera's lens


def test_a_nan_speed_is_refused_and_the_loop_runs_routines_after(app):
    """A NaN speed then 'run routine' made every loop step raise."""
    c = Client(url(app))
    try:
        wait(lambda: len(app.server.get_clients()) == 1, what="client")
        c.set(app.controls.handles["speed"], float("nan"))
        c.wait_notification("not a finite number")
        assert app.settings["speed"] == 1.0
        c.click(app.controls.handles["run"])
        wait(lambda: app.plan is not None and not app.state.playing, timeout=60, what="routine 2 to play")
        assert app.plan.reached
        # the loop writes the status after the step that ended playback: wait for it, do not race it
        wait(lambda: app.routines.status.content.count("5/5") == 1, what="the status at the plan's last step")
    finally:
        c.close()


# ---------------------------------------------------------------- file names
@pytest.mark.parametrize("bad", ["../x", "/tmp/x", "a/b", "a\\b", "..", ".hidden", "x.txt", "", "x" * 61, "é", "a b",
                                 "nul\x00", 3, None])
def test_file_names_are_short_plain_names(bad):
    with pytest.raises(ParameterError):
        file_name(bad, ".json")


def test_a_file_swapped_for_a_link_after_its_check_is_not_read(tmp_path, monkeypatch):
    """The data directory checked a name with lstat and then opened it, following links: a script
    swapping a file and a link to an outside file read the outside file (found by a reviewer). The
    swap is simulated at the moment between: lstat sees the regular file, open meets the link."""
    import os

    from dualpuma.viewer import datadir

    d = DataDir(tmp_path / "d")
    d.write("race", ".json", b"inside")
    (tmp_path / "outside.json").write_bytes(b"outside")
    regular = os.lstat(d.root / "race.json")
    (d.root / "race.json").unlink()
    (d.root / "race.json").symlink_to(tmp_path / "outside.json")
    monkeypatch.setattr(datadir.os, "lstat", lambda p: regular)
    with pytest.raises(FileError, match="symbolic link"):
        d.read("race", ".json", 1000)


def test_a_huge_number_is_told_back_short():
    """1e308 in a box was told back with its 309 digits."""
    from dualpuma.viewer.intents import Refused, number

    assert number(1e308, "x [mm]", -10.0, 10.0, "mm") == (10.0, "x [mm]: 1e+308 mm is beyond the limit; clamped to 10.0 mm")
    with pytest.raises(Refused, match=r"^x: -1\.5e\+12 s is outside \[0\.01, 5\.0\] s$"):
        number(-1.5e12, "x", 0.01, 5.0, "s", clamp=False)


def test_names_are_shown_as_written_not_as_markup():
    """A file named ``&lt;b&gt;x.json`` (put in the data directory by hand) was listed as ``<b>x``:
    HTML entities were decoded."""
    from dualpuma.viewer.status import markdown_text

    assert markdown_text("&lt;b&gt;x *y* [z](u) <i>") == r"\&lt;b\&gt;x \*y\* \[z\](u) \<i\>"


def test_data_dir_writes_only_inside_and_keeps_files(tmp_path):
    d = DataDir(tmp_path / "d")
    assert d.names(".json") == [] and not d.root.exists()  # created on the first write, not before
    p = d.write("pick-1", ".json", b"{}")
    assert p == tmp_path / "d" / "pick-1.json" and file_name("pick-1.json", ".json") == "pick-1.json"
    with pytest.raises(Exception, match="exists"):
        d.write("pick-1", ".json", b"[]")
    assert p.read_bytes() == b"{}"
    (d.root / "link.json").symlink_to(tmp_path / "elsewhere.json")
    with pytest.raises(Exception, match="link"):
        d.write("link", ".json", b"x", overwrite=True)
    assert not (tmp_path / "elsewhere.json").exists() and d.names(".json") == ["pick-1.json"]


# ---------------------------------------------------------------- hosts and ports
def test_check_listen_ports_and_hosts():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        busy = s.getsockname()[1]
        with pytest.raises(ParameterError, match="already in use.*--port auto"):
            check_listen("127.0.0.1", busy)
    for bad in (70000, -1, "x", 1.5, True):
        with pytest.raises(ParameterError, match="--port"):
            check_listen("127.0.0.1", bad)
    t0 = time.time()
    with pytest.raises(ParameterError, match="cannot be resolved"):
        check_listen("no-such-host.invalid", 8080)
    with pytest.raises(ParameterError, match="not an address of this machine"):
        check_listen("203.0.113.7", 8080)
    assert time.time() - t0 < 20
    assert isinstance(check_listen("127.0.0.1", "auto"), int)


def _serve(*args, timeout=30):
    return subprocess.run([sys.executable, "-m", "dualpuma.cli", "serve", *args], capture_output=True, text=True,
                          timeout=timeout, check=False)


@pytest.mark.parametrize("args,expect", [(["--port", "70000"], "--port"), (["--port", "-1"], "--port"),
                                          (["--host", "no-such-host.invalid", "--port", "0"], "cannot be resolved")])
def test_serve_exits_2_quickly_on_bad_hosts_and_ports(args, expect):
    t0 = time.time()
    r = _serve(*args)
    assert r.returncode == 2 and expect in r.stderr and "Traceback" not in r.stderr
    assert time.time() - t0 < 25


def test_serve_on_a_port_in_use_says_so_and_auto_moves_on(tmp_path):
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        busy = s.getsockname()[1]
        r = _serve("--port", str(busy), "--data-dir", str(tmp_path))
        assert r.returncode == 2 and "already in use" in r.stderr and "--port auto" in r.stderr
    assert not (tmp_path / "x").exists()


def test_serve_on_the_network_warns(tmp_path):
    import signal

    proc = serve_process("--host", "0.0.0.0", "--port", "0", "--data-dir", str(tmp_path))
    try:
        line, t0 = "", time.time()
        while "dualpuma viewer: http://" not in line and time.time() - t0 < 60:
            line = proc.stdout.readline()
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=20)
        assert "WARNING" in err and "anyone who can reach this machine" in err and "docs/security.md" in err
        assert proc.returncode == 0
    finally:
        if proc.poll() is None:
            proc.kill()


def test_typed_text_is_shown_not_interpreted(app):
    """A name a client types comes back in messages: as text, never as markup or HTML."""
    c = Client(url(app))
    try:
        wait(lambda: len(app.server.get_clients()) == 1, what="client")
        c.set(app.controls.handles["file_name"], "<img src=x onerror=alert(1)>")
        c.set(app.controls.handles["file_action"], "save")
        c.wait_notification("not saved")
        wait(lambda: "not saved" in app.status.line.content, what="the status line")
        line = app.status.line.content
        assert "\\<img" in line and not re.search(r"(?<!\\)[<>`*_]", line)  # every markup character escaped
    finally:
        c.close()
