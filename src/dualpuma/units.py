"""Units at the user's edge. Inside, everything is SI (metres, radians, seconds), and so is the
text the planners and solvers put in a plan's ``reason`` and ``events`` (they are API values, and
``--json`` prints them as they are). Where a person reads that text (the viewer's messages and
event list, the CLI's human output) lengths are shown in millimetres and angles in degrees, like
every other number on those surfaces: :func:`display_text`.
"""

from __future__ import annotations

import math
import re

__all__ = ["below_text", "display_text"]

#: a value as the planners write it, a decimal number or a vector of them ("[0.7619, -0.1662] m"),
#: then one space and a unit that is not part of a word or of a compound unit ("m/s", "m^2", "rad/s")
#: (a number's exponent is part of it: "1e-05 rad" is not "05 rad"; nor is "run-2 rad" a value)
_NUM = r"-?\d+(?:\.\d+)?(?:[eE][+-]?\d+)?"
_VALUE = rf"(?<![\w.+-])({_NUM}|\[{_NUM}(?:, {_NUM})*\]) "
_UNIT_END = r"(?![\w/^²³])"
_NUMBER = re.compile(r"-?\d+(?:\.(\d+))?([eE][+-]?\d+)?")
#: unit written -> (unit shown, factor, decimals fewer than written)
_SHOWN = {"m": ("mm", 1000.0, 3), "rad": ("deg", 180.0 / math.pi, 2)}
_WRITTEN = re.compile(_VALUE + r"(m|rad)" + _UNIT_END)


def display_text(text: str) -> str:
    """``text`` with every length written in metres ("0.0033 m") rewritten in millimetres
    ("3.3 mm") and every angle written in radians ("0.6109 rad") in degrees ("35.00 deg"), vectors
    ("[0.7619, -0.1662] m") too, keeping the precision that was written (three fewer decimals for
    millimetres, two fewer for degrees, none below zero).

    Everything else (words, degrees and millimetres already, seconds, compound units such as
    "rad/s", file names) is unchanged.
    """

    def shown(match: re.Match[str]) -> str:
        unit, factor, fewer = _SHOWN[match.group(2)]

        def number(m: re.Match[str]) -> str:
            v = float(m.group(0)) * factor
            return f"{v:.3g}" if m.group(2) else f"{v:.{max(len(m.group(1) or '') - fewer, 0)}f}"

        return f"{_NUMBER.sub(number, match.group(1))} {unit}"

    return _WRITTEN.sub(shown, str(text))


def below_text(value: float, limit: float, decimals: int = 4) -> str:
    """``value`` [m] written with ``decimals`` decimals, or more (up to 9) where that would round it
    to ``limit`` or above: a clearance just below a 20 mm margin reads "0.01997", not "0.0200"
    (which the CLI shows as "20.0 mm below 20 mm")."""
    d = decimals
    while d < 9 and float(f"{value:.{d}f}") >= limit > value:
        d += 1
    return f"{value:.{d}f}"
