"""Building blocks of the SE(3) RRT-Connect fallback (:mod:`dualpuma.fallback`): SE(3) geodesics,
the trees, the per-search context (dual IK and clearance of whole edges in batched calls), path
re-verification at real times, and shortcut smoothing."""

from __future__ import annotations

import itertools
import math
from collections import Counter
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from .clearance import clearance_batch
from .coordination import solve_path
from .fallback_params import FallbackParams
from .world import World

FloatArray = npt.NDArray[np.float64]

_JOINT_MATCH = 1e-6  # [rad] joints of two trees meeting at one pose must agree to this


# ----------------------------------------------------------------------------- SE(3) helpers
def _interp(A: FloatArray, B: FloatArray, s: FloatArray) -> FloatArray:
    """Poses at fractions ``s`` (K,) of the SE(3) geodesic A -> B (slerp + lerp): (K, 4, 4); s = 1 gives B."""
    out = np.zeros((s.size, 4, 4))
    out[:, 3, 3] = 1.0
    out[:, :3, 3] = A[:3, 3] + s[:, None] * (B[:3, 3] - A[:3, 3])
    w = pin.log3(A[:3, :3].T @ B[:3, :3])
    th = float(np.linalg.norm(w))
    if th < 1e-12:
        out[:, :3, :3] = A[:3, :3]
    else:
        k = w / th
        K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
        a = s * th
        R = np.eye(3) + np.sin(a)[:, None, None] * K + (1.0 - np.cos(a))[:, None, None] * (K @ K)
        out[:, :3, :3] = A[:3, :3] @ R
    out[s == 1.0] = B
    return out


def _angle(A: FloatArray, B: FloatArray) -> float:
    return float(np.linalg.norm(pin.log3(A[:3, :3].T @ B[:3, :3])))


def _quat(R: FloatArray) -> FloatArray:
    return np.asarray(pin.Quaternion(R).coeffs(), dtype=float)


class _Tree:
    """Nodes (pose, joints, parent, output steps of the edge from the parent, time)."""

    def __init__(self, T: FloatArray, qL: FloatArray, qR: FloatArray, t: float) -> None:
        self.T, self.qL, self.qR = [T], [qL], [qR]
        self.parent, self.n, self.t = [-1], [0], [t]
        self.pos = np.zeros((64, 3))
        self.quat = np.zeros((64, 4))
        self.pos[0], self.quat[0] = T[:3, 3], _quat(T[:3, :3])

    def __len__(self) -> int:
        return len(self.T)

    def add(
        self, T: FloatArray, qL: FloatArray, qR: FloatArray, parent: int, n: int, t: float
    ) -> int:
        k = len(self.T)
        if k == self.pos.shape[0]:
            self.pos = np.vstack([self.pos, np.zeros_like(self.pos)])
            self.quat = np.vstack([self.quat, np.zeros_like(self.quat)])
        self.pos[k], self.quat[k] = T[:3, 3], _quat(T[:3, :3])
        self.T.append(T)
        self.qL.append(qL)
        self.qR.append(qR)
        self.parent.append(parent)
        self.n.append(n)
        self.t.append(t)
        return k

    def nearest(self, T: FloatArray, w: float, k: int = 1) -> list[tuple[int, float]]:
        """The ``k`` nearest nodes to T in the metric ``|dp| + w * angle``: [(index, distance)], nearest first."""
        n = len(self.T)
        dots = np.abs(self.quat[:n] @ _quat(T[:3, :3]))
        d = np.linalg.norm(self.pos[:n] - T[:3, 3], axis=1) + w * 2.0 * np.arccos(
            np.minimum(dots, 1.0)
        )
        idx = np.argsort(d, kind="stable")[:k]
        return [(int(i), float(d[i])) for i in idx]

    def chain(self, i: int) -> list[int]:
        out = []
        while i >= 0:
            out.append(i)
            i = self.parent[i]
        return out


@dataclass
class _Run:
    """Validation of a run of output steps: ``m`` leading steps valid (fine arrays cover them)."""

    m: int
    P: FloatArray  # (m*sub, 4, 4) fine poses
    qL: FloatArray
    qR: FloatArray
    d: FloatArray
    pair: npt.NDArray[np.int64]
    reason: str = ""
    why: str = ""  # short category for statistics
    ratio: float = 0.0  # refused for a joint step: that step's joint change / max_joint_step


