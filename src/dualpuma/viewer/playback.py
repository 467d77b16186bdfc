"""Playing a plan at real speed, smoothly between its samples.

:class:`Playback` is built once per plan (in the planning worker, :meth:`Playback.from_plan`) and
then sampled by the loop at any time: joints are interpolated linearly between samples, the object
frame along the shortest SE(3) arc between the plan's object poses. Time runs at the plan's own
times (``plan.t``; a plan whose times do not increase is played at 0.1 s per step) times a speed
factor. When a plan carries a time-parameterised trajectory (an attribute ``trajectory`` with
arrays ``t``, ``q_left``, ``q_right``, as planned for timed plans) that trajectory is played
instead, the object following the left hand's grasp, and the clearance plot is indexed by time.

The clearance of every sample is part of the playback, so that the read-out, the plot and its
marker all show one set of numbers: for plan rows the plan's own ``clearance`` and ``pair`` — and
:attr:`Playback.mismatch` records how far the viewer's World disagrees with them (a plan checked
against other geometry than the cell shown).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ..lie import slerp

__all__ = ["DEFAULT_STEP_TIME", "Playback", "Sample"]

FloatArray = npt.NDArray[np.float64]

DEFAULT_STEP_TIME = 0.1  #: seconds per step for a plan without increasing times [s]


@dataclass(frozen=True, slots=True)
class Sample:
    """What is shown at one instant of a playback."""

    q_left: FloatArray
    q_right: FloatArray
    T_object: FloatArray
    t: float  # time [s]
    x: float  # position on the plot's x axis (step index, or time for a trajectory)
    step: int  # nearest sample index


def _trajectory(plan):
    """The plan's timed trajectory (t, q_left, q_right) if it has a usable one, else None."""
    tr = getattr(plan, "trajectory", None)
    if tr is None or callable(tr):
        return None
    try:
        t = np.asarray(tr.t, dtype=np.float64).reshape(-1)
        qL = np.asarray(tr.q_left, dtype=np.float64).reshape(-1, 6)
        qR = np.asarray(tr.q_right, dtype=np.float64).reshape(-1, 6)
    except (AttributeError, TypeError, ValueError):
        return None
    n = t.shape[0]
    if n < 2 or qL.shape[0] != n or qR.shape[0] != n or not (np.all(np.isfinite(t)) and np.all(np.diff(t) > 0)):
        return None
    if not (np.all(np.isfinite(qL)) and np.all(np.isfinite(qR))):
        return None
    return t, qL, qR


