"""Straight runs of the object frame for the Striving planner: interpolation, batched permission
checks (vectorised dual IK + one batched clearance query per chunk), step refinement on joint jumps,
and the twisting detector. Internal to :mod:`dualpuma.planner`."""

from __future__ import annotations

import math
import re

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from .branch_path import solve_lines_branch
from .clearance import _point_distance, bar_major_dimension
from .coordination import solve_path
from .paths import _exp3_batch, calc_rot, interpolate_object
from .queries import below_margin, min_clearance

FloatArray = npt.NDArray[np.float64]


class _Ctx:
    """Per-call state (never shared between calls)."""

    def __init__(self, world, params) -> None:
        self.world = world
        self.cell = world.cell
        self.p = params
        self.margin = float(world.cell.safety_margin if params.margin is None else params.margin)
        self.rho = bar_major_dimension(world.cell) if params.mapping else 0.0
        self.last_aa = math.nan  # arm–arm clearance of the last accepted step (twist detector)
        cache = world.__dict__.setdefault("_planner_reach", {})  # per World: its geometry never changes
        if not cache:
            g = world.geoms
            cache.update(left=_joint_reach(world, "left"), right=_joint_reach(world, "right"),
                         arm_arm=np.array([g[a].kind == "arm" and g[b].kind == "arm" for a, b in world.pair_ids]),
                         v_max=max([float(np.linalg.norm(ob.velocity)) for ob in world.cell.obstacles] + [0.0]))
        self.reach_L, self.reach_R = cache["left"], cache["right"]
        self.reach = np.concatenate([self.reach_L, self.reach_R])  # (12,) both arms' R_j [m]
        self.arm_arm_mask, self.v_max = cache["arm_arm"], cache["v_max"]
        a_l, a_r = world.arms["left"], world.arms["right"]
        self.one_branch_ik = a_l.analytic and a_r.analytic and np.array_equal(a_l.limits, a_r.limits)
        self.limits = a_l.limits
        self.base_inv = np.stack([world.T_base_inv["left"], world.T_base_inv["right"]])[:, None]
        self.object_hand = np.stack([world.T_object_hand["left"], world.T_object_hand["right"]])[:, None]

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
    dist = math.dist(A[:3, 3].tolist(), B[:3, 3].tolist())
    if ctx.p.orientation == "rpy":
        ang = float(np.max(np.abs(rpy_b - rpy_a)))
    else:
        ang = 0.0 if np.array_equal(A[:3, :3], B[:3, :3]) else _angle(A[:3, :3], B[:3, :3])
    return max(1, math.ceil(dist / step - 1e-9), math.ceil(ang / ctx.p.rot_step - 1e-9))


def _line(ctx: _Ctx, A: FloatArray, B: FloatArray, rpy_a, rpy_b, m: int, count: int | None = None) -> tuple[FloatArray, FloatArray]:
    """m poses after A ending exactly at B, and their rpy angles (rpy mode; else zeros); with
    ``count``, only the first ``count`` of them."""
    n = m if count is None else count
    s = np.arange(1, n + 1) / m
    if ctx.p.orientation == "rpy":
        rpy = rpy_a + s[:, None] * (rpy_b - rpy_a)
        P = np.tile(np.eye(4), (n, 1, 1))
        P[:, :3, 3] = A[:3, 3] + s[:, None] * (B[:3, 3] - A[:3, 3])
        P[:, :3, :3] = calc_rot(rpy)
        if n == m:
            P[-1, :3, :3] = B[:3, :3]
        return P, rpy
    if ctx.p.orientation == "slerp":  # trusted inline version of interpolate_object
        P = np.empty((n, 4, 4))
        P[:] = A
        P[:, :3, 3] = A[:3, 3] + s[:, None] * (B[:3, 3] - A[:3, 3])
        if not np.array_equal(A[:3, :3], B[:3, :3]):
            P[:, :3, :3] = A[:3, :3] @ _exp3_batch(s[:, None] * pin.log3(A[:3, :3].T @ B[:3, :3]))
        if n == m:
            P[-1] = B
    else:
        P = interpolate_object(A, B, m, ctx.p.orientation)[:n]
    return P, np.zeros((n, 3))


_ONE_START = np.zeros(1, dtype=np.int64)


class _Line:
    """A candidate straight run: its poses (``m`` steps of ``substeps`` poses), their rpy angles,
    and both arms' IK along it (filled by :func:`_solve_lines`): joints Q (n, 12), left then
    right, valid for the first ``n_ok`` poses (else ``reason``)."""

    __slots__ = ("P", "Q", "m", "n_ok", "reason", "rpy")

    def __init__(self, ctx: _Ctx, A: FloatArray, B: FloatArray, rpy_a, rpy_b, step: float) -> None:
        self.m = _n_steps(ctx, A, B, rpy_a, rpy_b, step)
        self.P, self.rpy = _line(ctx, A, B, rpy_a, rpy_b, self.m * ctx.p.substeps)


