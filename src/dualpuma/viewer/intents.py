"""Intents: what a user asked for, recorded by GUI callbacks and applied by the viewer's loop.

A callback never touches the kinematic state. It records an :class:`Intent` — the control's key,
the value the event carried and the client that sent it — in the :class:`IntentQueue`, and
returns. The loop drains the queue in order (:meth:`IntentQueue.drain`), validates each value
(:func:`number`, :func:`choice`, :func:`flag`, :func:`text`: a bad value raises :class:`Refused`,
whose message the sender sees) and applies it. The queue remembers, per control, the sequence
number of the last intent recorded (:meth:`IntentQueue.last_seq`): the loop writes a value back
to a control only when no intent newer than the state it is writing is pending for it, so it
never overwrites what a user has just done.
"""

from __future__ import annotations

import math
import numbers
import threading
from collections import deque
from dataclasses import dataclass
from typing import Any

__all__ = ["COALESCED", "MAX_PENDING", "Intent", "IntentQueue", "Refused", "choice", "flag", "number", "text"]

MAX_PENDING = 4096  #: intents waiting at most; more are refused (a client flooding the server)
#: kinds of controls whose consecutive intents (same key, same client) collapse into the last one
COALESCED = frozenset({"input", "gizmo"})


class Refused(Exception):
    """An intent that is not applied; the message says why (millimetres and degrees)."""


@dataclass(frozen=True, slots=True)
class Intent:
    """One user action.

    Attributes:
        seq: position in the order of arrival (1, 2, ...).
        key: the control's key (e.g. ``"joint.left.4"``, ``"jog"``).
        value: the value the event carried (a control's new value; a button group's option;
            ``(phase, wxyz, position)`` for a gizmo); ``None`` for a plain button.
        client: the viser client that sent it (``None``: the server itself, e.g. a test).
        kind: ``"input"``, ``"button"`` or ``"gizmo"``.
    """

    seq: int
    key: str
    value: Any
    client: Any
    kind: str = "input"

    @property
    def client_id(self) -> int | None:
        return getattr(self.client, "client_id", None)


class IntentQueue:
    """Thread-safe FIFO of :class:`Intent` (any thread puts, the loop drains)."""

    def __init__(self, limit: int = MAX_PENDING) -> None:
        self._lock = threading.Lock()
        self._items: deque[Intent] = deque()
        self._limit = limit
        self._seq = 0
        self._last: dict[str, int] = {}

    def put(self, key: str, value: Any = None, client: Any = None, kind: str = "input") -> Intent | None:
        """Record an intent; None (not recorded) when :data:`MAX_PENDING` are already waiting."""
        with self._lock:
            if len(self._items) >= self._limit:
                return None
            self._seq += 1
            it = Intent(self._seq, key, value, client, kind)
            self._items.append(it)
            self._last[key] = self._seq
            return it

    def drain(self) -> list[Intent]:
        """Every waiting intent in order; consecutive ones of a coalesced kind from the same client
        for the same control collapse into the last (a slider drag applies its final value)."""
        with self._lock:
            items, self._items = list(self._items), deque()
        out: list[Intent] = []
        for it in items:
            prev = out[-1] if out else None
            if (prev is not None and it.kind in COALESCED and prev.kind == it.kind and prev.key == it.key
                    and prev.client_id == it.client_id and not _is_gizmo_edge(prev) and not _is_gizmo_edge(it)):
                out[-1] = it
            else:
                out.append(it)
        return out

    def last_seq(self, key: str) -> int:
        """Sequence number of the last intent recorded for ``key`` (0 if none)."""
        with self._lock:
            return self._last.get(key, 0)

    @property
    def pending(self) -> int:
        with self._lock:
            return len(self._items)


def _is_gizmo_edge(it: Intent) -> bool:
    return it.kind == "gizmo" and isinstance(it.value, tuple) and it.value and it.value[0] != "update"


def _fmt(v: float) -> str:
    """One decimal (mm, deg), more below 1 so that a limit such as 0.01 s is not shown as 0.0, and
    an exponent from a billion on (1e308 was shown with its 309 digits)."""
    if abs(v) >= 1e9:
        return f"{v:.3g}"
    return f"{v:.1f}" if abs(v) >= 1.0 or v == 0.0 else f"{v:.3g}"


def number(value: object, what: str, lo: float, hi: float, unit: str = "", *, clamp: bool = True) -> tuple[float, str]:
    """A finite number, clamped into [lo, hi] (or refused outside it when ``clamp`` is False).

    Returns:
        (value, note): ``note`` says what was clamped ("" if nothing).

    Raises:
        Refused: not a number, NaN or infinite, or (without ``clamp``) out of range.
    """
    u = f" {unit}" if unit else ""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise Refused(f"{what}: expected a number, got {type(value).__name__}")
    v = float(value)
    if not math.isfinite(v):
        raise Refused(f"{what}: {v} is not a finite number")
    if lo <= v <= hi:
        return v, ""
    if not clamp:
        raise Refused(f"{what}: {_fmt(v)}{u} is outside [{_fmt(lo)}, {_fmt(hi)}]{u}")
    c = min(max(v, lo), hi)
    return c, f"{what}: {_fmt(v)}{u} is beyond the limit; clamped to {_fmt(c)}{u}"


def choice(value: object, options: tuple[str, ...] | list[str], what: str) -> str:
    """One of ``options``.

    Raises:
        Refused: anything else.
    """
    if not isinstance(value, str) or value not in options:
        shown = repr(value)[:60]
        raise Refused(f"{what}: {shown} is not one of the choices")
    return value


def flag(value: object, what: str) -> bool:
    """A bool.

    Raises:
        Refused: anything else.
    """
    if not isinstance(value, bool):
        raise Refused(f"{what}: expected on/off, got {type(value).__name__}")
    return value


def text(value: object, what: str, max_len: int) -> str:
    """A string of at most ``max_len`` characters.

    Raises:
        Refused: not a string, or longer (the value is not kept).
    """
    if not isinstance(value, str):
        raise Refused(f"{what}: expected text, got {type(value).__name__}")
    if len(value) > max_len:
        raise Refused(f"{what}: {len(value)} characters is too long (at most {max_len}); not kept")
    return value
