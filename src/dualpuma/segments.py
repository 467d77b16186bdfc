"""Straight runs of the object frame for the Striving planner: interpolation, batched permission
checks (vectorised dual IK + one batched clearance query per chunk), step refinement on joint jumps,
and the twisting detector. Internal to :mod:`dualpuma.planner`."""

from __future__ import annotations

import math
import re

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from .clearance import _point_distance, bar_major_dimension, clearance_batch
from .coordination import solve_path
from .paths import calc_rot, interpolate_object

FloatArray = npt.NDArray[np.float64]


class _Ctx:
    """Per-call state (never shared between calls)."""

    def __init__(self, world, params) -> None:
        self.world = world
        self.cell = world.cell
        self.p = params
        self.margin = float(world.cell.safety_margin if params.margin is None else params.margin)
        self.rho = bar_major_dimension(world.cell) if params.mapping else 0.0
        g = world.geoms
        self.arm_arm_mask = np.array([g[a].kind == "arm" and g[b].kind == "arm" for a, b in world.pair_ids])
        self.last_aa = math.nan  # arm–arm clearance of the last accepted step (twist detector)
        cache = world.__dict__.setdefault("_planner_reach", {})  # per World: its geometry never changes
        if not cache:
            cache.update(left=_joint_reach(world, "left"), right=_joint_reach(world, "right"))
        self.reach_L, self.reach_R = cache["left"], cache["right"]
        self.v_max = max([float(np.linalg.norm(ob.velocity)) for ob in world.cell.obstacles] + [0.0])

    def arm_arm(self, qL, qR, T) -> tuple[float, tuple[str, str]]:
        """Minimum arm–arm clearance and its pair at one configuration [m]."""
        c = self.world.clearance(qL, qR, T, per_pair=True)
        d = np.where(self.arm_arm_mask, c.pair_distances, np.inf)
        k = int(np.argmin(d))
        return float(d[k]), self.world.pair_names[k]


def _joint_reach(world, side: str) -> FloatArray:
    """Per joint of one arm, an upper bound of the distance from the joint's origin (hence axis) to
    any point of any geometry it moves (links downstream, and the bar for the left arm) [m]."""
    m, gm = world.model, world.geom_model
    joints = [j for j in range(1, m.njoints) if m.names[j].startswith(side + "/")]
    R = np.zeros(len(joints))
    for g, info in zip(gm.geometryObjects, world.geoms):
        if g.parentJoint not in joints:
            continue
        if info.shape == "box":
            ext = 0.5 * float(np.linalg.norm(info.size))
        elif info.shape == "capsule":
            ext = 0.5 * info.size[1] + info.size[0]
        else:
            ext = info.size[0] if info.size else 0.0
        ext += float(np.linalg.norm(g.placement.translation))
        i = joints.index(g.parentJoint)
        for k in range(i, -1, -1):  # the geometry's joint and every joint above it
            chain = sum(float(np.linalg.norm(m.jointPlacements[joints[l]].translation)) for l in range(k + 1, i + 1))
            R[k] = max(R[k], chain + ext)
    return R


def _angle(Ra: FloatArray, Rb: FloatArray) -> float:
    return float(np.linalg.norm(pin.log3(Ra.T @ Rb)))


def _n_steps(ctx: _Ctx, A: FloatArray, B: FloatArray, rpy_a, rpy_b, step: float) -> int:
    dist = float(np.linalg.norm(B[:3, 3] - A[:3, 3]))
    ang = float(np.max(np.abs(rpy_b - rpy_a))) if ctx.p.orientation == "rpy" else _angle(A[:3, :3], B[:3, :3])
    return max(1, math.ceil(dist / step - 1e-9), math.ceil(ang / ctx.p.rot_step - 1e-9))


def _line(ctx: _Ctx, A: FloatArray, B: FloatArray, rpy_a, rpy_b, m: int) -> tuple[FloatArray, FloatArray]:
    """m poses after A ending exactly at B, and their rpy angles (rpy mode; else zeros)."""
    s = np.arange(1, m + 1) / m
    if ctx.p.orientation == "rpy":
        rpy = rpy_a + s[:, None] * (rpy_b - rpy_a)
        P = np.tile(np.eye(4), (m, 1, 1))
        P[:, :3, 3] = A[:3, 3] + s[:, None] * (B[:3, 3] - A[:3, 3])
        P[:, :3, :3] = calc_rot(rpy)
        P[-1, :3, :3] = B[:3, :3]
        return P, rpy
    P = interpolate_object(A, B, m, ctx.p.orientation)
    return P, np.zeros((m, 3))


