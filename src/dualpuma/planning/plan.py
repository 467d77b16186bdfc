"""`Plan`: the frozen result of a planner run, with JSON and NPZ export/import.

A plan holds one row per step, the first row being the start. Poses are object frames in the world
(4, 4) [m]; joints are radians; clearance is the minimum signed distance over all checked pairs
[m]; ``t`` is each step's time [s] (for moving obstacles).
"""

from __future__ import annotations

import io
import json
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import numpy.typing as npt

from ..errors import ParameterError
from ..files import atomic_write
from .trajectory import Trajectory

__all__ = ["STATUSES", "Plan", "chain"]

FloatArray = npt.NDArray[np.float64]

#: every status a plan can have
STATUSES = ("reached", "frozen", "invalid_start", "invalid_goal", "invalid_input", "limit_exceeded", "error")

_ARRAYS = ("T_world_object", "q_left", "q_right", "clearance", "t")
_SCALARS = ("status", "reason", "path_length", "planning_time", "planner")
_FORMAT = "dualpuma.plan/1"


def _frozen(a: npt.ArrayLike, shape_tail: tuple[int, ...]) -> FloatArray:
    arr = np.array(a, dtype=np.float64).reshape((-1,) + shape_tail)
    arr.setflags(write=False)
    return arr


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
        if self.status not in STATUSES:
            raise ParameterError(f"status: expected one of {STATUSES}, got {self.status!r}")
        for name, tail in (("T_world_object", (4, 4)), ("q_left", (6,)), ("q_right", (6,)), ("clearance", ()), ("t", ())):
            object.__setattr__(self, name, _frozen(getattr(self, name), tail))
        n = self.T_world_object.shape[0]
        if any(getattr(self, a).shape[0] != n for a in _ARRAYS) or len(self.pair) != n:
            raise ParameterError("Plan: every per-step array (and pair) needs the same number of rows")
        object.__setattr__(self, "pair", tuple((str(a), str(b)) for a, b in self.pair))
        object.__setattr__(self, "events", tuple(str(e) for e in self.events))
        if self.trajectory is not None and not isinstance(self.trajectory, Trajectory):
            raise ParameterError(f"trajectory: expected a Trajectory or None, got {type(self.trajectory).__name__}")

    @classmethod
    def failed(cls, status: str, reason: str, planning_time: float = 0.0, planner: str = "striving") -> Plan:
        """A plan with no steps that failed before its first one (status and reason)."""
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
        """Plain-data form (JSON-ready)."""
        d = {k: getattr(self, k) for k in _SCALARS}
        d.update(format=_FORMAT, events=list(self.events), steps=self.steps(), meta=self.meta)
        if self.trajectory is not None:
            d["trajectory"] = self.trajectory.to_dict()
        return d

    def to_json(self, indent: int | None = None) -> str:
        """JSON text; :meth:`from_json` restores an equal plan (floats round-trip exactly)."""
        return json.dumps(self.to_dict(), indent=indent, allow_nan=True)

    @classmethod
    def from_dict(cls, d: dict) -> Plan:
        """Inverse of :meth:`to_dict`. Raises ParameterError on malformed data."""
        try:
            if d.get("format") != _FORMAT:
                raise ParameterError(f"not a dualpuma plan (format {d.get('format')!r}, expected {_FORMAT!r})")
            steps = d["steps"]
            return cls(
                status=d["status"],
                reason=d["reason"],
                T_world_object=np.array([s["T_world_object"] for s in steps], float).reshape(-1, 4, 4),
                q_left=np.array([s["q_left"] for s in steps], float).reshape(-1, 6),
                q_right=np.array([s["q_right"] for s in steps], float).reshape(-1, 6),
                clearance=np.array([s["clearance"] for s in steps], float),
                pair=tuple(tuple(s["pair"]) for s in steps),
                t=np.array([s["t"] for s in steps], float),
                events=tuple(d["events"]),
                path_length=float(d["path_length"]),
                planning_time=float(d["planning_time"]),
                planner=str(d["planner"]),
                meta=dict(d.get("meta", {})),
                trajectory=None if d.get("trajectory") is None else Trajectory.from_dict(d["trajectory"]),
            )
        except (KeyError, TypeError, ValueError) as e:
            raise ParameterError(f"malformed plan data: {type(e).__name__}: {e}") from e

    @classmethod
    def from_json(cls, text: str) -> Plan:
        """Inverse of :meth:`to_json`."""
        try:
            d = json.loads(text)
        except json.JSONDecodeError as e:
            raise ParameterError(f"plan JSON: {e}") from e
        if not isinstance(d, dict):
            raise ParameterError("plan JSON: expected an object at the top level")
        return cls.from_dict(d)

    # ------------------------------------------------------------------ NPZ
    def save_npz(self, path: str | os.PathLike, overwrite: bool = False) -> Path:
        """Write arrays + metadata to ``path`` (.npz). Refuses to overwrite unless asked."""
        meta = {k: getattr(self, k) for k in _SCALARS}
        meta.update(format=_FORMAT, events=list(self.events), pair=[list(x) for x in self.pair], meta=self.meta)
        extra: dict = {}
        if self.trajectory is not None:
            extra, meta["trajectory"] = self.trajectory.to_arrays()
        buf = io.BytesIO()
        np.savez(buf, **{a: getattr(self, a) for a in _ARRAYS}, **extra, meta=np.array(json.dumps(meta)))
        return atomic_write(path, buf.getvalue(), overwrite=overwrite)

    @classmethod
    def load_npz(cls, path: str | os.PathLike) -> Plan:
        """Inverse of :meth:`save_npz`."""
        with np.load(Path(path), allow_pickle=False) as z:
            meta = json.loads(str(z["meta"]))
            if meta.get("format") != _FORMAT:
                raise ParameterError(f"{path}: not a dualpuma plan")
            arrays = {a: z[a] for a in _ARRAYS}
            traj = None if meta.get("trajectory") is None else Trajectory.from_arrays(z, meta["trajectory"])
        return cls(
            **arrays,
            status=meta["status"],
            reason=meta["reason"],
            pair=tuple(tuple(x) for x in meta["pair"]),
            events=tuple(meta["events"]),
            path_length=meta["path_length"],
            planning_time=meta["planning_time"],
            planner=meta["planner"],
            meta=meta.get("meta", {}),
            trajectory=traj,
        )

    def equals(self, other: Plan, *, ignore_timing: bool = True) -> bool:
        """Exact equality of every field (``planning_time`` ignored by default)."""
        if not isinstance(other, Plan):
            return False
        same = all(np.array_equal(getattr(self, a), getattr(other, a), equal_nan=True) for a in _ARRAYS)
        keys = [k for k in _SCALARS if not (ignore_timing and k == "planning_time")]
        return (
            same
            and all(getattr(self, k) == getattr(other, k) for k in keys)
            and self.pair == other.pair
            and self.events == other.events
            and ((self.trajectory is None and other.trajectory is None)
                 or (self.trajectory is not None and self.trajectory.equals(other.trajectory)))
        )


def chain(first: Plan, second: Plan) -> Plan:
    """Concatenate two plans: the second starts where the first ends, in space and in time.

    Times are kept as planned: plan the second leg with ``t_start=first.t[-1]`` so that its moving
    obstacles were checked at its real times. A second leg planned from ``t = 0`` (without
    ``t_start``) is shifted to continue the first, as before, and the chained plan says so in its
    events (its moving obstacles were checked at the wrong times).

    Raises:
        ParameterError: the second plan does not start where (or when) the first ends.
    """
    if (first.T_world_object.shape[0] and second.T_world_object.shape[0]
            and not np.allclose(first.T_world_object[-1], second.T_world_object[0], atol=1e-9)):
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
                first.planning_time + second.planning_time, second.planner)
