"""Value semantics for frozen dataclasses that hold numpy arrays.

A dataclass's generated ``==`` compares its fields as a tuple, which for an array field asks numpy
for the truth value of an element-wise comparison and raises ``ValueError``; its generated hash
raises ``TypeError``. The classes here that a user builds and compares (a cell and its parts, a
planning problem) use :func:`value_eq` and :func:`value_hash` instead: arrays are equal when their
shapes and elements are (exactly: ``save_cell`` -> ``load_cell`` gives the same floats), and
``a == b`` implies ``hash(a) == hash(b)`` (0.0 and -0.0 hash alike, as they compare equal).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

__all__ = ["value_eq", "value_hash"]


def _same(x: Any, y: Any) -> bool:
    if isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
        return (isinstance(x, np.ndarray) and isinstance(y, np.ndarray) and x.shape == y.shape
                and bool(np.array_equal(x, y)))
    if isinstance(x, (tuple, list)) and isinstance(y, (tuple, list)):
        return type(x) is type(y) and len(x) == len(y) and all(_same(a, b) for a, b in zip(x, y))
    return bool(x == y)


def _key(v: Any) -> Any:
    if isinstance(v, np.ndarray):
        return (v.shape, (v + 0).tobytes() if v.dtype.kind in "fc" else v.tobytes())  # -0.0 + 0 is 0.0
    if isinstance(v, (tuple, list)):
        return tuple(_key(x) for x in v)
    return v


def value_eq(a: Any, b: Any) -> Any:
    """``a == b`` for dataclass instances: the same class and every field equal (arrays element
    for element); ``NotImplemented`` for another class."""
    if type(a) is not type(b):
        return NotImplemented
    return all(_same(getattr(a, f.name), getattr(b, f.name)) for f in dataclasses.fields(a))


def value_hash(a: Any) -> int:
    """A hash consistent with :func:`value_eq` (``TypeError`` for a field that cannot be hashed,
    such as a dict in a :class:`~dualpuma.planning.Problem`)."""
    return hash((type(a).__qualname__, tuple(_key(getattr(a, f.name)) for f in dataclasses.fields(a))))
