"""Units at the user's edge. Inside, everything is SI (metres, radians, seconds), and so is the
text the planners and solvers put in a plan's ``reason`` and ``events`` (they are API values, and
``--json`` prints them as they are). Where a person reads that text (the viewer's messages and
event list, the CLI's human output) lengths are shown in millimetres, like every other number on
those surfaces: :func:`display_text`.
"""

from __future__ import annotations

import re

__all__ = ["below_text", "display_text"]

#: a length in metres as the planners write it: a decimal number, one space, "m", not part of a
#: word or of a compound unit ("m/s", "m^2", "mm")
_METRES = re.compile(r"(?<![\w.])(-?\d+(?:\.(\d+))?) m(?![\w/^²³])")
#: ... and a vector of them: "[0.7619, -0.1662, -0.4331] m" (an IK message's wrist centre)
_METRE_VECTOR = re.compile(r"\[(-?\d+(?:\.\d+)?(?:, -?\d+(?:\.\d+)?)*)\] m(?![\w/^²³])")
_NUMBER = re.compile(r"-?\d+(?:\.(\d+))?")


def display_text(text: str) -> str:
    """``text`` with every length written in metres ("0.0033 m") rewritten in millimetres
    ("3.3 mm"), keeping the precision that was written (three fewer decimals, none below zero).

    Everything else (words, degrees, seconds, file names without a metre value) is unchanged.
    """

    def number_mm(match: re.Match[str]) -> str:
        decimals = len(match.group(1) or "")
        return f"{float(match.group(0)) * 1000.0:.{max(decimals - 3, 0)}f}"

    def mm(match: re.Match[str]) -> str:
        return f"{_NUMBER.sub(number_mm, match.group(1))} mm"

    def vector_mm(match: re.Match[str]) -> str:
        return f"[{_NUMBER.sub(number_mm, match.group(1))}] mm"

    return _METRES.sub(mm, _METRE_VECTOR.sub(vector_mm, str(text)))


def below_text(value: float, limit: float, decimals: int = 4) -> str:
    """``value`` [m] written with ``decimals`` decimals, or more (up to 9) where that would round it
    to ``limit`` or above: a clearance just below a 20 mm margin reads "0.01997", not "0.0200"
    (which the CLI shows as "20.0 mm below 20 mm")."""
    d = decimals
    while d < 9 and float(f"{value:.{d}f}") >= limit > value:
        d += 1
    return f"{value:.{d}f}"
