"""`Plan`: the frozen result of a planner run, with JSON and NPZ export/import.

A plan holds one row per step, the first row being the start. Poses are object frames in the world
(4, 4) [m]; joints are radians; clearance is the minimum signed distance over all checked pairs
[m]; ``t`` is each step's time [s] (for moving obstacles).

The file forms and the checks of plans read back are in :mod:`.plan_io`: JSON is strict (a
non-finite number is written as ``null`` and read back as NaN); every plan read back is checked
(a ``reached`` plan with NaN joints or a pose that is not rigid is refused).
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field, fields
from pathlib import Path

import numpy as np
import numpy.typing as npt

from ..checks import as_array, choice, flag, instance, integer, real, text
from ..errors import ParameterError
from ..files import atomic_write, read_limited
from .plan_io import (
    ARRAYS,
    FORMAT,
    MAX_PLAN_BYTES,
    SCALARS,
    STATUSES,
    fields_from_dict,
    fields_from_npz,
    json_safe,
    npz_bytes,
)
from .trajectory import Trajectory

__all__ = ["STATUSES", "Plan", "chain"]

FloatArray = npt.NDArray[np.float64]


def _is_inf(v: object) -> bool:
    return isinstance(v, (float, np.floating)) and bool(np.isinf(v))


def _frozen(a: npt.ArrayLike, shape_tail: tuple[int, ...], name: str) -> FloatArray:
    arr = as_array(a, name)
    if arr.ndim == 0 or arr.shape[1:] != shape_tail:
        raise ParameterError(f"{name}: expected shape (N,) + {shape_tail}, got {arr.shape}")
    arr = arr.copy()
    arr.setflags(write=False)
    return arr


def _pairs(pair: object) -> tuple[tuple[str, str], ...]:
    try:
        return tuple((str(a), str(b)) for a, b in pair)  # type: ignore[attr-defined]
    except (TypeError, ValueError):
        raise ParameterError("pair: expected one (name, name) per step") from None


@dataclass(frozen=True, slots=True, eq=False)
class Plan:
    """Result of :func:`dualpuma.planning.plan` (or a routine).

    Attributes:
        status: one of :data:`STATUSES` (``reached`` = the goal pose is the last step).
        reason: why it stopped when not reached ("" when reached).
        T_world_object: (N, 4, 4) object poses, row 0 = start [m].
        q_left, q_right: (N, 6) joints [rad].
        clearance: (N,) minimum signed distance [m].
        pair: per step the two geometry names achieving ``clearance``.
        t: (N,) times [s].
        events: human-readable log ("step 14: refused (bar – obstacle/box 0.012 m), took AP2").
        path_length: translation path length of the object origin [m].
        planning_time: wall time of the planner [s].
        planner: ``striving``, ``striving+rrt``, ``robmov`` (taught joint path), ...
        meta: free-form data (the planners record the ``margin`` they kept) [SI units].
        trajectory: the plan timed for execution (:func:`dualpuma.planning.time_plan`), or None.
    """

    status: str
    reason: str
    T_world_object: FloatArray
    q_left: FloatArray
    q_right: FloatArray
    clearance: FloatArray
    pair: tuple[tuple[str, str], ...]
    t: FloatArray
    events: tuple[str, ...] = ()
    path_length: float = 0.0
    planning_time: float = 0.0
    planner: str = "striving"
    meta: dict = field(default_factory=dict)
    trajectory: Trajectory | None = None

    def __post_init__(self) -> None:
        choice(self.status, STATUSES, "status")
        for name, tail in (("T_world_object", (4, 4)), ("q_left", (6,)), ("q_right", (6,)), ("clearance", ()), ("t", ())):
            object.__setattr__(self, name, _frozen(getattr(self, name), tail, name))
        n = self.T_world_object.shape[0]
        object.__setattr__(self, "pair", _pairs(self.pair))
        if any(getattr(self, a).shape[0] != n for a in ARRAYS) or len(self.pair) != n:
            raise ParameterError("Plan: every per-step array (and pair) needs the same number of rows")
        if isinstance(self.events, (str, bytes)) or not isinstance(self.events, (tuple, list)):
            raise ParameterError(f"events: expected a sequence of strings, got {type(self.events).__name__}")
        object.__setattr__(self, "events", tuple(str(e) for e in self.events))
        for name in ("path_length", "planning_time"):
            object.__setattr__(self, name, real(getattr(self, name), name, nan_ok=True)
                               if not _is_inf(getattr(self, name)) else float(getattr(self, name)))
        text(self.reason, "reason", max_len=100_000)
        text(self.planner, "planner")
        if not isinstance(self.meta, dict):
            raise ParameterError(f"meta: expected a dict, got {type(self.meta).__name__}")
        if self.trajectory is not None and not isinstance(self.trajectory, Trajectory):
            raise ParameterError(f"trajectory: expected a Trajectory or None, got {type(self.trajectory).__name__}")
        tr = self.trajectory
        if tr is not None and n and tr.n_samples:  # timed from these rows: it starts with them, passes each
            rt = tr.row_times
            if rt.shape[0] != n or abs(tr.t[0] - self.t[0]) > 1e-9 * max(1.0, abs(self.t[0])) or np.any(np.diff(rt) < 0) \
                    or rt[0] < tr.t[0] - 1e-9 or rt[-1] > tr.t[-1] + 1e-9:
                raise ParameterError("trajectory: its sample times and row_times do not fit this plan's rows (one "
                                     "non-decreasing time per row, within the samples, which start at the plan's t[0])")

    @classmethod
    def trusted(cls, status: str, reason: str, T_world_object: FloatArray, q_left: FloatArray, q_right: FloatArray,
                clearance: FloatArray, pair: tuple[tuple[str, str], ...], t: FloatArray, events: tuple[str, ...],
                path_length: float, planning_time: float, planner: str, meta: dict) -> Plan:
        """The Plan a planner builds from its own data, without the constructor's checks and copies:
        the caller guarantees what they check (a known status; C-contiguous float64 arrays of the
        right shapes and equal rows, new and no longer written by anyone: they are made read-only
        here, not copied; ``pair`` a tuple of (str, str); ``events`` a tuple of str; floats). The
        result equals the constructor's. Not for data from outside the planners."""
        plan = object.__new__(cls)
        for a in (T_world_object, q_left, q_right, clearance, t):
            a.setflags(write=False)
        given = {"status": status, "reason": reason, "T_world_object": T_world_object, "q_left": q_left,
                 "q_right": q_right, "clearance": clearance, "pair": pair, "t": t, "events": events,
                 "path_length": path_length, "planning_time": planning_time, "planner": planner, "meta": meta}
        for f in fields(cls):  # every field: the given ones, the rest at their defaults
            object.__setattr__(plan, f.name, given.get(f.name, f.default))
        return plan

    @classmethod
    def failed(cls, status: str, reason: str, planning_time: float = 0.0, planner: str = "striving") -> Plan:
        """A plan with no steps that failed before its first one (status and reason).

        Raises:
            ParameterError: an unknown status, a reason or planner that is not a string.
        """
        choice(status, STATUSES, "status")
        text(reason, "reason", max_len=100_000)
        text(planner, "planner")
        return cls(status, reason, np.zeros((0, 4, 4)), np.zeros((0, 6)), np.zeros((0, 6)), np.zeros(0), (),
                   np.zeros(0), (f"{status}: {reason}",), 0.0, planning_time, planner)

    # ------------------------------------------------------------------ convenience
    @property
    def reached(self) -> bool:
        """True if the plan ends at the goal."""
        return self.status == "reached"

    @property
    def n_steps(self) -> int:
        """Number of steps after the start."""
        return max(0, self.T_world_object.shape[0] - 1)

    @property
    def min_clearance(self) -> float:
        """Smallest clearance along the plan [m] (NaN for an empty plan)."""
        return float(np.min(self.clearance)) if self.clearance.size else float("nan")

    def steps(self) -> list[dict]:
        """Per step ``{T_world_object, q_left, q_right, clearance, pair, t}`` (lists, SI units)."""
        return [
            {
                "T_world_object": self.T_world_object[i].tolist(),
                "q_left": self.q_left[i].tolist(),
                "q_right": self.q_right[i].tolist(),
                "clearance": float(self.clearance[i]),
                "pair": list(self.pair[i]),
                "t": float(self.t[i]),
            }
            for i in range(self.T_world_object.shape[0])
        ]

    # ------------------------------------------------------------------ JSON
    def to_dict(self) -> dict:
        """Plain-data form, JSON-ready: lists, Python numbers, non-finite numbers as None.

        Raises:
            ParameterError: ``meta`` holds something JSON cannot (see :func:`.plan_io.json_safe`).
        """
        d = {k: getattr(self, k) for k in SCALARS}
        d.update(format=FORMAT, events=list(self.events), steps=self.steps(), meta=self.meta)
        if self.trajectory is not None:
            d["trajectory"] = self.trajectory.to_dict()
        return json_safe(d)  # type: ignore[return-value]

    def to_json(self, indent: int | None = None) -> str:
        """Strict JSON text (non-finite numbers as ``null``); :meth:`from_json` restores an equal
        plan (finite floats round-trip exactly; ``null`` comes back as NaN).

        Raises:
            ParameterError: ``indent`` not None or an integer in [0, 16]; ``meta`` not JSON data.
        """
        if indent is not None:
            indent = integer(indent, "indent", lo=0, hi=16)
        return json.dumps(self.to_dict(), indent=indent, allow_nan=False)

    @classmethod
    def from_dict(cls, d: dict) -> Plan:
        """Inverse of :meth:`to_dict`; the data is checked as :func:`.plan_io.checked_fields` says.

        Raises:
            ParameterError: not a dualpuma plan, or malformed (names the field).
        """
        return cls(**fields_from_dict(d, "plan data"))

    @classmethod
    def from_json(cls, text: str) -> Plan:
        """Inverse of :meth:`to_json` (checked as :meth:`from_dict`).

        Raises:
            ParameterError: not a string, not JSON, not a dualpuma plan, or malformed.
        """
        if not isinstance(text, (str, bytes, bytearray)):
            raise ParameterError(f"plan JSON: expected a string, got {type(text).__name__}")
        if len(text) > MAX_PLAN_BYTES:
            raise ParameterError(f"plan JSON: more than the {MAX_PLAN_BYTES} characters accepted")
        try:
            d = json.loads(text)
        except (ValueError, RecursionError) as e:  # JSONDecodeError, UnicodeDecodeError, nesting
            raise ParameterError(f"plan JSON: {type(e).__name__}: {e}"[:400]) from None
        if not isinstance(d, dict):
            raise ParameterError("plan JSON: expected an object at the top level")
        return cls(**fields_from_dict(d, "plan JSON"))

    # ------------------------------------------------------------------ NPZ
    def save_npz(self, path: str | os.PathLike, overwrite: bool = False) -> Path:
        """Write arrays + metadata to ``path`` (.npz) atomically. Refuses to overwrite unless asked.

        Raises:
            FileError: the file exists (and not ``overwrite``), the directory is missing, the
                target is a directory or a device, or the write failed.
        """
        overwrite = flag(overwrite, "overwrite")
        meta = {k: getattr(self, k) for k in SCALARS}
        meta.update(format=FORMAT, events=list(self.events), pair=[list(x) for x in self.pair], meta=self.meta)
        arrays = {a: getattr(self, a) for a in ARRAYS}
        if self.trajectory is not None:
            extra, meta["trajectory"] = self.trajectory.to_arrays()
            arrays.update(extra)
        return atomic_write(path, npz_bytes(arrays, meta), overwrite=overwrite)

    @classmethod
    def load_npz(cls, path: str | os.PathLike) -> Plan:
        """Inverse of :meth:`save_npz`, checked as :meth:`from_dict`.

        Raises:
            FileError: missing, unreadable, not a regular file, too large.
            ParameterError: not an NPZ file, truncated or corrupted, not a dualpuma plan, malformed.
        """
        data = read_limited(path, limit=MAX_PLAN_BYTES)
        return cls(**fields_from_npz(data, str(path)))

    def equals(self, other: Plan, *, ignore_timing: bool = True) -> bool:
        """Exact equality of every field, ``meta`` as its JSON text (``planning_time`` ignored by
        default)."""
        if not isinstance(other, Plan):
            return False
        same = all(np.array_equal(getattr(self, a), getattr(other, a), equal_nan=True) for a in ARRAYS)
        keys = [k for k in SCALARS if not (ignore_timing and k == "planning_time")]
        return (
            same
            and all(getattr(self, k) == getattr(other, k) for k in keys)
            and self.pair == other.pair
            and self.events == other.events
            and _meta_text(self.meta) == _meta_text(other.meta)
            and ((self.trajectory is None and other.trajectory is None)
                 or (self.trajectory is not None and self.trajectory.equals(other.trajectory)))
        )


