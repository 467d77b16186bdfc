"""Paths of the RRT-Connect fallback (:mod:`.rrt`): a path found by the trees is re-solved from
the start joints as a whole and verified at its real times (:func:`verify`), then shortened by
random shortcuts (:func:`shortcut`: straight SE(3) segments, each re-verified the same way and
joint-continuous with the rest of the path).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ..lie import slerp
from .edges import EdgeChecker

__all__ = ["JOINT_MATCH", "Path", "shortcut", "verify"]

FloatArray = npt.NDArray[np.float64]

JOINT_MATCH = 1e-6  #: joints of two paths meeting at one pose must agree to this [rad]


@dataclass
class Path:
    """A verified path at output resolution: poses P (N+1, 4, 4), joints, clearance; fine (N, sub, ...)."""

    P: FloatArray
    qL: FloatArray
    qR: FloatArray
    d: FloatArray
    FP: FloatArray
    FqL: FloatArray
    FqR: FloatArray
    Fd: FloatArray


def verify(
    ctx: EdgeChecker, waypoints: list[tuple[FloatArray, int]], q0: tuple[FloatArray, FloatArray], d0: float
) -> tuple[Path | None, str]:
    """Re-solve waypoints ``[(T, output steps from the previous)]`` from q0 as one path, at real times."""
    sub = ctx.sub
    parts = [
        slerp(A, B, np.arange(1, n * sub + 1) / (n * sub))
        for (A, _), (B, n) in itertools.pairwise(waypoints)
    ]
    P = np.concatenate(parts)
    n_out = P.shape[0] // sub
    run = ctx.validate(P, q0, ctx.t0 + np.arange(1, P.shape[0] + 1) / sub * ctx.dt, (d0, ctx.t0))
    if run.m < n_out:
        return None, f"output step {run.m + 1} of {n_out}: {run.reason}"
    last = np.arange(1, n_out + 1) * sub - 1
    return Path(
        np.concatenate([waypoints[0][0][None], P[last]]),
        np.vstack([q0[0], run.qL[last]]),
        np.vstack([q0[1], run.qR[last]]),
        np.concatenate([[d0], run.d[last]]),
        P.reshape(n_out, sub, 4, 4),
        run.qL.reshape(n_out, sub, 6),
        run.qR.reshape(n_out, sub, 6),
        run.d.reshape(n_out, sub),
    ), ""


def shortcut(ctx: EdgeChecker, path: Path, gen: np.random.Generator) -> Path:
    """Random shortcuts: replace output steps i..j by a straight SE(3) segment when it is shorter in
    the metric, permitted at every sub-pose, joint-continuous with step j, and (moving obstacles)
    the rest of the path stays permitted at its shifted times."""
    sub = ctx.sub
    for _ in range(ctx.p.shortcut_iterations):
        N = path.P.shape[0] - 1
        if N < 2:
            break
        i, j = sorted(int(v) for v in gen.integers(0, N + 1, size=2))
        if j - i < 2:
            continue
        old = sum(ctx.metric(path.P[k], path.P[k + 1]) for k in range(i, j))
        if ctx.metric(path.P[i], path.P[j]) >= old - 1e-9:
            continue
        run, n = ctx.edge(path.P[i], (path.qL[i], path.qR[i]), path.P[j], ctx.t0 + i * ctx.dt, d_a=float(path.d[i]))
        if run.m < n:
            continue
        if (
            max(np.abs(run.qL[-1] - path.qL[j]).max(), np.abs(run.qR[-1] - path.qR[j]).max())
            > JOINT_MATCH
        ):
            continue
        rest_d = path.Fd[j:]
        if ctx.timed and n != j - i and j < N:
            rest = path.FP[j:].reshape(-1, 4, 4)
            tt = ctx.t0 + (i + n + np.arange(1, rest.shape[0] + 1) / sub) * ctx.dt
            rd, _ = ctx.clear(path.FqL[j:].reshape(-1, 6), path.FqR[j:].reshape(-1, 6), tt)
            if np.any(rd < ctx.margin):
                continue
            rest_d = rd.reshape(-1, sub)
        last = np.arange(1, n + 1) * sub - 1
        path = Path(
            np.concatenate([path.P[: i + 1], run.P[last], path.P[j + 1 :]]),
            np.concatenate([path.qL[: i + 1], run.qL[last], path.qL[j + 1 :]]),
            np.concatenate([path.qR[: i + 1], run.qR[last], path.qR[j + 1 :]]),
            np.concatenate([path.d[: i + 1], run.d[last], rest_d[:, -1]]),
            np.concatenate([path.FP[:i], run.P.reshape(n, sub, 4, 4), path.FP[j:]]),
            np.concatenate([path.FqL[:i], run.qL.reshape(n, sub, 6), path.FqL[j:]]),
            np.concatenate([path.FqR[:i], run.qR.reshape(n, sub, 6), path.FqR[j:]]),
            np.concatenate([path.Fd[:i], run.d.reshape(n, sub), rest_d]),
        )
    return path
