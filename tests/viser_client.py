"""A viser client speaking viser's own WebSocket protocol (for tests that must act as a *client*:
security, concurrency, and defects of the callback wiring). It connects like a browser tab (same
Origin, viser's subprotocol), registers with a camera message, and sends GUI and gizmo updates
exactly as viser's web client does; a background thread reads what the server sends and keeps the
notifications addressed to this client."""

from __future__ import annotations

import threading
import time
from collections import Counter

import msgspec
import viser
import zstandard
from viser import _messages
from websockets.sync.client import connect

__all__ = ["Client", "control", "uuid_of"]


def uuid_of(handle) -> str:
    """The GUI handle's id on the wire."""
    return handle._impl.uuid


def control(server, label: str):
    """The input control a user sees labelled ``label`` (exactly one must exist)."""
    found = [h for h in server.gui._gui_input_handle_from_uuid.values() if h.label == label]
    if len(found) != 1:
        raise LookupError(f"{len(found)} controls labelled {label!r}")
    return found[0]


class Client:
    """One connected client of ``url`` (``ws://host:port``)."""

    def __init__(self, url: str, origin: str | None = "same", register: bool = True, **kw) -> None:
        http = url.replace("ws://", "http://")
        if origin == "same":
            kw["origin"] = http
        elif origin is not None:
            kw["origin"] = origin
        self.ws = connect(url, subprotocols=[f"viser-v{viser.__version__}"], proxy=None, open_timeout=10,
                          max_size=None, **kw)
        self.notifications: list[tuple[str, str]] = []
        self.received: Counter[str] = Counter()  # how many messages of each type the server sent
        self.poses: dict[str, dict[str, list[float]]] = {}  # scene node name -> its last "wxyz" / "position" sent
        self.toasts_shown = 0  # separate toasts on screen (an update of one is not a new one)
        self.closed: Exception | None = None
        self._lock = threading.Lock()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()
        if register:
            self.send(_messages.ViewerCameraMessage((1.0, 0.0, 0.0, 0.0), (3.0, 3.0, 3.0), 1.0, 0.01, 100.0, 600, 900,
                                                    (0.0, 0.0, 0.0), (0.0, 0.0, 1.0)))

    def _read(self) -> None:
        try:
            for raw in self.ws:
                try:  # viser's frames: sizes, zstd-compressed msgpack {"messages": [...]}, binary buffers
                    n, k = int.from_bytes(raw[:8], "little"), int.from_bytes(raw[8:16], "little")
                    msg = msgspec.msgpack.decode(zstandard.ZstdDecompressor().decompress(raw[16:16 + k], max_output_size=n))
                except (msgspec.DecodeError, zstandard.ZstdError, TypeError):
                    continue
                for m in msg.get("messages", []) if isinstance(msg, dict) else []:
                    with self._lock:
                        self.received[str(m.get("type") if isinstance(m, dict) else None)] += 1
                        if isinstance(m, dict) and m.get("type") in ("SetOrientationMessage", "SetPositionMessage"):
                            key = "wxyz" if m["type"] == "SetOrientationMessage" else "position"
                            self.poses.setdefault(str(m.get("name")), {})[key] = list(m.get(key, []))
                    if isinstance(m, dict) and m.get("type") in ("NotificationShowMessage", "NotificationUpdateMessage"):
                        p = m.get("props", {})  # a new toast, or new text in one on screen (both read)
                        with self._lock:
                            self.notifications.append((str(p.get("title")), str(p.get("body"))))
                            self.toasts_shown += m.get("type") == "NotificationShowMessage"
        except Exception as exc:  # noqa: BLE001 - the connection ended; remember how
            self.closed = exc

    def send(self, msg) -> None:
        self.ws.send(msgspec.msgpack.encode(msg.as_serializable_dict()))

    def send_raw(self, data: bytes) -> None:
        self.ws.send(data)

    def set(self, handle, value) -> None:
        """A control's new value (slider, number, text, checkbox, dropdown), or a button-group click."""
        self.send(_messages.GuiUpdateMessage(uuid_of(handle), {"value": value}))

    def click(self, handle) -> None:
        self.send(_messages.GuiUpdateMessage(uuid_of(handle), {"value": True}))

    def drag(self, name: str, phase: str, wxyz=(1.0, 0.0, 0.0, 0.0), position=(0.0, 0.0, 0.0)) -> None:
        """One phase of a gizmo drag on the scene node ``name``."""
        if phase == "start":
            self.send(_messages.TransformControlsDragStartMessage(name))
        elif phase == "update":
            self.send(_messages.TransformControlsUpdateMessage(name, tuple(wxyz), tuple(position)))
        else:
            self.send(_messages.TransformControlsDragEndMessage(name))

    def wait_notification(self, text: str, timeout: float = 10.0) -> tuple[str, str]:
        t0 = time.time()
        while time.time() - t0 < timeout:
            with self._lock:
                for n in self.notifications:
                    if text in n[0] or text in n[1]:
                        return n
            time.sleep(0.02)
        raise AssertionError(f"no notification containing {text!r}; got {self.notifications[-5:]}")

    def close(self) -> None:
        self.ws.close()