class _Ctx:
    def __init__(
        self, world: World, p: FallbackParams, A: FloatArray, t0: float, step_time: float
    ) -> None:
        self.world, self.p, self.A, self.t0, self.dt = world, p, A, t0, step_time
        self.sub = int(p.substeps)
        self.margin = float(world.cell.safety_margin if p.margin is None else p.margin)
        self.timed = bool(world.moving) and step_time > 0.0
        self.stats: Counter[str] = Counter()

    def clear(
        self, qL: FloatArray, qR: FloatArray, times: FloatArray
    ) -> tuple[FloatArray, npt.NDArray[np.int64]]:
        """Batched clearance; the bar rides on the left hand (its pose from the joints, which hold
        the object pose to IK precision), times only matter with moving obstacles."""
        return clearance_batch(self.world, qL, qR, None, times if self.world.moving else None)

    def n_out(self, A: FloatArray, B: FloatArray) -> int:
        d = float(np.linalg.norm(B[:3, 3] - A[:3, 3]))
        return max(
            1, math.ceil(d / self.p.step - 1e-9), math.ceil(_angle(A, B) / self.p.rot_step - 1e-9)
        )

    def metric(self, A: FloatArray, B: FloatArray) -> float:
        return float(np.linalg.norm(B[:3, 3] - A[:3, 3])) + self.p.rot_weight * _angle(A, B)

    def t_lb(self, P: FloatArray) -> FloatArray:
        """Earliest possible time of poses P (K, 4, 4): straight output steps from the start pose."""
        if not self.timed:
            return np.full(P.shape[0], self.t0)
        d = np.linalg.norm(P[:, :3, 3] - self.A[:3, 3], axis=1)
        c = np.clip((np.einsum("ij,kij->k", self.A[:3, :3], P[:, :3, :3]) - 1.0) / 2.0, -1.0, 1.0)
        n = np.maximum(
            np.ceil(d / self.p.step - 1e-9), np.ceil(np.arccos(c) / self.p.rot_step - 1e-9)
        )
        return self.t0 + n * self.dt

    def validate(self, P: FloatArray, q0: tuple[FloatArray, FloatArray], times: FloatArray) -> _Run:
        """Leading valid output steps of fine poses P (n*sub, 4, 4) continuing joints q0."""
        w, sub, p = self.world, self.sub, self.p
        n = P.shape[0] // sub
        sol = solve_path(w, P, q0, max_step=p.max_joint_step, _trusted=True)
        m, reason, why, ratio = sol.n_ok // sub, sol.reason, "", 0.0
        if m < n:
            why = " / ".join(
                f"{s} arm {st}" for s, st in zip(("left", "right"), sol.status) if st != "ok"
            )
        qL, qR = sol.q_left, sol.q_right
        if m:  # joint change between consecutive output steps
            idx = np.arange(1, m + 1) * sub - 1
            prevL, prevR = np.vstack([q0[0], qL[idx[:-1]]]), np.vstack([q0[1], qR[idx[:-1]]])
            jump = np.maximum(
                np.abs(qL[idx] - prevL).max(axis=1), np.abs(qR[idx] - prevR).max(axis=1)
            )
            bad = np.flatnonzero(jump > p.max_joint_step + 1e-12)
            if bad.size:
                m = int(bad[0])
                reason = (
                    f"a joint would move {math.degrees(jump[m]):.1f} deg in output step {m + 1}"
                )
                why, ratio = "joint step", float(jump[m] / p.max_joint_step)
        d = np.full(m * sub, np.nan)
        pair = np.zeros(m * sub, dtype=np.int64)
        k = 0  # pass 1: output-step poses, a few at a time (refusals are found 'substeps' times faster)
        while k < m:
            idx = np.arange(k, min(m, k + 8)) * sub + sub - 1
            d[idx], pair[idx] = self.clear(qL[idx], qR[idx], times[idx])
            bad = np.flatnonzero(d[idx] < self.margin)
            if bad.size:
                m = k + int(bad[0])
                j = idx[bad[0]]
                reason, why = self._clear_reason(d[j], int(pair[j]))
                break
            k += 8
        if m and sub > 1:  # pass 2: the sub-poses between output steps
            idx = np.flatnonzero(np.arange(m * sub) % sub != sub - 1)
            d[idx], pair[idx] = self.clear(qL[idx], qR[idx], times[idx])
            bad = np.flatnonzero(d[: m * sub] < self.margin)
            if bad.size:
                j = int(bad[0])
                m = j // sub
                reason, why = self._clear_reason(d[j], int(pair[j]))
        f = m * sub
        return _Run(
            m,
            P[:f],
            qL[:f],
            qR[:f],
            d[:f],
            pair[:f],
            reason if m < n else "",
            why if m < n else "",
            ratio,
        )

    def _clear_reason(self, d: float, k: int) -> tuple[str, str]:
        a, b = self.world.pair_names[k]
        return (
            f"clearance {d:.4f} m below the margin {self.margin:.3f} m ({a} – {b})",
            f"clearance {a} – {b}",
        )

    def edge(
        self,
        A: FloatArray,
        q0: tuple[FloatArray, FloatArray],
        B: FloatArray,
        t_a: float | None,
        n: int | None = None,
    ) -> tuple[_Run, int]:
        """Validate the geodesic A -> B from joints q0; ``t_a``: time at A (None: goal-tree lower bounds).

        ``n`` output steps (default: by ``step``/``rot_step``); where a joint would move more than
        ``max_joint_step`` in one output step (near the wrist singularity) the edge is cut into more
        steps, up to 8 times as many. Returns (run, output steps used).
        """
        n = self.n_out(A, B) if n is None else n
        n_max = 8 * n
        while True:
            F = n * self.sub
            P = _interp(A, B, np.arange(1, F + 1) / F)
            times = self.t_lb(P) if t_a is None else t_a + np.arange(1, F + 1) / self.sub * self.dt
            run = self.validate(P, q0, times)
            if run.why != "joint step" or n >= n_max:
                break
            n = min(n_max, math.ceil(n * min(4.0, 1.25 * run.ratio)))
        if run.why:
            self.stats[run.why] += 1
        return run, n


