"""GUI controls bound to intents: the only code that runs in viser's callbacks.

Every callback is ``async``: viser awaits it on its event loop right after storing the value the
client sent, so the value read from the event is exactly that message's (a pool thread reading it
later could see a newer one) and callbacks run in the order messages arrive. A callback whose
event has no client (``event.client is None``: the server itself set the value) records nothing —
that is how the loop's own write-backs are told apart from users, without any global flag.

:meth:`Controls.show` is the loop's write-back: it sets a control only when the value differs
from what the control holds, and only when no user intent for that control arrived after the
state being shown (``applied_seq``). The writes are made on viser's event loop
(:meth:`Controls.flush`, once per loop step, waiting for them): there a client's new value is
stored and its callback reads it in one stretch, so a write-back can never land between the two.
Written from the loop's own thread, one could: the callback then read the loop's stale value and
recorded it as the user's, and the value the user sent was lost.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import logging
import math
from typing import Any

from .intents import IntentQueue

__all__ = ["Controls"]

log = logging.getLogger(__name__)

FLUSH_TIMEOUT = 5.0  #: [s] the loop waits at most this long for its write-backs (skipped, shown next step)


class Controls:
    """Registry of the viewer's controls by key (see the module docstring).

    Args:
        queue: where callbacks record intents.
        loop: viser's event loop (``server.get_event_loop()``), where write-backs are made; None:
            in the calling thread (no server).
        on_full: called with the client when the queue refuses an intent (flooding).
    """

    def __init__(self, queue: IntentQueue, loop: asyncio.AbstractEventLoop | None = None, on_full=None) -> None:
        self.queue = queue
        self.handles: dict[str, Any] = {}
        self.held: set[str] = set()  # controls whose user value is waiting to be applied: never written
        self._loop = loop
        self._on_full = on_full
        self._writes: list[tuple[str, Any, int, float]] = []  # shown since the last flush

    def _put(self, key: str, value: Any, client: Any, kind: str) -> None:
        if self.queue.put(key, value, client, kind) is None and self._on_full is not None:
            self._on_full(client)

    def input(self, key: str, handle):
        """Bind an input (slider, number, text, checkbox, dropdown): intent = its new value."""
        self.handles[key] = handle

        async def changed(event) -> None:
            if event.client is None:
                return
            self._put(key, event.target.value, event.client, "input")

        handle.on_update(changed)
        return handle

    def button(self, key: str, handle, value: Any = None):
        """Bind a button: intent = ``value``."""
        self.handles[key] = handle

        async def clicked(event) -> None:
            if event.client is None:
                return
            self._put(key, value, event.client, "button")

        handle.on_click(clicked)
        return handle

    def group(self, key: str, handle):
        """Bind a button group: intent = the clicked option."""
        self.handles[key] = handle

        async def clicked(event) -> None:
            if event.client is None:
                return
            self._put(key, event.target.value, event.client, "button")

        handle.on_click(clicked)
        return handle

    def gizmo(self, key: str, handle):
        """Bind transform controls: intent = ``(phase, wxyz, position)`` of the drag."""
        self.handles[key] = handle

        async def dragged(event) -> None:
            if event.client is None:
                return
            t = event.target
            self._put(key, (event.phase, tuple(float(v) for v in t.wxyz), tuple(float(v) for v in t.position)),
                      event.client, "gizmo")

        handle.on_update(dragged)
        return handle

    def touched_after(self, key: str, applied_seq: int) -> bool:
        """True if a user intent for ``key`` arrived after the state of ``applied_seq``."""
        return self.queue.last_seq(key) > applied_seq

    def show(self, key: str, value: Any, applied_seq: int, tol: float = 1e-9) -> None:
        """Write ``value`` to the control ``key`` at the next :meth:`flush` (see the module
        docstring), if it is still to be written then."""
        if self._due(key, value, applied_seq, tol):  # (most controls hold their value already)
            self._writes.append((key, value, applied_seq, tol))

    def flush(self) -> None:
        """Make the write-backs shown since the last flush on viser's event loop, and wait for them."""
        writes, self._writes = self._writes, []
        loop = self._loop
        if not writes:
            return
        try:
            here = asyncio.get_running_loop()
        except RuntimeError:
            here = None
        if loop is None or here is loop or not loop.is_running():
            self._write(writes)  # no server, or already on its loop
            return
        fut = asyncio.run_coroutine_threadsafe(self._write_async(writes), loop)
        try:
            fut.result(timeout=FLUSH_TIMEOUT)
        except concurrent.futures.TimeoutError:
            fut.cancel()
            log.warning("control write-backs waited %.0f s for the server's event loop; shown next step", FLUSH_TIMEOUT)

    async def _write_async(self, writes: list[tuple[str, Any, int, float]]) -> None:
        self._write(writes)

    def _write(self, writes: list[tuple[str, Any, int, float]]) -> None:
        for key, value, applied_seq, tol in writes:
            if self._due(key, value, applied_seq, tol):
                self.handles[key].value = value

    def _due(self, key: str, value: Any, applied_seq: int, tol: float) -> bool:
        """Is ``value`` still to be written to ``key``: not held, different from what the control
        holds, and no user intent for it arrived after the state of ``applied_seq``?"""
        if key in self.held:
            return False
        cur = self.handles[key].value
        if isinstance(value, float) and isinstance(cur, (int, float)) and not isinstance(cur, bool):
            if math.isfinite(cur) and abs(cur - value) <= tol:
                return False
        elif cur == value:
            return False
        return not self.touched_after(key, applied_seq)
