"""Where the user sees what happened: a toast to the client that caused it, and a status line that
is always on screen (the control panel's title bar, via ``gui.set_panel_label``) plus the last
message under it (a line above the tabs).

Every refusal, clamp, error, save and plan result goes through :meth:`Status.tell`; a later
action replaces the line, so it never shows a stale message next to a newer one. Messages are
plain text (never HTML: a file name a client typed is shown, not interpreted), at most
:data:`MAX_MESSAGE` characters.
"""

from __future__ import annotations

import logging
import time
from collections import deque

import viser

__all__ = ["LEVELS", "MAX_MESSAGE", "TOAST_MERGE", "Status", "markdown_text"]

log = logging.getLogger("dualpuma.viewer")

MAX_MESSAGE = 400  #: longest message shown [characters]
#: a toast like the last one (same title) to the same client within this long of it replaces its
#: text instead of stacking another [s]: a joint slider dragged where the other arm cannot follow
#: was refused at every value, and a dozen toasts covered the 3-D view
TOAST_MERGE = 1.5
#: level -> (toast colour, toast seconds, prefix on the message line)
LEVELS = {
    "info": ("blue", 3.0, ""),
    "ok": ("green", 3.0, "✓ "),
    "warn": ("orange", 6.0, "⚠ "),
    "error": ("red", 8.0, "✗ "),
}


def markdown_text(s: object, limit: int = MAX_MESSAGE) -> str:
    """``s`` as literal text inside viser's markdown: no markup, no HTML, one line, at most ``limit``
    characters (file names, cell names, planner events are shown, never interpreted)."""
    s = " ".join(str(s).split())
    if len(s) > limit:
        s = s[: limit - 1] + "…"
    for ch in "\\`*_[]<>#|~&":  # & too: "&lt;b&gt;" in a file name was shown as <b>
        s = s.replace(ch, "\\" + ch)
    return s


class Status:
    """The status line and toasts of one server (see the module docstring)."""

    def __init__(self, server: viser.ViserServer, line) -> None:
        self.server = server
        self.line = line  # a markdown handle above the tabs
        self.message = ""
        self.level = "info"
        self.history: deque[tuple[float, str, str]] = deque(maxlen=50)
        self._summary = ""
        self._toasts: dict[object, tuple[str, object, float, float]] = {}  # client id -> (title, handle, shown, last)

    def tell(self, text: str, level: str = "info", client=None, title: str | None = None, toast: bool = True) -> None:
        """Show ``text``: a toast to ``client`` (every connected client when None), and the line."""
        text = str(text)[: 4 * MAX_MESSAGE]
        self.message, self.level = text, level
        self.history.append((time.time(), level, text))
        colour, seconds, prefix = LEVELS.get(level, LEVELS["info"])
        self.line.content = f"{prefix}{markdown_text(text)}"
        if not toast:
            return
        head = title or {"info": "dualpuma", "ok": "Done", "warn": "Refused", "error": "Error"}[level]
        clients = [client] if client is not None else list(self.server.get_clients().values())
        body, now = markdown_text(text).replace("\\", ""), time.monotonic()
        for c in clients:
            try:
                last = self._toasts.get(c.client_id)
                # the same kind of toast again, soon after the last and while it is still on screen
                if last is not None and last[0] == head and now - last[3] < TOAST_MERGE and now - last[2] < seconds - TOAST_MERGE:
                    last[1].body = body
                    self._toasts[c.client_id] = (head, last[1], last[2], now)
                    continue
                handle = c.add_notification(head, body, auto_close_seconds=seconds, color=colour)
                self._toasts[c.client_id] = (head, handle, now, now)
            except Exception as exc:  # noqa: BLE001 - a client that just left: nothing to show
                log.debug("notification not shown: %s", exc)

    def summary(self, text: str) -> None:
        """The always-visible short status (title bar); sent only when it changes."""
        if text != self._summary:
            self._summary = text
            self.server.gui.set_panel_label(text)
