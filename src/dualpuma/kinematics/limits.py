"""Joint limits: checking them, and choosing among equivalent joint angles (q + 2 pi k) the one
inside the limits nearest to a reference (revolute joints whose range exceeds a turn, like the
PUMA's q4 and q6, have several)."""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from ..checks import as_array
from ..errors import JointError

__all__ = ["LIMIT_TOL", "check_limits", "wrap", "wrap_rows"]

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

LIMIT_TOL = 1e-12  #: a joint this far outside a limit still counts as inside [rad]
_TWO_PI = 2.0 * math.pi


def check_limits(limits: npt.ArrayLike) -> FloatArray:
    """Joint limits as a float64 (6, 2) array [rad] (lower, upper per joint).

    Raises:
        JointError: not finite numbers of shape (6, 2) with lower <= upper.
    """
    lim = as_array(limits, "limits", JointError)
    if lim.shape != (6, 2) or not np.all(np.isfinite(lim)) or not np.all(lim[:, 0] <= lim[:, 1]):
        raise JointError(f"limits: expected finite shape (6, 2) with lower <= upper [rad], got shape {lim.shape}")
    return lim


def wrap(theta: FloatArray, ref: FloatArray, lo: float, hi: float) -> tuple[FloatArray, BoolArray]:
    """Equivalent angle theta + 2 pi k inside [lo, hi], nearest to ``ref``; and an inside mask.

    For ranges narrower than a turn there is at most one such angle, and where there is none the
    equivalent nearest the range is returned (q5 = -122.3 deg for [-100, 100] deg, not 237.7); wider
    ranges (q4, q6 of the PUMA) take the one nearest to ``ref`` clipped into the limits (a reference
    outside the limits, e.g. q4 = 20 rad, still gives an angle inside them). The mask is False for an
    angle that is not inside (NaN included)."""
    if hi - lo < _TWO_PI:  # in [lo - tol, lo + 2 pi - tol): angles within tol below lo stay put
        base = theta - _TWO_PI * np.floor((theta - lo + LIMIT_TOL) * (1.0 / _TWO_PI))
        inside = base <= hi + LIMIT_TOL
        # outside: the equivalent nearest the range (below lo rather than far above hi)
        below = base - _TWO_PI
        return np.where(~inside & (lo - below < base - hi), below, base), inside
    r = np.clip(ref, lo, hi)
    best = theta - _TWO_PI * np.round((theta - r) * (1.0 / _TWO_PI))
    best = np.where(best > hi + LIMIT_TOL, best - _TWO_PI, best)
    best = np.where(best < lo - LIMIT_TOL, best + _TWO_PI, best)
    return best, (best >= lo - LIMIT_TOL) & (best <= hi + LIMIT_TOL)


def wrap_rows(rows: list[list[float]], ref: list[float], lo: list[float], hi: list[float]) -> list[bool]:
    """:func:`wrap` of joint vectors in place (plain floats); per row, True if inside the limits."""
    narrow = [(j, lo[j] - LIMIT_TOL, hi[j] + LIMIT_TOL) for j in range(6) if hi[j] - lo[j] < _TWO_PI]
    # wide ranges: the reference clipped into the limits is the same for every row
    wide = [(j, lo[j] - LIMIT_TOL, hi[j] + LIMIT_TOL, min(max(ref[j], lo[j]), hi[j]))
            for j in range(6) if hi[j] - lo[j] >= _TWO_PI]
    out = []
    for row in rows:
        ok = True
        for j, lo_t, hi_t in narrow:
            th = row[j]
            if not lo_t <= th <= hi_t:
                th -= _TWO_PI * math.floor((th - lo_t) / _TWO_PI)
                if th > hi_t:  # outside: the equivalent nearest the range
                    ok = False
                    if lo[j] - (th - _TWO_PI) < th - hi[j]:
                        th -= _TWO_PI
                row[j] = th
        for j, lo_t, hi_t, r in wide:
            th = row[j]
            th -= _TWO_PI * round((th - r) / _TWO_PI)
            th = th - _TWO_PI if th > hi_t else th + _TWO_PI if th < lo_t else th
            ok = ok and lo_t <= th <= hi_t
            row[j] = th
        out.append(ok)
    return out
