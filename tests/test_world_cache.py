"""WorldCache (model/cache.py): shared objects are built once, also when a build asks for another
shared object (a reentrant lock: with a plain lock that nesting deadlocked, so callers had to build
inputs outside first), and per-thread objects are per thread."""

from __future__ import annotations

import threading

from dualpuma.model.cache import WorldCache


def test_a_shared_build_may_ask_for_another_shared_object():
    cache, calls = WorldCache(), []

    def inner():
        calls.append("inner")
        return 2

    def outer():
        calls.append("outer")
        return cache.shared("inner", inner) + 1

    result = []
    t = threading.Thread(target=lambda: result.append(cache.shared("outer", outer)), daemon=True)
    t.start()
    t.join(10.0)
    assert not t.is_alive(), "a nested shared() build deadlocked"
    assert result == [3] and cache.shared("outer", outer) == 3 and calls == ["outer", "inner"]


def test_shared_objects_are_built_once_across_threads_and_per_thread_ones_per_thread():
    cache, built = WorldCache(), []
    barrier = threading.Barrier(4)
    seen_shared, seen_local = [], []

    def work():
        barrier.wait()
        seen_shared.append(cache.shared("k", lambda: built.append(1) or object()))
        seen_local.append(cache.per_thread("b", object))

    threads = [threading.Thread(target=work) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(10.0)
    assert len(built) == 1 and len({id(x) for x in seen_shared}) == 1
    assert len({id(x) for x in seen_local}) == 4
