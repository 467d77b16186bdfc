"""`Trajectory`: a plan timed for execution (both arms' joints, velocities and accelerations at
sample times), with its plain-data (JSON) and array (NPZ) forms. Built by
:func:`dualpuma.planning.timing.time_plan`; carried by :attr:`Plan.trajectory`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ..errors import ParameterError

__all__ = ["TRAJECTORY_ARRAYS", "TRAJECTORY_FIELDS", "TRAJECTORY_SCALARS", "Trajectory"]

FloatArray = npt.NDArray[np.float64]

#: per-sample arrays (K rows) and their trailing shapes
TRAJECTORY_ARRAYS = {"t": (), "q_left": (6,), "q_right": (6,), "qd_left": (6,), "qd_right": (6,),
                     "qdd_left": (6,), "qdd_right": (6,)}
_OTHER_ARRAYS = {"row_times": (), "v_max": (12,), "a_max": (12,)}
#: every array field (the NPZ form stores each as ``trajectory_<name>``)
TRAJECTORY_FIELDS = (*TRAJECTORY_ARRAYS, *_OTHER_ARRAYS)
_TEXTS = ("reason", "limits_source", "method")
_MAX_TEXT = 100_000
#: scalar fields
TRAJECTORY_SCALARS = ("duration", "closure_tol", "closure_error", "velocity_ratio", "acceleration_ratio",
                      "min_clearance", "certified", "reason", "limits_source", "method", "start_delay", "time_scale",
                      "period")
#: scalars that files written before they existed lack, and their values then
_SCALAR_DEFAULTS = {"start_delay": 0.0, "time_scale": 1.0, "period": 0.0}


def _scalar(source: dict, name: str):
    """``source[name]``, or its default for a file written before the field existed (KeyError else)."""
    return source.get(name, _SCALAR_DEFAULTS[name]) if name in _SCALAR_DEFAULTS else source[name]


@dataclass(frozen=True, slots=True, eq=False)
class Trajectory:
    """A time-parameterised joint trajectory of both arms (one time law for both: the bar is never
    torn apart), sampled for execution.

    Attributes:
        t: (K,) sample times [s] (absolute: the plan's start time is ``t[0]``).
        q_left, q_right: (K, 6) joints [rad]; qd_*: velocities [rad/s]; qdd_*: accelerations [rad/s^2].
        row_times: (N,) the time at which each row of the plan is reached [s].
        v_max, a_max: (12,) the joint velocity [rad/s] and acceleration [rad/s^2] limits used (left
            arm then right arm).
        duration: ``t[-1] - t[0]`` [s].
        closure_tol: the closed-chain tolerance [m] (see :mod:`.timing`).
        closure_error: the largest closed-chain error measured at the samples and halfway between
            consecutive samples (joint-linear) [m].
        velocity_ratio, acceleration_ratio: the largest ``|qd| / v_max`` and ``|qdd| / a_max`` over
            the samples.
        min_clearance: the smallest clearance at the samples [m].
        certified: the joint-linear motion between consecutive samples keeps the planner's margin
            at the samples' times (:func:`~dualpuma.planning.certify.certify_chords`).
        reason: why it is not certified ("" when it is).
        limits_source: where ``v_max``/``a_max`` come from.
        method: how the time law was computed.
        start_delay: how long the arms wait at the first row before they move [s] (0 unless moving
            obstacles made the fastest timing unsafe: :func:`~dualpuma.planning.timing.time_plan`).
        time_scale: the time law runs this many times slower than the fastest one (>= 1; 1 unless
            moving obstacles made the fastest timing unsafe).
        period: the controller cycle the samples are on [s]: ``t[k] = t[0] + k period`` (0: sampled
            per piece, at most ``dt`` apart; see :mod:`~dualpuma.planning.schedule`).
    """

    t: FloatArray
    q_left: FloatArray
    q_right: FloatArray
    qd_left: FloatArray
    qd_right: FloatArray
    qdd_left: FloatArray
    qdd_right: FloatArray
    row_times: FloatArray
    v_max: FloatArray
    a_max: FloatArray
    duration: float
    closure_tol: float
    closure_error: float
    velocity_ratio: float
    acceleration_ratio: float
    min_clearance: float
    certified: bool
    reason: str = ""
    limits_source: str = ""
    method: str = ""
    start_delay: float = 0.0
    time_scale: float = 1.0
    period: float = 0.0

    def __post_init__(self) -> None:
        shapes = {**TRAJECTORY_ARRAYS, **_OTHER_ARRAYS}
        for name, tail in shapes.items():
            v = getattr(self, name)
            if isinstance(v, (str, bytes, dict)) or (isinstance(v, np.ndarray) and v.dtype.kind not in "biuf"):
                raise ParameterError(f"Trajectory.{name}: expected numbers of shape (K, *{tail})")
            try:
                with np.errstate(all="ignore"):
                    arr = np.array(v, dtype=np.float64).reshape((-1,) + tail)  # JSON null -> NaN
            except (TypeError, ValueError, OverflowError) as e:
                raise ParameterError(f"Trajectory.{name}: expected numbers of shape (K, *{tail}): {e}"[:300]) from None
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        k = self.t.shape[0]
        if any(getattr(self, a).shape[0] != k for a in TRAJECTORY_ARRAYS):
            raise ParameterError("Trajectory: every per-sample array needs the same number of rows")
        if self.v_max.shape[0] != 1 or self.a_max.shape[0] != 1:
            raise ParameterError("Trajectory: v_max and a_max need 12 values each")
        object.__setattr__(self, "v_max", self.v_max[0])
        object.__setattr__(self, "a_max", self.a_max[0])
        if not np.all(np.isfinite(self.t)) or np.any(np.diff(self.t) < 0):
            raise ParameterError("Trajectory.t: sample times must be finite and non-decreasing")
        for name in (*TRAJECTORY_ARRAYS, *_OTHER_ARRAYS):
            if not np.all(np.isfinite(getattr(self, name))):  # a file's samples go to a controller as they are
                raise ParameterError(f"Trajectory.{name}: contains NaN or inf")
        if np.any(self.v_max <= 0.0) or np.any(self.a_max <= 0.0):
            raise ParameterError("Trajectory: v_max and a_max must be positive")
        for name in TRAJECTORY_SCALARS:
            if name == "certified" or name in _TEXTS:
                continue
            v = getattr(self, name)
            if v is None:  # a non-finite number written as JSON null
                v = math.nan
            if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
                raise ParameterError(f"Trajectory.{name}: expected a number, got {type(v).__name__}")
            try:
                object.__setattr__(self, name, float(v))
            except OverflowError:
                raise ParameterError(f"Trajectory.{name}: beyond the float range") from None
        if not isinstance(self.certified, (bool, np.bool_)):
            raise ParameterError(f"Trajectory.certified: expected true or false, got {type(self.certified).__name__}")
        object.__setattr__(self, "certified", bool(self.certified))
        if not (0.0 <= self.start_delay < math.inf):
            raise ParameterError(f"Trajectory.start_delay: expected a finite delay >= 0 [s], got {self.start_delay}")
        if not (1.0 <= self.time_scale < math.inf):
            raise ParameterError(f"Trajectory.time_scale: expected a finite factor >= 1, got {self.time_scale}")
        if not (0.0 <= self.period < math.inf):
            raise ParameterError(f"Trajectory.period: expected a finite period >= 0 [s], got {self.period}")
        if self.period > 0.0 and k > 1:  # a promise to a controller: the samples are on its clock
            grid = self.t[0] + np.arange(k) * self.period
            slack = 1e-9 + 8.0 * np.finfo(float).eps * float(np.abs(self.t).max())
            if float(np.abs(self.t - grid).max()) > slack:
                raise ParameterError(f"Trajectory.t: the samples are not {self.period:g} s apart, as period says")
        for name in _TEXTS:
            v = getattr(self, name)
            if not isinstance(v, str) or len(v) > _MAX_TEXT:
                raise ParameterError(f"Trajectory.{name}: expected a string of at most {_MAX_TEXT} characters")
        self._check_consistent()

    def _check_consistent(self) -> None:
        """What the samples show agrees with what the trajectory says of them (a file could say
        anything): the duration; no joint moving faster between samples than its velocity limit
        allows; the stated velocity and acceleration ratios at least the samples' and at most 1; a
        certified trajectory within its closed-chain tolerance.

        Raises:
            ParameterError: naming the first disagreement.
        """
        t, k = self.t, self.t.shape[0]
        if abs(self.duration - (t[-1] - t[0])) > 1e-9 * max(1.0, abs(t[-1])):
            raise ParameterError(f"Trajectory.duration: {self.duration} s, but the samples span {t[-1] - t[0]} s")
        Q = np.hstack([self.q_left, self.q_right])
        if k > 1:  # between samples the mean speed is at most the largest, at most the limit
            dq, dt = np.abs(np.diff(Q, axis=0)), np.diff(t)[:, None]
            over = dq > self.v_max * dt * (1.0 + 1e-6) + 1e-9
            if over.any():
                i, j = (int(x) for x in np.argwhere(over)[0])
                raise ParameterError(f"Trajectory: joint {j % 6 + 1} of the {('left', 'right')[j // 6]} arm moves "
                                     f"{dq[i, j]:.6g} rad between samples {i} and {i + 1} ({dt[i, 0]:.6g} s apart), "
                                     f"faster than its v_max {self.v_max[j]:.6g} rad/s")
        for name, a, lim in (("velocity_ratio", np.hstack([self.qd_left, self.qd_right]), self.v_max),
                             ("acceleration_ratio", np.hstack([self.qdd_left, self.qdd_right]), self.a_max)):
            seen = float(np.max(np.abs(a) / lim)) if k else 0.0
            if not seen * (1.0 - 1e-9) <= getattr(self, name) <= 1.0 + 1e-9:
                raise ParameterError(f"Trajectory.{name}: {getattr(self, name)}, but the samples reach {seen:.6g} "
                                     "(and a trajectory keeps its limits: at most 1)")
        if self.certified and not self.closure_error <= self.closure_tol:
            raise ParameterError(f"Trajectory: certified with a closed-chain error {self.closure_error} m above its "
                                 f"closure_tol {self.closure_tol} m")

    @property
    def n_samples(self) -> int:
        """Number of samples K."""
        return int(self.t.shape[0])

    @property
    def retimed(self) -> str:
        """How the timing gives way to moving obstacles, in words ("" when it is the fastest one):
        the wait at the first row and the slowdown."""
        parts = ([f"waits {self.start_delay:.2f} s at the first row"] if self.start_delay > 0 else []) + (
            [f"runs {self.time_scale:g}x slower"] if self.time_scale > 1 else [])
        return f"{' and '.join(parts)} to let a moving obstacle pass" if parts else ""

    # ------------------------------------------------------------------ plain data
    def to_dict(self) -> dict:
        """Plain-data form (JSON-ready; floats round-trip exactly)."""
        d: dict = {k: getattr(self, k).tolist() for k in (*TRAJECTORY_ARRAYS, *_OTHER_ARRAYS)}
        d.update({k: getattr(self, k) for k in TRAJECTORY_SCALARS})
        return d

    @classmethod
    def from_dict(cls, d: dict) -> Trajectory:
        """Inverse of :meth:`to_dict`. Raises ParameterError on malformed data."""
        if not isinstance(d, dict):
            raise ParameterError("trajectory: expected an object")
        try:
            return cls(**{k: d[k] for k in (*TRAJECTORY_ARRAYS, *_OTHER_ARRAYS)},
                       **{k: _scalar(d, k) for k in TRAJECTORY_SCALARS})
        except (KeyError, TypeError, ValueError) as e:
            raise ParameterError(f"malformed trajectory data: {type(e).__name__}: {e}") from e

    # ------------------------------------------------------------------ arrays (NPZ)
    def to_arrays(self, prefix: str = "trajectory_") -> tuple[dict[str, FloatArray], dict]:
        """``({prefix + name: array}, {scalar name: value})`` for an NPZ file and its metadata."""
        arrays = {prefix + k: getattr(self, k) for k in (*TRAJECTORY_ARRAYS, *_OTHER_ARRAYS)}
        return arrays, {k: getattr(self, k) for k in TRAJECTORY_SCALARS}

    @classmethod
    def from_arrays(cls, arrays, scalars: dict, prefix: str = "trajectory_") -> Trajectory:
        """Inverse of :meth:`to_arrays`. Raises ParameterError on malformed data."""
        try:
            if not isinstance(scalars, dict):
                raise TypeError("the trajectory's scalars are not an object")
            return cls(**{k: np.asarray(arrays[prefix + k]) for k in (*TRAJECTORY_ARRAYS, *_OTHER_ARRAYS)},
                       **{k: _scalar(scalars, k) for k in TRAJECTORY_SCALARS})
        except (KeyError, TypeError, ValueError) as e:
            raise ParameterError(f"malformed trajectory arrays: {type(e).__name__}: {e}") from e

    def equals(self, other: object) -> bool:
        """Exact equality of every field."""
        if not isinstance(other, Trajectory):
            return False
        return (all(np.array_equal(getattr(self, k), getattr(other, k), equal_nan=True)
                    for k in (*TRAJECTORY_ARRAYS, *_OTHER_ARRAYS))
                and all(getattr(self, k) == getattr(other, k) or (getattr(self, k) != getattr(self, k)
                                                                   and getattr(other, k) != getattr(other, k))
                        for k in TRAJECTORY_SCALARS))