class Playback:
    """A plan ready to play (see the module docstring). Attributes are read-only arrays.

    Attributes:
        title: what the plan is ("routine 8", "plan to goal").
        plan: the :class:`~dualpuma.planning.Plan`.
        t: (N,) sample times [s], increasing.
        q_left, q_right: (N, 6) joints [rad].
        T_object: (N, 4, 4) object poses [m].
        clearance: (N,) [m]; ``pair``: the closest pair per sample.
        x: (N,) the plot's x values; ``x_label`` names them.
        timed: True when a trajectory is played.
        row_t: (R,) the time each row of the plan is reached [s] (R = the plan's rows).
        mismatch: largest |viewer's clearance - plan's| over the plan's rows [m] (0 if not checked).
    """

    def __init__(self, title: str, plan, t, q_left, q_right, T_object, clearance, pair, x, x_label: str,
                 timed: bool, mismatch: float = 0.0, row_t=None) -> None:
        self.title, self.plan, self.timed, self.x_label = title, plan, timed, x_label
        self.row_t = _ro(t if row_t is None else row_t)
        self.t, self.q_left, self.q_right = _ro(t), _ro(q_left), _ro(q_right)
        self.T_object, self.clearance, self.x = _ro(T_object), _ro(clearance), _ro(x)
        self.pair = tuple(pair)
        self.mismatch = float(mismatch)

    @classmethod
    def from_plan(cls, plan, title: str, world=None) -> Playback | None:
        """The playback of ``plan`` (None if it has no steps). With ``world``: the clearance of a
        trajectory's samples is computed, and the plan's recorded clearance is checked against it."""
        n = plan.T_world_object.shape[0]
        if n == 0:
            return None
        tr = _trajectory(plan)
        if tr is not None and world is not None:
            t, qL, qR = tr
            T = np.array([world.T_world_base["left"] @ world.arms["left"].fk(q) @ np.linalg.inv(world.T_object_hand["left"])
                          for q in qL])
            c, pair = [], []
            for i in range(len(t)):
                d, k = world.min_distance(qL[i], qR[i], T[i], float(t[i]))
                c.append(d)
                pair.append(world.pair_names[k])
            row_t = getattr(plan.trajectory, "row_times", None)
            if row_t is None or np.shape(row_t) != (n,):
                row_t = np.interp(np.arange(n), np.linspace(0, n - 1, len(t)), t)  # a stand-in without row times
            return cls(title, plan, t, qL, qR, T, c, pair, t - t[0], "t [s]", True, row_t=row_t)
        t = np.asarray(plan.t, dtype=np.float64)
        if n > 1 and not np.all(np.diff(t) > 0):
            t = np.arange(n) * DEFAULT_STEP_TIME
        mismatch = 0.0
        if world is not None:
            live = [world.min_distance(plan.q_left[i], plan.q_right[i], plan.T_world_object[i], float(plan.t[i]))[0]
                    for i in range(n)]
            mismatch = float(np.max(np.abs(np.asarray(live) - plan.clearance)))
        return cls(title, plan, t, plan.q_left, plan.q_right, plan.T_world_object, plan.clearance, plan.pair,
                   np.arange(n, dtype=float), "step", False, mismatch)

    @property
    def n(self) -> int:
        return int(self.t.shape[0])

    def margin(self, default: float) -> float:
        """The margin [m] the plan kept (its ``meta["margin"]``: routines 2, 5 and 8 keep 10 mm),
        else ``default`` (the cell's) for a plan that does not say."""
        m = self.plan.meta.get("margin") if isinstance(self.plan.meta, dict) else None
        if isinstance(m, (int, float)) and not isinstance(m, bool) and math.isfinite(m) and m >= 0.0:
            return float(m)
        return float(default)

    @property
    def t_end(self) -> float:
        return float(self.t[-1])

    @property
    def x_end(self) -> float:
        return float(self.x[-1])

    def row_at(self, time: float) -> int:
        """The last row of the plan reached at ``time`` [s] (0 .. the plan's steps)."""
        return int(np.clip(np.searchsorted(self.row_t, time + 1e-9, side="right") - 1, 0, len(self.row_t) - 1))

    def next_row_time(self, time: float, direction: int) -> float:
        """The time of the plan's next row after ``time`` (``direction`` +1) or the last one before
        it (-1), clamped to the first and last rows: the -1 / +1 buttons step by the plan's rows,
        also through a timed trajectory's samples (ten or more between two rows)."""
        r = self.row_t
        if direction > 0:
            k = int(np.searchsorted(r, time + 1e-9, side="right"))
        else:
            k = int(np.searchsorted(r, time - 1e-9, side="left")) - 1
        return float(r[int(np.clip(k, 0, len(r) - 1))])

    def time_at_x(self, x: float) -> float:
        """The time at plot position ``x`` (clamped to the playback)."""
        return float(np.interp(x, self.x, self.t))

    def time_at_step(self, i: int) -> float:
        return float(self.t[int(np.clip(i, 0, self.n - 1))])

    def step_at(self, time: float) -> int:
        """Index of the sample nearest to ``time``."""
        return int(np.clip(np.rint(np.interp(time, self.t, np.arange(self.n))), 0, self.n - 1))

    def sample(self, time: float) -> Sample:
        """The pose at ``time`` [s] (clamped to the playback), interpolated between samples."""
        tt = float(np.clip(time, self.t[0], self.t[-1]))
        i = int(np.clip(np.searchsorted(self.t, tt, side="right") - 1, 0, self.n - 1))
        if i >= self.n - 1:
            k = self.n - 1
            return Sample(self.q_left[k], self.q_right[k], self.T_object[k], float(self.t[k]), float(self.x[k]), k)
        s = (tt - self.t[i]) / (self.t[i + 1] - self.t[i])
        if s <= 0.0:
            return Sample(self.q_left[i], self.q_right[i], self.T_object[i], float(self.t[i]), float(self.x[i]), i)
        qL = self.q_left[i] + s * (self.q_left[i + 1] - self.q_left[i])
        qR = self.q_right[i] + s * (self.q_right[i + 1] - self.q_right[i])
        T = slerp(self.T_object[i], self.T_object[i + 1], np.array([s]))[0]
        x = float(self.x[i] + s * (self.x[i + 1] - self.x[i]))
        return Sample(qL, qR, T, tt, x, i if s < 0.5 else i + 1)


def _ro(a) -> FloatArray:
    arr = np.array(a, dtype=np.float64)
    arr.setflags(write=False)
    return arr