# ----------------------------------------------------------------------------- path
@dataclass
class _Path:
    """A verified path at output resolution: poses P (N+1, 4, 4), joints, clearance; fine (N, sub, ...)."""

    P: FloatArray
    qL: FloatArray
    qR: FloatArray
    d: FloatArray
    FP: FloatArray
    FqL: FloatArray
    FqR: FloatArray
    Fd: FloatArray


def _verify(
    ctx: _Ctx, waypoints: list[tuple[FloatArray, int]], q0: tuple[FloatArray, FloatArray], d0: float
) -> tuple[_Path | None, str]:
    """Re-solve waypoints ``[(T, output steps from the previous)]`` from q0 as one path, at real times."""
    sub = ctx.sub
    parts = [
        _interp(A, B, np.arange(1, n * sub + 1) / (n * sub))
        for (A, _), (B, n) in itertools.pairwise(waypoints)
    ]
    P = np.concatenate(parts)
    n_out = P.shape[0] // sub
    run = ctx.validate(P, q0, ctx.t0 + np.arange(1, P.shape[0] + 1) / sub * ctx.dt)
    if run.m < n_out:
        return None, f"output step {run.m + 1} of {n_out}: {run.reason}"
    last = np.arange(1, n_out + 1) * sub - 1
    return _Path(
        np.concatenate([waypoints[0][0][None], P[last]]),
        np.vstack([q0[0], run.qL[last]]),
        np.vstack([q0[1], run.qR[last]]),
        np.concatenate([[d0], run.d[last]]),
        P.reshape(n_out, sub, 4, 4),
        run.qL.reshape(n_out, sub, 6),
        run.qR.reshape(n_out, sub, 6),
        run.d.reshape(n_out, sub),
    ), ""


def _shortcut(ctx: _Ctx, path: _Path, gen: np.random.Generator) -> _Path:
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
        run, n = ctx.edge(path.P[i], (path.qL[i], path.qR[i]), path.P[j], ctx.t0 + i * ctx.dt)
        if run.m < n:
            continue
        if (
            max(np.abs(run.qL[-1] - path.qL[j]).max(), np.abs(run.qR[-1] - path.qR[j]).max())
            > _JOINT_MATCH
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
        path = _Path(
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