def _solve_lines(ctx: _Ctx, lines: list[_Line], q0: FloatArray) -> None:
    """Both arms' IK along every line from the joints ``q0`` (12,): one vectorised call for all of
    them (the PUMA fast path of :mod:`dualpuma.branch_path`), else :func:`solve_path` per line."""
    w, max_step = ctx.world, ctx.p.max_joint_step
    q0s = (q0[:6], q0[6:])
    out = None
    if ctx.one_branch_ik:
        if len(lines) == 1:
            T, starts = lines[0].P, _ONE_START
        else:
            T = np.concatenate([ln.P for ln in lines])
            starts = np.zeros(len(lines), dtype=np.int64)
            for i, ln in enumerate(lines[:-1]):
                starts[i + 1] = starts[i] + ln.P.shape[0]
        T_bh = ctx.base_inv @ T[None] @ ctx.object_hand  # (2, M, 4, 4): both hands' targets
        out = solve_lines_branch(T_bh, starts, q0s, ctx.limits, max_step)
    if out is None:
        for ln in lines:
            sol = solve_path(w, ln.P, q0s, max_step=max_step, _trusted=True)
            ln.Q, ln.n_ok = np.hstack([sol.q_left, sol.q_right]), sol.n_ok
            ln.reason = re.sub(r" at step \d+", "", sol.reason)
        return
    for ln, (Q, _ok, first, status, why) in zip(lines, out):
        ln.n_ok = int(first.min())
        ln.Q = Q
        fails = [(int(first[k]), f"{s} arm: {status[k]}: {why[k]}") for k, s in enumerate(("left", "right")) if status[k] != "ok"]
        ln.reason = min(fails)[1] if fails else ""


def _solve_chains(ctx: _Ctx, chains: list[tuple[_Line, _Line]], q0: FloatArray) -> None:
    """Solve (approach, continuation) pairs of lines in one IK call: each pair as one path from
    ``q0`` (the continuation starts where its approach ends, so it is solved exactly as it would
    be from the approach's last joints), then split back into the two lines."""
    joined = []
    for a, b in chains:
        ln = _Line.__new__(_Line)
        ln.P = np.concatenate([a.P, b.P])
        joined.append(ln)
    _solve_lines(ctx, joined, q0)
    for (a, b), ln in zip(chains, joined):
        n1 = a.P.shape[0]
        a.Q, b.Q = ln.Q[:n1], ln.Q[n1:]
        a.n_ok, a.reason = min(ln.n_ok, n1), (ln.reason if ln.n_ok < n1 else "")
        b.n_ok, b.reason = max(ln.n_ok - n1, 0), ln.reason


def _permitted_prefix(ctx: _Ctx, P: FloatArray, Q: FloatArray, n_ok: int, reason: str, q0: FloatArray, t0: float,
                      k_per_pose: float, d0: float):
    """How many leading poses of P (whole steps of ``substeps`` poses) are permitted, given both
    arms' joints along P (Q (n, 12), valid for the first ``n_ok`` poses, else ``reason``) from
    ``q0`` (12,) with clearance ``d0``; their clearances and the refusal reason.

    Clearance is queried at every step pose, and at a pose between steps only when a rigorous
    lower bound cannot already clear it: for two configurations a and b, no point of any geometry
    moves more than D(a, b) = sum_j |q_j(a) - q_j(b)| R_j over both arms (R_j bounds the distance
    of every geometry downstream of joint j from its axis; moving obstacles add |v| dt), so the
    clearance at b is at least d(a) - D(a, b). A between-step pose is queried only if the bound
    from both neighbouring step poses is below the margin, and then only whether it keeps the
    margin (:func:`~dualpuma.queries.below_margin`; its distance only if not).
    """
    w = ctx.world
    sub = ctx.p.substeps
    n = P.shape[0]
    d = np.full(n, np.inf)
    idx = np.zeros(n, dtype=np.int64)
    m = n_ok // sub  # whole steps with IK
    if m == 0:
        return n_ok, d, idx, reason
    times = t0 + k_per_pose * np.arange(1, n + 1)
    coarse = np.arange(1, m + 1) * sub - 1
    # the bar is placed by the left hand's chain: IK holds the grasp exactly, so no poses are passed
    d_c, idx[coarse] = min_clearance(w, Q[coarse], times[coarse])
    d[coarse] = d_c
    bad_c = d_c < ctx.margin
    if bad_c.any():  # poses after the first refused step pose cannot matter
        m = int(bad_c.argmax()) + 1
        coarse, d_c = coarse[:m], d_c[:m]
    if sub > 1:
        fine = np.arange(m * sub)
        fine = fine[fine % sub != sub - 1]
        k = fine // sub  # the step each between-pose belongs to
        Qc, Qf = Q[coarse], Q[fine]
        prev = np.vstack([q0, Qc[:-1]])[k]
        d_prev = np.concatenate([[d0], d_c[:-1]])[k]
        lb = np.maximum(d_prev - np.abs(Qf - prev) @ ctx.reach, d_c[k] - np.abs(Qc[k] - Qf) @ ctx.reach)
        need = fine[lb - ctx.v_max * k_per_pose * sub < ctx.margin]
        if need.size:  # whether they keep the margin; distances only where they do not
            hit = need[below_margin(w, Q[need], times[need], ctx.margin)]
            if hit.size:
                d[hit], idx[hit] = min_clearance(w, Q[hit], times[hit])
    bad = d[: m * sub] < ctx.margin
    if ctx.p.mapping and ctx.cell.obstacles:
        bad |= _in_grown(ctx, P[: m * sub, :3, 3], times[: m * sub])
    if not bad.any():
        return (min(m * sub, n_ok)), d, idx, reason
    first = int(bad.argmax())
    if d[first] < ctx.margin:
        a, b = w.pair_names[idx[first]]
        reason = f"clearance {d[first]:.4f} m below {ctx.margin:.3f} m ({a} – {b})"
    else:
        reason = "object origin inside a grown obstacle (configuration mapping)"
    return first, d, idx, reason


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


