"""The samples of a timed plan (used by :mod:`.timing`): its pieces' time laws (:mod:`.time_law`)
run one after the other from the plan's start time, after an optional wait at rest at the first
row and with an optional uniform slowdown, sampled in one of two ways:

* **per piece** (:func:`sample`, the default): each piece evenly, at most ``step`` apart, its first
  and last instants included (the rows where pieces meet are sampled at rest);
* **on a controller's clock** (:func:`sample` with ``on_clock``): every sample exactly ``step``
  after the previous one from the start time, as a joint controller with a fixed cycle (a servo
  loop at 250 Hz, 500 Hz, 1 kHz) consumes them; the last sample is the first grid instant at or
  after the end of the motion (at rest at the last row), so the pieces' ends need not fall on the
  grid.

A wait is sampled on the same grid from the start time whatever its length (:func:`wait_times`),
so a wait is a prefix of a longer one. Velocities are divided by the slowdown and accelerations by
its square, so a law within the limits stays within them.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from ..errors import ParameterError
from .time_law import evaluate, time_at

__all__ = ["sample", "total_duration", "wait_times"]

FloatArray = npt.NDArray[np.float64]


def total_duration(pieces, delay: float = 0.0, scale: float = 1.0) -> float:
    """How long [s] the pieces take one after the other, after ``delay`` [s], ``scale`` times slower."""
    return delay + scale * sum(float(law[2][-1]) for _, law, _ in pieces)


def wait_times(step: float, delay: float) -> FloatArray:
    """Times [s] of a wait of ``delay`` [s] from its start: every ``step`` [s], then ``delay`` (the
    same grid for every delay, so a wait is a prefix of a longer one)."""
    tw = np.arange(max(1, math.ceil(delay / step - 1e-9))) * step
    return np.append(tw[tw < delay], delay)


def sample(pieces, step: float, t0: float, delay: float = 0.0, scale: float = 1.0, on_clock: bool = False,
           max_samples: int | None = None):
    """Samples of the pieces (``(path, law, s_rows)``: a spline, its time law and its rows' path
    parameters) timed one after the other from ``t0`` [s]: after ``delay`` [s] at rest at the first
    row, each piece's law run ``scale`` (>= 1) times slower. Per piece at most ``step`` [s] apart,
    or ``on_clock`` exactly ``step`` apart from ``t0`` (the module docstring).

    Returns:
        ``(times (K,) [s], joints (K, dof) [rad], velocities [rad/s], accelerations [rad/s^2],
        the times the rows are reached (rows,) [s])``.

    Raises:
        ParameterError: more than ``max_samples`` samples would be needed.
    """
    total = total_duration(pieces, delay, scale)
    if max_samples is not None and total / step > max_samples:
        raise ParameterError(f"time_plan: the trajectory would take {total:.4g} s, more than {max_samples} samples "
                             f"{step:.3g} s apart: raise the joint limits (v_max, a_max) or the sampling period (dt or period)")
    if on_clock:
        return _on_clock(pieces, step, t0, delay, scale)
    Ts, Qs, Qd, Qdd, rows = [], [], [], [], [np.array([t0])]
    if delay > 0.0:  # at rest at the first row until t0 + delay (that instant starts the first piece)
        path, law, _ = pieces[0]
        tw = wait_times(step, delay)[:-1]
        _, q, _, _ = evaluate(path, law, np.zeros(1))
        Ts.append(t0 + tw)
        Qs.append(np.repeat(q, tw.size, axis=0))
        Qd.append(np.zeros((tw.size, q.shape[1])))
        Qdd.append(np.zeros((tw.size, q.shape[1])))
    offset = t0 + delay
    for k, (path, law, s_rows) in enumerate(pieces):
        dur = scale * float(law[2][-1])
        n = max(1, math.ceil(dur / step - 1e-9))
        t = np.linspace(0.0, dur, n + 1)
        if k:
            t = t[1:]  # the piece starts where the previous one stopped (at rest)
        _, q, qd, qdd = evaluate(path, law, t / scale)
        Ts.append(offset + t)
        Qs.append(q)
        Qd.append(qd / scale)
        Qdd.append(qdd / (scale * scale))
        rows.append(offset + scale * time_at(law, s_rows[1:]))
        offset += dur
    return np.concatenate(Ts), np.concatenate(Qs), np.concatenate(Qd), np.concatenate(Qdd), np.concatenate(rows)


def _on_clock(pieces, period: float, t0: float, delay: float, scale: float):
    """:func:`sample` on the grid ``t0 + k period``, k = 0 .. the first k at or after the end."""
    total = total_duration(pieces, delay, scale)
    tau = np.arange(max(0, math.ceil(total / period - 1e-9)) + 1) * period  # from t0
    path0, law0, _ = pieces[0]
    first = evaluate(path0, law0, np.zeros(1))[1]
    Q = np.empty((tau.size, first.shape[1]))
    Qd = np.zeros_like(Q)
    Qdd = np.zeros_like(Q)
    rows = [np.array([t0])]
    Q[tau < delay] = first  # the wait: at rest at the first row
    start = delay
    for k, (path, law, s_rows) in enumerate(pieces):
        dur = scale * float(law[2][-1])
        last = k == len(pieces) - 1
        sel = np.flatnonzero((tau >= start) & ((tau < start + dur) | last))
        local = np.minimum(tau[sel] - start, dur)
        _, q, qd, qdd = evaluate(path, law, local / scale)
        Q[sel] = q
        moving = tau[sel] - start < dur  # after the end of the last piece: at rest there
        Qd[sel[moving]] = qd[moving] / scale
        Qdd[sel[moving]] = qdd[moving] / (scale * scale)
        rows.append(t0 + start + scale * time_at(law, s_rows[1:]))
        start += dur
    return t0 + tau, Q, Qd, Qdd, np.concatenate(rows)
