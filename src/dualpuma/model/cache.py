"""Objects derived from a :class:`~dualpuma.model.world.World` and kept with it.

Other modules derive objects from a World that are worth keeping as long as the World lives: the
clearance kernel's tables and work buffers, the planner's bounds, coal data set up for margin
tests. They are stored in the World's :class:`WorldCache` (``world.cache``), an explicit object
the World owns, never as attributes of the World itself.
"""

from __future__ import annotations

import threading
import warnings
from collections.abc import Callable, Hashable
from typing import TypeVar

import coal
import numpy as np
import pinocchio as pin

__all__ = ["WorldCache", "history_free_data", "pin_box_support"]

_T = TypeVar("_T")
_MISSING = object()


class WorldCache:
    """Objects derived from one :class:`World`, built on first use and owned by it.

    * :meth:`shared` — one object for all threads, built once under a lock; it must not change
      after it is built (tables, bounds).
    * :meth:`per_thread` — one object per thread (work buffers, coal data with query state).

    A World's geometry never changes, so entries stay valid; :meth:`World.reset` renews the
    per-thread ones when coal keeps query history (see :attr:`World.history_free`).
    """

    def __init__(self) -> None:
        self._shared: dict[Hashable, object] = {}
        self._lock = threading.RLock()  # reentrant: a build may derive its inputs through shared() too
        self._local = threading.local()
        self._generation = 0

    def shared(self, key: Hashable, build: Callable[[], _T]) -> _T:
        """The object stored under ``key``, built by ``build()`` the first time (thread-safe; a
        build may itself ask for other shared objects)."""
        value = self._shared.get(key, _MISSING)
        if value is _MISSING:
            with self._lock:
                value = self._shared.get(key, _MISSING)
                if value is _MISSING:
                    value = self._shared[key] = build()
        return value  # type: ignore[return-value]

    def per_thread(self, key: Hashable, build: Callable[[], _T]) -> _T:
        """This thread's object under ``key``, built by ``build()`` on first use in the thread."""
        entries = getattr(self._local, "entries", None)
        if entries is None or entries[0] != self._generation:
            entries = self._local.entries = (self._generation, {})
        value = entries[1].get(key, _MISSING)
        if value is _MISSING:
            value = entries[1][key] = build()
        return value  # type: ignore[return-value]

    def renew(self) -> None:
        """Forget every thread's per-thread objects (each thread rebuilds its own on next use)."""
        self._generation += 1


def history_free_data(geom_model: pin.GeometryModel) -> tuple[pin.GeometryData, bool]:
    """A GeometryData with coal's warm start (the GJK guess cached from the previous query of each
    pair) turned off, so that every distance depends on the configuration only, bit for bit; and
    whether this coal version offers that switch (else queries keep history: see World.reset)."""
    gd = pin.GeometryData(geom_model)
    ok = True
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        for reqs in (gd.distanceRequests, gd.collisionRequests):
            if not len(reqs):
                continue
            # A fresh GeometryData holds one default request per pair (Pinocchio's constructor): the
            # first one switched, copied over all of them, is each one switched (the deprecated
            # setter warns on every call, which made the per-request loop a third of a World build).
            req = reqs[0]
            try:
                req.enable_cached_gjk_guess = False
            except AttributeError:
                ok = False
                continue
            reqs[:] = [req] * len(reqs)
    return gd, ok


def pin_box_support() -> None:
    """Fix the factor coal's box support function keeps from its first call in a process.

    coal 3.0's ``getShapeSupport(const Box*, ...)`` holds a tie-breaking factor in a function-local
    ``static`` (one per template instantiation), set by the direction of the first call in the
    process (coal-library/coal#894). Which query ran first then changes later box distances in their
    last bits: a capsule-box distance of ``mixed_puma_ur5`` read 0.03142843034439442 m in a fresh
    process and ...441 after a ``World(Cell.default()).clearance(...)``, so plans differed between
    processes (``plan_many``'s workers and ``plan``). These queries (a box against a sphere, a
    capsule and a box, each way round, every first direction with zeros) run when dualpuma is
    imported, first in any process that imports dualpuma before it queries coal itself, so every
    such process uses the same factors. Without effect once the factors are set (idempotent)."""
    far = coal.Transform3s(np.eye(3), np.array([2.0, 0.0, 0.0]))
    for other in (coal.Sphere(0.1), coal.Capsule(0.1, 0.5), coal.Box(0.5, 0.5, 0.5)):
        for a, b, ta, tb in ((coal.Box(1.0, 1.0, 1.0), other, coal.Transform3s(), far),
                             (other, coal.Box(1.0, 1.0, 1.0), far, coal.Transform3s())):
            coal.distance(a, ta, b, tb, coal.DistanceRequest(), coal.DistanceResult())


pin_box_support()
