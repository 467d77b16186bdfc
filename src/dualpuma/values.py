"""Value semantics for frozen dataclasses that hold numpy arrays.

A dataclass's generated ``==`` compares its fields as a tuple, which for an array field asks numpy
for the truth value of an element-wise comparison and raises ``ValueError``; its generated hash
raises ``TypeError``. The public value classes that hold arrays (a cell and its parts, a planning
problem, the results of IK, clearance, planning searches and envelopes) use :func:`value_eq` and
:func:`value_hash` instead (:func:`value_class` puts them on a class): arrays are equal when their shapes and elements are (exactly:
``save_cell`` -> ``load_cell`` gives the same floats; NaN equals NaN, as a result computed twice
is the same result), and ``a == b`` implies ``hash(a) == hash(b)`` (0.0 and -0.0 hash alike, as
they compare equal, and every NaN alike).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

__all__ = ["value_class", "value_eq", "value_hash"]


def _same(x: Any, y: Any) -> bool:
    if isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
        if not (isinstance(x, np.ndarray) and isinstance(y, np.ndarray) and x.shape == y.shape):
            return False
        nan = x.dtype.kind in "fc" and y.dtype.kind in "fc"
        return bool(np.array_equal(x, y, equal_nan=nan))
    if isinstance(x, (tuple, list)) and isinstance(y, (tuple, list)):
        return type(x) is type(y) and len(x) == len(y) and all(_same(a, b) for a, b in zip(x, y))
    if isinstance(x, float) and isinstance(y, float) and math.isnan(x) and math.isnan(y):
        return True  # NaN: the same result
    return bool(x == y)


def _key(v: Any) -> Any:
    if isinstance(v, np.ndarray):
        if v.dtype.kind in "biufc":  # equal numbers hash alike whatever their dtype: as float64 (complex128)
            v = v.astype(np.complex128 if v.dtype.kind == "c" else np.float64)
            v = np.where(np.isnan(v), np.nan, v + 0)  # -0.0 + 0 is 0.0; one NaN
        return (v.shape, v.tobytes())
    if isinstance(v, (tuple, list)):
        return tuple(_key(x) for x in v)
    if isinstance(v, float) and math.isnan(v):
        return "nan"
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


def value_class(cls: type) -> type:
    """Class decorator, above ``@dataclass``: ``==`` and ``hash`` by value (:func:`value_eq`,
    :func:`value_hash`) in place of the dataclass's own, which fail on array fields."""
    cls.__eq__ = value_eq
    cls.__hash__ = value_hash
    return cls