def _permitted_prefix(ctx: _Ctx, P: FloatArray, q0: tuple[FloatArray, FloatArray], t0: float, k_per_pose: float,
                      d0: float):
    """How many leading poses of P (whole steps of ``substeps`` poses) are permitted; their joints,
    clearances and the refusal reason.

    Clearance is queried at every step pose, and at a pose between steps only when a rigorous
    lower bound cannot already clear it: for two configurations a and b, no point of any geometry
    moves more than D(a, b) = sum_j |q_j(a) - q_j(b)| R_j over both arms (R_j bounds the distance
    of every geometry downstream of joint j from its axis; moving obstacles add |v| dt), so the
    clearance at b is at least d(a) - D(a, b). A between-step pose is queried only if the bound
    from both neighbouring step poses is below the margin.
    """
    w = ctx.world
    sub = ctx.p.substeps
    sol = solve_path(w, P, q0, max_step=ctx.p.max_joint_step, _trusted=True)
    n_ok = sol.n_ok
    reason = re.sub(r" at step \d+", "", sol.reason)
    n = P.shape[0]
    d = np.full(n, np.inf)
    idx = np.zeros(n, dtype=np.int64)
    m = n_ok // sub  # whole steps with IK
    if m == 0:
        return n_ok, sol, d, idx, reason
    times = t0 + k_per_pose * np.arange(1, n + 1)
    QL, QR = sol.q_left, sol.q_right
    coarse = np.arange(1, m + 1) * sub - 1
    # the bar is placed by the left hand's chain: IK holds the grasp exactly, so no poses are passed
    d[coarse], idx[coarse] = clearance_batch(w, QL[coarse], QR[coarse], t=times[coarse])
    if sub > 1:
        fine = np.setdiff1d(np.arange(m * sub), coarse, assume_unique=True)
        k = fine // sub  # the step each between-pose belongs to
        prevL = np.vstack([q0[0], QL[coarse[:-1]]])[k]
        prevR = np.vstack([q0[1], QR[coarse[:-1]]])[k]
        d_prev = np.concatenate([[d0], d[coarse[:-1]]])[k]
        v = ctx.v_max * k_per_pose * sub
        lb_prev = d_prev - (np.abs(QL[fine] - prevL) @ ctx.reach_L + np.abs(QR[fine] - prevR) @ ctx.reach_R) - v
        lb_next = d[coarse][k] - (np.abs(QL[coarse][k] - QL[fine]) @ ctx.reach_L
                                  + np.abs(QR[coarse][k] - QR[fine]) @ ctx.reach_R) - v
        need = fine[np.maximum(lb_prev, lb_next) < ctx.margin]
        if need.size:
            d[need], idx[need] = clearance_batch(w, QL[need], QR[need], t=times[need])
    bad = d[: m * sub] < ctx.margin
    if ctx.p.mapping and ctx.cell.obstacles:
        bad |= _in_grown(ctx, P[: m * sub, :3, 3], times[: m * sub])
    n_ok = m * sub if n_ok >= m * sub and not bad.any() else n_ok
    if bad.any():
        first = int(np.argmax(bad))
        if d[first] < ctx.margin:
            a, b = w.pair_names[idx[first]]
            reason = f"clearance {d[first]:.4f} m below {ctx.margin:.3f} m ({a} – {b})"
        else:
            reason = "object origin inside a grown obstacle (configuration mapping)"
        n_ok = first
    return n_ok, sol, d, idx, reason


def _in_grown(ctx: _Ctx, p: FloatArray, times: FloatArray) -> npt.NDArray[np.bool_]:
    out = np.zeros(p.shape[0], dtype=bool)
    for ob in ctx.cell.obstacles:
        size = tuple(float(v) for v in np.atleast_1d(ob.size))
        if np.any(ob.velocity != 0):
            dist = np.array([_point_distance(ob.shape, size, ob.pose_at(t), pi) for pi, t in zip(p, times)])
        else:
            dist = _point_distance(ob.shape, size, ob.T_world_obstacle, p)
        out |= dist < ctx.rho
    return out


