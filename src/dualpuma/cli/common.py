"""Argument parsing shared by the subcommands (the UI edge: millimetres and degrees come in here)."""

from __future__ import annotations

import numpy as np

from ..errors import ParameterError

__all__ = ["floats"]


def floats(text: str, n: int, what: str) -> np.ndarray:
    """``n`` numbers from a string such as ``"10 20 30"`` or ``"10,20,30"``.

    Raises:
        ParameterError: not ``n`` numbers.
    """
    try:
        vals = [float(v) for v in text.replace(",", " ").split()]
    except ValueError:
        raise ParameterError(f"{what}: expected {n} numbers, got {text!r}") from None
    if len(vals) != n:
        raise ParameterError(f"{what}: expected {n} numbers, got {len(vals)}")
    return np.array(vals)
