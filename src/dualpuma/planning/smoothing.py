"""Paths of the RRT-Connect fallback (:mod:`.rrt`): a path found by the trees is re-solved from
the start joints as a whole and verified at its real times, its motion between output steps
certified (:func:`verify`), then shortened (:func:`smooth`): random shortcuts (:func:`shortcut`:
straight SE(3) segments, each checked at its poses and between them and joint-continuous with the
rest of the path), a deterministic pass (:func:`final_pass`) before and after them, and a last
verification of the whole, which certifies the shortcuts' motion (lazily: once, for the rows that
remain). The planner smooths the *whole* returned path this way, Striving's prefix included.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ..lie import slerp
from .edges import EdgeChecker, Run

__all__ = ["JOINT_MATCH", "Path", "final_pass", "path_from_run", "shortcut", "smooth", "step_owner", "try_shortcut", "verify",
           "verify_run"]

FloatArray = npt.NDArray[np.float64]

JOINT_MATCH = 1e-6  #: joints of two paths meeting at one pose must agree to this [rad]


@dataclass
class Path:
    """A verified path at output resolution: poses P (N+1, 4, 4), joints, clearance; fine (N, sub, ...);
    ``seg`` (N,): each output step's length in the search's metric [m]."""

    P: FloatArray
    qL: FloatArray
    qR: FloatArray
    d: FloatArray
    FP: FloatArray
    FqL: FloatArray
    FqR: FloatArray
    Fd: FloatArray
    seg: FloatArray


def _seg(ctx: EdgeChecker, P: FloatArray) -> FloatArray:
    """The metric length of each step of poses P (K, 4, 4): (K - 1,) [m]."""
    return np.array([ctx.metric(a, b) for a, b in itertools.pairwise(P)])


def verify(
    ctx: EdgeChecker, waypoints: list[tuple[FloatArray, int]], q0: tuple[FloatArray, FloatArray], d0: float
) -> tuple[Path | None, str]:
    """Re-solve waypoints ``[(T, output steps from the previous)]`` from q0 as one path, at real times.
    A waypoint at the previous one's pose (two trees meeting at the goal, each with its own node
    there) adds no step: the path is re-solved through it anyway. Returns ``(the path, "")`` or
    ``(None, why)`` (:func:`verify_run` also tells which step failed and how)."""
    path, run, n_out = verify_run(ctx, waypoints, q0, d0)
    if path is None:
        return None, f"output step {run.m + 1} of {n_out}: {run.reason}"
    return path, ""


def verify_run(
    ctx: EdgeChecker, waypoints: list[tuple[FloatArray, int]], q0: tuple[FloatArray, FloatArray], d0: float
) -> tuple[Path | None, Run, int]:
    """:func:`verify` with its run: ``(the path or None, the run (its ``m`` leading output steps
    valid; ``why`` the failure's category), the path's output steps)``. :func:`step_owner` maps a
    step to its waypoint."""
    sub = ctx.sub
    waypoints = [waypoints[i] for i in _kept(waypoints)]
    parts = [
        slerp(A, B, np.arange(1, n * sub + 1) / (n * sub))
        for (A, _), (B, n) in itertools.pairwise(waypoints)
    ]
    P = np.concatenate(parts)
    n_out = P.shape[0] // sub
    run = ctx.validate(P, q0, ctx.t0 + np.arange(1, P.shape[0] + 1) / sub * ctx.dt, (d0, ctx.t0), whole=True)
    if run.m < n_out:
        return None, run, n_out
    return path_from_run(ctx, waypoints[0][0], q0, d0, run), run, n_out


def _kept(waypoints: list[tuple[FloatArray, int]]) -> list[int]:
    """Indices of the waypoints a path through them keeps: the first, and each one not at the pose
    of the one before it."""
    return [0] + [i for i in range(1, len(waypoints)) if not np.array_equal(waypoints[i][0], waypoints[i - 1][0])]


def step_owner(waypoints: list[tuple[FloatArray, int]], step: int) -> int:
    """The index into ``waypoints`` of the waypoint whose segment (from the kept waypoint before it)
    holds output step ``step`` (0-based) of the path :func:`verify` makes of them; -1 past the end."""
    first = 0
    for i in _kept(waypoints)[1:]:
        first += waypoints[i][1]
        if step < first:
            return i
    return -1


def path_from_run(ctx: EdgeChecker, A: FloatArray, q0: tuple[FloatArray, FloatArray], d0: float, run: Run) -> Path:
    """The :class:`Path` of a whole valid, certified run from pose A (joints q0, clearance d0 [m])."""
    sub, n_out = ctx.sub, run.m
    last = np.arange(1, n_out + 1) * sub - 1
    out = np.concatenate([A[None], run.P[last]])
    return Path(
        out,
        np.vstack([q0[0], run.qL[last]]),
        np.vstack([q0[1], run.qR[last]]),
        np.concatenate([[d0], run.d[last]]),
        run.P.reshape(n_out, sub, 4, 4),
        run.qL.reshape(n_out, sub, 6),
        run.qR.reshape(n_out, sub, 6),
        run.d.reshape(n_out, sub),
        _seg(ctx, out),
    )


def shortcut(ctx: EdgeChecker, path: Path, gen: np.random.Generator, certify: bool = True) -> Path:
    """Random shortcuts (``shortcut_iterations`` attempts): replace output steps i..j by a straight
    SE(3) segment when it is shorter in the metric (by more than ``min_shortcut_gain``), permitted
    at every sub-pose, joint-continuous with step j, its motion between output steps certified
    (with ``certify``; else that is the final verification's: :func:`smooth`), and (moving
    obstacles) the rest of the path stays permitted at its shifted times."""
    for _ in range(ctx.p.shortcut_iterations):
        N = path.P.shape[0] - 1
        if N < 2:
            break
        i, j = sorted(int(v) for v in gen.integers(0, N + 1, size=2))
        if j - i >= 2:
            path = try_shortcut(ctx, path, i, j, certify) or path
    return path


def final_pass(ctx: EdgeChecker, path: Path, certify: bool = True) -> Path:
    """A deterministic pass after the random shortcuts: from each row in turn, the farthest row
    ahead that a straight segment reaches among the goal and the rows halfway there, a quarter of
    the way, ... two rows on; after a shortcut the pass continues from its end (the new segment is
    straight already). ``certify``: as in :func:`shortcut`."""
    i = 0
    while i < path.P.shape[0] - 2:
        N = path.P.shape[0] - 1
        j, nxt = N, i + 1
        while j - i >= 2:
            new = try_shortcut(ctx, path, i, j, certify)
            if new is not None:
                nxt = i + (new.P.shape[0] - path.P.shape[0]) + (j - i)  # the shortcut's end, re-indexed
                path = new
                break
            j = i + (j - i) // 2
        i = max(nxt, i + 1)
    return path


def try_shortcut(ctx: EdgeChecker, path: Path, i: int, j: int, certify: bool = True) -> Path | None:
    """The path with output steps i..j replaced by a straight SE(3) segment, or None when that is
    not shorter in the metric by more than ``min_shortcut_gain`` or not permitted (see
    :func:`shortcut`; ``certify``: whether the segment's motion between output steps is certified
    here)."""
    sub, N = ctx.sub, path.P.shape[0] - 1
    old = sum(path.seg[i:j].tolist())
    if ctx.metric(path.P[i], path.P[j]) >= old - max(ctx.p.min_shortcut_gain, 1e-9):
        return None
    run, n = ctx.edge(path.P[i], (path.qL[i], path.qR[i]), path.P[j], ctx.t0 + i * ctx.dt, d_a=float(path.d[i]),
                      whole=True, certify=certify)
    if run.m < n:
        return None
    if max(np.abs(run.qL[-1] - path.qL[j]).max(), np.abs(run.qR[-1] - path.qR[j]).max()) > JOINT_MATCH:
        return None
    rest_d = path.Fd[j:]
    if ctx.timed and n != j - i and j < N:
        rest = path.FP[j:].reshape(-1, 4, 4)
        tt = ctx.t0 + (i + n + np.arange(1, rest.shape[0] + 1) / sub) * ctx.dt
        rd, _ = ctx.clear(path.FqL[j:].reshape(-1, 6), path.FqR[j:].reshape(-1, 6), tt)
        if np.any(rd < ctx.margin):
            return None
        rest_d = rd.reshape(-1, sub)
    last = np.arange(1, n + 1) * sub - 1
    rows = run.P[last]
    return Path(
        np.concatenate([path.P[: i + 1], rows, path.P[j + 1 :]]),
        np.concatenate([path.qL[: i + 1], run.qL[last], path.qL[j + 1 :]]),
        np.concatenate([path.qR[: i + 1], run.qR[last], path.qR[j + 1 :]]),
        np.concatenate([path.d[: i + 1], run.d[last], rest_d[:, -1]]),
        np.concatenate([path.FP[:i], run.P.reshape(n, sub, 4, 4), path.FP[j:]]),
        np.concatenate([path.FqL[:i], run.qL.reshape(n, sub, 6), path.FqL[j:]]),
        np.concatenate([path.FqR[:i], run.qR.reshape(n, sub, 6), path.FqR[j:]]),
        np.concatenate([path.Fd[:i], run.d.reshape(n, sub), rest_d]),
        np.concatenate([path.seg[:i], _seg(ctx, np.concatenate([path.P[i][None], rows])), path.seg[j:]]),
    )


def smooth(ctx: EdgeChecker, path: Path, q0: tuple[FloatArray, FloatArray], d0: float,
           gen: np.random.Generator, lazy: bool = True) -> Path:
    """The deterministic pass, random shortcuts, the pass again, then the whole result re-verified
    from q0 at its real times with its motion certified; the input path (verified and certified
    itself) when that fails. The first pass straightens a tree's zigzag in a few long segments, so
    the random shortcuts start from a short path (on the hard set: 3 % shorter paths in slightly
    less time than random shortcuts first).

    With ``lazy`` the shortcuts' motion is certified once, for the smoothed path as a whole: each
    shortcut is checked at its poses and between them as it is made, and the final verification
    certifies the motion between the rows that remain (a shortcut that a later one replaces is
    never certified). Where that fails, smoothing is done again from the same path and random state
    with every shortcut certified as it is made, which is what ``lazy=False`` does (on the hard set
    the same 36 paths, 8 % less time at the median, three problems smoothed twice)."""
    state = gen.bit_generator.state
    for certify in (False, True) if lazy else (True,):
        gen.bit_generator.state = state
        out = final_pass(ctx, shortcut(ctx, final_pass(ctx, path, certify), gen, certify), certify)
        if out is path:
            return path
        final, _ = verify(ctx, [(out.P[0], 0)] + [(T, 1) for T in out.P[1:]], q0, d0)
        if final is not None:
            return final
    return path
