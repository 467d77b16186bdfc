"""General fallback beyond the seed: bidirectional RRT-Connect over object poses in SE(3).

When Striving freezes, the bar's frame is searched in SE(3) — rotation included, so the bar can
"snake" (weave by rotating) through a slot field, the seed's §7.3 wish. Each tree node holds an
object pose and both arms' joints. An edge between two poses is the SE(3) geodesic of the bar
(translation linear, rotation along the shortest arc), cut into ``n`` output steps no longer than
``step`` [m] and ``rot_step`` [rad]; it is *permitted* when every one of its ``n * substeps``
sub-poses has dual IK that continues the neighbour's joints (same IK branches, no joint moving more
than ``max_joint_step``, inside the limits) and clearance >= ``margin`` — and no joint moves more than
``max_joint_step`` between consecutive output steps (an edge that would is cut into more steps, up
to 8 times as many: near the wrist singularity q4 and q6 turn fast). The goal tree's roots are the
goal solved on the start's IK branches (and their wrist partners, which a path through q5 = 0
continues on), so a connected path keeps each arm's branch from start to goal. Trees meet where an
edge from one arrives at a node of the other with the same joints up to whole turns (q4 + 2 pi is
the same arm); the whole path is then re-solved forward, where the joint limits decide.

Search details: samples are uniform in a box around start and goal, or (``local_bias``) Gaussian
around a random node of the growing tree, which keeps exploring narrow regions such as the space
between two plates; the other tree tries to connect to each new node from its nearest node in the
metric and from its nearest nodes by position alone.

A found path is re-solved from the start joints as a whole and verified at its real times, then
shortened by random shortcuts (straight SE(3) segments, each re-verified the same way, joints
continuous with the rest of the path) and returned at output-step resolution.

Moving obstacles: the pose at output index ``i`` of the final path is at time ``t0 + i * step_time``.
During the search the time of a start-tree pose is exact for its tree path (``t0`` + output steps
from the root × ``step_time``); a goal-tree pose has no known arrival index, so its time is
approximated by the earliest possible one — the number of output steps of the straight edge from the
start pose to it. Every candidate path (and shortcut) is re-verified at its real times, so this
approximation can cost a failed connection, never an invalid result.

Deterministic: the same inputs and rng seed give bit-identical results (``world.reset()`` first).
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import time
from collections import Counter
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from . import puma
from .cell import Cell, Obstacle
from .clearance import clearance_batch
from .coordination import hands_from_object, solve_path
from .errors import ParameterError
from .paths import calc_rot
from .puma import validate_joints, validate_pose
from .world import World

__all__ = ["FallbackParams", "FallbackResult", "rrt_connect", "slot_field_cell"]

FloatArray = npt.NDArray[np.float64]
_JOINT_MATCH = 1e-6  # [rad] joints of two trees meeting at one pose must agree to this


def _positive(name: str, v: object, *, integer: bool = False, zero_ok: bool = False) -> None:
    ok_type = (
        isinstance(v, (int, np.integer))
        if integer
        else isinstance(v, (int, float, np.floating, np.integer))
    )
    if (
        isinstance(v, bool)
        or not ok_type
        or not math.isfinite(float(v))
        or (v < 0 if zero_ok else v <= 0)
    ):  # type: ignore[operator]
        kind = "an integer" if integer else "a finite value"
        raise ParameterError(
            f"FallbackParams.{name}: expected {kind} {'>= 0' if zero_ok else '> 0'}, got {v!r}"
        )


@dataclass(frozen=True, slots=True)
class FallbackParams:
    """Parameters of :func:`rrt_connect` (frozen; validated on construction, SI units).

    Attributes:
        max_iterations: RRT-Connect iterations (one extend + one connect each) before giving up.
        step: longest translation of the bar's frame per output step [m].
        rot_step: largest rotation per output step [rad].
        substeps: validity is checked at ``substeps`` evenly spaced sub-poses per output step.
        max_joint_step: largest joint change per output step and per sub-pose [rad].
        max_extend: longest extension of a tree per iteration, in the SE(3) metric [m].
        goal_bias: probability of extending towards the other tree's root instead of a sample.
        local_bias: probability of sampling near a random node of the growing tree (Gaussian,
            standard deviation ``max_extend / 2`` in translation and ``max_extend / (2 rot_weight)``
            in rotation) instead of in the whole box: explores narrow passages such as slots.
        bounds: ``((x, y, z) lower, (x, y, z) upper)`` box sampled for the object origin [m];
            None: the box around start and goal grown by ``bounds_padding``, clipped at the floor.
        bounds_padding: growth of the default sampling box [m].
        max_rotation: sampled orientations are the start's or the goal's turned by at most this
            angle about a random axis [rad] (90 deg: the bar may pitch, roll and yaw to snake).
        rot_weight: SE(3) metric ``|dp| + rot_weight * angle`` [m/rad].
        connect_attempts: the other tree tries to reach each new node from this many of its nodes:
            the nearest in the metric (which also grows by its permitted prefix) and the nearest by
            position alone (a full edge or nothing) — trees meeting in a narrow region from opposite
            orientations are nearest by position, not by the metric.
        shortcut_iterations: random shortcut attempts on a found path (0 = no smoothing).
        margin: required clearance [m]; None = the cell's ``safety_margin``.
    """

    max_iterations: int = 5000
    step: float = 0.05
    rot_step: float = math.radians(10.0)
    substeps: int = 5
    max_joint_step: float = math.radians(20.0)
    max_extend: float = 0.25
    goal_bias: float = 0.1
    local_bias: float = 0.5
    bounds: tuple[tuple[float, float, float], tuple[float, float, float]] | None = None
    bounds_padding: float = 0.5
    max_rotation: float = math.radians(90.0)
    rot_weight: float = 0.15
    connect_attempts: int = 3
    shortcut_iterations: int = 100
    margin: float | None = None

    def __post_init__(self) -> None:
        for name in ("max_iterations", "substeps", "connect_attempts"):
            _positive(name, getattr(self, name), integer=True)
        _positive("shortcut_iterations", self.shortcut_iterations, integer=True, zero_ok=True)
        for name in (
            "step",
            "rot_step",
            "max_joint_step",
            "max_extend",
            "max_rotation",
            "rot_weight",
        ):
            _positive(name, getattr(self, name))
        _positive("bounds_padding", self.bounds_padding, zero_ok=True)
        if self.rot_step > math.pi or self.max_rotation > math.pi:
            raise ParameterError(
                f"FallbackParams.rot_step/max_rotation: expected angles <= pi [rad], got {self.rot_step}, {self.max_rotation}"
            )
        for name in ("goal_bias", "local_bias"):
            g = getattr(self, name)
            if isinstance(g, bool) or not isinstance(g, (int, float)) or not 0.0 <= g <= 1.0:
                raise ParameterError(
                    f"FallbackParams.{name}: expected a probability in [0, 1], got {g!r}"
                )
        if self.goal_bias + self.local_bias > 1.0:
            raise ParameterError(
                f"FallbackParams.goal_bias + local_bias: expected <= 1, got {self.goal_bias + self.local_bias}"
            )
        if self.margin is not None:
            _positive("margin", self.margin, zero_ok=True)
        if self.bounds is not None:
            try:
                b = np.array(self.bounds, dtype=float)
            except (TypeError, ValueError):
                b = np.zeros(0)
            if b.shape != (2, 3) or not np.all(np.isfinite(b)) or not np.all(b[0] < b[1]):
                raise ParameterError(
                    f"FallbackParams.bounds: expected ((x, y, z) lower, (x, y, z) upper) [m] with lower < upper, got {self.bounds!r}"
                )
            object.__setattr__(self, "bounds", (tuple(map(float, b[0])), tuple(map(float, b[1]))))


@dataclass(frozen=True, slots=True)
class FallbackResult:
    """Result of :func:`rrt_connect` (arrays read-only; empty when ``ok`` is False).

    Attributes:
        ok: a permitted path from start to goal was found.
        T_world_object: object poses (N, 4, 4) [m]; row 0 = start, row N-1 = goal.
        q_left, q_right: joints (N, 6) [rad].
        clearance: minimum signed distance per pose (N,) [m].
        reason: why it failed ("" when ok).
        iterations: RRT-Connect iterations run.
        n_nodes: nodes in both trees.
        time_s: wall time [s].
        t: time of each pose (N,) [s]: ``t0 + i * step_time``.
    """

    ok: bool
    T_world_object: FloatArray
    q_left: FloatArray
    q_right: FloatArray
    clearance: FloatArray
    reason: str
    iterations: int
    n_nodes: int
    time_s: float
    t: FloatArray = field(default_factory=lambda: np.zeros(0))

    def __post_init__(self) -> None:
        for name in ("T_world_object", "q_left", "q_right", "clearance", "t"):
            arr = np.array(getattr(self, name), dtype=np.float64)
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)


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


# ----------------------------------------------------------------------------- search
def _generator(rng: np.random.Generator | int | None) -> np.random.Generator:
    if isinstance(rng, np.random.Generator):
        return rng
    if rng is None:
        return np.random.default_rng(0)
    if isinstance(rng, bool) or not isinstance(rng, (int, np.integer)) or rng < 0:
        raise ParameterError(
            f"rng: expected a numpy Generator, a seed (int >= 0) or None, got {rng!r}"
        )
    return np.random.default_rng(int(rng))


def _sampler(ctx: _Ctx, A: FloatArray, B: FloatArray, gen: np.random.Generator):
    """Object poses: origin uniform in the bounds, rotation the start's or the goal's (even odds)
    turned about a uniformly random axis by an angle distributed as in a uniform ball of radius
    ``max_rotation`` (density growing with the angle squared)."""
    p = ctx.p
    if p.bounds is None:
        lo = np.minimum(A[:3, 3], B[:3, 3]) - p.bounds_padding
        hi = np.maximum(A[:3, 3], B[:3, 3]) + p.bounds_padding
        lo[2] = max(lo[2], float(ctx.world.cell.floor_z))
        hi[2] = max(hi[2], lo[2] + 1e-3)
    else:
        lo, hi = np.array(p.bounds[0]), np.array(p.bounds[1])

    def sample() -> FloatArray:
        T = np.eye(4)
        T[:3, 3] = gen.uniform(lo, hi)
        axis = gen.normal(size=3)
        ang = p.max_rotation * gen.uniform() ** (1.0 / 3.0)
        R0 = A[:3, :3] if gen.uniform() < 0.5 else B[:3, :3]
        T[:3, :3] = R0 @ pin.exp3(axis / max(float(np.linalg.norm(axis)), 1e-12) * ang)
        return T

    return sample


def _near(ctx: _Ctx, tree: _Tree, gen: np.random.Generator) -> FloatArray:
    """A pose near a random node of ``tree`` (see ``FallbackParams.local_bias``)."""
    T0 = tree.T[int(gen.integers(len(tree)))]
    T = np.eye(4)
    T[:3, 3] = T0[:3, 3] + gen.normal(scale=0.5 * ctx.p.max_extend, size=3)
    T[:3, :3] = T0[:3, :3] @ pin.exp3(
        gen.normal(scale=0.5 * ctx.p.max_extend / ctx.p.rot_weight, size=3)
    )
    return T


def _fail(reason: str, it: int, nodes: int, tic: float) -> FallbackResult:
    e = np.zeros(0)
    return FallbackResult(
        False,
        np.zeros((0, 4, 4)),
        np.zeros((0, 6)),
        np.zeros((0, 6)),
        e,
        reason,
        it,
        nodes,
        time.perf_counter() - tic,
        e,
    )


def _root_checks(
    ctx: _Ctx, A: FloatArray, q0: tuple[FloatArray, FloatArray], B: FloatArray
) -> tuple[str, float, list[tuple[FloatArray, FloatArray]]]:
    """(reason, start clearance, goal joints): the goal solved on the start's IK branches and their
    wrist partners (up to 4 permitted combinations, the goal tree's roots); reason "" if fine."""
    w = ctx.world
    for s, H, q in zip(("left", "right"), w.hand_poses(*q0), q0):
        if not np.allclose(H, A @ w.T_object_hand[s], atol=1e-6):
            return (
                f"invalid start: the {s} hand is not at its grasp of the start pose",
                math.nan,
                [],
            )
        if not np.all(w.arms[s].within_limits(q, tol=1e-12)):
            return f"invalid start: {s} arm joints outside the limits", math.nan, []
    c = w.clearance(q0[0], q0[1], A, ctx.t0)
    if c.distance < ctx.margin:
        return (
            f"invalid start: clearance {c.distance:.4f} m below the margin {ctx.margin:.3f} m ({c.pair[0]} – {c.pair[1]})",
            c.distance,
            [],
        )
    options: list[list[FloatArray]] = []
    for k, (s, T_bh) in enumerate(zip(("left", "right"), hands_from_object(w.cell, B))):
        arm = w.arms[s]
        if arm.analytic:  # the start's branch and its wrist partner (reached through q5 = 0)
            b = int(puma.branch_of(q0[k]))
            rs = [arm.ik(T_bh, config=c, q_near=q0[k]) for c in (b, b ^ 1)]
        else:
            rs = [arm.ik(T_bh, q_near=q0[k])]
        ok = [np.array(r.q, dtype=float) for r in rs if r.ok]
        if not ok:
            r = rs[0]
            return (
                f"goal unreachable: {s} arm IK on the start's branch: {r.status}: {r.reason}",
                c.distance,
                [],
            )
        options.append(ok)
    tg = float(ctx.t_lb(B[None])[0])
    roots, worst = [], None
    for qL in options[0]:
        for qR in options[1]:
            cg = w.clearance(qL, qR, B, tg)
            if cg.distance >= ctx.margin:
                roots.append((qL, qR))
            elif worst is None or cg.distance < worst.distance:
                worst = cg
    if not roots and worst is not None:
        return (
            (
                f"goal blocked: clearance at the goal pose itself is {worst.distance:.4f} m, below the "
                f"margin {ctx.margin:.3f} m ({worst.pair[0]} – {worst.pair[1]}, t = {tg:.2f} s)"
            ),
            c.distance,
            [],
        )
    return "", c.distance, roots


def rrt_connect(
    world: World,
    T_start: npt.ArrayLike,
    q_start: tuple[npt.ArrayLike, npt.ArrayLike],
    T_goal: npt.ArrayLike,
    params: FallbackParams = FallbackParams(),
    rng: np.random.Generator | int | None = None,
    *,
    t0: float = 0.0,
    step_time: float = 0.0,
    striving: object | None = None,
) -> FallbackResult:
    """Bidirectional RRT-Connect over object poses in SE(3), then shortcut smoothing (module docstring).

    Args:
        world: the :class:`~dualpuma.world.World` of the cell (its scratch buffers are used).
        T_start: start object pose (4, 4) [m].
        q_start: (q_left, q_right) at the start [rad], each (6,); their IK branches are kept.
        T_goal: goal object pose (4, 4) [m].
        params: :class:`FallbackParams`.
        rng: a Generator (advanced), a seed, or None (= seed 0, deterministic).
        t0: time of the start pose [s] (moving obstacles).
        step_time: time per output step [s].
        striving: the frozen Striving run's :class:`~dualpuma.planner.StrivingParams` (optional): its
            margin applies when ``params.margin`` is None and validity is checked at least at its
            ``substeps``, so the result meets Striving's permission rule.

    Returns:
        :class:`FallbackResult`; an invalid start, an unreachable or blocked goal, or no path within
        ``max_iterations`` give ``ok=False`` with a reason (never an exception).

    Raises:
        ParameterError: params of the wrong type, bad rng / t0 / step_time.
        PoseError, JointError: malformed poses or joints.
    """
    tic = time.perf_counter()
    if not isinstance(params, FallbackParams):
        raise ParameterError(f"params: expected FallbackParams, got {type(params).__name__}")
    if not isinstance(world, World):
        raise ParameterError(f"world: expected a dualpuma World, got {type(world).__name__}")
    if not (math.isfinite(t0) and math.isfinite(step_time) and step_time >= 0):
        raise ParameterError(
            f"t0, step_time: expected finite times with step_time >= 0 [s], got {t0}, {step_time}"
        )
    A = validate_pose(T_start, name="T_start").copy()
    B = validate_pose(T_goal, name="T_goal").copy()
    if A.shape != (4, 4) or B.shape != (4, 4):
        raise ParameterError("T_start and T_goal must be single poses of shape (4, 4)")
    if len(q_start) != 2:
        raise ParameterError("q_start: expected (q_left, q_right)")
    q0 = (
        np.array(validate_joints(q_start[0], name="q_start[0]"), float),
        np.array(validate_joints(q_start[1], name="q_start[1]"), float),
    )
    if q0[0].shape != (6,) or q0[1].shape != (6,):
        raise ParameterError("q_start: expected two joint vectors of shape (6,)")
    if striving is not None:
        m = getattr(striving, "margin", None)
        sub = max(params.substeps, int(getattr(striving, "substeps", 1)))
        params = dataclasses.replace(
            params, substeps=sub, margin=params.margin if params.margin is not None else m
        )
    gen = _generator(rng)
    world.reset()  # bit-identical distances whatever the world computed before
    ctx = _Ctx(world, params, A, float(t0), float(step_time))
    why, d0, roots = _root_checks(ctx, A, q0, B)
    if not roots:
        return _fail(why, 0, 0, tic)

    def done(path: _Path, it: int, nodes: int) -> FallbackResult:
        smooth = _shortcut(ctx, path, gen)
        final, _ = _verify(ctx, [(smooth.P[0], 0)] + [(T, 1) for T in smooth.P[1:]], q0, d0)
        path = final if final is not None else path  # the smoothed path is re-verified as a whole
        n = path.P.shape[0]
        return FallbackResult(
            True,
            path.P,
            path.qL,
            path.qR,
            path.d,
            "",
            it,
            nodes,
            time.perf_counter() - tic,
            ctx.t0 + np.arange(n) * ctx.dt,
        )

    run, n = ctx.edge(A, q0, B, ctx.t0)
    direct = _verify(ctx, [(A, 0), (B, n)], q0, d0)[0] if run.m == n else None
    if direct is not None:
        return done(direct, 0, 2)
    t_goal = float(ctx.t_lb(B[None])[0])
    trees = (_Tree(A, q0[0], q0[1], ctx.t0), _Tree(B, roots[0][0], roots[0][1], t_goal))
    for qL, qR in roots[1:]:
        trees[1].add(B, qL, qR, -1, 0, t_goal)  # further roots: the same goal pose, other joints
    sample = _sampler(ctx, A, B, gen)
    failed_joins: list[str] = []
    it = 0
    for it in range(1, params.max_iterations + 1):
        ia = (it - 1) % 2
        ta, tb = trees[ia], trees[1 - ia]
        u = gen.uniform()
        S = (
            tb.T[0]
            if u < params.goal_bias
            else (_near(ctx, ta, gen) if u < params.goal_bias + params.local_bias else sample())
        )
        new = _extend(ctx, ta, ia == 0, S)
        if new < 0:
            continue
        hit = _connect(ctx, tb, ia == 1, ta.T[new], (ta.qL[new], ta.qR[new]))
        if hit is None:
            continue
        j, n_conn = hit
        (ts, i_s), (tg_, i_g) = ((ta, new), (tb, j)) if ia == 0 else ((tb, j), (ta, new))
        way = [(ts.T[k], ts.n[k]) for k in reversed(ts.chain(i_s))]
        way.append((tg_.T[i_g], n_conn))
        for k in tg_.chain(i_g)[:-1]:
            way.append((tg_.T[tg_.parent[k]], tg_.n[k]))
        path, why = _verify(ctx, way, q0, d0)
        if path is not None:
            return done(path, it, len(ta) + len(tb))
        failed_joins.append(why)
    nodes = len(trees[0]) + len(trees[1])
    top = ", ".join(f"{k} ({v})" for k, v in ctx.stats.most_common(3))
    extra = (
        f"; {len(failed_joins)} connection(s) failed re-verification at real times (first: {failed_joins[0]})"
        if failed_joins
        else ""
    )
    return _fail(
        f"no path found in {it} iterations ({len(trees[0])} start-tree, {len(trees[1])} goal-tree nodes); "
        f"most frequent refusals: {top or 'none'}{extra}",
        it,
        nodes,
        tic,
    )


def _node_time(ctx: _Ctx, tree: _Tree, forward: bool, parent: int, m: int, T: FloatArray) -> float:
    return tree.t[parent] + m * ctx.dt if forward else float(ctx.t_lb(T[None])[0])


def _extend(ctx: _Ctx, tree: _Tree, forward: bool, S: FloatArray) -> int:
    """Grow ``tree`` from its nearest node towards S by at most ``max_extend``; new node or -1."""
    i, d = tree.nearest(S, ctx.p.rot_weight)[0]
    if d < 1e-9:
        return -1
    T = S if d <= ctx.p.max_extend else _interp(tree.T[i], S, np.array([ctx.p.max_extend / d]))[0]
    run, _ = ctx.edge(tree.T[i], (tree.qL[i], tree.qR[i]), T, tree.t[i] if forward else None)
    if run.m == 0:
        return -1
    k = run.m * ctx.sub - 1
    return tree.add(
        run.P[k], run.qL[k], run.qR[k], i, run.m, _node_time(ctx, tree, forward, i, run.m, run.P[k])
    )


def _same_joints(run: _Run, q: tuple[FloatArray, FloatArray]) -> bool:
    """Do the edge's last joints equal q up to whole turns? (q4 + 2 pi is the same arm geometry; the
    path is re-solved forward as a whole, where the joint limits decide.)"""
    gap = [
        np.abs((a[-1] - b + np.pi) % (2 * np.pi) - np.pi).max()
        for a, b in ((run.qL, q[0]), (run.qR, q[1]))
    ]
    return max(gap) <= _JOINT_MATCH


def _connect(
    ctx: _Ctx, tree: _Tree, forward: bool, X: FloatArray, qX: tuple[FloatArray, FloatArray]
) -> tuple[int, int] | None:
    """Grow ``tree`` straight towards pose X (held by the other tree with joints qX).

    Returns (node of ``tree`` whose edge to X is fully permitted and arrives with joints qX, that
    edge's output steps), or None after adding the permitted prefix as nodes every ``max_extend``.
    """
    order = tree.nearest(X, ctx.p.rot_weight)
    extra = [i for i, _ in tree.nearest(X, 0.0, ctx.p.connect_attempts) if i != order[0][0]][
        : ctx.p.connect_attempts - 1
    ]
    for (
        i
    ) in extra:  # nearest by position (any orientation): a full, joint-continuous edge or nothing
        run, n = ctx.edge(tree.T[i], (tree.qL[i], tree.qR[i]), X, tree.t[i] if forward else None)
        if run.m == n and _same_joints(run, qX):
            return i, n
    i, d = order[0]
    run, n = ctx.edge(tree.T[i], (tree.qL[i], tree.qR[i]), X, tree.t[i] if forward else None)
    m = run.m
    if m == n:
        if _same_joints(run, qX):
            return i, n
        m -= 1  # same pose, other joints (e.g. q4 + 2 pi): keep the prefix only
    every = max(1, int(ctx.p.max_extend / max(d / n, 1e-9)))
    parent, done = i, 0
    for k in list(range(every, m, every)) + ([m] if m else []):
        f = k * ctx.sub - 1
        parent = tree.add(
            run.P[f],
            run.qL[f],
            run.qR[f],
            parent,
            k - done,
            _node_time(ctx, tree, forward, parent, k - done, run.P[f]),
        )
        done = k
    return None


# ----------------------------------------------------------------------------- the snaking scenario
SLOT_YAW = math.radians(
    45.0
)  #: yaw of the slot in the upper plate of :func:`slot_field_cell` (lower: minus) [rad]


def slot_field_cell() -> tuple[Cell, FloatArray, FloatArray]:
    """A slot field that the bar passes only by yawing one way, then the other ("snaking").

    ``Cell.default()`` with two horizontal plates 0.26 m apart under the middle of the bar, between
    the hands: each a strip 0.12 m wide (x), 1.5 m long (y) and 0.04 m thick, cut by a slot 0.14 m
    wide yawed by +45 deg (upper plate) and -45 deg (lower plate) about the vertical. The bar (0.75 m
    along x, 0.05 m square) is lowered 0.49 m through both. It fits a slot with the 2 cm margin only
    when its yaw is within roughly 10..50 deg of the slot's sense; held unrotated its clearance to the
    slot's edges is about 14 mm, below the 20 mm margin, so the straight, fixed-orientation path is
    blocked. Each slot's edge is a thin yawed lip (0.015 m); the strip's straight pieces overlap its
    far edge at one side of the strip, leaving small triangular pockets that no bar can pass.
    Start and goal: the bar level and unrotated, centred between the shoulders (0.93 m and 0.44 m up),
    both arms away from their wrist singularity.

    Returns:
        ``(cell, T_start, T_goal)``: object poses (4, 4) [m]; the cell's home joints hold the bar at
        ``cell.T_world_object_start`` (not ``T_start``: solve the start on the home branches).
    """
    base = Cell.default()
    A = base.T_world_object_start.copy()
    A[:3, 3] += (-0.40, -0.35, 0.70)
    B = A.copy()
    B[2, 3] -= 0.49
    hw, gap, thick, half_len, lip = 0.06, 0.14, 0.04, 0.75, 0.015
    c0 = (A @ base.bar.T_object_bar)[:3, 3]
    obstacles = []
    for k, (dz, yaw) in enumerate(((-0.11, SLOT_YAW), (-0.37, -SLOT_YAW))):
        c = c0 + (0.0, 0.0, dz)  # slot centre on the bar centre's straight way down
        R = calc_rot([0.0, 0.0, yaw])
        ca, ta = math.cos(yaw), abs(math.tan(yaw))
        yf = (gap / 2 + lip) / ca + hw * ta - 0.005  # straight pieces overlap the lips' far edges
        for sgn, name in ((1, "back"), (-1, "front")):
            T = np.eye(4)
            T[:3, :3] = R
            T[:3, 3] = c + (0.0, sgn * (gap / 2 + lip / 2) / ca, 0.0)  # lip centred over the strip
            obstacles.append(
                Obstacle(
                    f"plate{k + 1}_{name}_lip",
                    "box",
                    np.array([2 * hw / ca + lip * ta, lip, thick]),
                    T,
                )
            )
            T = np.eye(4)
            T[:3, 3] = c + (0.0, sgn * 0.5 * (yf + half_len), 0.0)
            obstacles.append(
                Obstacle(f"plate{k + 1}_{name}", "box", np.array([2 * hw, half_len - yf, thick]), T)
            )
    return dataclasses.replace(base, obstacles=tuple(obstacles), name="slot-field"), A, B