def _meta_text(meta: dict) -> str:
    """``meta`` as a file holds it (tuples and lists alike, keys sorted); its ``repr`` if it holds
    something a file cannot (such a plan cannot be saved, but still compares)."""
    try:
        return json.dumps(json_safe(meta), sort_keys=True)
    except ParameterError:
        return repr(meta)


def chain(first: Plan, second: Plan) -> Plan:
    """Concatenate two plans: the second starts where the first ends, in space and in time.

    Times are kept as planned: plan the second leg with ``t_start=first.t[-1]`` so that its moving
    obstacles were checked at its real times. A second leg planned from ``t = 0`` (without
    ``t_start``) is shifted to continue the first, as before, and the chained plan says so in its
    events (its moving obstacles were checked at the wrong times).

    ``meta`` keeps what both legs record alike, and the smaller of their ``margin`` entries (the
    margin the whole plan kept; a leg that records none leaves the chained plan without one). A
    trajectory is not kept: time the chained plan (:func:`~dualpuma.planning.time_plan`).

    Raises:
        ParameterError: either is not a Plan; the second plan does not start where (or when) the
            first ends.
    """
    instance(first, Plan, "first")
    instance(second, Plan, "second")
    if (first.T_world_object.shape[0] and second.T_world_object.shape[0]
            and not np.allclose(first.T_world_object[-1], second.T_world_object[0], rtol=0.0, atol=1e-9)):
        raise ParameterError("chain: the second plan does not start where the first ends")

    def cat(a, b):
        return np.concatenate([a, b[1:]]) if a.shape[0] else b

    n0 = first.T_world_object.shape[0]
    t, note = second.t, ()
    if n0 and second.t.shape[0]:
        end, begin = float(first.t[-1]), float(second.t[0])
        if abs(begin - end) <= 1e-9 * max(1.0, abs(end)):
            t = np.concatenate([first.t, second.t[1:]])
        elif begin == 0.0:
            t = np.concatenate([first.t, second.t[1:] + end])
            note = ((f"chain: the second leg was planned from t = 0, shifted to start at t = {end:.3f} s "
                     "(plan it with t_start for moving obstacles)"),)
        else:
            raise ParameterError(f"chain: the second plan starts at t = {begin} s, the first ends at t = {end} s")
    elif n0:
        t = first.t
    return Plan(second.status, second.reason, cat(first.T_world_object, second.T_world_object),
                cat(first.q_left, second.q_left), cat(first.q_right, second.q_right),
                cat(first.clearance, second.clearance), first.pair + second.pair[1:], t,
                first.events + note + second.events, first.path_length + second.path_length,
                first.planning_time + second.planning_time, second.planner,
                _chained_meta(first.meta, second.meta) if n0 else dict(second.meta))


def _chained_meta(a: dict, b: dict) -> dict:
    """Two legs' ``meta`` for their chain: the entries they agree on (as a file holds them), and
    the smaller ``margin`` when both record one."""
    out = {k: v for k, v in a.items() if k != "margin" and k in b and _meta_text({k: v}) == _meta_text({k: b[k]})}
    ma, mb = a.get("margin"), b.get("margin")
    if isinstance(ma, (int, float)) and isinstance(mb, (int, float)):
        out["margin"] = min(float(ma), float(mb))
    return out
