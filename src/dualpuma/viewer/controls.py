"""GUI controls bound to intents: the only code that runs in viser's callbacks.

Every callback is ``async``: viser awaits it on its event loop right after storing the value the
client sent, so the value read from the event is exactly that message's (a pool thread reading it
later could see a newer one) and callbacks run in the order messages arrive. A callback whose
event has no client (``event.client is None``: the server itself set the value) records nothing —
that is how the loop's own write-backs are told apart from users, without any global flag.

:meth:`Controls.show` is the loop's write-back: it sets a control only when the value differs
from what the control holds, and only when no user intent for that control arrived after the
state being shown (``applied_seq``).
"""

from __future__ import annotations

import math
from typing import Any

from .intents import IntentQueue

__all__ = ["Controls"]


class Controls:
    """Registry of the viewer's controls by key (see the module docstring).

    Args:
        queue: where callbacks record intents.
        on_full: called with the client when the queue refuses an intent (flooding).
    """

    def __init__(self, queue: IntentQueue, on_full=None) -> None:
        self.queue = queue
        self.handles: dict[str, Any] = {}
        self.held: set[str] = set()  # controls whose user value is waiting to be applied: never written
        self._on_full = on_full

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

    def show(self, key: str, value: Any, applied_seq: int, tol: float = 1e-9) -> bool:
        """Write ``value`` to the control ``key`` (see the module docstring); True if written."""
        if key in self.held:
            return False
        h = self.handles[key]
        cur = h.value
        if isinstance(value, float) and isinstance(cur, (int, float)) and not isinstance(cur, bool):
            if math.isfinite(cur) and abs(cur - value) <= tol:
                return False
        elif cur == value:
            return False
        if self.touched_after(key, applied_seq):
            return False
        h.value = value
        return True