def _permitted_lazy(ctx: _Ctx, ln: _Line, q0: FloatArray, t0: float, dt: float, first: int, d0: float):
    """:func:`_permitted_prefix` over a solved line in two chunks (``first`` poses, then the rest):
    a refusal near the start (the common case after a recovery) costs only the first chunk's
    clearance queries."""
    n = ln.P.shape[0]
    D, I = np.full(n, np.nan), np.zeros(n, dtype=np.int64)
    start, chunk, q = 0, max(1, first), q0
    while start < n:
        end = min(n, start + chunk)
        n_ik = min(max(ln.n_ok - start, 0), end - start)
        why = ln.reason if ln.n_ok < end else ""
        n_ok, d, idx, reason = _permitted_prefix(ctx, ln.P[start:end], ln.Q[start:end], n_ik, why, q, t0 + start * dt, dt, d0)
        D[start : start + n_ok], I[start : start + n_ok] = d[:n_ok], idx[:n_ok]
        if n_ok < end - start:
            return start + n_ok, D, I, reason
        q = ln.Q[end - 1]
        d0 = float(d[n_ok - 1])
        start, chunk = end, n  # the first chunk survived: the rest in one go
    return n, D, I, ""


class _Segment:
    """Result of trying to move from the current pose towards a target."""

    __slots__ = ("P", "d", "idx", "line", "n", "n_acc", "qL", "qR", "reason", "rpy")


def _try_segment(ctx: _Ctx, A, rpy_a, q, B, rpy_b, k0: int, d0: float, line: _Line | None = None) -> _Segment:
    """Move A -> B in steps; returns how many whole steps are permitted (with refinement on jumps).
    ``q`` = (q_left, q_right) at A, ``d0`` the clearance there (step k0) [m]; ``line``: A -> B at
    the default step, already solved from q (see :func:`_solve_lines`)."""
    p = ctx.p
    step = p.step
    sub = p.substeps
    q12 = np.concatenate(q)
    while True:
        if line is None:
            line = _Line(ctx, A, B, rpy_a, rpy_b, step)
            _solve_lines(ctx, [line], q12)
        P, rpy, m, Q = line.P, line.rpy, line.m, line.Q
        n_fine, d, idx, reason = _permitted_lazy(ctx, line, q12, k0 * p.step_time, p.step_time / sub, 2 * sub, d0)
        n_acc = n_fine // sub
        rows = np.arange(1, n_acc + 1) * sub - 1
        # the seed's RobMov bound holds per step: refine the step when a joint would move too far
        Qs = Q[rows]
        dq = np.abs(Qs - np.vstack([q12, Qs[:-1]])).max(axis=1) if n_acc else Qs[:, 0]
        too_far = np.flatnonzero(dq > p.max_joint_step)
        if too_far.size and step > p.min_step:
            step = max(p.min_step, step / 2)
            line = None
            continue
        if too_far.size:
            n_acc = int(too_far[0])
            rows = rows[:n_acc]
            reason = f"a joint would move more than {math.degrees(p.max_joint_step):.1f} deg in one step"
        if p.twist_buffer > 0 and n_acc and _angle(A[:3, :3], B[:3, :3]) > 1e-9:
            n_acc, rows, reason = _twist_check(ctx, P, Q, rows, n_acc, reason)
        seg = _Segment()
        seg.P, seg.rpy = P[rows], rpy[rows]
        Qs = Q[rows]
        seg.qL, seg.qR = Qs[:, :6], Qs[:, 6:]
        seg.d, seg.idx = d[rows], idx[rows]
        seg.n_acc, seg.n, seg.reason, seg.line = n_acc, m, reason, line
        return seg


def _twist_check(ctx: _Ctx, P, Q, rows, n_acc: int, reason: str):
    """Twisting detector over the accepted steps (see StrivingParams.twist_buffer)."""
    buf = ctx.p.twist_buffer
    prev = ctx.last_aa
    for i, r in enumerate(rows[:n_acc]):
        d, pair = ctx.arm_arm(Q[r, :6], Q[r, 6:], P[r])
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