def _permitted_lazy(ctx: _Ctx, P: FloatArray, q0, t0: float, dt: float, first: int, d0: float):
    """:func:`_permitted_prefix` over P in two chunks (``first`` poses, then the rest): a refusal
    near the start (the common case after a recovery) costs only the first chunk."""
    n = P.shape[0]
    QL, QR = np.full((n, 6), np.nan), np.full((n, 6), np.nan)
    D, I = np.full(n, np.nan), np.zeros(n, dtype=np.int64)
    start, chunk, q = 0, max(1, first), q0
    while start < n:
        end = min(n, start + chunk)
        n_ok, sol, d, idx, reason = _permitted_prefix(ctx, P[start:end], q, t0 + start * dt, dt, d0)
        QL[start : start + n_ok], QR[start : start + n_ok] = sol.q_left[:n_ok], sol.q_right[:n_ok]
        D[start : start + n_ok], I[start : start + n_ok] = d[:n_ok], idx[:n_ok]
        if n_ok < end - start:
            return start + n_ok, QL, QR, D, I, reason
        q = (sol.q_left[n_ok - 1], sol.q_right[n_ok - 1])
        d0 = float(d[n_ok - 1])
        start, chunk = end, n  # the first chunk survived: the rest in one go
    return n, QL, QR, D, I, ""


class _Segment:
    """Result of trying to move from the current pose towards a target."""

    __slots__ = ("P", "d", "idx", "n", "n_acc", "qL", "qR", "reason", "rpy")


def _try_segment(ctx: _Ctx, A, rpy_a, q, B, rpy_b, k0: int) -> _Segment:
    """Move A -> B in steps; returns how many whole steps are permitted (with refinement on jumps)."""
    p = ctx.p
    step = p.step
    d0 = float(ctx.world.min_distance(q[0], q[1], A, k0 * p.step_time)[0])
    while True:
        m = _n_steps(ctx, A, B, rpy_a, rpy_b, step)
        sub = p.substeps
        P, rpy = _line(ctx, A, B, rpy_a, rpy_b, m * sub)
        n_fine, QL, QR, d, idx, reason = _permitted_lazy(ctx, P, q, k0 * p.step_time, p.step_time / sub, 2 * sub, d0)
        n_acc = n_fine // sub
        rows = np.arange(1, n_acc + 1) * sub - 1
        # the seed's RobMov bound holds per step: refine the step when a joint would move too far
        qL = np.vstack([q[0], QL[rows]])
        qR = np.vstack([q[1], QR[rows]])
        dq = np.maximum(np.abs(np.diff(qL, axis=0)).max(axis=1), np.abs(np.diff(qR, axis=0)).max(axis=1))
        too_far = np.flatnonzero(dq > p.max_joint_step)
        if too_far.size and step > p.min_step:
            step = max(p.min_step, step / 2)
            continue
        if too_far.size:
            n_acc = int(too_far[0])
            rows = rows[:n_acc]
            reason = f"a joint would move more than {math.degrees(p.max_joint_step):.1f} deg in one step"
        if p.twist_buffer > 0 and n_acc and _angle(A[:3, :3], B[:3, :3]) > 1e-9:
            n_acc, rows, reason = _twist_check(ctx, P, QL, QR, rows, n_acc, reason)
        seg = _Segment()
        seg.P, seg.rpy = P[rows], rpy[rows]
        seg.qL, seg.qR = QL[rows], QR[rows]
        seg.d, seg.idx = d[rows], idx[rows]
        seg.n_acc, seg.n, seg.reason = n_acc, m, reason
        return seg


def _twist_check(ctx: _Ctx, P, QL, QR, rows, n_acc: int, reason: str):
    """Twisting detector over the accepted steps (see StrivingParams.twist_buffer)."""
    buf = ctx.p.twist_buffer
    prev = ctx.last_aa
    for i, r in enumerate(rows[:n_acc]):
        d, pair = ctx.arm_arm(QL[r], QR[r], P[r])
        if math.isfinite(prev) and d < prev and d < buf:
            why = (f"twisting collision ahead: arm–arm clearance {d:.4f} m ({pair[0]} – {pair[1]}) is inside the "
                   f"{buf:.3f} m buffer and closing by {prev - d:.4f} m per step while the bar rotates")
            ctx.last_aa = prev
            return i, rows[:i], why
        prev = d
    ctx.last_aa = prev
    return n_acc, rows, reason


def _key(T: FloatArray) -> tuple[int, ...]:
    """Visited-pose key: position to 1 mm, rotation matrix entries to 1e-3."""
    return tuple(np.round(T[:3, 3] * 1e3).astype(np.int64).tolist() + np.round(T[:3, :3] * 1e3).astype(np.int64).ravel().tolist())
